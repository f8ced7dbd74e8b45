//! A manifest that plans builds: whatever `Plan::new` accepts, the first sample of every
//! stratum can be made and verified.
//!
//! This is the contract between planning and building. Everything knowable before building
//! (families, parameters, sizes, feasibility of every combination, deformation settings,
//! shard sizes) is decided by the plan; a manifest that passes it must not fail at build
//! time for one of those reasons (`growth_probability = 0` once did: it planned, then every
//! attempt of every shard failed).
//!
//! Inputs are random valid-looking manifests drawn over the whole schema, small enough to
//! build in a test: every family with small parameters, Betti vectors, both modes,
//! components, hypervolume bins, resolutions, every deformation method with settings at and
//! near the ends of their ranges, and every compression. The runner's seed is fixed, so CI
//! sees the same cases every time; `BETTIMILL_FUZZ_CASES=N` multiplies them.

use bettimill_plan::Plan;
use bettimill_sample::make_sample;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// Class tables for each dimension (2D, 3D, 4D); sizes and combinations the plan cannot
/// build are still drawn, and it drops or refuses them.
const CLASSES: [&[&str]; 3] = [
    &[
        "family = \"ball\"",
        "family = \"handle\"",
        "family = \"shell\"",
        "family = \"handlebody\"\ngenus = [1, 2]",
        "family = \"curve\"",
        "betti = [1, [0, 1]]",
        "betti = [2, 1]",
    ],
    &[
        "family = \"ball\"",
        "family = \"handle\"",
        "family = \"shell\"",
        "family = \"torus_shell\"",
        "family = \"handlebody\"\ngenus = 2",
        "family = \"curve\"",
        "family = \"s1_x_handlebody\"\nj = 1",
        "family = \"tunnel\"\nintervals = 1",
        "family = \"knot\"\nknot = \"trefoil\"",
        "family = \"link\"\nlink = \"hopf\"",
        "betti = [1, 1, 0]",
    ],
    &[
        "family = \"ball\"",
        "family = \"handle\"",
        "family = \"s2_x_b2\"",
        "family = \"t2_x_b2\"",
        "family = \"connected_sum\"\ng = 1\nh = 1\ni = 0\nj = 0",
        "family = \"klein_bottle\"",
        "family = \"tunnel\"\nintervals = 2\ncircle = true",
        "betti = [1, 0, 1, 0]",
    ],
];

const DEFORMS: &[&str] = &[
    "method = \"moves\"\nsteps = 20",
    "method = \"moves\"\nsteps = 5\nmax_distance = 8\noctaves = 24",
    "method = \"dilate\"\nsteps = 2\ngrowth_probability = 1.0",
    "method = \"dilate\"\nsteps = 1\ngrowth_probability = 0.001\nnoise_frequency = 1.0",
    "method = \"erode\"\nsteps = 2\ngrowth_probability = 0.5\nnoise_frequency = 0.000001",
];

#[derive(Clone, Debug)]
struct Case {
    dimension: u32,
    side: u32,
    modes: &'static str,
    classes: Vec<&'static str>,
    components: Option<&'static str>,
    bins: Option<&'static str>,
    resolution: bool,
    deform: Option<&'static str>,
    compression: &'static str,
}

impl Case {
    fn text(&self) -> String {
        let mut text = format!(
            "schema_version = 1\nname = \"p\"\ndimension = {}\nside = {}\nmode = {}\n\
             samples = 40\nshard_size = 7\nseed = 3\ncompression = \"{}\"\n",
            self.dimension, self.side, self.modes, self.compression
        );
        if let Some(components) = self.components {
            text.push_str(&format!("components = {components}\n"));
        }
        if self.resolution && self.side.is_multiple_of(2) {
            text.push_str(&format!("resolutions = [{}]\n", self.side / 2));
        }
        if let Some(bins) = self.bins {
            text.push_str(&format!("[hypervolume]\nbins = {bins}\n"));
        }
        if let Some(deform) = self.deform {
            text.push_str(&format!("[deform]\n{deform}\n"));
        }
        for class in &self.classes {
            text.push_str(&format!("[[classes]]\n{class}\n"));
        }
        text
    }
}

fn cases() -> impl Strategy<Value = Case> {
    let shape = prop_oneof![
        (Just(2u32), 16u32..48),
        (Just(3u32), 20u32..34),
        (Just(4u32), 14u32..19)
    ]
    .prop_flat_map(|(dimension, side)| {
        let classes: Vec<&'static str> = CLASSES[dimension as usize - 2].to_vec();
        (
            Just((dimension, side)),
            prop::sample::subsequence(classes, 1..=2),
        )
    });
    (
        shape,
        prop::sample::select(vec!["\"embed\"", "\"carve\"", "[\"embed\", \"carve\"]"]),
        prop::option::of(prop::sample::select(vec!["[1, 2]", "[2]"])),
        // Bins below what thinning can reach are left out: how thin a construction can get
        // depends on the size drawn for it, which the plan does not know yet (a carved 2D
        // ball in a 16-side image stalls at 27 foreground voxels, above a [6, 25] bin).
        prop::option::of(prop::sample::select(vec![
            "[[0.15, 0.3]]",
            "[[0.2, 0.3], [0.3, 0.5]]",
        ])),
        any::<bool>(),
        prop::option::of(prop::sample::select(DEFORMS.to_vec())),
        prop::sample::select(vec!["auto", "none", "gzip", "zstd"]),
    )
        .prop_map(
            |(
                ((dimension, side), classes),
                modes,
                components,
                bins,
                resolution,
                deform,
                compression,
            )| {
                Case {
                    dimension,
                    side,
                    modes,
                    classes,
                    components,
                    bins,
                    resolution,
                    deform,
                    compression,
                }
            },
        )
}

#[test]
fn every_manifest_that_plans_builds_the_first_sample_of_every_stratum() {
    let scale: u32 = std::env::var("BETTIMILL_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    let mut runner = TestRunner::new_with_rng(
        Config {
            cases: 40 * scale,
            failure_persistence: None,
            ..Config::default()
        },
        TestRng::deterministic_rng(RngAlgorithm::ChaCha),
    );
    let planned = std::sync::atomic::AtomicU32::new(0);
    let built = std::sync::atomic::AtomicU32::new(0);
    let result = runner.run(&cases(), |case| {
        let text = case.text();
        let plan = match Plan::parse(&text, std::path::Path::new("case.toml")) {
            Ok(plan) => plan,
            Err(err) => {
                if std::env::var_os("SHOW_REFUSALS").is_some() {
                    eprintln!("refused: {err}");
                }
                return Ok(());
            }
        };
        planned.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut seen = vec![false; plan.strata.len()];
        'shards: for shard in plan.shards() {
            for task in plan.shard_tasks(&shard) {
                if std::mem::replace(&mut seen[task.stratum], true) {
                    continue;
                }
                let sample = make_sample(&plan, &task);
                prop_assert!(
                    sample.is_ok(),
                    "planned but did not build: {}\n{text}",
                    sample.unwrap_err()
                );
                built.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if seen.iter().all(|&s| s) {
                    break 'shards;
                }
            }
        }
        Ok(())
    });
    if let Err(err) = result {
        panic!("{err}");
    }
    let (planned, built) = (planned.into_inner(), built.into_inner());
    // The generator must reach the building half of the property, not only refusals.
    assert!(
        planned >= 10 && built >= 20,
        "only {planned} manifests planned and {built} samples built"
    );
}
