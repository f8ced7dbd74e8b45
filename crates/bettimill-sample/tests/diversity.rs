//! Deformation reshapes the phase that carries the topology, and only near it.
//!
//! - On the 4D mixed 128 preset reduced to side 32 (its families that fit there, its
//!   components, bins and deformation sequence; one sample of every stratum), the cavities of a sample overlap
//!   their undeformed construction ([`bettimill_sample::construction`]) with a mean voxel
//!   IoU below 0.8: the network sees reshaped cavities, not the implicit-equation shapes.
//! - Within one stratum, every sample draws its own deformation strengths from the
//!   manifest's ranges.
//! - In carve mode, a voxel of the solid farther from every cavity than the deformation's
//!   reach (`bettimill_deform::reach`, summed over the steps a label records) is the same
//!   as in the construction.
//! - The components of one binned sample differ in size: a scene's voxel count is shared
//!   among its objects over a wide range.
//!
//! Every sample comes from `make_sample`, so each one is also verified.

use bettimill_plan::Plan;
use bettimill_sample::{construction, make_sample, Sample};
use std::collections::BTreeSet;

fn preset(side: u32, samples: usize, classes: Option<&str>) -> String {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../manifests/4d-mixed-128.toml"
    );
    let text = std::fs::read_to_string(path).expect("the preset is readable");
    let mut out = String::new();
    let mut in_splits = false;
    for line in text.lines() {
        let line = match line.split_once(" = ").map(|(k, _)| k) {
            Some("side") => format!("side = {side}"),
            Some("samples") => format!("samples = {samples}"),
            Some("resolutions") => String::new(),
            Some("bins") => scaled_bins(line, side),
            Some("train") if in_splits => format!("train = {samples}"),
            Some("val" | "test") if in_splits => String::new(),
            _ => line.to_string(),
        };
        if line.starts_with('[') {
            in_splits = line == "[splits]";
            if classes.is_some() && line == "[[classes]]" {
                // Everything from the first class on is replaced.
                break;
            }
        }
        out.push_str(&line);
        out.push('\n');
    }
    if let Some(classes) = classes {
        out.push_str(classes);
    }
    out
}

/// The preset's bins hold the cavities to a share of the solid inside the cube's
/// one-voxel border; at a smaller side the border takes a larger share of the cube, so the
/// same cavity share is a smaller foreground fraction.
fn scaled_bins(line: &str, side: u32) -> String {
    let inside = |s: f64| ((s - 2.0) / s).powi(4);
    let numbers: Vec<f64> = line
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter(|t| !t.is_empty())
        .map(|t| t.parse().expect("a number"))
        .collect();
    let scaled: Vec<String> = numbers
        .chunks(2)
        .map(|b| {
            let f = |x: f64| x / inside(128.0) * inside(side as f64);
            format!("[{:.6}, {:.6}]", f(b[0]), f(b[1]))
        })
        .collect();
    format!("bins = [{}]", scaled.join(", "))
}

fn build(text: &str) -> (Plan, Vec<Sample>) {
    let plan = Plan::parse(text, std::path::Path::new("reduced.toml")).expect("plans");
    let samples = plan
        .shards()
        .flat_map(|s| plan.shard_tasks(&s))
        .map(|task| make_sample(&plan, &task).expect("every planned sample builds"))
        .collect();
    (plan, samples)
}

/// The sorted flat indices of `sample`'s construction's phase and of its own phase.
fn phases(plan: &Plan, sample: &Sample) -> (Vec<usize>, Vec<usize>) {
    let index = plan
        .shards()
        .flat_map(|s| plan.shard_tasks(&s))
        .find(|t| t.key == sample.label.key)
        .expect("the sample's task");
    let built = construction(plan, &index, sample.label.attempt).expect("constructs");
    (
        built.phase.voxels(&built.image),
        built.phase.voxels(&sample.image),
    )
}

fn iou(a: &[usize], b: &[usize]) -> f64 {
    let (mut i, mut j, mut both) = (0, 0, 0usize);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                both += 1;
                i += 1;
                j += 1;
            }
        }
    }
    both as f64 / (a.len() + b.len() - both) as f64
}

