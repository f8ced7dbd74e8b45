use super::*;
use bettimill_manifest::Manifest;

const MANIFEST: &str = r#"schema_version = 1
name = "audit"
dimension = 2
side = 20
mode = ["embed", "carve"]
samples = 12
shard_size = 4
seed = 5
resolutions = [10]

[[classes]]
family = ["ball", "handle"]
"#;

fn built(dir: &Path) -> Dataset {
    let manifest = Manifest::parse(MANIFEST, Path::new("audit.toml")).unwrap();
    let dataset = Dataset::bind(dir, MANIFEST, manifest).unwrap();
    dataset.build_in_process(|_, _| {}).unwrap();
    dataset
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "bettimill-audit-test-{}-{name}",
        std::process::id(),
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn a_clean_dataset_rebuilds_identically_and_relabels_cleanly() {
    let dir = scratch("clean");
    let dataset = built(&dir);
    let all = select(
        &dataset,
        &Selection::Fraction {
            fraction: 1.0,
            seed: 0,
        },
    )
    .unwrap();
    assert_eq!(all.len(), 3);
    let ticks = std::sync::atomic::AtomicU64::new(0);
    let tick = || {
        ticks.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    };
    let report = rebuild_with_progress(&dir, &all, &tick).unwrap();
    assert_eq!(report.rebuilt.len(), 3);
    assert!(report.findings.is_empty(), "{:?}", report.findings);
    assert_eq!(ticks.load(std::sync::atomic::Ordering::Relaxed), 12);
    let report = relabel_with_progress(&dir, &all, &tick).unwrap();
    assert_eq!(report.relabelled_samples, 12);
    assert!(report.findings.is_empty(), "{:?}", report.findings);
    assert_eq!(ticks.load(std::sync::atomic::Ordering::Relaxed), 24);
    assert_eq!(relabel(&dir, &all).unwrap(), report);
    assert!(!dir.join(format!(".audit-{}", std::process::id())).exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_tampered_shard_is_named_exactly() {
    let dir = scratch("tampered");
    let dataset = built(&dir);
    let target = dataset.plan.shard(1);
    let path = dataset.tar_path(&target);
    let mut bytes = std::fs::read(&path).unwrap();
    // Change one voxel of the first array: the rebuild must name that member.
    let entries = bettimill_shard::tar_entries(&bytes, u64::MAX).unwrap();
    let npy = entries.iter().find(|e| e.name.ends_with(".npy")).unwrap();
    let name = npy.name.to_string();
    let offset = npy.header_offset as usize + 512 + npy.data.len() - 1;
    drop(entries);
    bytes[offset] ^= 1;
    std::fs::write(&path, &bytes).unwrap();
    let chosen = select(&dataset, &Selection::Shards(vec!["1".into()])).unwrap();
    let report = rebuild(&dir, &chosen).unwrap();
    assert_eq!(
        report.findings,
        vec![Finding::RebuildDiffers {
            shard: target.name.clone(),
            offset: offset as u64,
            member: Some(name),
        }]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn fractions_choose_reproducibly() {
    let dir = scratch("fractions");
    let dataset = built(&dir);
    let a = select(
        &dataset,
        &Selection::Fraction {
            fraction: 0.5,
            seed: 1,
        },
    )
    .unwrap();
    let b = select(
        &dataset,
        &Selection::Fraction {
            fraction: 0.5,
            seed: 1,
        },
    )
    .unwrap();
    assert_eq!(a, b);
    assert_eq!(a.len(), 2);
    assert!(select(
        &dataset,
        &Selection::Fraction {
            fraction: 0.0,
            seed: 1
        }
    )
    .is_err());
    assert!(select(&dataset, &Selection::Shards(vec!["nope".into()])).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}
