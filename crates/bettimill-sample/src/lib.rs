//! One sample: generate, deform, verify, label.
//!
//! This is the "task -> sample" step of the pipeline. A sample is only ever returned after
//! its Betti numbers have been computed from the final voxels and found equal to the
//! construction's analytic numbers; a mismatch is regenerated from the next attempt seed
//! (see `bettimill_plan::attempt_rng`), so the result is still a pure function of the
//! manifest and the sample index, and the number of attempts is recorded in the label.
//!
//! A sample is made from the plan and its task alone: the plan carries every resolved
//! setting (deformation, resolutions), and the label a sample must carry is the plan's
//! stratum's, decided once when the manifest was planned.

use bettimill_deform::{Phase, APART};
pub use bettimill_format::{Label, Pooling, ResolutionLabel, TOOL_VERSION};
use bettimill_grid::npy;
use bettimill_grid::{BinaryImage, Mode};
use bettimill_plan::{attempt_rng, derive_seed, mode_name, Plan, SampleTask, TubeFloor};
use bettimill_shapes::Generated;
use serde::{Deserialize, Serialize};

/// How many attempts a sample gets before the build reports it as failed.
pub const MAX_ATTEMPTS: u32 = 16;

/// How many attempts build with a manifest's wider `inner_gap` before the rest fall back
/// to the usual gap. A rule of the attempt alone, so that [`construction`] at a label's
/// `attempt` is the construction that sample started from.
pub const WIDE_GAP_ATTEMPTS: u32 = 4;

/// How many attempts check a manifest's `survives_dilations`. The check refuses what the
/// image's room forces on some samples (a loop grown to a large bin wraps round its own
/// hole), so the last attempts skip it and the label says so: every stratum the plan
/// accepts builds.
pub const DILATION_CHECKED_ATTEMPTS: u32 = 12;

/// A verified sample.
#[derive(Clone, Debug)]
pub struct Sample {
    /// The voxels.
    pub image: BinaryImage,
    /// Its label.
    pub label: Label,
    /// Downscaled copies, in the manifest's order of `resolutions`.
    pub downscaled: Vec<BinaryImage>,
}

impl Sample {
    /// `KEY.npy` bytes (uint8, C order).
    pub fn npy_bytes(&self) -> Vec<u8> {
        npy::write_bytes(&self.image, npy::Dtype::U8)
    }

    /// `KEY.json` bytes (compact JSON and a newline).
    pub fn json_bytes(&self) -> Vec<u8> {
        let mut out = serde_json::to_vec(&self.label).expect("labels always serialise");
        out.push(b'\n');
        out
    }

    /// `KEY.cls` bytes (the class index in ASCII decimal).
    pub fn cls_bytes(&self) -> Vec<u8> {
        self.label.stratum.to_string().into_bytes()
    }

    /// Every field of the sample (`cls`, `json`, `npy`, `rSIDE.npy`...) with its bytes,
    /// sorted by field name as WebDataset writers should.
    pub fn fields(&self) -> Vec<(String, Vec<u8>)> {
        let mut fields = vec![
            ("cls".to_string(), self.cls_bytes()),
            ("json".to_string(), self.json_bytes()),
            ("npy".to_string(), self.npy_bytes()),
        ];
        for image in &self.downscaled {
            fields.push((
                format!("r{}.npy", image.shape()[0]),
                npy::write_bytes(image, npy::Dtype::U8),
            ));
        }
        fields.sort_by(|a, b| a.0.cmp(&b.0));
        fields
    }
}

