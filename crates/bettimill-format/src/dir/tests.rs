//! Unit tests of the dataset directory: binding, identity refusals, the tar check through
//! shard states, leftovers of a stopped creation and links.

use super::*;
use crate::{FormatError, ShardRecord, TOOL_VERSION};
use std::path::Path;

fn bound(dir: &Path) -> (DatasetDir, BuildInfo) {
    let layout = DatasetDir::new(dir.join("ds"));
    let info = BuildInfo::current("m1", "p1");
    layout.bind("name = \"x\"\n", &info).unwrap();
    (layout, info)
}

/// The message `verify` gives for a path without `index.json`.
fn not_a_dataset(path: &Path) -> String {
    match DatasetDir::new(path).verify(&mut |_, _| {}) {
        Err(err @ FormatError::NotADataset { .. }) => err.to_string(),
        other => panic!("{}: expected NotADataset, got {other:?}", path.display()),
    }
}

#[test]
fn verify_of_a_non_dataset_says_what_the_path_holds() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    assert!(not_a_dataset(&root.join("nowhere")).ends_with("it does not exist"));
    std::fs::write(root.join("file.txt"), "x").unwrap();
    assert!(not_a_dataset(&root.join("file.txt")).contains("it is a file"));
    let empty = root.join("empty");
    std::fs::create_dir(&empty).unwrap();
    assert!(not_a_dataset(&empty).ends_with("it is empty"));
    let photos = root.join("photos");
    std::fs::create_dir(&photos).unwrap();
    for name in [
        "b.png", "a.png", "c.png", "d.png", "e.png", "f.png", "g.png",
    ] {
        std::fs::write(photos.join(name), "x").unwrap();
    }
    let message = not_a_dataset(&photos);
    assert!(
            message.ends_with(
                "it holds 7 entries (a.png, b.png, c.png, d.png, e.png and 2 more) and none of a dataset's files"
            ),
            "{message}"
        );
    // A dataset one level down, and a build that has not finished.
    let (layout, _) = bound(root);
    let message = not_a_dataset(&layout.root);
    assert!(message.contains("has not finished (build.json and 0 completed shard(s))"));
    assert!(
        message.contains("bettimill build MANIFEST --out"),
        "{message}"
    );
    std::fs::write(layout.index_path(), "{}").unwrap();
    let message = not_a_dataset(root);
    assert!(message.contains(&format!("one level down: {}", layout.root.display())));
}

#[test]
fn binding_creates_the_identity_files_and_accepts_the_same_identity() {
    let tmp = tempfile::tempdir().unwrap();
    let (layout, info) = bound(tmp.path());
    assert_eq!(layout.read_build_info().unwrap(), info);
    assert_eq!(layout.read_manifest_text().unwrap(), "name = \"x\"\n");
    assert!(layout.shards_dir().is_dir() && layout.records_dir().is_dir());
    layout.bind("ignored", &info).unwrap();
    assert_eq!(layout.read_manifest_text().unwrap(), "name = \"x\"\n");
}

#[test]
fn another_tool_version_or_plan_or_manifest_is_refused_naming_both() {
    let tmp = tempfile::tempdir().unwrap();
    let (layout, info) = bound(tmp.path());
    let before = std::fs::read(layout.build_info_path()).unwrap();
    // A build.json written by another bettimill version.
    let mut older = info.clone();
    older.tool_version = "0.0.9".into();
    let mut bytes = serde_json::to_vec_pretty(&older).unwrap();
    bytes.push(b'\n');
    std::fs::write(layout.build_info_path(), &bytes).unwrap();
    let err = layout.bind("x", &info).unwrap_err().to_string();
    assert!(err.contains("built by bettimill 0.0.9"), "{err}");
    assert!(
        err.contains(&format!("this is bettimill {TOOL_VERSION}")),
        "{err}"
    );
    assert_eq!(std::fs::read(layout.build_info_path()).unwrap(), bytes);

    std::fs::write(layout.build_info_path(), &before).unwrap();
    let other_plan = BuildInfo::current("m1", "p2");
    let err = layout.bind("x", &other_plan).unwrap_err().to_string();
    assert!(err.contains("holds plan p1"), "{err}");
    assert!(err.contains("as p2"), "{err}");
    assert!(
        err.contains(&format!("built by bettimill {TOOL_VERSION}")),
        "{err}"
    );

    let other_manifest = BuildInfo::current("m2", "p1");
    let err = layout.bind("x", &other_manifest).unwrap_err();
    assert!(
        matches!(err, FormatError::DifferentManifest { .. }),
        "{err}"
    );
}

