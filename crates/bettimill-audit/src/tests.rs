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

/// Rewrites the label of the first sample of shard `index` with `edit`, then updates the
/// shard's record and index.json as an attacker would, so that `verify` passes and only
/// relabelling can tell.
fn tamper_label(dataset: &Dataset, index: u64, edit: &dyn Fn(&mut serde_json::Value)) {
    let shard = dataset.plan.shard(index);
    let bytes = std::fs::read(dataset.tar_path(&shard)).unwrap();
    let mut members = bettimill_shard::read_tar(&bytes).unwrap();
    let json = members
        .iter_mut()
        .find(|m| m.name.ends_with(".json"))
        .unwrap();
    let mut label: serde_json::Value = serde_json::from_slice(&json.data).unwrap();
    edit(&mut label);
    json.data = serde_json::to_vec(&label).unwrap();
    json.data.push(b'\n');
    let mut samples: Vec<Vec<bettimill_shard::Member>> = Vec::new();
    for member in members {
        let key = MemberName::parse(&member.name).unwrap().key.to_string();
        match samples.last_mut() {
            Some(last) if MemberName::parse(&last[0].name).unwrap().key == key => last.push(member),
            _ => samples.push(vec![member]),
        }
    }
    let relative = bettimill_format::DatasetDir::relative_tar_name(&shard.name);
    let (bytes, record) = bettimill_format::build_shard(&relative, &shard.split, &samples).unwrap();
    bettimill_shard::write_atomic(&dataset.tar_path(&shard), &bytes).unwrap();
    let old = dataset.layout().read_record(&shard.name).unwrap().unwrap();
    let record = bettimill_format::CompletionRecord {
        shard: record,
        regenerations: old.regenerations,
    };
    dataset.layout().write_record(&shard.name, &record).unwrap();
    dataset.finalize().unwrap();
}

#[test]
fn relabel_names_every_tampered_field_derived_from_the_voxels() {
    let dir = scratch("fields");
    let dataset = built(&dir);
    let all: Vec<ShardPlan> = dataset.plan.shards().collect();
    type Edit = Box<dyn Fn(&mut serde_json::Value)>;
    let bump = |field: &'static str| -> Edit {
        Box::new(move |v| v[field] = (v[field].as_i64().unwrap() + 1).into())
    };
    let copy = |field: &'static str| -> Edit {
        Box::new(move |v| {
            let r = &mut v["resolutions"][0][field];
            let changed: serde_json::Value = match &*r {
                serde_json::Value::Bool(b) => (!*b).into(),
                other => (other.as_i64().unwrap() + 1).into(),
            };
            *r = changed;
        })
    };
    let cases: Vec<(&str, Edit)> = vec![
        ("betti", Box::new(|v| v["betti"][1] = 7.into())),
        ("euler", bump("euler")),
        ("hypervolume", bump("hypervolume")),
        ("components", bump("components")),
        ("dim", bump("dim")),
        ("shape", Box::new(|v| v["shape"][0] = 21.into())),
        (
            "class_label",
            Box::new(|v| v["class_label"] = "ball/embed/x".into()),
        ),
        (
            "mode",
            Box::new(|v| {
                let other = if v["mode"] == "embed" {
                    "carve"
                } else {
                    "embed"
                };
                v["mode"] = other.into();
            }),
        ),
        ("family", Box::new(|v| v["family"] = "shell".into())),
        (
            "hypervolume_bin",
            Box::new(|v| v["hypervolume_bin"] = serde_json::json!([1, 2])),
        ),
        (
            "resolutions[0].betti",
            Box::new(|v| v["resolutions"][0]["betti"][0] = 9.into()),
        ),
        ("resolutions[0].euler", copy("euler")),
        ("resolutions[0].hypervolume", copy("hypervolume")),
        ("resolutions[0].preserved", copy("preserved")),
        (
            "resolutions[0].side",
            Box::new(|v| v["resolutions"][0]["side"] = 5.into()),
        ),
    ];
    // Clean first: every field agrees on an untouched dataset.
    let report = relabel(&dir, &all).unwrap();
    assert!(report.findings.is_empty(), "{:?}", report.findings);
    let original = std::fs::read(dataset.tar_path(&all[0])).unwrap();
    let original_record = dataset.layout().read_record(&all[0].name).unwrap().unwrap();
    for (field, edit) in &cases {
        tamper_label(&dataset, 0, edit.as_ref());
        // The tampering is invisible to verify: the hashes were updated.
        let verified = dataset.layout().verify(&mut |_, _| {}).unwrap();
        assert!(
            verified.problems.is_empty(),
            "{field}: {:?}",
            verified.problems
        );
        let report = relabel(&dir, &all[..1]).unwrap();
        let named: Vec<String> = report
            .findings
            .iter()
            .map(|f| match f {
                Finding::LabelDiffers { key, .. } if key.contains('@') => {
                    "resolutions[0].betti".to_string()
                }
                Finding::LabelDiffers { .. } => "betti".to_string(),
                Finding::FieldDiffers { field, .. } => field.clone(),
                other => format!("{other:?}"),
            })
            .collect();
        assert!(
            named.iter().any(|n| n == field),
            "tampering `{field}` was not named: {:?}",
            report.findings
        );
        // Put the shard back for the next case.
        bettimill_shard::write_atomic(&dataset.tar_path(&all[0]), &original).unwrap();
        dataset
            .layout()
            .write_record(&all[0].name, &original_record)
            .unwrap();
        dataset.finalize().unwrap();
    }
    let report = relabel(&dir, &all).unwrap();
    assert!(report.findings.is_empty(), "{:?}", report.findings);
    std::fs::remove_dir_all(&dir).unwrap();
}