/// Pools `image` by `factor` along every axis with `pooling`: a block is foreground when
/// any of its voxels is ([`Pooling::ForegroundAny`], max pooling) or when all of them are
/// ([`Pooling::BackgroundAny`], min pooling: background when any voxel is). Every axis
/// length must be a multiple of `factor`.
pub fn downscale(image: &BinaryImage, factor: usize, pooling: Pooling) -> BinaryImage {
    let d = image.dim().get();
    let shape: Vec<usize> = image.shape().iter().map(|&n| n / factor).collect();
    let mut out = BinaryImage::zeros(&shape).expect("a downscaled valid image is valid");
    let in_strides = image.strides().to_vec();
    let out_strides = out.strides().to_vec();
    let row_len = image.shape()[d - 1];
    // The value a block takes when any of its voxels has the winning value.
    let (winner, other) = match pooling {
        Pooling::ForegroundAny => (1u8, 0u8),
        Pooling::BackgroundAny => (0u8, 1u8),
    };
    let out_data = out.data_mut();
    out_data.fill(other);
    // Row by row along the last axis: the leading coordinates of a row pick the output
    // row, and each run of `factor` voxels along it one output voxel.
    for (r, row) in image.data().chunks_exact(row_len).enumerate() {
        let mut rest = r * row_len;
        let mut base = 0;
        for axis in 0..d - 1 {
            base += rest / in_strides[axis] / factor * out_strides[axis];
            rest %= in_strides[axis];
        }
        for (j, run) in row.chunks_exact(factor).enumerate() {
            if run.iter().any(|&v| (v != 0) as u8 == winner) {
                out_data[base + j] = winner;
            }
        }
    }
    out
}

/// The pooling rule of a mode's downscaled copies. Embed mode pools the objects
/// ([`Pooling::ForegroundAny`]). Carve mode pools the same way: on the 4D mixed 128 preset
/// max pooling keeps more copies' topology than pooling the cavities
/// ([`Pooling::BackgroundAny`]), because the binned constructions' cavities are thick
/// tubes while the foreground between their parts can be a few voxels thin, and min
/// pooling closes those gaps. The rule is in every copy's label either way. The plan sizes
/// carved tubes for this rule (`bettimill_plan::tube_floor_for`): change both together.
pub fn pooling_for(mode: Mode) -> Pooling {
    match mode {
        Mode::Embed | Mode::Carve => Pooling::ForegroundAny,
    }
}

/// The image cut down to the bounding box of its foreground (a copy; the image itself
/// when the box is the whole image or there is no foreground). The foreground, and so its
/// Betti numbers, is the same, and homology does not have to thin the thick background
/// shell around a solid box (binned carve samples).
pub fn foreground_window(image: &BinaryImage) -> std::borrow::Cow<'_, BinaryImage> {
    let (lo, hi) = image.whole_box();
    match image.value_box(1, &lo, &hi) {
        Some((lo, hi)) => crop(image, &lo, &hi),
        None => std::borrow::Cow::Borrowed(image),
    }
}

/// A part of the image with the same homology as the whole, as small as this can be
/// shown cheaply: what a sample's Betti numbers are computed from.
///
/// It is the [`foreground_window`], further cut down to the box `B` of the background
/// voxels inside the window grown by one voxel, when every other voxel of the window is
/// foreground and `B` keeps at least one voxel in from each of the window's faces: a
/// carved solid, whose cavities are small beside the wall around them. Why the homology
/// is the same, in the model of the closed voxels (foreground voxels touching at a corner
/// are connected, background ones through a face; outside the image is background): let
/// `X` be the union of the closed foreground voxels, `X_B` that of the foreground voxels
/// of `B` (the foreground of the cut image) and `Y` that of the voxels of the window
/// outside `B`, all foreground. Then `X = X_B ∪ Y`, and `X_B ∩ Y` is the boundary sphere
/// `∂B` of the box `B`: a common point lies on `∂B`, and every point of `∂B` lies in a
/// voxel of `B`'s outer layer (foreground, as the background box is one voxel further in)
/// and in a voxel of the window just outside `B`. `Y` is a closed box with an open box
/// strictly inside removed, so `∂B` is a deformation retract of it, and Mayer-Vietoris
/// (`H(∂B) -> H(Y)` an isomorphism) gives `H(X) = H(X_B)` in every degree; the Euler
/// characteristic follows. Otherwise (objects in empty space, cavities reaching the wall's
/// surface) it is the foreground window.
pub fn verification_window(image: &BinaryImage) -> std::borrow::Cow<'_, BinaryImage> {
    let (lo, hi) = image.whole_box();
    let Some((lo, hi)) = image.value_box(1, &lo, &hi) else {
        return std::borrow::Cow::Borrowed(image);
    };
    let d = image.dim().get();
    if let Some((blo, bhi)) = image.value_box(0, &lo, &hi) {
        if (0..d).all(|a| blo[a] >= lo[a] + 2 && bhi[a] + 2 <= hi[a]) {
            let grown_lo: [usize; 4] = std::array::from_fn(|a| blo[a].saturating_sub(1));
            let grown_hi: [usize; 4] = std::array::from_fn(|a| bhi[a] + 1);
            return crop(image, &grown_lo, &grown_hi);
        }
    }
    crop(image, &lo, &hi)
}

