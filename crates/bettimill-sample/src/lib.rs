//! One sample: generate, deform, verify, label.
//!
//! This is the "task -> sample" step of the pipeline. A sample is only ever returned after
//! its Betti numbers have been computed from the final voxels and found equal to the
//! construction's analytic numbers; a mismatch is regenerated from the next attempt seed
//! (see `bettimill_plan::attempt_rng`), so the result is still a pure function of the
//! manifest and the sample index, and the number of attempts is recorded in the label.

use bettimill_grid::npy;
use bettimill_grid::BinaryImage;
use bettimill_manifest::{DeformSpec, Manifest};
use bettimill_plan::{attempt_rng, mode_name, Plan, SampleTask};
use serde::{Deserialize, Serialize};

/// How many attempts a sample gets before the build reports it as failed.
pub const MAX_ATTEMPTS: u32 = 16;

/// The version written into every label.
pub const TOOL_VERSION: &str = env!("CARGO_PKG_VERSION");

/// The label stored as `KEY.json`. Field order is fixed by this struct, and the
/// construction record is a JSON value with sorted keys, so equal labels are equal bytes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Label {
    /// The WebDataset key.
    pub key: String,
    /// Betti numbers over Z/2, computed from the stored voxels.
    pub betti: Vec<u64>,
    /// Betti numbers over Q when they differ from the Z/2 ones (non-orientable pieces).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub betti_rational: Option<Vec<u64>>,
    /// The coefficient field of `betti`.
    pub field: String,
    /// Euler characteristic.
    pub euler: i64,
    /// Foreground voxel count.
    pub hypervolume: u64,
    /// Number of objects placed by the construction.
    pub components: u64,
    /// Image shape.
    pub shape: Vec<usize>,
    /// Number of axes.
    pub dim: usize,
    /// `embed` or `carve`.
    pub mode: String,
    /// Construction family label.
    pub family: String,
    /// Knot or link type ("none" when there is none): a label Betti numbers cannot see.
    pub knot_type: String,
    /// Index of the sample's stratum (also stored as `KEY.cls`).
    pub class_index: usize,
    /// Human-readable stratum name.
    pub class_label: String,
    /// The sample's seed, 64 hex digits.
    pub seed: String,
    /// Which attempt (from 0) produced the sample; > 0 means earlier attempts were rejected.
    pub attempt: u32,
    /// The manifest's canonical hash.
    pub manifest_hash: String,
    /// bettimill version.
    pub tool_version: String,
    /// How the sample was built.
    pub construction: serde_json::Value,
    /// Deformation applied, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deform: Option<DeformSpec>,
}

/// A verified sample.
#[derive(Clone, Debug)]
pub struct Sample {
    /// The voxels.
    pub image: BinaryImage,
    /// Its label.
    pub label: Label,
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
        self.label.class_index.to_string().into_bytes()
    }
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
}

/// Makes and verifies one sample.
pub fn make_sample(
    manifest: &Manifest,
    plan: &Plan,
    task: &SampleTask,
) -> Result<Sample, SampleError> {
    let stratum = &plan.strata[task.stratum];
    let side = plan.side as usize;
    let mut last = String::new();
    for attempt in 0..MAX_ATTEMPTS {
        let mut rng = attempt_rng(&task.seed, attempt);
        let generated = match bettimill_shapes::generate(
            &stratum.family,
            plan.dimension,
            side,
            stratum.mode,
            &mut rng,
        ) {
            Ok(g) => g,
            Err(err) => {
                last = format!("generation failed: {err}");
                continue;
            }
        };
        let mut image = generated.image;
        if let Some(spec) = &manifest.deform {
            if let Err(err) = deform(&mut image, spec, &task.seed, attempt) {
                last = format!("deformation failed: {err}");
                continue;
            }
        }
        let topology = bettimill_homology::topology(&image);
        if topology.betti != generated.betti {
            last = format!(
                "computed Betti numbers {:?}, the construction says {:?}",
                topology.betti, generated.betti
            );
            continue;
        }
        let label = Label {
            key: task.key.clone(),
            betti: topology.betti,
            betti_rational: generated.betti_rational,
            field: "Z/2".to_string(),
            euler: topology.euler,
            hypervolume: image.count_foreground(),
            components: generated.components,
            shape: image.shape().to_vec(),
            dim: plan.dimension.get(),
            mode: mode_name(stratum.mode).to_string(),
            family: stratum.family.label(),
            knot_type: generated.knot_type,
            class_index: stratum.index,
            class_label: stratum.label.clone(),
            seed: hex(&task.seed),
            attempt,
            manifest_hash: plan.manifest_hash.clone(),
            tool_version: TOOL_VERSION.to_string(),
            construction: generated.construction,
            deform: manifest.deform.clone(),
        };
        return Ok(Sample { image, label });
    }
    Err(SampleError::GaveUp {
        key: task.key.clone(),
        class: stratum.label.clone(),
        attempts: MAX_ATTEMPTS,
        last,
    })
}

fn deform(
    _image: &mut BinaryImage,
    _spec: &DeformSpec,
    _seed: &[u8; 32],
    _attempt: u32,
) -> Result<(), String> {
    Err("deformations are not wired into builds yet".to_string())
}

/// Lower-case hex of bytes.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
