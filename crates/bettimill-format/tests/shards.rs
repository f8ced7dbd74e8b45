//! Format and fault-injection tests of shards: property round trips, GNU tar compatibility
//! (failing in CI, skipped with a message elsewhere, without GNU tar), and `verify` against
//! flipped bytes, truncation, missing and extra files.

use bettimill_format::{
    build_shard, Index, IndexError, IndexShard, NoRecord, Problem, Region, ShardRecord,
    VerifyReport,
};
use bettimill_shard::ustar::{header_block, tar_len};
use bettimill_shard::{
    blake3_hex, compress, read_tar, read_tar_with_limit, tar_bytes, write_atomic, Compression,
    Member, ShardError,
};
use proptest::prelude::*;
use std::path::Path;
use std::process::Command;

fn sample(key: &str, sizes: [usize; 3]) -> Vec<Member> {
    ["cls", "json", "npy"]
        .iter()
        .zip(sizes)
        .map(|(field, size)| {
            let data = (0..size)
                .map(|i| (i * 31 + key.len()) as u8 | 1)
                .collect::<Vec<u8>>();
            Member::new(format!("{key}.{field}"), data)
        })
        .collect()
}

/// Writes a two-shard dataset and returns its directory and records.
fn dataset() -> (tempfile::TempDir, Vec<ShardRecord>) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("shards")).unwrap();
    let mut records = Vec::new();
    for (shard, first) in [(0, 0), (1, 3)] {
        let samples: Vec<_> = (first..first + 3)
            .map(|i| sample(&format!("train/s{i:06}"), [1, 200 + i, 512 * (i % 2) + 700]))
            .collect();
        let name = format!("shards/train-{shard:06}.tar");
        let (bytes, record) = build_shard(&name, "train", &samples).unwrap();
        write_atomic(&dir.path().join(&name), &bytes).unwrap();
        records.push(record);
    }
    write_index(dir.path(), &records);
    (dir, records)
}

/// Writes index.json listing `records`, each record beside it as `records/STEM.json` (the
/// sidecar the index's `record_blake3` covers).
fn write_index(dir: &Path, records: &[ShardRecord]) {
    std::fs::create_dir_all(dir.join("records")).unwrap();
    let mut entries = Vec::new();
    for record in records {
        let json = serde_json::to_vec(record).unwrap();
        std::fs::write(record_path(dir, &record_entry_name(record)), &json).unwrap();
        entries.push(record.index_entry(blake3_hex(&json)));
    }
    let index = Index::new("0.1.0", "manifest", "plan", entries);
    write_atomic(&dir.join("index.json"), &index.to_json_bytes()).unwrap();
}

fn record_entry_name(record: &ShardRecord) -> String {
    record.name.clone()
}

fn record_path(dir: &Path, shard: &str) -> std::path::PathBuf {
    let stem = shard.trim_start_matches("shards/").trim_end_matches(".tar");
    dir.join("records").join(format!("{stem}.json"))
}

/// The records of an index entry, from the sidecar [`write_index`] wrote.
fn sidecar(dir: &Path) -> impl FnMut(&IndexShard) -> Result<ShardRecord, NoRecord> + '_ {
    move |entry| {
        let path = record_path(dir, &entry.name);
        let Ok(json) = std::fs::read(&path) else {
            return Err(NoRecord::Missing { path });
        };
        let found = blake3_hex(&json);
        if found != entry.record_blake3 {
            return Err(NoRecord::HashDiffers {
                path,
                found,
                indexed: entry.record_blake3.clone(),
            });
        }
        Ok(serde_json::from_slice(&json).expect("the test writes valid records"))
    }
}

fn verify(dir: &Path) -> Result<VerifyReport, IndexError> {
    bettimill_format::verify(dir, &mut sidecar(dir))
}