/// The voxels of the inclusive box `lo ..= hi` as an image of their own (the image itself
/// when the box is the whole image).
fn crop<'a>(
    image: &'a BinaryImage,
    lo: &[usize; 4],
    hi: &[usize; 4],
) -> std::borrow::Cow<'a, BinaryImage> {
    let d = image.dim().get();
    let shape = image.shape();
    if (0..d).all(|a| lo[a] == 0 && hi[a] + 1 == shape[a]) {
        return std::borrow::Cow::Borrowed(image);
    }
    let window: Vec<usize> = (0..d).map(|a| hi[a] - lo[a] + 1).collect();
    let mut out = BinaryImage::zeros(&window).expect("a window of a valid image is valid");
    let out_row = window[d - 1];
    for r in 0..out.len() / out_row {
        let dst = r * out_row;
        let wc = out.coords(dst);
        let mut src_coords = [0usize; 4];
        for a in 0..d {
            src_coords[a] = wc[a] + lo[a];
        }
        let src = image.index(&src_coords[..d]);
        out.data_mut()[dst..dst + out_row].copy_from_slice(&image.data()[src..src + out_row]);
    }
    std::borrow::Cow::Owned(out)
}

/// The foreground count a binned sample is built for: uniform in the middle 80% of
/// `[lo, hi]`, from the sample's seed and attempt.
pub fn position_in_bin(lo: u64, hi: u64, seed: &[u8; 32], attempt: u32) -> u64 {
    let bits = sub_seed("bettimill hypervolume position v1", seed, attempt);
    let u = 0.1 + 0.8 * ((bits >> 11) as f64 / (1u64 << 53) as f64);
    lo + ((hi - lo) as f64 * u) as u64
}

/// A u64 seed in the named domain for (sample seed, attempt).
fn sub_seed(domain: &str, seed: &[u8; 32], attempt: u32) -> u64 {
    let bytes = derive_seed(domain, &[seed, &attempt.to_le_bytes()]);
    u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes"))
}

/// A point of `lo ..= hi` from a uniform u64 `draw` (multiply and shift: no modulo bias
/// beyond 2^-64, no loop).
fn draw_between(draw: u64, lo: u64, hi: u64) -> u64 {
    lo + ((u128::from(draw) * (u128::from(hi - lo) + 1)) >> 64) as u64
}

/// A u64 seed in the named domain for (sample seed, attempt, deformation step).
fn step_seed(domain: &str, seed: &[u8; 32], attempt: u32, step: &[u8]) -> u64 {
    let bytes = derive_seed(domain, &[seed, &attempt.to_le_bytes(), step]);
    u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes"))
}

