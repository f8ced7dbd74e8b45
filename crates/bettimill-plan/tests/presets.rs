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
        "18a4e67205e80126bc17d1b7b9a5d3d6aaad57d119fea70a685d15c41fd68a47",
    ),
    (
        "demo-2d.toml",
        "cc2354e39875e9c53d7fb5c6189489551e2077ce40d68d449fce53ccacd2d22c",
        "c616738139d6d8d86d7bf33953ee9ecc898320a3f900bbbaddbbebe0a70b8870",
    ),
    (
        "demo-3d.toml",
        "cd84651b630c278590e533c4446138fc8450c1a2aa8a02cc16306832a37e04a3",
        "d1710307f8f24afae489c3c8caf466e0178f38345b32f5c6129f251ce92f733c",
    ),
    (
        "demo-4d.toml",
        "7cde66fdff2b0f6b9510368e9df75b45f28d258d081e11aafdbbfeaf77d60678",
        "cc0abbf760278291266688436f0d9b88e13ad0404c4ea6202f7b242ce56aaabb",
    ),
    (
        "paper-figures.toml",
        "d70501597856eb02a72a5b63ecd1202512bdcd3d4132e1269d3ba75f7b65eb1c",
        "293d41b49a29fe63ebc01c040af8e1d7b7f44fb9dd2d0587d4dafbd3f41de4b6",
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
