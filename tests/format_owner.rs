//! The dataset directory has one owner, `bettimill-format`:
//!
//! - no other crate parses JSON of the directory (records, labels, `build.json`) itself:
//!   outside the format crate, library and binary sources never call `serde_json::from_*`,
//!   and audit and preview never hold a `serde_json::Value`;
//! - no other crate spells the layout (`join("records")`, `join("build.json")`, ...);
//! - the storage crate `bettimill-shard` knows no dataset: no layout names, no records,
//!   no index, and it does not depend on the format crate (storage below, format above);
//! - audit, preview and the CLI depend on the format crate, preview no longer on sample;
//! - a directory started by another bettimill version is refused, naming both versions;
//! - every file a build writes is covered by `index.json` and checked by `verify`;
//! - `classes.json` says what every `KEY.cls` of the dataset means.

use std::path::{Path, PathBuf};

mod common;
use common::{repo_root as workspace, run as bettimill};

/// The non-test part of every `.rs` file under `crates/NAME/src`: everything before the
/// first `#[cfg(test)]`, and nothing of files named `tests.rs`.
fn sources(krate: &str) -> Vec<(PathBuf, String)> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs")
                && path.file_name().is_some_and(|n| n != "tests.rs")
            {
                out.push(path);
            }
        }
    }
    let mut files = Vec::new();
    walk(
        &workspace().join("crates").join(krate).join("src"),
        &mut files,
    );
    assert!(!files.is_empty(), "no sources for {krate}");
    files.sort();
    files
        .into_iter()
        .map(|path| {
            let text = std::fs::read_to_string(&path).unwrap();
            let code = match text.find("#[cfg(test)]") {
                Some(at) => text[..at].to_string(),
                None => text,
            };
            (path, code)
        })
        .collect()
}

const READERS: [&str; 6] = [
    "bettimill-shard",
    "bettimill-executor",
    "bettimill-audit",
    "bettimill-preview",
    "bettimill-cli",
    "bettimill-sample",
];

#[test]
fn only_the_format_crate_parses_directory_json() {
    let mut offences = Vec::new();
    for krate in READERS {
        for (path, code) in sources(krate) {
            for needle in [
                "serde_json::from_slice",
                "serde_json::from_str",
                "serde_json::from_reader",
                "serde_json::from_value",
                "serde_json::Deserializer",
            ] {
                if code.contains(needle) {
                    offences.push(format!("{}: {needle}", path.display()));
                }
            }
            if (krate == "bettimill-audit" || krate == "bettimill-preview")
                && code.contains("serde_json::Value")
            {
                offences.push(format!("{}: serde_json::Value", path.display()));
            }
        }
    }
    assert!(
        offences.is_empty(),
        "read the dataset directory through bettimill-format instead:\n{}",
        offences.join("\n")
    );
}

#[test]
fn only_the_format_crate_spells_the_layout() {
    let mut offences = Vec::new();
    for krate in READERS {
        for (path, code) in sources(krate) {
            for file in [
                "records",
                "shards",
                "build.json",
                "index.json",
                "manifest.toml",
                "README.md",
            ] {
                let needle = format!("join(\"{file}\")");
                if code.contains(&needle) {
                    offences.push(format!("{}: {needle}", path.display()));
                }
            }
        }
    }
    assert!(
        offences.is_empty(),
        "use bettimill_format::DatasetDir for paths inside a dataset:\n{}",
        offences.join("\n")
    );
}

/// Where `code` (Rust source) names a dataset concept the storage crate must not know:
/// `(line number, what)` for each, comment lines left out.
fn dataset_concepts(code: &str) -> Vec<(usize, &'static str)> {
    const CONCEPTS: [&str; 12] = [
        "\"shards",
        "\"records",
        "\"timings",
        "index.json",
        "build.json",
        "classes.json",
        "manifest.toml",
        "ShardRecord",
        "MemberRecord",
        "IndexShard",
        "IndexHeader",
        "read_index",
    ];
    let mut found = Vec::new();
    for (number, line) in code.lines().enumerate() {
        if line.trim_start().starts_with("//") {
            continue;
        }
        for concept in CONCEPTS {
            if line.contains(concept) {
                found.push((number + 1, concept));
            }
        }
    }
    found
}