/// Why a sample could not be made.
#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    /// Every attempt failed to generate or verify.
    #[error("sample {key} ({class}): all {attempts} attempts failed; last: {last}")]
    GaveUp {
        /// The sample key.
        key: String,
        /// The stratum.
        class: String,
        /// Attempts made.
        attempts: u32,
        /// The last failure.
        last: String,
    },
    /// The construction of one attempt could not be rasterised (see [`construction`]).
    #[error("sample {key}, attempt {attempt}: the construction failed: {reason}")]
    Construction {
        /// The sample key.
        key: String,
        /// The attempt.
        attempt: u32,
        /// Why.
        reason: String,
    },
}

/// A stage of making one sample, in the order they run (see [`make_sample_observed`]).
/// [`Stage::Encode`] is not made by this crate: the shard writer reports it when it turns
/// the verified sample into its (compressed) members.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Stage {
    /// The construction is rasterised.
    Generate,
    /// The manifest's topology-preserving deformation.
    Deform,
    /// Simple-point flips into the stratum's hypervolume bin.
    Hypervolume,
    /// The Betti numbers of the final voxels are computed and compared with the label.
    Verify,
    /// The downscaled copy of this side is pooled and its topology computed.
    Downscale {
        /// The copy's side.
        side: u32,
    },
    /// The sample becomes its shard members (serialised, compressed).
    Encode,
}

impl Stage {
    /// The part of a sample's time spent before this stage and in it, as fractions of the
    /// whole: typical shares of a 4D 128^4 sample (the stage breakdown in BENCHMARKS.md),
    /// rounded. An estimate of where the sample is, not a voxel count.
    pub fn span(self) -> (f64, f64) {
        match self {
            Stage::Generate => (0.0, 0.2),
            Stage::Deform => (0.2, 0.05),
            Stage::Hypervolume => (0.25, 0.05),
            Stage::Verify => (0.3, 0.45),
            Stage::Downscale { .. } => (0.75, 0.15),
            Stage::Encode => (0.9, 0.1),
        }
    }

    /// Where a sample is when this stage is `within` (0 to 1) done, as a fraction of the
    /// whole sample (see [`Stage::span`]).
    pub fn sample_fraction(self, within: f64) -> f64 {
        let (start, width) = self.span();
        (start + width * within.clamp(0.0, 1.0)).min(1.0)
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Stage::Generate => f.write_str("generate"),
            Stage::Deform => f.write_str("deform"),
            Stage::Hypervolume => f.write_str("hypervolume targeting"),
            Stage::Verify => f.write_str("verify"),
            Stage::Downscale { side } => write!(f, "downscale r{side}"),
            Stage::Encode => f.write_str("encode"),
        }
    }
}

/// What [`make_sample_observed`] tells its observer when a stage starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageProgress {
    /// The attempt (0 first; a regeneration starts again at [`Stage::Generate`]).
    pub attempt: u32,
    /// The stage starting.
    pub stage: Stage,
    /// Where the sample is, as a fraction of the whole (see [`Stage::sample_fraction`]).
    pub fraction: f64,
}

/// Makes and verifies one sample.
pub fn make_sample(plan: &Plan, task: &SampleTask) -> Result<Sample, SampleError> {
    make_sample_observed(plan, task, &mut |_| {})
}

