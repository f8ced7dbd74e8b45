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
    rewrite_shard(dataset, index, &|members| {
        let json = members
            .iter_mut()
            .find(|m| m.name.ends_with(".json"))
            .unwrap();
        let mut label: serde_json::Value = serde_json::from_slice(&json.data).unwrap();
        edit(&mut label);
        json.data = serde_json::to_vec(&label).unwrap();
        json.data.push(b'\n');
    });
}

/// Rewrites the members of shard `index` with `edit`, then its record and index.json as an
/// attacker would.
fn rewrite_shard(dataset: &Dataset, index: u64, edit: &dyn Fn(&mut Vec<bettimill_shard::Member>)) {
    let shard = dataset.plan.shard(index);
    let bytes = std::fs::read(dataset.tar_path(&shard)).unwrap();
    let mut members = bettimill_shard::read_tar(&bytes).unwrap();
    edit(&mut members);
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
        // Fields the plan fixes for the sample.
        ("key", Box::new(|v| v["key"] = "train/s999999".into())),
        ("field", Box::new(|v| v["field"] = "Z/3".into())),
        ("seed", Box::new(|v| v["seed"] = "00".repeat(32).into())),
        (
            "manifest_hash",
            Box::new(|v| v["manifest_hash"] = "ab".repeat(32).into()),
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

/// Rewrites `file` of the dataset with `edit` and then updates its size and blake3 in
/// index.json in place, as an attacker would, so the hash check of `verify` passes.
fn forge(dir: &Path, file: &str, edit: &dyn Fn(&str) -> String) {
    let path = dir.join(file);
    let old = std::fs::read(&path).unwrap();
    let new = edit(std::str::from_utf8(&old).unwrap()).into_bytes();
    assert_ne!(old, new, "{file}: the edit changed nothing");
    std::fs::write(&path, &new).unwrap();
    rehash(dir, &old, &new);
}

/// Replaces the size and blake3 of `old` by those of `new` in index.json (in place: the
/// rest of its bytes stay the build's).
fn rehash(dir: &Path, old: &[u8], new: &[u8]) {
    let index_path = dir.join("index.json");
    let mut index = std::fs::read_to_string(&index_path).unwrap();
    let (old_hash, new_hash) = (
        bettimill_shard::blake3_hex(old),
        bettimill_shard::blake3_hex(new),
    );
    let at = index.find(&old_hash).expect("index.json lists the file");
    let bytes_at = index[..at].rfind("\"bytes\": ").unwrap() + "\"bytes\": ".len();
    let bytes_end = bytes_at + index[bytes_at..].find(',').unwrap();
    index.replace_range(at..at + old_hash.len(), &new_hash);
    index.replace_range(bytes_at..bytes_end, &new.len().to_string());
    std::fs::write(&index_path, index).unwrap();
}

/// The fields of findings naming `file`.
fn fields_of(findings: &[Finding], file: &str) -> Vec<String> {
    findings
        .iter()
        .filter_map(|f| match f {
            Finding::FileDiffers {
                file: name, field, ..
            } if name == file => Some(field.clone()),
            _ => None,
        })
        .collect()
}

/// A changed `topology_class` or `betti` in classes.json, a changed class table in the
/// card, a changed count in a wids index and a changed index.json (spacing only) used to
/// pass `verify` and `audit` once the hashes were rewritten: every file that is a pure
/// function of the plan is now regenerated and compared byte for byte, and the file and
/// field are named.
#[test]
fn forged_label_tables_are_named_by_file_and_field() {
    let dir = scratch("forged");
    let dataset = built(&dir);
    assert!(check_files(&dataset).is_empty());
    let pristine: Vec<(String, Vec<u8>)> = ["classes.json", "README.md", "index.json"]
        .iter()
        .map(|f| (f.to_string(), std::fs::read(dir.join(f)).unwrap()))
        .collect();
    let wids = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .find(|n| n.starts_with("shardindex-"))
        .unwrap();
    let wids_bytes = std::fs::read(dir.join(&wids)).unwrap();
    type Edit = Box<dyn Fn(&str) -> String>;
    let cases: Vec<(String, Edit, &str)> = vec![
        (
            "classes.json".into(),
            Box::new(|t: &str| t.replacen("\"topology_class\": 0", "\"topology_class\": 1", 1)),
            "topology_class",
        ),
        (
            "classes.json".into(),
            Box::new(|t: &str| {
                t.replacen("\"betti\": [\n        1,", "\"betti\": [\n        2,", 1)
            }),
            "betti",
        ),
        (
            "README.md".into(),
            Box::new(|t: &str| t.replacen("| 0 | ", "| 1 | ", 1)),
            "line ",
        ),
        (
            wids.clone(),
            Box::new(|t: &str| t.replacen("\"nsamples\": 4", "\"nsamples\": 5", 1)),
            "nsamples",
        ),
    ];
    for (file, edit, field) in &cases {
        forge(&dir, file, edit.as_ref());
        let verified = dataset.layout().verify(&mut |_, _| {}).unwrap();
        assert!(
            verified.problems.is_empty(),
            "{file}: {:?}",
            verified.problems
        );
        let findings = check_files(&dataset);
        assert!(
            fields_of(&findings, file).iter().any(|f| f.contains(field)),
            "forging {file} ({field}) was not named: {findings:?}"
        );
        for (name, bytes) in &pristine {
            std::fs::write(dir.join(name), bytes).unwrap();
        }
        std::fs::write(dir.join(&wids), &wids_bytes).unwrap();
        assert!(check_files(&dataset).is_empty(), "{file}: not restored");
    }
    // index.json itself, spacing only: its values are right, its bytes are not the build's.
    let index = std::fs::read_to_string(dir.join("index.json")).unwrap();
    std::fs::write(dir.join("index.json"), index.replacen("{\n", "{\n ", 1)).unwrap();
    let verified = dataset.layout().verify(&mut |_, _| {}).unwrap();
    assert!(verified.problems.is_empty(), "{:?}", verified.problems);
    assert_eq!(
        fields_of(&check_files(&dataset), "index.json"),
        vec!["(bytes)"]
    );
    std::fs::write(dir.join("index.json"), index).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A sample taken out of a shard, a member added to one and an array stored with another
/// dtype holding the same values passed relabelling; each is now a finding.
#[test]
fn relabel_finds_missing_samples_extra_members_and_foreign_npy_headers() {
    let dir = scratch("members");
    let dataset = built(&dir);
    let all: Vec<ShardPlan> = dataset.plan.shards().collect();
    let key_of = |name: &str| MemberName::parse(name).unwrap().key.to_string();
    // The second sample of shard 0 put under a key the plan does not have (its count
    // stays, so finalize accepts the record: the plan's sample is missing all the same).
    let tasks = dataset.plan.shard_tasks(&all[0]);
    let second = tasks[1].key.clone();
    rewrite_shard(&dataset, 0, &|members| {
        for member in members.iter_mut() {
            if key_of(&member.name) == second {
                member.name = member.name.replacen(&second, &format!("{second}x"), 1);
            }
        }
    });
    // A member `KEY.zz` added to the first sample of shard 1, and its image stored as bool.
    rewrite_shard(&dataset, 1, &|members| {
        let first = key_of(&members[0].name);
        let at = members
            .iter()
            .position(|m| key_of(&m.name) != first)
            .unwrap();
        let mut extra = members[0].clone();
        extra.name = format!("{first}.zz");
        members.insert(at, extra);
        let image = members
            .iter_mut()
            .find(|m| m.name == format!("{first}.npy"))
            .unwrap();
        let npy = bettimill_grid::npy::read_bytes(&image.data, true).unwrap();
        image.data = bettimill_grid::npy::write_bytes(
            &npy.image,
            bettimill_grid::npy::Dtype {
                kind: 'b',
                size: 1,
                big_endian: false,
            },
        );
    });
    let verified = dataset.layout().verify(&mut |_, _| {}).unwrap();
    assert!(verified.problems.is_empty(), "{:?}", verified.problems);
    let report = relabel(&dir, &all[..2]).unwrap();
    let text: Vec<String> = report.findings.iter().map(|f| f.to_string()).collect();
    assert!(
        report
            .findings
            .iter()
            .any(|f| matches!(f, Finding::SampleMissing { key, .. } if *key == second)),
        "{text:?}"
    );
    assert!(
        report
            .findings
            .iter()
            .any(|f| matches!(f, Finding::Unexpected { member, .. } if member.ends_with(".zz"))),
        "{text:?}"
    );
    assert!(
        report.findings.iter().any(
            |f| matches!(f, Finding::Unexpected { member, .. } if *member == format!("{second}x"))
        ),
        "{text:?}"
    );
    assert!(
        text.iter()
            .any(|t| t.contains(".npy: cannot decode: .npy header") && t.contains("|b1")),
        "{text:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
