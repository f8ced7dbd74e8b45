//! A streamed upload of a file many parts large holds a few parts in memory, not the file:
//! the peak resident set of this test binary (its only test, so nothing else runs in the
//! process) stays far below the file's size, and the object is the file, byte for byte,
//! with no temporary left under the prefix.
//!
//! A system test against the local S3 server (ci/s3-up.sh): it runs only with
//! BETTIMILL_SYSTEM_TESTS=1, fails in CI (CI=true) when the server cannot be started and
//! is skipped with a message elsewhere.

mod common;

use bettimill_shard::object::{ObjectDir, PARTS_IN_FLIGHT, PART_BYTES, UPLOADS_DIR};
use bettimill_testkit::system_test;
use std::io::Write;

/// The file: 20 parts.
const FILE_BYTES: usize = 20 * PART_BYTES;

/// This process's peak resident set in bytes (`VmHWM` of /proc/self/status).
fn peak_bytes() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .expect("VmHWM in /proc/self/status");
    let kib: u64 = line
        .trim_start_matches("VmHWM:")
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .unwrap();
    kib << 10
}

#[test]
fn a_file_of_many_parts_uploads_in_bounded_memory_and_arrives_whole() {
    if !system_test("object storage on a local S3 server") {
        return;
    }
    let Some((server, config)) = common::s3_up() else {
        return;
    };
    let url = format!(
        "s3://{}/{}",
        server.bucket,
        server.fresh_prefix("shard-tests", "upload-memory")
    );
    let dir = ObjectDir::open(&url, &config).unwrap();

    // Written a MiB at a time (xorshift bytes, so no part equals another), hashed on the way.
    let scratch = tempfile::tempdir().unwrap();
    let path = scratch.path().join("big.tar");
    let mut file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    let mut hasher = blake3::Hasher::new();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut chunk = vec![0u8; 1 << 20];
    for _ in 0..FILE_BYTES >> 20 {
        for word in chunk.chunks_mut(8) {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            word.copy_from_slice(&state.to_le_bytes());
        }
        hasher.update(&chunk);
        file.write_all(&chunk).unwrap();
    }
    file.into_inner().unwrap().sync_all().unwrap();
    drop(chunk);
    let expected = hasher.finalize();

    let before = peak_bytes();
    dir.put_file_new("shards/big.tar", &path).unwrap();
    let peak = peak_bytes();
    // The parts held (PARTS_IN_FLIGHT) and the client's buffers; a whole-file read alone
    // would be FILE_BYTES.
    let bound = (PARTS_IN_FLIGHT + 2) * PART_BYTES;
    assert!(
        peak.saturating_sub(before) < bound as u64,
        "the upload raised the peak resident set from {before} to {peak} bytes, more than \
         {bound} for a file of {FILE_BYTES}"
    );

    assert_eq!(dir.size("shards/big.tar").unwrap(), Some(FILE_BYTES as u64));
    let mut got = blake3::Hasher::new();
    std::io::copy(
        &mut dir.reader("shards/big.tar", FILE_BYTES as u64),
        &mut got,
    )
    .unwrap();
    assert_eq!(got.finalize(), expected, "the object is the file");
    let names: Vec<String> = dir.list().unwrap().into_iter().map(|e| e.name).collect();
    assert_eq!(
        names,
        vec!["shards/big.tar".to_string()],
        "no {UPLOADS_DIR}/ left"
    );
}
