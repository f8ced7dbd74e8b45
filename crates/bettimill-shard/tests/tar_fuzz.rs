//! Fuzzing the untrusted tar reader with proptest (cargo-fuzz needs a nightly toolchain).
//!
//! `tests/shards.rs` checks each refusal once (absolute path, `..`, every link and device
//! type, giant and base-256 sizes, bad checksums) and flips one byte of 64 archives. This
//! file runs thousands of inputs: random bytes, valid shards damaged in several places,
//! and archives whose headers are correctly checksummed but carry random names (with `/`,
//! `..`, control characters), random type flags and random size fields. Properties:
//! `read_tar` never panics; whatever it accepts has only safe relative names, regular-file
//! members, and no more data than the input holds (no allocation beyond the input).
//!
//! Each test prints how many inputs it ran; `BETTIMILL_FUZZ_CASES=N` multiplies them.

use bettimill_shard::ustar::header_block;
use bettimill_shard::{read_tar, tar_bytes, Member};
use bettimill_testkit::fuzz;
use proptest::prelude::*;

/// What every accepted archive must satisfy.
fn check_accepted(bytes: &[u8]) -> Result<(), TestCaseError> {
    let Ok(members) = read_tar(bytes) else {
        return Ok(());
    };
    let total: usize = members.iter().map(|m| m.data.len()).sum();
    prop_assert!(
        total <= bytes.len(),
        "{total} data bytes from {}",
        bytes.len()
    );
    for member in &members {
        let name = &member.name;
        prop_assert!(!name.is_empty() && !name.starts_with('/'), "{name:?}");
        prop_assert!(
            !name.split('/').any(|c| c == ".." || c.is_empty()),
            "{name:?}"
        );
        prop_assert!(!name.chars().any(char::is_control), "{name:?}");
    }
    Ok(())
}

fn member_strategy() -> impl Strategy<Value = Member> {
    let name = "[a-z0-9]{1,8}(/[a-z0-9]{1,6})?\\.(npy|json|cls)";
    (name, prop::collection::vec(any::<u8>(), 0..700)).prop_map(|(n, d)| Member::new(n, d))
}

#[test]
fn random_bytes_never_panic() {
    fuzz(
        "tar random bytes",
        3000,
        prop_oneof![
            prop::collection::vec(any::<u8>(), 0..2048),
            // Block-sized inputs reach the header parser more often.
            (1usize..5, any::<u64>()).prop_map(|(blocks, seed)| {
                let mut state = seed | 1;
                (0..blocks * 512)
                    .map(|_| {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        state as u8
                    })
                    .collect()
            }),
        ],
        |bytes| check_accepted(&bytes),
    );
}

#[test]
fn damaged_shards_never_panic() {
    fuzz(
        "tar damaged shard",
        3000,
        (
            prop::collection::vec(member_strategy(), 1..4),
            prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
            any::<prop::sample::Index>(),
            any::<bool>(),
        ),
        |(members, flips, cut, truncate)| {
            let mut bytes = tar_bytes(&members).unwrap();
            prop_assert_eq!(read_tar(&bytes).unwrap(), members);
            for (at, value) in flips {
                let i = at.index(bytes.len());
                bytes[i] = value;
            }
            if truncate {
                bytes.truncate(cut.index(bytes.len()));
            }
            check_accepted(&bytes)
        },
    );
}

/// A header with this name, type flag and size field, checksummed correctly, followed by
/// `data_blocks` blocks and the end marker.
fn forged_archive(name: &[u8], typeflag: u8, size_field: &[u8], data_blocks: usize) -> Vec<u8> {
    let mut header = header_block("placeholder.npy", 0).unwrap();
    header[..100].fill(0);
    let n = name.len().min(100);
    header[..n].copy_from_slice(&name[..n]);
    header[156] = typeflag;
    let s = size_field.len().min(12);
    header[124..124 + s].copy_from_slice(&size_field[..s]);
    header[148..156].fill(b' ');
    let sum: u32 = header.iter().map(|&b| b as u32).sum();
    header[148..156].copy_from_slice(format!("{sum:06o}\0 ").as_bytes());
    let mut bytes = header.to_vec();
    bytes.resize(512 * (1 + data_blocks), 0x41);
    bytes.extend_from_slice(&[0; 1024]);
    bytes
}

#[test]
fn forged_headers_with_hostile_names_types_and_sizes_are_refused_or_safe() {
    let name = prop_oneof![
        "(/|\\.\\./|\\./)?[a-z.]{0,6}(/(\\.\\.|\\.|[a-z]{1,4}|))*(\\.npy)?",
        prop::collection::vec(any::<u8>(), 0..100)
            .prop_map(|v| String::from_utf8_lossy(&v).into_owned()),
    ];
    let typeflag = prop_oneof![
        prop::sample::select(b"0\x001234567xgLKSDV".to_vec()),
        any::<u8>(),
    ];
    let size = prop_oneof![
        (0u64..4096).prop_map(|n| format!("{n:011o}\0").into_bytes()),
        Just(b"77777777777\0".to_vec()),
        prop::collection::vec(any::<u8>(), 12),
        (any::<u64>()).prop_map(|n| {
            let mut f = vec![0x80u8; 12];
            f[4..].copy_from_slice(&n.to_be_bytes());
            f
        }),
    ];
    fuzz(
        "tar forged header",
        3000,
        (name, typeflag, size, 0usize..4),
        |(name, typeflag, size, blocks)| {
            let bytes = forged_archive(name.as_bytes(), typeflag, &size, blocks);
            if let Ok(members) = read_tar(&bytes) {
                // Only regular files and directories are ever accepted.
                prop_assert!(
                    matches!(typeflag, b'0' | 0 | b'5' | b'7'),
                    "type flag {typeflag:?} accepted: {members:?}"
                );
            }
            check_accepted(&bytes)
        },
    );
}