#[test]
fn deformed_cavities_of_the_reduced_preset_are_far_from_their_constructions() {
    // One sample of every stratum of the preset's families that fit at side 32 (its
    // connected sums need side 44 or more).
    let families = "[[classes]]\nfamily = [\"ball\", \"handle\", \"s2_x_b2\", \"t2_x_b2\"]\n";
    let strata = Plan::parse(
        &preset(32, 9600, Some(families)),
        std::path::Path::new("r.toml"),
    )
    .expect("plans")
    .strata
    .len();
    // Families x components x bins, less what the plan finds cannot be built at side 32.
    assert!(strata >= 24, "{strata} strata");
    let (plan, samples) = build(&preset(32, strata, Some(families)));
    assert_eq!(samples.len(), strata);
    let mut overlaps = Vec::new();
    for sample in &samples {
        let (before, after) = phases(&plan, sample);
        assert!(
            !before.is_empty() && !after.is_empty(),
            "{}",
            sample.label.key
        );
        overlaps.push(iou(&before, &after));
        assert_eq!(sample.label.deform.len(), 5, "{}", sample.label.key);
    }
    let mean = overlaps.iter().sum::<f64>() / overlaps.len() as f64;
    let least = overlaps.iter().cloned().fold(f64::INFINITY, f64::min);
    let most = overlaps.iter().cloned().fold(0.0, f64::max);
    assert!(
        mean < 0.8,
        "mean cavity IoU with the construction {mean:.3} (min {least:.3}, max {most:.3})"
    );
}