#[test]
fn a_non_empty_foreign_directory_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("x"), b"x").unwrap();
    let err = DatasetDir::new(tmp.path())
        .bind("", &BuildInfo::current("m", "p"))
        .unwrap_err();
    assert!(matches!(err, FormatError::ForeignDirectory { .. }), "{err}");
}

#[test]
fn tar_check_and_shard_state() {
    let tmp = tempfile::tempdir().unwrap();
    let (layout, _) = bound(tmp.path());
    assert_eq!(layout.shard_state("t-000000"), ShardState::Missing);
    let member = bettimill_shard::Member::new("s0.json", b"{}".to_vec());
    let (bytes, record) =
        crate::build_shard("shards/t-000000.tar", "train", &[vec![member]]).unwrap();
    std::fs::write(layout.tar_path("t-000000"), &bytes).unwrap();
    assert!(matches!(
        layout.shard_state("t-000000"),
        ShardState::Invalid { .. }
    ));
    let completion = CompletionRecord {
        shard: record.clone(),
        regenerations: vec![],
    };
    layout.write_record("t-000000", &completion).unwrap();
    assert_eq!(
        layout.shard_state("t-000000"),
        ShardState::Complete(completion.clone())
    );
    assert_eq!(layout.record_names().unwrap(), vec!["t-000000"]);
    assert_eq!(layout.shard_names().unwrap(), vec!["t-000000"]);
    for (byte, found) in [
        (513, "data of member s0.json"),
        (600, "at 600 after member s0.json"),
        (3, "(at byte 0) is corrupt from byte 3"),
        (bytes.len() - 1, "end-of-archive marker"),
    ] {
        let mut flipped = bytes.clone();
        flipped[byte] ^= 1;
        std::fs::write(layout.tar_path("t-000000"), &flipped).unwrap();
        assert!(layout.recorded("t-000000").is_some(), "same size");
        let ShardState::Invalid { reason } = layout.shard_state("t-000000") else {
            panic!("a flipped byte {byte} must be found");
        };
        assert!(reason.contains(found), "{byte}: {reason}");
    }
    std::fs::write(layout.tar_path("t-000000"), &bytes[..1024]).unwrap();
    assert!(layout.recorded("t-000000").is_none());
    assert!(layout
        .check_tar("t-000000", &record, TarCheck::Size)
        .unwrap_err()
        .to_string()
        .contains("1024 bytes"));
}

