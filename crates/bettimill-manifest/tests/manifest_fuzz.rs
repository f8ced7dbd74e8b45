//! Fuzzing the manifest parser with proptest (cargo-fuzz needs a nightly toolchain).
//!
//! Inputs are the presets in `manifests/` mutated at three levels: whole lines (deleted,
//! duplicated, swapped), values (replaced by hostile ones: negative, zero, 2^64 - 1, huge
//! floats, NaN, strings, arrays, tables), and bytes (inserted, replaced); plus random text.
//! Properties: `Manifest::parse` never panics; an error names a line within the file; an
//! accepted manifest's splits and hypervolume bins can be computed without panicking. (What
//! the plan makes of an accepted manifest is fuzzed in `bettimill-sample`'s
//! `plan_then_build` test: a manifest that plans builds.)
//!
//! Each test prints how many inputs it ran; `BETTIMILL_FUZZ_CASES=N` multiplies them.

use bettimill_manifest::{Manifest, ManifestError};
use bettimill_testkit::fuzz;
use proptest::prelude::*;
use std::path::Path;

/// Presets that parse in well under a millisecond.
const FAST_PRESETS: [&str; 3] = [
    include_str!("../../../manifests/demo-2d.toml"),
    include_str!("../../../manifests/demo-3d.toml"),
    include_str!("../../../manifests/demo-4d.toml"),
];

/// Presets whose class feasibility checks take 0.1 to 0.5 s per parse (they place knots,
/// links and scenes at full size), so they get fewer cases.
const SLOW_PRESETS: [&str; 2] = [
    include_str!("../../../manifests/paper-figures.toml"),
    include_str!("../../../manifests/4d-mixed-128.toml"),
];

const HOSTILE_VALUES: [&str; 24] = [
    "-1",
    "0",
    "1",
    "8",
    "1024",
    "1025",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775807",
    "-9223372036854775808",
    "1e400",
    "nan",
    "-inf",
    "0.5",
    "\"\"",
    "\"../../etc/passwd\"",
    "\"a\\u0000b\"",
    "[]",
    "[[]]",
    "{}",
    "true",
    "1979-05-27T07:32:00Z",
    "[\"ball\", \"ball\", \"ball\", \"ball\", \"ball\", \"ball\", \"ball\", \"ball\"]",
];

fn check(text: &str) -> Result<(), TestCaseError> {
    let path = Path::new("fuzz.toml");
    match Manifest::parse(text, path) {
        Ok(manifest) => {
            let splits = manifest.split_sizes();
            prop_assert_eq!(splits.iter().map(|s| s.1).sum::<u64>(), manifest.samples);
            let _ = manifest.hypervolume_voxel_bins();
        }
        Err(err) => {
            let message = err.to_string();
            prop_assert!(!message.is_empty());
            if let ManifestError::Invalid { line, .. } = &err {
                prop_assert!(
                    *line <= text.lines().count() + 1,
                    "line {} of a {}-line file: {}",
                    line,
                    text.lines().count(),
                    message
                );
            }
        }
    }
    Ok(())
}

#[derive(Clone, Debug)]
enum Mutation {
    DeleteLine(usize),
    DuplicateLine(usize),
    SwapLines(usize, usize),
    ReplaceValue(usize, &'static str),
    InsertByte(usize, u8),
    ReplaceByte(usize, u8),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        1 => any::<usize>().prop_map(Mutation::DeleteLine),
        1 => any::<usize>().prop_map(Mutation::DuplicateLine),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        3 => (any::<usize>(), prop::sample::select(HOSTILE_VALUES.to_vec()))
            .prop_map(|(l, v)| Mutation::ReplaceValue(l, v)),
        1 => (any::<usize>(), prop::sample::select(b"=[]{}\"'#\n,.-0123456789 \\".to_vec()))
            .prop_map(|(at, b)| Mutation::InsertByte(at, b)),
        1 => (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Mutation::ReplaceByte(at, b)),
    ]
}

fn mutate(text: &str, mutations: &[Mutation]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for m in mutations {
        let n = lines.len().max(1);
        match m {
            Mutation::DeleteLine(i) if !lines.is_empty() => {
                lines.remove(i % n);
            }
            Mutation::DuplicateLine(i) if !lines.is_empty() => {
                let line = lines[i % n].clone();
                lines.insert(i % n, line);
            }
            Mutation::SwapLines(a, b) if !lines.is_empty() => lines.swap(a % n, b % n),
            Mutation::ReplaceValue(i, value) => {
                // The i-th `key = value` line (counting only such lines).
                let assignments: Vec<usize> = (0..lines.len())
                    .filter(|&k| lines[k].contains('=') && !lines[k].trim_start().starts_with('#'))
                    .collect();
                if !assignments.is_empty() {
                    let k = assignments[i % assignments.len()];
                    let key = lines[k].split('=').next().unwrap_or("").to_string();
                    lines[k] = format!("{key}= {value}");
                }
            }
            Mutation::InsertByte(at, byte) => {
                let mut bytes = lines.join("\n").into_bytes();
                let i = at % (bytes.len() + 1);
                bytes.insert(i, *byte);
                lines = String::from_utf8_lossy(&bytes)
                    .lines()
                    .map(str::to_string)
                    .collect();
            }
            Mutation::ReplaceByte(at, byte) => {
                let mut bytes = lines.join("\n").into_bytes();
                if !bytes.is_empty() {
                    let i = at % bytes.len();
                    bytes[i] = *byte;
                }
                lines = String::from_utf8_lossy(&bytes)
                    .lines()
                    .map(str::to_string)
                    .collect();
            }
            _ => {}
        }
    }
    lines.join("\n")
}

#[test]
fn every_preset_parses_unchanged() {
    for preset in FAST_PRESETS.iter().chain(&SLOW_PRESETS) {
        Manifest::parse(preset, Path::new("preset.toml")).expect("presets are valid");
    }
}

#[test]
fn mutated_presets_never_panic() {
    fuzz(
        "manifest mutated demo preset",
        4000,
        (
            prop::sample::select(FAST_PRESETS.to_vec()),
            prop::collection::vec(mutation(), 1..5),
        ),
        |(preset, mutations)| check(&mutate(preset, &mutations)),
    );
}

#[test]
fn mutated_large_presets_never_panic() {
    fuzz(
        "manifest mutated large preset",
        24,
        (
            prop::sample::select(SLOW_PRESETS.to_vec()),
            prop::collection::vec(mutation(), 1..5),
        ),
        |(preset, mutations)| check(&mutate(preset, &mutations)),
    );
}

#[test]
fn random_toml_like_text_never_panics() {
    let key = prop::sample::select(vec![
        "schema_version",
        "name",
        "dimension",
        "side",
        "mode",
        "samples",
        "shard_size",
        "shard_bytes",
        "seed",
        "compression",
        "family",
        "copies",
        "components",
        "splits",
        "hypervolume",
        "resolutions",
        "classes",
        "unknown",
    ]);
    let line = prop_oneof![
        (key.clone(), prop::sample::select(HOSTILE_VALUES.to_vec()))
            .prop_map(|(k, v)| format!("{k} = {v}")),
        key.clone().prop_map(|k| format!("[{k}]")),
        key.prop_map(|k| format!("[[{k}]]")),
        "[ -~]{0,30}",
    ];
    fuzz(
        "manifest random text",
        2000,
        prop::collection::vec(line, 0..14),
        |lines| check(&lines.join("\n")),
    );
}