fn verify_with_progress(
    dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<VerifyReport, IndexError> {
    bettimill_format::verify_with_progress(dir, &[], &mut sidecar(dir), progress)
}

#[test]
fn verify_reports_progress_per_shard() {
    let (dir, _) = dataset();
    let mut calls = Vec::new();
    let report =
        verify_with_progress(dir.path(), &mut |done, total| calls.push((done, total))).unwrap();
    assert!(report.is_ok());
    assert_eq!(calls, vec![(0, 2), (1, 2), (2, 2)]);
}

fn shard_path(dir: &Path, record: &ShardRecord) -> std::path::PathBuf {
    dir.join(&record.name)
}

#[test]
fn a_clean_dataset_verifies() {
    let (dir, records) = dataset();
    let report = verify(dir.path()).unwrap();
    assert!(report.is_ok(), "{:?}", report.problems);
    assert_eq!(report.shards_checked, 2);
    assert_eq!(report.samples_checked, 6);
    assert_eq!(
        report.bytes_checked,
        records.iter().map(|r| r.bytes).sum::<u64>()
    );
}

#[test]
fn tar_bytes_are_identical_across_calls_and_builds() {
    let samples = vec![sample("a", [1, 2, 3]), sample("b", [600, 0, 513])];
    let members: Vec<Member> = samples.iter().flatten().cloned().collect();
    let first = tar_bytes(&members).unwrap();
    assert_eq!(first, tar_bytes(&members).unwrap());
    let (built, record) = build_shard("shards/x-000000.tar", "train", &samples).unwrap();
    assert_eq!(built, first);
    let (_, again) = build_shard("shards/x-000000.tar", "train", &samples).unwrap();
    assert_eq!(record, again);
}

/// Whether `tar` is GNU tar. When it is not, the GNU tar tests fail in CI (CI=true) and
/// skip with a message elsewhere.
fn gnu_tar() -> bool {
    let reason = match Command::new("tar").arg("--version").output() {
        Ok(output) if String::from_utf8_lossy(&output.stdout).contains("GNU tar") => return true,
        Ok(output) => format!(
            "`tar --version` says {:?}",
            String::from_utf8_lossy(&output.stdout)
        ),
        Err(err) => format!("cannot run tar: {err}"),
    };
    bettimill_testkit::skip_unless_ci("GNU tar", &reason);
    false
}

#[test]
fn gnu_tar_lists_and_extracts_the_members() {
    if !gnu_tar() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let samples = vec![sample("d/s1", [1, 300, 1024]), sample("d/s2", [0, 5, 7])];
    let (bytes, _) = build_shard("shards/t-000000.tar", "train", &samples).unwrap();
    let path = dir.path().join("t.tar");
    std::fs::write(&path, &bytes).unwrap();
    let listing = Command::new("tar").arg("-tvf").arg(&path).output().unwrap();
    assert!(
        listing.status.success(),
        "{}",
        String::from_utf8_lossy(&listing.stderr)
    );
    let text = String::from_utf8(listing.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 6, "{text}");
    for (line, member) in lines.iter().zip(samples.iter().flatten()) {
        assert!(line.starts_with("-r--r--r-- bettimill/bettimill"), "{line}");
        assert!(line.contains("1970-01-01"), "{line}");
        assert!(line.ends_with(&member.name), "{line}");
        assert!(line.contains(&format!(" {} ", member.data.len())), "{line}");
    }
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let status = Command::new("tar")
        .arg("-xf")
        .arg(&path)
        .arg("-C")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    for member in samples.iter().flatten() {
        assert_eq!(std::fs::read(out.join(&member.name)).unwrap(), member.data);
    }
}

#[test]
fn read_tar_reads_what_gnu_tar_writes() {
    if !gnu_tar() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("src");
    std::fs::create_dir_all(src.join("k")).unwrap();
    std::fs::write(src.join("k/a.json"), b"{}").unwrap();
    std::fs::write(src.join("k/a.npy"), vec![1u8; 1500]).unwrap();
    let path = dir.path().join("gnu.tar");
    let status = Command::new("tar")
        .arg("--format=ustar")
        .arg("-cf")
        .arg(&path)
        .arg("-C")
        .arg(&src)
        .arg("k/a.json")
        .arg("k/a.npy")
        .status()
        .expect("tar runs");
    assert!(status.success());
    // GNU tar pads the archive to 10 KiB records with zeros: still a valid end.
    let members = read_tar(&std::fs::read(&path).unwrap()).unwrap();
    assert_eq!(members.len(), 2);
    assert_eq!(members[0], Member::new("k/a.json", b"{}".to_vec()));
    assert_eq!(members[1].data, vec![1u8; 1500]);
}

fn member_strategy() -> impl Strategy<Value = Member> {
    let name = "([a-z0-9_-]{1,12}/){0,2}[a-z0-9][a-z0-9_-]{0,11}\\.[a-z]{1,4}(\\.[a-z]{1,3})?";
    (name, proptest::collection::vec(any::<u8>(), 0..1600)).prop_map(|(n, d)| Member::new(n, d))
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 64,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn read_tar_inverts_tar_bytes(members in proptest::collection::vec(member_strategy(), 0..6)) {
        let bytes = tar_bytes(&members).unwrap();
        prop_assert_eq!(bytes.len() as u64, tar_len(members.iter().map(|m| m.data.len() as u64)));
        prop_assert_eq!(bytes.len() % 512, 0);
        prop_assert_eq!(read_tar(&bytes).unwrap(), members);
    }

    #[test]
    fn read_tar_never_panics_on_damaged_input(
        members in proptest::collection::vec(member_strategy(), 1..4),
        position in any::<prop::sample::Index>(),
        value in any::<u8>(),
        cut in any::<prop::sample::Index>(),
    ) {
        let mut bytes = tar_bytes(&members).unwrap();
        let at = position.index(bytes.len());
        bytes[at] = value;
        let _ = read_tar(&bytes);
        let end = cut.index(bytes.len());
        let _ = read_tar(&bytes[..end]);
    }
}

#[test]
fn verify_names_shard_member_and_offset_of_flipped_bytes() {
    let (dir, records) = dataset();
    let record = &records[1];
    let path = shard_path(dir.path(), record);
    let pristine = std::fs::read(&path).unwrap();
    // Sample offsets: the first and last byte of every member's header and data, one
    // byte inside each padding, and the end-of-archive marker.
    let mut cases = Vec::new();
    for member in &record.members {
        let header = member.offset - 512;
        cases.push((header, Some(member.name.as_str()), Region::Header));
        cases.push((header + 124, Some(member.name.as_str()), Region::Header));
        cases.push((header + 511, Some(member.name.as_str()), Region::Header));
        if member.bytes > 0 {
            cases.push((member.offset, Some(member.name.as_str()), Region::Data));
            cases.push((
                member.offset + member.bytes - 1,
                Some(member.name.as_str()),
                Region::Data,
            ));
        }
        if member.bytes % 512 != 0 {
            cases.push((
                member.offset + member.bytes,
                Some(member.name.as_str()),
                Region::Padding,
            ));
        }
    }
    cases.push((record.bytes - 1024, None, Region::EndMarker));
    cases.push((record.bytes - 1, None, Region::EndMarker));
    for (offset, member, region) in cases {
        let mut bytes = pristine.clone();
        bytes[offset as usize] ^= 0x5a;
        std::fs::write(&path, &bytes).unwrap();
        let report = verify(dir.path()).unwrap();
        let expected = match region {
            Region::Header => Problem::HeaderCorrupt {
                shard: record.name.clone(),
                member: member.unwrap().to_string(),
                header_offset: offset - offset % 512,
                offset,
            },
            Region::Data => {
                let m = record
                    .members
                    .iter()
                    .find(|m| Some(m.name.as_str()) == member)
                    .unwrap();
                Problem::DataCorrupt {
                    shard: record.name.clone(),
                    member: m.name.clone(),
                    offset: m.offset,
                    bytes: m.bytes,
                    expected_blake3: m.blake3.clone(),
                    found_blake3: blake3::hash(
                        &bytes[m.offset as usize..(m.offset + m.bytes) as usize],
                    )
                    .to_hex()
                    .to_string(),
                }
            }
            Region::Padding | Region::EndMarker => Problem::NonZeroPadding {
                shard: record.name.clone(),
                member: member.map(str::to_string),
                offset,
            },
        };
        assert_eq!(report.problems, vec![expected], "flip at {offset}");
        let message = report.problems[0].to_string();
        assert!(message.contains(&record.name), "{message}");
        assert!(
            message.contains(&offset.to_string()) || region == Region::Data,
            "{message}"
        );
    }
    std::fs::write(&path, &pristine).unwrap();
    assert!(verify(dir.path()).unwrap().is_ok());
}

#[test]
fn verify_locates_truncation_at_every_boundary_and_inside_headers() {
    let (dir, records) = dataset();
    let record = &records[0];
    let path = shard_path(dir.path(), record);
    let pristine = std::fs::read(&path).unwrap();
    let mut cases: Vec<(u64, Option<&str>, Region)> = Vec::new();
    for member in &record.members {
        let header = member.offset - 512;
        cases.push((header, Some(&member.name), Region::Header));
        cases.push((header + 1, Some(&member.name), Region::Header));
        cases.push((header + 300, Some(&member.name), Region::Header));
        if member.bytes > 1 {
            cases.push((
                member.offset + member.bytes / 2,
                Some(&member.name),
                Region::Data,
            ));
        }
        if member.bytes % 512 != 0 {
            cases.push((
                member.offset + member.bytes,
                Some(&member.name),
                Region::Padding,
            ));
        }
    }
    cases.push((record.bytes - 1024, None, Region::EndMarker));
    cases.push((record.bytes - 1, None, Region::EndMarker));
    for (length, member, region) in cases {
        std::fs::write(&path, &pristine[..length as usize]).unwrap();
        let report = verify(dir.path()).unwrap();
        assert_eq!(
            report.problems,
            vec![Problem::Truncated {
                shard: record.name.clone(),
                expected_bytes: record.bytes,
                found_bytes: length,
                member: member.map(str::to_string),
                region,
            }],
            "cut at {length}"
        );
        // The safe reader refuses the same cut file instead of returning fewer members.
        assert!(
            matches!(
                read_tar(&pristine[..length as usize]),
                Err(ShardError::TarTruncated { .. })
            ),
            "read_tar accepted a shard cut at {length}"
        );
    }
    let mut longer = pristine.clone();
    longer.extend_from_slice(&[0; 512]);
    std::fs::write(&path, &longer).unwrap();
    assert_eq!(
        verify(dir.path()).unwrap().problems,
        vec![Problem::TrailingBytes {
            shard: record.name.clone(),
            expected_bytes: record.bytes,
            found_bytes: record.bytes + 512,
        }]
    );
}

#[test]
fn verify_reports_missing_shards_and_extra_files() {
    let (dir, records) = dataset();
    std::fs::remove_file(shard_path(dir.path(), &records[0])).unwrap();
    std::fs::write(
        dir.path().join("shards/.train-000002.tar.tmp-77"),
        b"partial",
    )
    .unwrap();
    std::fs::create_dir(dir.path().join("shards/old")).unwrap();
    std::fs::write(dir.path().join("shards/old/x.tar"), b"").unwrap();
    let report = verify(dir.path()).unwrap();
    assert_eq!(
        report.problems,
        vec![
            Problem::MissingShard {
                shard: records[0].name.clone()
            },
            Problem::ExtraFile {
                path: "shards/.train-000002.tar.tmp-77".into()
            },
            Problem::ExtraFile {
                path: "shards/old/x.tar".into()
            },
        ]
    );
}

#[test]
fn verify_reports_a_sample_count_the_members_contradict() {
    let (dir, mut records) = dataset();
    records[0].samples = 4;
    write_index(dir.path(), &records);
    let report = verify(dir.path()).unwrap();
    assert_eq!(
        report.problems,
        vec![Problem::SampleCount {
            shard: records[0].name.clone(),
            expected: 4,
            found: 3
        }]
    );
}

#[test]
fn verify_reports_a_wrong_shard_hash_when_every_member_checks_out() {
    let (dir, mut records) = dataset();
    records[1].blake3 = "0".repeat(64);
    write_index(dir.path(), &records);
    let problems = verify(dir.path()).unwrap().problems;
    assert!(
        matches!(&problems[..], [Problem::HashMismatch { shard, .. }] if *shard == records[1].name),
        "{problems:?}"
    );
}

#[test]
fn verify_fails_only_on_a_bad_index() {
    let (dir, _) = dataset();
    std::fs::write(dir.path().join("index.json"), b"{\"format\": 1").unwrap();
    assert!(matches!(verify(dir.path()), Err(IndexError::Json { .. })));
    std::fs::remove_file(dir.path().join("index.json")).unwrap();
    let err = verify(dir.path()).unwrap_err();
    assert!(err.to_string().contains("index.json"), "{err}");
}

/// A raw header with arbitrary name, type and size, checksummed correctly.
fn raw_header(name: &[u8], typeflag: u8, size_field: &[u8; 12]) -> [u8; 512] {
    let mut header = header_block("placeholder.npy", 0).unwrap();
    header[..100].fill(0);
    header[..name.len()].copy_from_slice(name);
    header[156] = typeflag;
    header[124..136].copy_from_slice(size_field);
    header[148..156].fill(b' ');
    let sum: u32 = header.iter().map(|&b| b as u32).sum();
    header[148..156].copy_from_slice(format!("{sum:06o}\0 ").as_bytes());
    header
}

fn archive(header: [u8; 512], data_blocks: usize) -> Vec<u8> {
    let mut bytes = header.to_vec();
    bytes.resize(512 * (1 + data_blocks), 7);
    bytes.extend_from_slice(&[0; 1024]);
    bytes
}

#[test]
fn read_tar_refuses_unsafe_archives() {
    let size0 = b"00000000000\0";
    let check = |bytes: Vec<u8>, what: &str| {
        let result = read_tar(&bytes);
        assert!(result.is_err(), "{what} was accepted: {result:?}");
        result.unwrap_err()
    };
    assert!(matches!(
        check(
            archive(raw_header(b"/etc/passwd", b'0', size0), 0),
            "absolute"
        ),
        ShardError::BadName { .. }
    ));
    assert!(matches!(
        check(
            archive(raw_header(b"a/../../x.npy", b'0', size0), 0),
            "dot-dot"
        ),
        ShardError::BadName { .. }
    ));
    assert!(matches!(
        check(archive(raw_header(b"..", b'0', size0), 0), "bare dot-dot"),
        ShardError::BadName { .. }
    ));
    for (flag, kind) in [
        (b'2', "symbolic link"),
        (b'1', "hard link"),
        (b'3', "character device"),
        (b'4', "block device"),
        (b'6', "FIFO"),
        (b'x', "PAX extended header"),
        (b'L', "GNU long name"),
    ] {
        let err = check(archive(raw_header(b"link.npy", flag, size0), 0), kind);
        assert!(
            matches!(&err, ShardError::UnsupportedEntry { kind: k, offset: 0, .. } if *k == kind),
            "{err}"
        );
    }
    // A size of 8 GiB - 1 on a tiny file: refused before any allocation.
    let giant = check(
        archive(raw_header(b"big.npy", b'0', b"77777777777\0"), 1),
        "giant size",
    );
    assert!(
        matches!(giant, ShardError::MemberTooLarge { .. }),
        "{giant}"
    );
    let beyond = read_tar_with_limit(
        &archive(raw_header(b"big.npy", b'0', b"77777777777\0"), 1),
        u64::MAX,
    )
    .unwrap_err();
    assert!(
        matches!(beyond, ShardError::TarTruncated { .. }),
        "{beyond}"
    );
    let limited = read_tar_with_limit(
        &archive(raw_header(b"a.npy", b'0', b"00000001000\0"), 1),
        100,
    )
    .unwrap_err();
    assert!(
        matches!(
            limited,
            ShardError::MemberTooLarge {
                bytes: 512,
                limit: 100,
                ..
            }
        ),
        "{limited}"
    );
    let base256 = check(
        archive(
            raw_header(b"b.npy", b'0', &[0x80, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0]),
            1,
        ),
        "base-256 size",
    );
    assert!(
        matches!(base256, ShardError::Tar { offset: 124, .. }),
        "{base256}"
    );
    let mut bad_sum = archive(raw_header(b"ok.npy", b'0', size0), 0);
    bad_sum[0] = b'p';
    assert!(matches!(
        check(bad_sum, "checksum"),
        ShardError::HeaderChecksum { offset: 0, .. }
    ));
    // The same header with a regular type and a safe name is fine.
    assert_eq!(
        read_tar(&archive(raw_header(b"ok.npy", b'0', size0), 0))
            .unwrap()
            .len(),
        1
    );
}

#[test]
fn tar_bytes_refuses_bad_names() {
    for name in [
        "/abs.npy",
        "a/../b.npy",
        "a.b/c.npy",
        "noext",
        &format!("{}.npy", "k".repeat(97)),
    ] {
        let err = tar_bytes(&[Member::new(name, b"x".to_vec())]).unwrap_err();
        assert!(matches!(err, ShardError::BadName { .. }), "{name}: {err}");
    }
}

/// Pins the exact bytes: a change here means every dataset ever built changes hash, so it
/// must be deliberate (a new index format version or a documented codec upgrade).
#[test]
fn golden_hashes_of_tar_and_compressed_members() {
    let data: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 31) as u8)
        .collect();
    let members = vec![
        Member::new("train/s000000.cls", b"3".to_vec()),
        Member::new("train/s000000.npy", data.clone()),
    ];
    let hash = |bytes: &[u8]| blake3::hash(bytes).to_hex().to_string();
    let golden = [
        ("tar", hash(&tar_bytes(&members).unwrap()), GOLDEN_TAR),
        (
            "gzip",
            hash(&compress(&data, Compression::Gzip).unwrap()),
            GOLDEN_GZIP,
        ),
        (
            "zstd",
            hash(&compress(&data, Compression::Zstd).unwrap()),
            GOLDEN_ZSTD,
        ),
    ];
    for (what, found, expected) in golden {
        assert_eq!(found, expected, "{what} bytes changed");
    }
}

const GOLDEN_TAR: &str = "696ca64d3d197aad4e9d81dafd79da5968f0fcd4df909b36ffb830ec32577fb1";
const GOLDEN_GZIP: &str = "ad73bc0a1e1eadbe9526fa6b99cbf4460deb23bfd1404d6fa938cf63e5799800";
const GOLDEN_ZSTD: &str = "3a6acd34af019532dad995d478d245e199523e6b3e1f41393bea68697b07e305";