#[test]
fn a_record_is_checked_whole_against_its_tar() {
    let tmp = tempfile::tempdir().unwrap();
    let (layout, _) = bound(tmp.path());
    let samples = vec![
        vec![
            bettimill_shard::Member::new("s0.json", b"{}".to_vec()),
            bettimill_shard::Member::new("s0.npy", vec![1u8; 700]),
        ],
        vec![bettimill_shard::Member::new("s1.json", b"[]".to_vec())],
    ];
    let (bytes, record) = crate::build_shard("shards/t-000000.tar", "train", &samples).unwrap();
    std::fs::write(layout.tar_path("t-000000"), &bytes).unwrap();
    let write = |record: &ShardRecord| {
        let completion = CompletionRecord {
            shard: record.clone(),
            regenerations: vec![],
        };
        layout.write_record("t-000000", &completion).unwrap();
    };
    write(&record);
    assert!(matches!(
        layout.shard_state("t-000000"),
        ShardState::Complete(_)
    ));
    type Edit = fn(&mut ShardRecord);
    let edits: [(Edit, &str); 6] = [
        (
            |r| r.members[1].blake3.replace_range(0..1, "x"),
            "data of member s0.npy",
        ),
        (
            |r| r.members[2].offset += 512,
            "puts member s1.json at byte",
        ),
        (
            |r| r.members[1].name = "s0.npz".into(),
            "member s0.npz (at byte 1024)",
        ),
        (|r| r.samples = 3, "its record says 3 samples"),
        (|r| r.last_key = "s9".into(), "from s0 to s9"),
        (|r| r.name = "shards/u-000000.tar".into(), "names the shard"),
    ];
    for (edit, found) in edits {
        let mut bad = record.clone();
        edit(&mut bad);
        write(&bad);
        let ShardState::Invalid { reason } = layout.shard_state("t-000000") else {
            panic!("{found}: the edited record was accepted");
        };
        assert!(reason.contains(found), "{found}: {reason}");
    }
}

#[test]
fn the_leftovers_of_a_stopped_creation_are_told_from_foreign_files() {
    let tmp = tempfile::tempdir().unwrap();
    let layout = DatasetDir::new(tmp.path().join("ds"));
    assert_eq!(layout.unbound_state().unwrap(), Unbound::Empty);
    std::fs::create_dir(layout.root()).unwrap();
    std::fs::write(layout.root().join(LOCK_FILE), b"").unwrap();
    assert_eq!(layout.unbound_state().unwrap(), Unbound::Empty);
    std::fs::write(layout.root().join(".build.json.tmp-12"), b"{").unwrap();
    std::fs::write(layout.manifest_path(), b"m").unwrap();
    assert_eq!(
        layout.unbound_state().unwrap(),
        Unbound::Unfinished {
            manifest: true,
            temporaries: vec![layout.root().join(".build.json.tmp-12")],
        }
    );
    assert!(matches!(
        layout.require_bound(),
        Err(FormatError::Unfinished { .. })
    ));
    let info = BuildInfo::current("m1", "p1");
    assert!(matches!(
        layout.bind("other", &info),
        Err(FormatError::UnfinishedOtherManifest { .. })
    ));
    layout.bind("m", &info).unwrap();
    assert_eq!(layout.read_build_info().unwrap(), info);
    assert!(!layout.root().join(".build.json.tmp-12").exists());
    for foreign in [".build.json.tmp-x", "shards", "notes"] {
        let other = DatasetDir::new(tmp.path().join(format!("f{foreign}")));
        std::fs::create_dir(other.root()).unwrap();
        std::fs::write(other.root().join(foreign), b"").unwrap();
        assert_eq!(
            other.unbound_state().unwrap(),
            Unbound::Foreign,
            "{foreign}"
        );
    }
}

#[test]
fn links_inside_the_directory_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let (layout, info) = bound(tmp.path());
    let outside = tmp.path().join("outside");
    std::fs::create_dir(&outside).unwrap();
    std::fs::remove_dir(layout.records_dir()).unwrap();
    std::os::unix::fs::symlink(&outside, layout.records_dir()).unwrap();
    let err = layout.bind("x", &info).unwrap_err();
    assert!(matches!(err, FormatError::Symlinked { .. }), "{err}");
    assert_eq!(
        dataset_containing(&layout.shards_dir().join("x.png")),
        Some(std::fs::canonicalize(layout.root()).unwrap())
    );
    // Through the link the file would land outside: that is the link's business.
    assert_eq!(
        dataset_containing(&layout.records_dir().join("x.png")),
        None
    );
    assert_eq!(dataset_containing(&outside.join("x.png")), None);
}
