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

pub use bettimill_format::{Label, ResolutionLabel, TOOL_VERSION};
use bettimill_grid::npy;
use bettimill_grid::BinaryImage;
use bettimill_plan::{attempt_rng, derive_seed, mode_name, Plan, SampleTask};

/// How many attempts a sample gets before the build reports it as failed.
pub const MAX_ATTEMPTS: u32 = 16;

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

/// Max pooling by `factor` along every axis: a block is foreground when any of its voxels
/// is. Every axis length must be a multiple of `factor`.
pub fn downscale(image: &BinaryImage, factor: usize) -> BinaryImage {
    let d = image.dim().get();
    let shape: Vec<usize> = image.shape().iter().map(|&n| n / factor).collect();
    let mut out = BinaryImage::zeros(&shape).expect("a downscaled valid image is valid");
    let in_strides = image.strides().to_vec();
    let out_strides = out.strides().to_vec();
    let row_len = image.shape()[d - 1];
    let out_data = out.data_mut();
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
            if run.iter().any(|&v| v != 0) {
                out_data[base + j] = 1;
            }
        }
    }
    out
}

/// A u64 seed in the named domain for (sample seed, attempt).
fn sub_seed(domain: &str, seed: &[u8; 32], attempt: u32) -> u64 {
    let bytes = derive_seed(domain, &[seed, &attempt.to_le_bytes()]);
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
}

/// Makes and verifies one sample.
pub fn make_sample(plan: &Plan, task: &SampleTask) -> Result<Sample, SampleError> {
    let stratum = &plan.strata[task.stratum];
    let side = plan.side as usize;
    let mut last = String::new();
    for attempt in 0..MAX_ATTEMPTS {
        let mut rng = attempt_rng(&task.seed, attempt);
        let generated = match bettimill_shapes::generate_planned(
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
        if let Some(settings) = &plan.deform {
            let seed = sub_seed("bettimill deform seed v1", &task.seed, attempt);
            if let Err(err) = bettimill_deform::deform(&mut image, settings, seed) {
                last = format!("deformation failed: {err}");
                continue;
            }
        }
        if let Some((lo, hi)) = stratum.hypervolume {
            let seed = sub_seed("bettimill hypervolume seed v1", &task.seed, attempt);
            if let Err(err) = bettimill_deform::target_hypervolume(&mut image, lo, hi, seed) {
                last = format!("hypervolume targeting failed: {err}");
                continue;
            }
        }
        // The label is the plan's: the stratum's analytic numbers, decided once.
        debug_assert_eq!(
            generated.betti, stratum.betti,
            "the construction and the plan disagree on {}",
            stratum.label
        );
        let topology = bettimill_homology::topology(&image);
        if topology.betti != stratum.betti {
            last = format!(
                "computed Betti numbers {:?}, the plan's stratum says {:?}",
                topology.betti, stratum.betti
            );
            continue;
        }
        let mut downscaled = Vec::new();
        let mut resolutions = Vec::new();
        for &r in &plan.resolutions {
            let small = downscale(&image, side / r as usize);
            let t = bettimill_homology::topology(&small);
            resolutions.push(ResolutionLabel {
                side: r,
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
            stratum: stratum.index,
            class_label: stratum.label.clone(),
            seed: hex(&task.seed),
            attempt,
            manifest_hash: plan.manifest_hash.clone(),
            tool_version: TOOL_VERSION.to_string(),
            construction: generated.construction,
            deform: plan.deform.clone(),
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

/// Lower-case hex of bytes.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition, voxel by voxel.
    fn downscale_slowly(image: &BinaryImage, factor: usize) -> BinaryImage {
        let d = image.dim().get();
        let shape: Vec<usize> = image.shape().iter().map(|&n| n / factor).collect();
        let mut out = BinaryImage::zeros(&shape).unwrap();
        for (index, &v) in image.data().iter().enumerate() {
            if v != 0 {
                let c = image.coords(index);
                let small: Vec<usize> = c[..d].iter().map(|&x| x / factor).collect();
                out.set(&small, true);
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
                *v = (state % 11 == 0) as u8;
            }
            assert_eq!(
                downscale(&image, factor).data(),
                downscale_slowly(&image, factor).data(),
                "{shape:?} / {factor}"
            );
        }
    }

    #[test]
    fn downscaling_is_max_pooling() {
        let mut image = BinaryImage::zeros(&[4, 4, 4]).unwrap();
        image.set(&[3, 0, 1], true);
        let small = downscale(&image, 2);
        assert_eq!(small.shape(), &[2, 2, 2]);
        assert_eq!(small.count_foreground(), 1);
        assert!(small.get(&[1, 0, 0]));
    }
}
