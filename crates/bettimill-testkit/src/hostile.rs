//! The hostile-manifest generator: presets mutated as a hostile user or a broken editor
//! would, at three levels: whole lines (deleted, duplicated, swapped), values (replaced by
//! hostile ones: negative, zero, 2^64 - 1, huge floats, NaN, strings, arrays, tables, bins
//! out of reach, repeated or odd downscaled copies) and bytes (inserted, replaced). The
//! manifest parser's fuzz test feeds it every preset; the plan-then-build property builds
//! what it makes of the small ones.

use proptest::prelude::*;

/// Values a mutation writes in place of a `key = value` line's value.
pub const HOSTILE_VALUES: [&str; 28] = [
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
    "[[0.03, 0.031]]",
    "[[0.001, 0.002], [0.5, 0.6]]",
    "[[0.95, 0.999]]",
    "[[0.3, 0.31], [0.6, 0.61]]",
];

/// Hypervolume bins a mutation writes in place of a `bins` value: below a carved solid's
/// outer layers, at both extremes, near where growth and thinning stop, several at once.
pub const HOSTILE_BINS: [&str; 8] = [
    "[[0.03, 0.031]]",
    "[[0.001, 0.002], [0.5, 0.6]]",
    "[[0.0001, 0.0005]]",
    "[[0.95, 0.999]]",
    "[[0.3, 0.31], [0.6, 0.61]]",
    "[[0.42, 0.43], [0.44, 0.45]]",
    "[[0.7, 0.72], [0.74, 0.76]]",
    "[[0.0, 1.0]]",
];

/// Downscaled-copy lists a mutation writes in place of a `resolutions` value (or adds where
/// there is none): sides that divide the presets' sides (18, 24, 32, 52), several at
/// once, and hostile ones: repeated, not dividing, below the smallest copy, zero, empty.
pub const HOSTILE_RESOLUTIONS: [&str; 14] = [
    "[16, 8]",
    "[8, 4]",
    "[12, 6]",
    "[12, 4]",
    "[6]",
    "[9, 6]",
    "[26, 13]",
    "[4]",
    "[9, 9]",
    "[12, 12]",
    "[17]",
    "[4, 2, 1]",
    "[0]",
    "[]",
];

/// One edit of a manifest's text.
#[derive(Clone, Debug)]
pub enum Mutation {
    /// Deletes a line.
    DeleteLine(usize),
    /// Writes a line twice.
    DuplicateLine(usize),
    /// Swaps two lines.
    SwapLines(usize, usize),
    /// Replaces the value of the n-th `key = value` line.
    ReplaceValue(usize, &'static str),
    /// Replaces the value of every `bins = ...` line.
    ReplaceBins(&'static str),
    /// Replaces the value of every `resolutions = ...` line, or adds one after the first
    /// `seed = ...` line when there is none.
    ReplaceResolutions(String),
    /// Inserts a byte.
    InsertByte(usize, u8),
    /// Replaces a byte.
    ReplaceByte(usize, u8),
}

/// A random [`Mutation`], value replacements three times as likely as each other kind.
pub fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        1 => any::<usize>().prop_map(Mutation::DeleteLine),
        1 => any::<usize>().prop_map(Mutation::DuplicateLine),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        3 => (any::<usize>(), prop::sample::select(HOSTILE_VALUES.to_vec()))
            .prop_map(|(l, v)| Mutation::ReplaceValue(l, v)),
        1 => prop::sample::select(HOSTILE_BINS.to_vec()).prop_map(Mutation::ReplaceBins),
        1 => prop::sample::select(HOSTILE_RESOLUTIONS.to_vec())
            .prop_map(|r| Mutation::ReplaceResolutions(r.to_string())),
        1 => (any::<usize>(), prop::sample::select(b"=[]{}\"'#\n,.-0123456789 \\".to_vec()))
            .prop_map(|(at, b)| Mutation::InsertByte(at, b)),
        1 => (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Mutation::ReplaceByte(at, b)),
    ]
}

/// `text` with `mutations` applied in order (positions taken modulo the text's size).
pub fn mutate(text: &str, mutations: &[Mutation]) -> String {
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
            Mutation::ReplaceBins(bins) => {
                for line in lines.iter_mut() {
                    if line
                        .split('=')
                        .next()
                        .is_some_and(|key| key.trim() == "bins")
                    {
                        *line = format!("bins = {bins}");
                    }
                }
            }
            Mutation::ReplaceResolutions(resolutions) => {
                let key_of = |line: &str| line.split('=').next().unwrap_or("").trim().to_string();
                let line = format!("resolutions = {resolutions}");
                if lines.iter().any(|l| key_of(l) == "resolutions") {
                    for l in lines.iter_mut().filter(|l| key_of(l) == "resolutions") {
                        l.clone_from(&line);
                    }
                } else if let Some(k) = lines.iter().position(|l| key_of(l) == "seed") {
                    lines.insert(k + 1, line);
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

/// One to four random mutations.
pub fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    prop::collection::vec(mutation(), 1..5)
}
