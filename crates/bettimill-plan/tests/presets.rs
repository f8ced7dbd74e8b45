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
        "8572852c10283c011f41c064ffbb3cb343d1cfbe4ae71a5d07bab84a49edd3ad",
        "da639d8a221a0351c7b8ca0ff3351f4d689e2cb46e31d52ac8027a61a7df7496",
    ),
    (
        "demo-2d.toml",
        "4d054ea08eaf4c49b8518cad775a85a221313d7be2bf464a96008e7069deab66",
        "a0318a52a37f9e5e2812392e4c9db0a68f1f8b5e8a49b974cbd1596347200038",
    ),
    (
        "demo-3d.toml",
        "961e048ae115da8939a8227633826acac87c68499ca01d0a8020c211c439be6b",
        "87f6da0fce4d30ffdd92d33723d9cdad1d73e59af5d8db0424ae254a5987fdd4",
    ),
    (
        "demo-4d.toml",
        "45234cd5bb2bb89b461ccd66bf9a9d1ff06bffd50616549b4e0f508fdd08f308",
        "3108433fbe7a22565280540f4d3894e837d1187363adea6869f642e27293bb7a",
    ),
    (
        "paper-figures.toml",
        "2a7b1641b213f6aa5013a6422a291713d73708cd08abe5cb626481c898c4c8dd",
        "49a3a1b67b0ee06d6f89bd0bfc76f247a4b7731a9a408e27f268c98104da20e1",
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
