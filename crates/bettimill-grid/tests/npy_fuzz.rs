//! Fuzzing the `.npy` reader with proptest (cargo-fuzz needs a nightly toolchain).
//!
//! Inputs are valid files written by `write_bytes` and then damaged: random byte flips,
//! truncations and insertions, random bytes after the magic, and headers that lie (huge or
//! overflowing shapes, wrong or unknown dtypes, Fortran order, missing keys). Properties:
//! `read_bytes` never panics, and whatever it accepts fits in the input, i.e. the voxel
//! buffer it allocates is never larger than the bytes it was given. A lying shape therefore
//! has to come back as an error, never as an allocation.
//!
//! Each test prints how many inputs it ran. `BETTIMILL_FUZZ_CASES=N` multiplies the number
//! of cases (the longer run in docs/reliability.md uses 200).

use bettimill_grid::npy::{read_bytes, write_bytes, Dtype, NpyError};
use bettimill_grid::BinaryImage;
use bettimill_testkit::fuzz;
use proptest::prelude::*;

fn dtype_strategy() -> impl Strategy<Value = Dtype> {
    (
        prop::sample::select(vec![
            ('b', 1usize),
            ('u', 1),
            ('i', 1),
            ('u', 2),
            ('i', 4),
            ('u', 8),
        ]),
        any::<bool>(),
    )
        .prop_map(|((kind, size), big_endian)| Dtype {
            kind,
            size,
            big_endian: big_endian && size > 1,
        })
}

/// A small valid file: random 2D-4D image, random dtype.
fn valid_file() -> impl Strategy<Value = Vec<u8>> {
    (
        prop::collection::vec(1usize..5, 2..=4),
        dtype_strategy(),
        any::<u64>(),
    )
        .prop_map(|(shape, dtype, bits)| {
            let mut image = BinaryImage::zeros(&shape).expect("small shapes are valid");
            for (i, v) in image.data_mut().iter_mut().enumerate() {
                *v = ((bits >> (i % 64)) & 1) as u8;
            }
            write_bytes(&image, dtype)
        })
}

/// The accepted-input invariant: what comes back fits in what went in.
fn check_bounded(bytes: &[u8]) -> Result<(), TestCaseError> {
    if let Ok(read) = read_bytes(bytes, false) {
        let needed = read.image.len() * read.dtype.size;
        prop_assert!(
            needed <= bytes.len(),
            "accepted {} voxels of {} bytes from a {}-byte file",
            read.image.len(),
            read.dtype.size,
            bytes.len()
        );
    }
    let _ = read_bytes(bytes, true);
    Ok(())
}

#[derive(Clone, Debug)]
enum Damage {
    Flip { at: usize, xor: u8 },
    Truncate { at: usize },
    Insert { at: usize, bytes: Vec<u8> },
    Overwrite { at: usize, bytes: Vec<u8> },
}

fn damage_strategy() -> impl Strategy<Value = Damage> {
    prop_oneof![
        (any::<usize>(), 1u8..=255).prop_map(|(at, xor)| Damage::Flip { at, xor }),
        any::<usize>().prop_map(|at| Damage::Truncate { at }),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..40))
            .prop_map(|(at, bytes)| Damage::Insert { at, bytes }),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(at, bytes)| Damage::Overwrite { at, bytes }),
    ]
}

fn apply(mut bytes: Vec<u8>, damage: &[Damage]) -> Vec<u8> {
    for d in damage {
        let len = bytes.len().max(1);
        match d {
            Damage::Flip { at, xor } => {
                if !bytes.is_empty() {
                    let i = at % bytes.len();
                    bytes[i] ^= xor;
                }
            }
            Damage::Truncate { at } => bytes.truncate(at % len),
            Damage::Insert { at, bytes: more } => {
                let i = at % (bytes.len() + 1);
                bytes.splice(i..i, more.iter().copied());
            }
            Damage::Overwrite { at, bytes: more } => {
                let i = at % len;
                for (k, b) in more.iter().enumerate() {
                    if let Some(slot) = bytes.get_mut(i + k) {
                        *slot = *b;
                    }
                }
            }
        }
    }
    bytes
}

/// A version 1.0 file with `header` (padded as NumPy does) and `data_len` bytes of ones.
fn with_header(header: &str, data_len: usize) -> Vec<u8> {
    let mut text = header.to_string();
    while !(10 + text.len() + 1).is_multiple_of(64) {
        text.push(' ');
    }
    text.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(text.len() as u16).to_le_bytes());
    bytes.extend_from_slice(text.as_bytes());
    bytes.extend(std::iter::repeat_n(1u8, data_len));
    bytes
}