#[test]
fn the_storage_crate_knows_no_dataset() {
    // The checker sees what it must refuse, and passes what storage may say.
    let bad = "fn f() {\n    let p = dir.join(\"shards\");\n    read_index(p);\n}\n";
    assert_eq!(
        dataset_concepts(bad),
        vec![(2, "\"shards"), (3, "read_index")]
    );
    assert!(dataset_concepts("/// index.json is format's\nfn tar_bytes() {}\n").is_empty());
    let mut offences = Vec::new();
    for (path, code) in sources("bettimill-shard") {
        for (line, concept) in dataset_concepts(&code) {
            offences.push(format!("{}:{line}: {concept}", path.display()));
        }
    }
    assert!(
        offences.is_empty(),
        "bettimill-shard is storage only; the dataset's layout, records and index belong \
         to bettimill-format:\n{}",
        offences.join("\n")
    );
    let manifest =
        std::fs::read_to_string(workspace().join("crates/bettimill-shard/Cargo.toml")).unwrap();
    assert!(
        !manifest.contains("bettimill-format"),
        "bettimill-shard must not depend on bettimill-format"
    );
}

#[test]
fn readers_depend_on_the_format_crate() {
    for krate in [
        "bettimill-executor",
        "bettimill-audit",
        "bettimill-preview",
        "bettimill-cli",
        "bettimill-sample",
    ] {
        let toml =
            std::fs::read_to_string(workspace().join("crates").join(krate).join("Cargo.toml"))
                .unwrap();
        assert!(
            toml.contains("bettimill-format.workspace = true"),
            "{krate} must read the directory through bettimill-format"
        );
        if krate == "bettimill-preview" {
            assert!(
                !toml.contains("bettimill-sample"),
                "preview needs only the label, which lives in bettimill-format"
            );
        }
    }
}

/// A 2D dataset of 4 balls in two shards ([`SMALL`]), built in `dir`: the manifest's path
/// and the output directory.
fn built_dataset(dir: &Path) -> (PathBuf, PathBuf) {
    built_from(dir, SMALL, "out")
}

const SMALL: &str =
    "schema_version = 1\nname = \"v\"\ndimension = 2\nside = 16\nmode = [\"embed\"]\n\
     samples = 4\nshard_size = 2\nseed = 1\n\n[[classes]]\nfamily = \"ball\"\n";

/// Writes `text` as `DIR/m.toml` and builds it into `DIR/out_name` with one worker.
fn built_from(dir: &Path, text: &str, out_name: &str) -> (PathBuf, PathBuf) {
    let manifest = dir.join("m.toml");
    std::fs::write(&manifest, text).unwrap();
    let out = dir.join(out_name);
    let built = bettimill(&[
        "build",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--workers",
        "1",
    ]);
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    (manifest, out)
}

#[test]
fn a_directory_of_another_tool_version_is_refused_naming_both_versions() {
    let tmp = tempfile::tempdir().unwrap();
    let (manifest, out) = built_dataset(tmp.path());
    let (m, o) = (manifest.to_str().unwrap(), out.to_str().unwrap());
    // Pretend an older bettimill started the directory.
    let build_json = out.join("build.json");
    let text = std::fs::read_to_string(&build_json).unwrap();
    let version = env!("CARGO_PKG_VERSION");
    let older = text.replace(
        &format!("\"tool_version\": \"{version}\""),
        "\"tool_version\": \"0.0.1-old\"",
    );
    assert_ne!(older, text, "build.json records the tool version");
    std::fs::write(&build_json, &older).unwrap();
    let shard = out.join("shards").join("v-000001.tar");
    std::fs::remove_file(&shard).unwrap();
    for args in [
        vec!["build", m, "--out", o, "--quiet", "--workers", "1"],
        vec!["status", o],
        vec!["finalize", o, "--quiet"],
    ] {
        let refused = bettimill(&args);
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert!(!refused.status.success(), "{args:?} must refuse: {stderr}");
        assert!(
            stderr.contains("built by bettimill 0.0.1-old")
                && stderr.contains(&format!("this is bettimill {version}")),
            "{args:?}: {stderr}"
        );
    }
    assert!(
        !shard.exists(),
        "nothing is written into the other version's directory"
    );
}

#[test]
fn verify_and_audit_of_an_index_of_format_version_1_say_so() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, out) = built_dataset(tmp.path());
    let o = out.to_str().unwrap();
    assert!(bettimill(&["verify", o]).status.success());
    // What bettimill 0.1.0 wrote before the index grew with shards: format_version 1, every
    // member listed, no shard_count.
    let index = out.join("index.json");
    let text = std::fs::read_to_string(&index).unwrap();
    let old = text
        .replace("\"format_version\": 3", "\"format_version\": 1")
        .replace("  \"shard_count\": 2,\n  \"samples\": 4,\n", "")
        .replace("\"record_blake3\"", "\"members\": [], \"x\"");
    assert_ne!(old, text);
    std::fs::write(&index, &old).unwrap();
    for args in [vec!["verify", o], vec!["audit", o, "--relabel"]] {
        let refused = bettimill(&args);
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert_eq!(refused.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("format_version 1") && stderr.contains("bettimill finalize"),
            "{args:?}: {stderr}"
        );
    }
    // finalize rewrites it from the records, byte for byte as before.
    let finalized = bettimill(&["finalize", o, "--quiet"]);
    assert!(
        finalized.status.success(),
        "{}",
        String::from_utf8_lossy(&finalized.stderr)
    );
    assert_eq!(std::fs::read_to_string(&index).unwrap(), text);
}

