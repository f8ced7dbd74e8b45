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
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};

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

/// Plans `text` and, when the plan accepts it, makes the first sample of every stratum:
/// `Some(samples made)`, or `None` when the plan refuses it. A sample that fails is the
/// property's failure.
#[allow(clippy::print_stderr)] // The refusals, asked for with SHOW_REFUSALS, are the test's own report.
fn build_every_stratum(text: &str) -> Result<Option<u32>, TestCaseError> {
    let plan = match Plan::parse(text, std::path::Path::new("case.toml")) {
        Ok(plan) => plan,
        Err(err) => {
            if bettimill_env::var(bettimill_env::EnvVars::SHOW_REFUSALS).is_some() {
                eprintln!("refused: {err}");
            }
            return Ok(None);
        }
    };
    let mut seen = vec![false; plan.strata.len()];
    let mut built = 0;
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
            built += 1;
            if seen.iter().all(|&s| s) {
                break 'shards;
            }
        }
    }
    Ok(Some(built))
}

#[test]
fn every_manifest_that_plans_builds_the_first_sample_of_every_stratum() {
    let scale = bettimill_testkit::fuzz_scale();
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
        if let Some(samples) = build_every_stratum(&text)? {
            planned.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            built.fetch_add(samples, std::sync::atomic::Ordering::Relaxed);
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

/// Every preset in `manifests/`, reduced to sizes a test builds: the small demos as they
/// are, the 4D demo at side 18 with the classes that fit there, the mixed 128 preset's
/// layout (carve mode, copies, hypervolume bins, downscaled copies, the deformation
/// sequence) at 4D side 18 and 3D side 24, so that bins and their reach are mutated too,
/// and the paper's figures at side 52 (the smallest its scene of four objects fits in when
/// carved) with a tenth of its moves. The hostile-manifest generator mutates these.
fn small_presets() -> Vec<String> {
    let demo_4d = include_str!("../../../manifests/demo-4d.toml")
        .replace("side = 32", "side = 18")
        .replace(
            r#"family = ["ball", "handle", "s2_x_b2", "t2_x_b2"]"#,
            r#"family = ["ball", "handle"]"#,
        );
    let mixed = include_str!("../../../manifests/4d-mixed-128.toml");
    let classes = mixed.find("[[classes]]").expect("the preset has classes");
    let mixed = mixed[..classes]
        .replace("side = 128", "side = 18")
        .replace("resolutions = [64, 32]", "resolutions = [9]")
        .replace("steps = [0, 20000]", "steps = [0, 200]")
        .replace(
            "bins = [[0.929, 0.931], [0.931, 0.933], [0.933, 0.935], [0.935, 0.937]]",
            "bins = [[0.45, 0.47], [0.55, 0.57]]",
        )
        + "[[classes]]\nfamily = [\"ball\", \"handle\"]\n";
    let mixed_3d = mixed
        .replace("dimension = 4", "dimension = 3")
        .replace("side = 18", "side = 24")
        .replace("resolutions = [9]", "resolutions = [12]")
        .replace("mode = \"carve\"", "mode = [\"embed\", \"carve\"]");
    let figures = include_str!("../../../manifests/paper-figures.toml")
        .replace("side = 64", "side = 52")
        .replace("steps = 600", "steps = 60");
    vec![
        include_str!("../../../manifests/demo-2d.toml").to_string(),
        include_str!("../../../manifests/demo-3d.toml").to_string(),
        demo_4d,
        mixed,
        mixed_3d,
        figures,
    ]
}

/// The largest sample the hostile cases build: the reduced paper figures' (a mutated side
/// can ask for 1024^3, which is planned and left).
const MAX_BUILT_VOXELS: u64 = 52 * 52 * 52;

/// Every preset in `manifests/` is among [`small_presets`], and each, reduced, plans and
/// builds the first sample of every stratum.
#[test]
fn every_reduced_preset_plans_and_builds_the_first_sample_of_every_stratum() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../manifests");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    names.sort();
    let presets = small_presets();
    let reduced: Vec<String> = presets
        .iter()
        .map(|text| {
            let table: toml::Table = text.parse().unwrap();
            format!("{}.toml", table["name"].as_str().unwrap())
        })
        .collect();
    for name in &names {
        let text = std::fs::read_to_string(dir.join(name)).unwrap();
        let table: toml::Table = text.parse().unwrap();
        let wanted = format!("{}.toml", table["name"].as_str().unwrap());
        assert!(reduced.contains(&wanted), "{name} has no reduced form here");
    }
    for text in &presets {
        // Combinations that do not fit at the reduced side are left out with a reason
        // (two handles in a 4D side-18 cube); every stratum planned must build.
        let plan = Plan::parse(text, std::path::Path::new("preset.toml")).unwrap();
        assert!(!plan.strata.is_empty(), "{text}");
        let built = build_every_stratum(text).unwrap();
        assert_eq!(built, Some(plan.strata.len() as u32), "{text}");
    }
}

#[test]
fn every_hostile_manifest_that_plans_builds_the_first_sample_of_every_stratum() {
    let presets = small_presets();
    for preset in &presets {
        let plan = Plan::parse(preset, std::path::Path::new("preset.toml"));
        assert!(plan.is_ok(), "{}\n{preset}", plan.unwrap_err());
    }
    let mut runner = TestRunner::new_with_rng(
        Config {
            cases: 200 * bettimill_testkit::fuzz_scale(),
            failure_persistence: None,
            ..Config::default()
        },
        TestRng::deterministic_rng(RngAlgorithm::ChaCha),
    );
    let counts = std::sync::Mutex::new((0u32, 0u32, 0u32, 0u32));
    // Half of the cases also write hostile bins, so that bins out of reach meet manifests
    // that otherwise plan, and half write downscaled copies the preset's side allows (one
    // or two of its divisors, down to the smallest copy), whose cavities carving must make
    // thick enough; the generator's own copy lists are mostly refused by the plan.
    use bettimill_testkit::hostile::{mutate, mutations, Mutation, HOSTILE_BINS};
    let bins = prop::option::of(prop::sample::select(HOSTILE_BINS.to_vec()));
    let copies = prop::option::of((any::<usize>(), any::<bool>()));
    let strategy = (0..presets.len(), mutations(), bins, copies);
    let result = runner.run(&strategy, |(preset, mut mutations, bins, copies)| {
        mutations.extend(bins.map(Mutation::ReplaceBins));
        if let Some((pick, two)) = copies {
            let list = copy_sides(&presets[preset], pick, two);
            mutations.push(Mutation::ReplaceResolutions(list));
        }
        let text = mutate(&presets[preset], &mutations);
        // Only small samples are built; a larger one is planned and left.
        let small = bettimill_manifest_voxels(&text).is_some_and(|v| v <= MAX_BUILT_VOXELS);
        if !small {
            return Ok(());
        }
        if let Some(samples) = build_every_stratum(&text)? {
            let mut counts = counts.lock().unwrap();
            counts.0 += 1;
            counts.1 += samples;
            counts.2 += u32::from(text.contains("[hypervolume]"));
            counts.3 += u32::from(has_copies(&text));
        }
        Ok(())
    });
    if let Err(err) = result {
        panic!("{err}");
    }
    let (planned, built, binned, copies) = counts.into_inner().unwrap();
    eprintln!(
        "hostile manifests: {planned} planned (binned {binned}, with downscaled copies {copies}), {built} samples built"
    );
    // The generator must reach the building half of the property, binned manifests and
    // manifests with downscaled copies too.
    assert!(
        planned >= 15 && built >= 40 && binned >= 5 && copies >= 5,
        "only {planned} hostile manifests planned ({binned} binned, {copies} with copies) and {built} samples built"
    );
}

/// A `resolutions` list for the preset `text`: its side's `pick`-th divisor from 4 to below
/// the side, and with `two` the next smaller one too.
fn copy_sides(text: &str, pick: usize, two: bool) -> String {
    let table: toml::Table = text.parse().expect("a preset parses");
    let side = table["side"].as_integer().expect("a preset has a side");
    let divisors: Vec<i64> = (4..side).rev().filter(|d| side % d == 0).collect();
    let first = pick % divisors.len();
    let chosen: Vec<String> = divisors[first..]
        .iter()
        .take(if two { 2 } else { 1 })
        .map(i64::to_string)
        .collect();
    format!("[{}]", chosen.join(", "))
}

/// Whether the manifest `text` asks for at least one downscaled copy.
fn has_copies(text: &str) -> bool {
    let Ok(table) = text.parse::<toml::Table>() else {
        return false;
    };
    table
        .get("resolutions")
        .and_then(|r| r.as_array())
        .is_some_and(|r| !r.is_empty())
}

/// The voxels of one sample of the manifest `text` (`side ^ dimension`), if both parse.
fn bettimill_manifest_voxels(text: &str) -> Option<u64> {
    let table: toml::Table = text.parse().ok()?;
    let side = table.get("side")?.as_integer()?;
    let dimension = table.get("dimension")?.as_integer()?;
    let (side, dimension) = (u64::try_from(side).ok()?, u32::try_from(dimension).ok()?);
    side.checked_pow(dimension)
}