#[test]
fn valid_files_read_back_and_damaged_files_never_panic_or_over_allocate() {
    let n = fuzz(
        "npy mutated",
        3000,
        (valid_file(), prop::collection::vec(damage_strategy(), 1..4)),
        |(file, damage)| {
            let read = read_bytes(&file, true);
            prop_assert!(read.is_ok(), "a valid file was refused: {:?}", read.err());
            check_bounded(&apply(file, &damage))
        },
    );
    assert!(n >= 3000);
}

#[test]
fn random_bytes_after_the_magic_never_panic() {
    fuzz(
        "npy random",
        3000,
        (
            prop::sample::select(vec![1u8, 2, 3, 4, 0]),
            prop::collection::vec(any::<u8>(), 0..300),
        ),
        |(major, tail)| {
            let mut bytes = b"\x93NUMPY".to_vec();
            bytes.push(major);
            bytes.push(0);
            bytes.extend_from_slice(&tail);
            check_bounded(&bytes)
        },
    );
}

#[test]
fn lying_shapes_are_errors_not_allocations() {
    // Shapes whose element count is far above the data present, or overflows u64 when
    // multiplied by the element size, next to a few bytes of data.
    let big = prop_oneof![
        Just(usize::MAX),
        Just(1usize << 40),
        Just(1usize << 32),
        (1usize << 20)..(1usize << 62),
    ];
    fuzz(
        "npy lying shape",
        2000,
        (
            prop::collection::vec(prop_oneof![1usize..8, big], 2..=4),
            prop::sample::select(vec!["|u1", "<u2", ">i4", "<u8", "|b1"]),
            0usize..600,
        ),
        |(shape, descr, data_len)| {
            let dims: Vec<String> = shape.iter().map(|n| n.to_string()).collect();
            let header = format!(
                "{{'descr': '{descr}', 'fortran_order': False, 'shape': ({}), }}",
                dims.join(", ")
            );
            let bytes = with_header(&header, data_len);
            let element_size: u128 = descr[2..].parse().unwrap();
            let element_bytes = shape
                .iter()
                .fold(element_size, |acc, &n| acc.saturating_mul(n as u128));
            let result = read_bytes(&bytes, false);
            if element_bytes > data_len as u128 {
                prop_assert!(
                    matches!(
                        result,
                        Err(NpyError::Truncated { .. } | NpyError::Format(_))
                    ),
                    "shape {shape:?} with {data_len} data bytes: {result:?}"
                );
            }
            check_bounded(&bytes)
        },
    );
}

#[test]
fn lying_headers_get_clear_errors() {
    let cases: &[(&str, usize, &str)] = &[
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }",
            32,
            "unsupported dtype",
        ),
        (
            "{'descr': '|O', 'fortran_order': False, 'shape': (2, 2), }",
            32,
            "unsupported dtype",
        ),
        (
            "{'descr': '<u3', 'fortran_order': False, 'shape': (2, 2), }",
            12,
            "unsupported dtype",
        ),
        (
            "{'descr': '|u1', 'fortran_order': True, 'shape': (2, 2), }",
            4,
            "Fortran",
        ),
        (
            "{'descr': '|u1', 'fortran_order': False, 'shape': (4294967296, 4294967296, 4294967296), }",
            4,
            "overflows",
        ),
        (
            "{'descr': '|u1', 'fortran_order': False, 'shape': (100000, 100000), }",
            4,
            "truncated data: the header promises 10000000000 bytes of data, the file has 4",
        ),
        (
            "{'descr': '|u1', 'fortran_order': False, 'shape': (2, 2), }",
            3,
            "truncated data",
        ),
        (
            "{'descr': '|u1', 'fortran_order': False, 'shape': (2, 2), }",
            5,
            "unexpected bytes",
        ),
        (
            "{'descr': '|u1', 'fortran_order': False, 'shape': (2, -2), }",
            4,
            "not a length",
        ),
        (
            "{'descr': '|u1', 'fortran_order': False, 'shape': (4,), }",
            4,
            "unsupported shape",
        ),
        (
            "{'descr': '|u1', 'fortran_order': False, }",
            4,
            "no 'shape'",
        ),
    ];
    for (header, data_len, expected) in cases {
        let err = read_bytes(&with_header(header, *data_len), false)
            .expect_err(header)
            .to_string();
        assert!(err.contains(expected), "{header}: {err}");
    }
    // A header length field far beyond the file.
    let mut bytes = with_header(
        "{'descr': '|u1', 'fortran_order': False, 'shape': (2, 2), }",
        4,
    );
    bytes[6] = 2;
    bytes[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = read_bytes(&bytes, false).unwrap_err().to_string();
    assert!(err.contains("at most 65536"), "{err}");
}