/// [`make_sample`], telling `observe` as each stage starts (and, for the downscaled copies,
/// each copy), from the calling thread. The observer sees the work, it cannot change it:
/// the sample is the same with any observer.
pub fn make_sample_observed(
    plan: &Plan,
    task: &SampleTask,
    observe: &mut dyn FnMut(StageProgress),
) -> Result<Sample, SampleError> {
    let stratum = &plan.strata[task.stratum];
    let side = plan.side as usize;
    let mut last = String::new();
    for attempt in 0..MAX_ATTEMPTS {
        let mut report = |stage: Stage, within: f64| {
            observe(StageProgress {
                attempt,
                stage,
                fraction: stage.sample_fraction(within),
            })
        };
        report(Stage::Generate, 0.0);
        let (generated, mut phase) = match generate(plan, task, attempt) {
            Ok(made) => made,
            Err(err) => {
                last = format!("generation failed: {err}");
                continue;
            }
        };
        let mut image = generated.image;
        let mut applied = Vec::new();
        // The gap width growth keeps, drawn per sample (uniform over the range) so that a
        // stratum holds holes and gaps of many widths.
        let clearance = plan.clearance.map(|range| {
            let (lo, hi) = range.bounds();
            let draw = sub_seed("bettimill clearance v1", &task.seed, attempt);
            draw_between(draw, lo.into(), hi.into()) as u32
        });
        phase = phase.with_clearance(clearance.unwrap_or(0));
        // The phase's components: the objects of embed mode (b0), the cavities of carve
        // mode (b_{d-1} of the solid, by Alexander duality). Only two or more need labels
        // to be kept apart, by the gap placement drew for them.
        let components = if phase.value == 1 {
            stratum.betti[0]
        } else {
            stratum.betti[stratum.betti.len() - 1]
        };
        let separated = components >= 2;
        let mut apart = if separated {
            bettimill_deform::Apart::keeping(&image, &phase, generated.gap as i64)
        } else {
            None
        };
        if let Some(deformation) = &plan.deform {
            report(Stage::Deform, 0.0);
            let mut failed = None;
            // Counted once; each step reports the count it leaves.
            let mut foreground = image.count_foreground();
            for (i, step) in deformation.0.iter().enumerate() {
                let at = (i as u32).to_le_bytes();
                let draw = step_seed("bettimill deform draw v2", &task.seed, attempt, &at);
                let settings = bettimill_deform::draw_settings(step, draw);
                let seed = step_seed("bettimill deform seed v2", &task.seed, attempt, &at);
                match bettimill_deform::deform_phase_counted(
                    &mut image,
                    &settings,
                    &mut phase,
                    apart.as_mut(),
                    seed,
                    foreground,
                ) {
                    Ok(step_report) => foreground = step_report.foreground_after,
                    Err(err) => {
                        failed = Some(format!("deformation step {i} failed: {err}"));
                        break;
                    }
                }
                applied.push(settings);
            }
            if let Some(failure) = failed {
                last = failure;
                continue;
            }
        }
        let mut kept_clearance = true;
        if let Some((lo, hi)) = stratum.hypervolume {
            report(Stage::Hypervolume, 0.0);
            let seed = sub_seed("bettimill hypervolume seed v1", &task.seed, attempt);
            // A count outside the bin moves to a point of the bin drawn per sample, so
            // that a bin's samples spread over it instead of piling on its nearer end.
            let draw = sub_seed("bettimill hypervolume goal v1", &task.seed, attempt);
            let goal = draw_between(draw, lo, hi);
            let target = |image: &mut BinaryImage,
                          apart: Option<&mut bettimill_deform::Apart>,
                          phase: &mut Phase| {
                bettimill_deform::target_hypervolume_phase(image, lo, hi, goal, phase, apart, seed)
            };
            // A bin the parts cannot reach while kept apart and their gaps kept open (the
            // image leaves them too little room) is reached without the clearance, then
            // with the narrowest gap between parts, then without the separation: the plan
            // accepted it.
            let mut reached = target(&mut image, apart.as_mut(), &mut phase);
            if reached.is_err() && phase.clearance() > 1 {
                phase = phase.with_clearance(0);
                kept_clearance = false;
                reached = target(&mut image, apart.as_mut(), &mut phase);
            }
            if reached.is_err() && apart.as_ref().is_some_and(|a| a.gap() > APART) {
                apart = bettimill_deform::Apart::new(&image, &phase);
                reached = target(&mut image, apart.as_mut(), &mut phase);
            }
            if reached.is_err() && apart.is_some() {
                apart = None;
                reached = target(&mut image, None, &mut phase);
            }
            if let Err(err) = reached {
                last = format!("hypervolume targeting failed: {err}");
                continue;
            }
        }
        // The label is the plan's: the stratum's analytic numbers and knot type, decided
        // once. The construction's own claim is only a cross-check.
        debug_assert_eq!(
            (
                &generated.betti,
                &generated.betti_rational,
                &generated.knot_type
            ),
            (&stratum.betti, &stratum.betti_rational, &stratum.knot_type),
            "the construction and the plan disagree on {}",
            stratum.label
        );
        report(Stage::Verify, 0.0);
        let topology = bettimill_homology::topology(&verification_window(&image));
        if topology.betti != stratum.betti {
            last = format!(
                "computed Betti numbers {:?}, the plan's stratum says {:?}",
                topology.betti, stratum.betti
            );
            continue;
        }
        let survives_dilations = plan.survives_dilations.filter(|&n| n > 0).map(|n| {
            if attempt < DILATION_CHECKED_ATTEMPTS {
                n
            } else {
                0
            }
        });
        if let Some(n) = survives_dilations.filter(|&n| n > 0) {
            let dilated = phase.dilated(&image, n as usize);
            let closed = bettimill_homology::topology(&verification_window(&dilated)).betti;
            if closed != topology.betti {
                last = format!(
                    "{n} dilation(s) of the {} change the Betti numbers to {closed:?}",
                    if phase.value == 1 {
                        "objects"
                    } else {
                        "cavities"
                    }
                );
                continue;
            }
        }
        let mut downscaled = Vec::new();
        let mut resolutions = Vec::new();
        let pooling = pooling_for(stratum.mode);
        for (i, &r) in plan.resolutions.iter().enumerate() {
            report(
                Stage::Downscale { side: r },
                i as f64 / plan.resolutions.len() as f64,
            );
            let small = downscale(&image, side / r as usize, pooling);
            let t = bettimill_homology::topology(&verification_window(&small));
            resolutions.push(ResolutionLabel {
                side: r,
                pooling,
                preserved: t.betti == topology.betti,
                betti: t.betti,
                euler: t.euler,
                hypervolume: small.count_foreground(),
            });
            downscaled.push(small);
        }
        let label = Label {
            key: task.key.clone(),
            betti: topology.betti,
            betti_rational: stratum.betti_rational.clone(),
            field: "Z/2".to_string(),
            euler: topology.euler,
            hypervolume: image.count_foreground(),
            components: generated.components,
            shape: image.shape().to_vec(),
            dim: plan.dimension.get(),
            mode: mode_name(stratum.mode).to_string(),
            family: stratum.family.label(),
            knot_type: stratum.knot_type.clone(),
            stratum: stratum.index,
            class_label: stratum.label.clone(),
            seed: hex(&task.seed),
            attempt,
            manifest_hash: plan.manifest_hash.clone(),
            tool_version: TOOL_VERSION.to_string(),
            construction: generated.construction,
            deform: applied,
            clearance: clearance.map(|c| if kept_clearance { c } else { 0 }),
            survives_dilations,
            separation: separated.then(|| apart.as_ref().map_or(0, |a| a.gap() as u32)),
            hypervolume_bin: stratum.hypervolume,
            resolutions,
        };
        return Ok(Sample {
            image,
            label,
            downscaled,
        });
    }
    Err(SampleError::GaveUp {
        key: task.key.clone(),
        class: stratum.label.clone(),
        attempts: MAX_ATTEMPTS,
        last,
    })
}