#[test]
fn samples_of_one_stratum_draw_their_own_strengths() {
    let ball = "[[classes]]\nfamily = \"ball\"\n";
    let text = preset(24, 8, Some(ball)).replace("components = [1, 2]", "components = [1]");
    let text = text
        .lines()
        .map(|l| {
            if l.starts_with("bins = ") {
                scaled_bins("bins = [[0.929, 0.937]]", 24)
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let (plan, samples) = build(&text);
    assert_eq!(plan.strata.len(), 1);
    assert_eq!(samples.len(), 8);
    let drawn: BTreeSet<String> = samples
        .iter()
        .map(|s| format!("{:?}", s.label.deform))
        .collect();
    assert_eq!(drawn.len(), 8, "every sample draws its own strengths");
    for step in 0..5 {
        let steps: BTreeSet<u32> = samples.iter().map(|s| s.label.deform[step].steps).collect();
        assert!(steps.len() >= 3, "step {step} drew {steps:?}");
    }
}

/// Marks every voxel within Chebyshev distance `radius` of a marked one (a box
/// dilation, one axis at a time).
fn dilate(mask: &mut [bool], shape: &[usize], radius: usize) {
    let mut strides = vec![1usize; shape.len()];
    for a in (0..shape.len() - 1).rev() {
        strides[a] = strides[a + 1] * shape[a + 1];
    }
    for (a, &n) in shape.iter().enumerate() {
        let stride = strides[a];
        let before = mask.to_vec();
        for (i, out) in mask.iter_mut().enumerate() {
            let x = (i / stride) % n;
            let lo = x.saturating_sub(radius);
            let hi = (x + radius).min(n - 1);
            let base = i - x * stride;
            *out = (lo..=hi).any(|y| before[base + y * stride]);
        }
    }
}

fn in_box(mut i: usize, shape: &[usize], phase: &bettimill_deform::Phase) -> bool {
    let mut inside = true;
    for a in (0..shape.len()).rev() {
        let x = i % shape[a];
        i /= shape[a];
        inside &= (phase.lo[a]..=phase.hi[a]).contains(&x);
    }
    inside
}

#[test]
fn carved_solid_beyond_the_deformations_reach_is_untouched() {
    for (dimension, side) in [(3, 40), (4, 32)] {
        let text = format!(
            r#"
schema_version = 1
name = "reach"
dimension = {dimension}
side = {side}
mode = "carve"
samples = 12
shard_size = 12
seed = 5
components = [1, 2]

[[deform]]
method = "erode"
steps = [0, 2]
[[deform]]
method = "dilate"
steps = 1
[[deform]]
method = "tentacles"
count = [1, 3]
steps = [1, 3]
[[deform]]
method = "walk"
count = [1, 2]
steps = [1, 3]
[[deform]]
method = "moves"
steps = [0, 2]

[[classes]]
family = ["ball", "handle"]
"#
        );
        let (plan, samples) = build(&text);
        let mut beyond = 0usize;
        let mut changed = 0usize;
        for sample in &samples {
            let label = &sample.label;
            let reach: u64 = label.deform.iter().map(bettimill_deform::reach).sum();
            let (before, _) = phases(&plan, sample);
            let task = plan
                .shards()
                .flat_map(|s| plan.shard_tasks(&s))
                .find(|t| t.key == label.key)
                .expect("the task");
            let built = construction(&plan, &task, label.attempt).expect("constructs");
            let mut near = vec![false; sample.image.len()];
            for &i in &before {
                near[i] = true;
            }
            dilate(&mut near, sample.image.shape(), reach as usize);
            for (i, (&was, &is)) in built
                .image
                .data()
                .iter()
                .zip(sample.image.data())
                .enumerate()
            {
                if was != is {
                    changed += 1;
                    assert!(
                        near[i],
                        "{}: voxel {i} changed farther than the reach {reach} from every cavity",
                        label.key
                    );
                } else if !near[i] && was == 1 && in_box(i, sample.image.shape(), &built.phase) {
                    beyond += 1;
                }
            }
        }
        // The check bites: deformation changed voxels, and solid it was allowed to edit
        // lay beyond its reach.
        assert!(changed > 0, "{dimension}D: nothing was deformed");
        assert!(beyond > 0, "{dimension}D: no solid beyond the reach");
    }
}

#[test]
fn deformed_samples_spread_over_their_bin() {
    // Growth by the deformations carries most samples out of their bin; targeting brings
    // each back to a count drawn in the bin, so the counts cover the bin instead of
    // sitting on its ends.
    let text = r#"
schema_version = 1
name = "spread"
dimension = 3
side = 24
mode = "embed"
samples = 24
shard_size = 24
seed = 7

[[deform]]
method = "dilate"
steps = [1, 3]
growth_probability = [0.3, 0.8]

[[deform]]
method = "tentacles"
count = [1, 3]
steps = [2, 8]

[[classes]]
family = "handle"

[hypervolume]
unit = "fraction"
bins = [[0.03, 0.06]]
"#;
    let (plan, samples) = build(text);
    let (lo, hi) = plan.strata[0].hypervolume.expect("binned");
    let counts: Vec<u64> = samples.iter().map(|s| s.label.hypervolume).collect();
    assert!(counts.iter().all(|c| (lo..=hi).contains(c)), "{counts:?}");
    let on_ends = counts.iter().filter(|&&c| c == lo || c == hi).count();
    assert!(
        on_ends <= 4,
        "{on_ends} of 24 on the bin's ends: {counts:?}"
    );
    let third = (hi - lo) / 3;
    let middle = counts
        .iter()
        .filter(|&&c| c > lo + third && c < hi - third)
        .count();
    assert!(
        middle >= 4,
        "{middle} of 24 in the bin's middle third: {counts:?}"
    );
}

/// The 26-connected components of a 3D foreground: a label per voxel (0 for background,
/// 1, 2, ... in order of first voxel).
fn component_labels(image: &[u8], side: usize) -> Vec<u32> {
    let mut labels = vec![0u32; image.len()];
    let mut next = 0;
    for start in 0..image.len() {
        if image[start] == 0 || labels[start] != 0 {
            continue;
        }
        next += 1;
        labels[start] = next;
        let mut stack = vec![start];
        while let Some(i) = stack.pop() {
            let (x, y, z) = (i / (side * side), i / side % side, i % side);
            for dx in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dz in -1i64..=1 {
                        let (a, b, c) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                        let inside = |v: i64| (0..side as i64).contains(&v);
                        if !(inside(a) && inside(b) && inside(c)) {
                            continue;
                        }
                        let j = (a as usize * side + b as usize) * side + c as usize;
                        if image[j] != 0 && labels[j] == 0 {
                            labels[j] = next;
                            stack.push(j);
                        }
                    }
                }
            }
        }
    }
    labels
}

/// The sizes of the 26-connected components of a 3D foreground, largest first.
fn component_sizes(image: &[u8], side: usize) -> Vec<usize> {
    let labels = component_labels(image, side);
    let mut sizes = vec![0usize; labels.iter().copied().max().unwrap_or(0) as usize];
    for &l in labels.iter().filter(|&&l| l != 0) {
        sizes[l as usize - 1] += 1;
    }
    sizes.sort_unstable_by(|a, b| b.cmp(a));
    sizes
}

/// The smallest Chebyshev distance between voxels of different components of a 3D
/// foreground, looking up to `within` apart (`within` when none is closer).
fn closest_components(image: &[u8], side: usize, within: i64) -> i64 {
    let labels = component_labels(image, side);
    let mut closest = within;
    for (i, &l) in labels.iter().enumerate().filter(|(_, &l)| l != 0) {
        let (x, y, z) = (i / (side * side), i / side % side, i % side);
        let reach = within - 1;
        for dx in -reach..=reach {
            for dy in -reach..=reach {
                for dz in -reach..=reach {
                    let (a, b, c) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                    let inside = |v: i64| (0..side as i64).contains(&v);
                    if !(inside(a) && inside(b) && inside(c)) {
                        continue;
                    }
                    let m = labels[(a as usize * side + b as usize) * side + c as usize];
                    if m != 0 && m != l {
                        closest = closest.min(dx.abs().max(dy.abs()).max(dz.abs()));
                    }
                }
            }
        }
    }
    closest
}

#[test]
fn parts_of_a_deformed_scene_keep_the_gap_they_were_placed_with() {
    // Objects are placed a gap apart that each sample draws (two background voxels or
    // more); growth to the bin and moves press them together unless the deformation keeps
    // them apart. Parts that always meet across a one- or two-voxel gap would teach a
    // network that this is what two components look like.
    let text = r#"
schema_version = 1
name = "apart"
dimension = 3
side = 32
mode = "embed"
samples = 16
shard_size = 16
seed = 11
components = [2]

[[classes]]
family = "ball"

[hypervolume]
unit = "fraction"
bins = [[0.05, 0.08]]

[[deform]]
method = "dilate"
steps = [2, 4]

[[deform]]
method = "moves"
steps = 600
"#;
    let (_, samples) = build(text);
    let found: Vec<(i64, i64)> = samples
        .iter()
        .map(|s| {
            let gap = s.label.separation.expect("two parts record their gap");
            let placed = s.label.construction["gap_voxels"].as_i64().expect("a gap");
            assert!(
                gap == 0 || gap == 2 || i64::from(gap) == placed,
                "{gap} {placed}"
            );
            (i64::from(gap), closest_components(s.image.data(), 32, 8))
        })
        .collect();
    assert!(
        found.iter().all(|&(gap, closest)| closest > gap),
        "(gap, closest parts): {found:?}"
    );
    let gaps: BTreeSet<i64> = found.iter().map(|&(gap, _)| gap).collect();
    assert!(
        gaps.len() >= 3 && gaps.iter().all(|gap| (2..=6).contains(gap)),
        "gaps drawn: {gaps:?}"
    );
}

#[test]
fn components_of_one_sample_differ_in_size() {
    // A scene's voxel count is shared among its objects at random over a wide range, so
    // one component may be many times another's size (as in shapes made any other way),
    // not always about as large.
    let text = r#"
schema_version = 1
name = "shares"
dimension = 3
side = 32
mode = "embed"
samples = 24
shard_size = 24
seed = 7
components = [2]

[[classes]]
family = "ball"

[hypervolume]
unit = "fraction"
bins = [[0.03, 0.05]]
"#;
    let (_, samples) = build(text);
    let mut ratios: Vec<f64> = samples
        .iter()
        .map(|s| {
            let sizes = component_sizes(s.image.data(), 32);
            assert_eq!(sizes.len(), 2, "{}: {sizes:?}", s.label.key);
            sizes[0] as f64 / sizes[1] as f64
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    let at_least = |r: f64| ratios.iter().filter(|&&x| x >= r).count();
    assert!(
        at_least(3.0) >= 6 && at_least(1.5) >= 12,
        "size ratios of the two components: {ratios:?}"
    );
}
