//! Fuzzing the manifest parser with proptest (cargo-fuzz needs a nightly toolchain).
//!
//! Inputs are the presets in `manifests/` mutated by the hostile-manifest generator
//! (`bettimill_testkit::hostile`: lines, values and bytes), plus random text.
//! Properties: `Manifest::parse` never panics; an error names a line within the file; an
//! accepted manifest's splits and hypervolume bins can be computed without panicking. (What
//! the plan makes of an accepted manifest is fuzzed in `bettimill-sample`'s
//! `plan_then_build` test: a manifest that plans builds, this generator's included.)
//!
//! Each test prints how many inputs it ran; `BETTIMILL_FUZZ_CASES=N` multiplies them.

use bettimill_manifest::{Manifest, ManifestError};
use bettimill_testkit::fuzz;
use bettimill_testkit::hostile::{mutate, mutations, HOSTILE_VALUES};
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
        (prop::sample::select(FAST_PRESETS.to_vec()), mutations()),
        |(preset, mutations)| check(&mutate(preset, &mutations)),
    );
}

#[test]
fn mutated_large_presets_never_panic() {
    fuzz(
        "manifest mutated large preset",
        24,
        (prop::sample::select(SLOW_PRESETS.to_vec()), mutations()),
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