/// Rasterises the construction of `task` at `attempt` and finds the phase that carries
/// its topology: the cavities inside the solid in carve mode, the objects in embed mode.
/// Deformation and targeting edit that phase alone.
fn generate(
    plan: &Plan,
    task: &SampleTask,
    attempt: u32,
) -> Result<(Generated, Phase), bettimill_shapes::ShapeError> {
    let stratum = &plan.strata[task.stratum];
    let mut rng = attempt_rng(&task.seed, attempt);
    // Binned samples are built near a foreground count drawn inside the bin, so that
    // only a small remainder is left to topology-preserving flips.
    let foreground = stratum
        .hypervolume
        .map(|(lo, hi)| position_in_bin(lo, hi, &task.seed, attempt));
    // A manifest's wider `inner_gap` is the plan's estimate of what shrinks into the bin;
    // where the wider objects still stop above it, later attempts build with the usual gap
    // (the construction records which), so every stratum the plan accepts builds.
    let floor = if attempt < WIDE_GAP_ATTEMPTS {
        stratum.tube_floor
    } else {
        stratum.tube_floor.with_gap(TubeFloor::USUAL.gap())
    };
    let generated = bettimill_shapes::generate_planned_for(
        &stratum.family,
        plan.dimension,
        plan.side as usize,
        stratum.mode,
        foreground,
        plan.solid,
        floor,
        &mut rng,
    )?;
    let phase = match &generated.phase_box {
        Some((lo, hi)) => Phase::cavities(&generated.image, lo, hi),
        None => Phase::foreground(&generated.image),
    };
    Ok((generated, phase))
}