#[test]
fn every_file_a_build_writes_is_listed_in_the_index_and_checked_by_verify() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, out) = built_dataset(tmp.path());
    let o = out.to_str().unwrap();
    let index = std::fs::read(out.join("index.json")).unwrap();
    let index = bettimill_format::Index::from_json_bytes(&index, Path::new("index.json")).unwrap();
    let listed: Vec<&str> = index.header.files.iter().map(|f| f.name.as_str()).collect();
    // Every top-level file but the index itself and the lock; shards and records are
    // covered by the shard entries.
    let mut on_disk: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_type().unwrap().is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n != "index.json" && n != ".lock")
        .collect();
    on_disk.sort();
    assert_eq!(listed, on_disk);
    for name in bettimill_format::REQUIRED_FILES {
        assert!(listed.contains(name), "{name} is listed");
    }
    // One changed byte in any of them is found, naming the file.
    for name in &on_disk {
        let path = out.join(name);
        let original = std::fs::read(&path).unwrap();
        let mut changed = original.clone();
        changed[original.len() / 2] ^= 1;
        std::fs::write(&path, &changed).unwrap();
        let found = bettimill(&["verify", o]);
        let stdout = String::from_utf8_lossy(&found.stdout);
        assert_eq!(found.status.code(), Some(1), "{name}: {stdout}");
        assert!(stdout.contains(&format!("{name}: ")), "{name}: {stdout}");
        std::fs::write(&path, &original).unwrap();
        std::fs::remove_file(&path).unwrap();
        let missing = bettimill(&["verify", o]);
        assert_eq!(missing.status.code(), Some(1), "{name} removed");
        std::fs::write(&path, &original).unwrap();
    }
    assert!(bettimill(&["verify", o]).status.success());
    // The index's own identity is checked against build.json.
    let index_path = out.join("index.json");
    let text = std::fs::read_to_string(&index_path).unwrap();
    let wrong = text.replace(
        &format!("\"manifest_hash\": \"{}\"", index.header.manifest_hash),
        &format!("\"manifest_hash\": \"{}\"", "0".repeat(64)),
    );
    assert_ne!(wrong, text);
    std::fs::write(&index_path, wrong).unwrap();
    let found = bettimill(&["verify", o]);
    let stdout = String::from_utf8_lossy(&found.stdout);
    assert_eq!(found.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("index.json: manifest_hash is 000") && stdout.contains("build.json says"),
        "{stdout}"
    );
}

#[test]
fn classes_json_says_what_every_cls_of_the_dataset_means() {
    let tmp = tempfile::tempdir().unwrap();
    // Two modes and two classes of equal Betti numbers in 2D (a handle embedded, a ball
    // carved: both [1, 1]), so strata outnumber topology classes.
    let text = SMALL
        .replace("mode = [\"embed\"]", "mode = [\"embed\", \"carve\"]")
        .replace("samples = 4", "samples = 8")
        .replace("side = 16", "side = 24")
        + "\n[[classes]]\nfamily = \"handle\"\n";
    let (_, out) = built_from(tmp.path(), &text, "classes");
    let table = bettimill_format::DatasetDir::new(&out)
        .read_class_table()
        .unwrap();
    assert_eq!(table.classes, 4);
    assert_eq!(table.topology_classes, 3, "{table:#?}");
    let mut seen = 0;
    for entry in std::fs::read_dir(out.join("shards")).unwrap() {
        let bytes = std::fs::read(entry.unwrap().path()).unwrap();
        let members = bettimill_shard::read_tar(&bytes).unwrap();
        for member in members.iter().filter(|m| m.name.ends_with(".json")) {
            let label = bettimill_format::Label::from_json(&member.data).unwrap();
            let cls_name = member.name.replace(".json", ".cls");
            let cls = members.iter().find(|m| m.name == cls_name).unwrap();
            let cls: usize = std::str::from_utf8(&cls.data).unwrap().parse().unwrap();
            let entry = &table.strata[cls];
            assert_eq!(entry.cls, cls);
            assert_eq!(entry.name, label.class_label);
            assert_eq!(entry.betti, label.betti);
            assert_eq!(entry.mode, label.mode);
            assert_eq!(entry.knot_type, label.knot_type);
            let topology = &table.topology[entry.topology_class];
            assert_eq!(topology.betti, label.betti);
            seen += 1;
        }
    }
    assert_eq!(seen, 8);
    let counted: u64 = table.strata.iter().map(|s| s.samples).sum();
    assert_eq!(counted, 8);
}
