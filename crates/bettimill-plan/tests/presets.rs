//! Golden plan hashes for every preset in `manifests/`.
//!
//! A plan hash covers the strata, shards and dealing order, and sample seeds follow from the
//! manifest hash, so these two numbers pin down every sample of a preset. If a change to the
//! schema or the planner alters them on purpose, that is a new dataset: update the table
//! in the same commit and say so in the changelog.

use bettimill_manifest::Manifest;
use bettimill_plan::Plan;
use std::path::Path;

const GOLDEN: &[(&str, &str, &str)] = &[
    (
        "4d-mixed-128.toml",
        "0a569d549084b9b4769ee989a102a41083ef0a09629eea49d34c84284f7fcff6",
        "3b05e753a19c53473fce33d78fe19807dbc6dc9600465030ae3e3d9e3e783acc",
    ),
    (
        "demo-2d.toml",
        "cc2354e39875e9c53d7fb5c6189489551e2077ce40d68d449fce53ccacd2d22c",
        "410d10f4017a8c489acce4fa4b745dab8500d4fc8b34c377624c6d6d13ed7608",
    ),
    (
        "demo-3d.toml",
        "cd84651b630c278590e533c4446138fc8450c1a2aa8a02cc16306832a37e04a3",
        "25fbb9791a6d7a55d3129afbffd4a687ccfd2f50c3e0bd3b7e534f2b5206d17e",
    ),
    (
        "demo-4d.toml",
        "7cde66fdff2b0f6b9510368e9df75b45f28d258d081e11aafdbbfeaf77d60678",
        "29a3f52bd47961888298a1d6f534a6f72c2810924092c67f57dbc129406861b6",
    ),
    (
        "paper-figures.toml",
        "d70501597856eb02a72a5b63ecd1202512bdcd3d4132e1269d3ba75f7b65eb1c",
        "19bfc5d54081bbc79043986ab240161459e365ef294f033602f7cdf63ba551cb",
    ),
];

#[test]
fn every_preset_has_its_golden_plan() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../manifests");
    let mut presets: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    presets.sort();
    let listed: Vec<&str> = GOLDEN.iter().map(|g| g.0).collect();
    assert_eq!(presets, listed, "every preset needs a golden entry");
    for (file, manifest_hash, plan_hash) in GOLDEN {
        let manifest = Manifest::from_path(&dir.join(file)).unwrap();
        let plan = Plan::new(&manifest).unwrap();
        assert_eq!(&plan.manifest_hash, manifest_hash, "{file}");
        assert_eq!(&plan.hash(), plan_hash, "{file}");
        // Two expansions agree sample by sample, not only by hash.
        let again = Plan::new(&manifest).unwrap();
        let last = plan.shard(plan.shard_count() - 1);
        assert_eq!(plan.shard_tasks(&last), again.shard_tasks(&last), "{file}");
    }
}

#[test]
fn the_embedded_demo_is_the_3d_preset() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../manifests");
    assert_eq!(
        std::fs::read_to_string(dir.join("demo-3d.toml")).unwrap(),
        bettimill_manifest::DEMO_MANIFEST
    );
}