/// A sample's undeformed construction: the voxels as rasterised, before any deformation
/// or hypervolume targeting, and the phase those edit.
#[derive(Clone, Debug)]
pub struct Construction {
    /// The rasterised voxels.
    pub image: BinaryImage,
    /// The phase that carries the topology (and the box deformation may edit).
    pub phase: Phase,
}

/// The construction [`make_sample`] starts from at `attempt` (a written sample's label
/// records its `attempt`): what a sample looked like before it was deformed, for
/// measuring how far deformation took it. Not verified; only [`make_sample`]'s output is.
pub fn construction(
    plan: &Plan,
    task: &SampleTask,
    attempt: u32,
) -> Result<Construction, SampleError> {
    let (generated, phase) =
        generate(plan, task, attempt).map_err(|err| SampleError::Construction {
            key: task.key.clone(),
            attempt,
            reason: err.to_string(),
        })?;
    Ok(Construction {
        image: generated.image,
        phase,
    })
}

/// Lower-case hex of bytes.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition, voxel by voxel: a block takes the winning value when any of its
    /// voxels has it.
    fn downscale_slowly(image: &BinaryImage, factor: usize, pooling: Pooling) -> BinaryImage {
        let d = image.dim().get();
        let shape: Vec<usize> = image.shape().iter().map(|&n| n / factor).collect();
        let winner = pooling == Pooling::ForegroundAny;
        let mut out = BinaryImage::zeros(&shape).unwrap();
        if !winner {
            out.data_mut().fill(1);
        }
        for (index, &v) in image.data().iter().enumerate() {
            if (v != 0) == winner {
                let c = image.coords(index);
                let small: Vec<usize> = c[..d].iter().map(|&x| x / factor).collect();
                out.set(&small, winner);
            }
        }
        out
    }

    #[test]
    fn downscaling_agrees_with_the_definition() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for (shape, factor) in [
            (vec![8usize, 12], 2usize),
            (vec![9, 6, 12], 3),
            (vec![8, 8, 4, 12], 4),
            (vec![4, 4, 4, 4], 1),
        ] {
            let mut image = BinaryImage::zeros(&shape).unwrap();
            for v in image.data_mut() {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                *v = state.is_multiple_of(11) as u8;
            }
            for pooling in [Pooling::ForegroundAny, Pooling::BackgroundAny] {
                assert_eq!(
                    downscale(&image, factor, pooling).data(),
                    downscale_slowly(&image, factor, pooling).data(),
                    "{shape:?} / {factor} {pooling:?}"
                );
            }
        }
    }

    #[test]
    fn foreground_any_is_max_pooling_and_background_any_is_min_pooling() {
        let mut image = BinaryImage::zeros(&[4, 4, 4]).unwrap();
        image.set(&[3, 0, 1], true);
        let small = downscale(&image, 2, Pooling::ForegroundAny);
        assert_eq!(small.shape(), &[2, 2, 2]);
        assert_eq!(small.count_foreground(), 1);
        assert!(small.get(&[1, 0, 0]));
        // The complement: one background voxel clears its whole block.
        for v in image.data_mut() {
            *v = 1 - *v;
        }
        let small = downscale(&image, 2, Pooling::BackgroundAny);
        assert_eq!(small.count_foreground(), 7);
        assert!(!small.get(&[1, 0, 0]));
    }

    #[test]
    fn the_foreground_window_keeps_the_foreground_and_its_topology() {
        let mut image = BinaryImage::zeros(&[9, 8, 10]).unwrap();
        assert_eq!(foreground_window(&image).shape(), &[9, 8, 10]);
        // A hollow box from (2, 1, 3) to (6, 5, 8).
        for x in 2..=6 {
            for y in 1..=5 {
                for z in 3..=8 {
                    let inner =
                        (3..=5).contains(&x) && (2..=4).contains(&y) && (4..=7).contains(&z);
                    image.set(&[x, y, z], !inner);
                }
            }
        }
        let window = foreground_window(&image);
        assert_eq!(window.shape(), &[5, 5, 6]);
        assert_eq!(window.count_foreground(), image.count_foreground());
        assert_eq!(
            bettimill_homology::topology(&window).betti,
            bettimill_homology::topology(&image).betti
        );
        assert_eq!(bettimill_homology::topology(&window).betti, vec![1, 0, 1]);
    }

    #[test]
    fn the_observer_sees_every_stage_in_order_and_changes_nothing() {
        let text = "schema_version = 1\nname = \"obs\"\ndimension = 2\nside = 32\n\
                    mode = \"carve\"\nsamples = 3\nshard_size = 3\nseed = 9\n\
                    resolutions = [16, 8]\n\
                    [deform]\nmethod = \"moves\"\nsteps = 20\n\
                    [hypervolume]\nunit = \"fraction\"\nbins = [[0.55, 0.75]]\n\
                    [[classes]]\nfamily = \"ball\"\n";
        let plan = Plan::parse(text, std::path::Path::new("obs.toml")).unwrap();
        for index in 0..plan.samples {
            let task = plan.task(index).unwrap();
            let mut seen = Vec::new();
            let observed = make_sample_observed(&plan, &task, &mut |p| seen.push(p)).unwrap();
            let plain = make_sample(&plan, &task).unwrap();
            assert_eq!(observed.fields(), plain.fields(), "sample {index}");
            // The last attempt's stages, in order, each once, and nothing after the copies.
            let attempt = observed.label.attempt;
            let last: Vec<Stage> = seen
                .iter()
                .filter(|p| p.attempt == attempt)
                .map(|p| p.stage)
                .collect();
            assert_eq!(
                last,
                [
                    Stage::Generate,
                    Stage::Deform,
                    Stage::Hypervolume,
                    Stage::Verify,
                    Stage::Downscale { side: 16 },
                    Stage::Downscale { side: 8 },
                ],
                "sample {index}"
            );
            assert!(seen.iter().all(|p| p.attempt <= attempt));
            let fractions: Vec<f64> = seen
                .iter()
                .filter(|p| p.attempt == attempt)
                .map(|p| p.fraction)
                .collect();
            assert!(
                fractions.windows(2).all(|w| w[0] < w[1]) && fractions[0] == 0.0,
                "{fractions:?}"
            );
            assert!(*fractions.last().unwrap() < Stage::Encode.sample_fraction(0.0));
        }
        assert_eq!(Stage::Encode.sample_fraction(1.0), 1.0);
        assert_eq!(Stage::Downscale { side: 64 }.to_string(), "downscale r64");
    }

    #[test]
    fn both_modes_record_max_pooling() {
        assert_eq!(pooling_for(Mode::Carve), Pooling::ForegroundAny);
        assert_eq!(pooling_for(Mode::Embed), Pooling::ForegroundAny);
    }
}
