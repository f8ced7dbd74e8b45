//! Necks: the phase narrowed inside slabs across it, so that one part looks like two
//! blobs joined by a thin neck (as chains of blobs and random-walk bodies do), while its
//! topology stays as it was.
//!
//! Each neck is a slab [`SLAB_HALF`] either side of a hyperplane: its normal is a uniform
//! random direction, and its depth is drawn between the first and the third quartile of
//! the phase's frontier voxels' depths along that normal, so that it crosses the phase's
//! body rather than grazing it. Inside the slab the phase shrinks exactly as
//! [`crate::Method::Erode`] shrinks it (simple-point flips, the lowest-noise share of the
//! frontier per iteration), and nothing outside the slab changes. Erosion only removes
//! phase voxels that are simple, so a part never splits: it thins to a neck as narrow as
//! its topology allows.

use crate::apart::Apart;
use crate::morphology::{self, Morphology, Slab};
use crate::phase::{Layout, Phase};
use crate::walkers::{normal, normalise, unit_open};
use crate::{DeformError, DeformReport, DeformSettings};
use bettimill_grid::BinaryImage;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The rand_chacha stream of the slabs (see `moves::MOVES_STREAM`).
const PINCH_STREAM: u64 = 4;

/// Half the slab's thickness: voxel centres within 1.5 of the plane, three voxels along
/// an axis.
pub(crate) const SLAB_HALF: f64 = 1.5;

/// Makes `settings.count` necks of `settings.steps` erosion iterations each.
pub(crate) fn run(
    image: &mut BinaryImage,
    phase: &mut Phase,
    mut apart: Option<&mut Apart>,
    settings: &DeformSettings,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    // The foreground counts are the caller's (`deform_phase_counted`).
    let mut report = DeformReport::default();
    let d = image.dim().get();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(PINCH_STREAM);
    for _ in 0..settings.count {
        let layout = Layout::new(image, phase);
        if settings.steps == 0 || layout.is_empty() {
            break;
        }
        let frontier = layout.frontier(image, phase.value);
        if frontier.is_empty() {
            break;
        }
        let mut direction = [0f64; 4];
        loop {
            for x in direction.iter_mut().take(d) {
                *x = normal(&mut rng);
            }
            if normalise(&mut direction, d) {
                break;
            }
        }
        let mut depths: Vec<f64> = frontier
            .iter()
            .map(|&v| Slab::depth(&direction, layout.coords(v)))
            .collect();
        depths.sort_unstable_by(f64::total_cmp);
        let quantile = 0.25 + 0.5 * unit_open(&mut rng);
        let at = ((depths.len() - 1) as f64 * quantile) as usize;
        let one = morphology::run(
            image,
            &mut Morphology {
                phase,
                grow: false,
                steps: settings.steps,
                growth_probability: settings.growth_probability,
                noise_frequency: settings.noise_frequency,
                octaves: settings.octaves,
                seed: rng.gen(),
                slab: Some(Slab {
                    normal: direction,
                    offset: depths[at],
                    half: SLAB_HALF,
                }),
            },
            apart.as_deref_mut(),
        )?;
        report.applied += one.applied;
        report.rejected += one.rejected;
        report.iterations += one.iterations;
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Method;
    use bettimill_homology::topology;

    /// A ball of `radius` about the middle of a cube of `side`, in `d` dimensions; with
    /// `carve`, the cube (less its outer layer) with the ball as its cavity.
    fn ball(d: usize, side: usize, radius: f64, carve: bool) -> BinaryImage {
        let mut image = BinaryImage::zeros(&vec![side; d]).unwrap();
        let middle = (side as f64 - 1.0) / 2.0;
        for v in 0..image.len() {
            let c = image.coords(v);
            let c = &c[..d];
            let inside =
                c.iter().map(|&x| (x as f64 - middle).powi(2)).sum::<f64>() <= radius * radius;
            let border = c.iter().any(|&x| x == 0 || x + 1 == side);
            image.data_mut()[v] = if carve { !border && !inside } else { inside } as u8;
        }
        image
    }

    fn phase_of(image: &BinaryImage, carve: bool) -> Phase {
        let d = image.dim().get();
        let side = image.shape()[0];
        if carve {
            Phase::cavities(image, &vec![2; d], &vec![side - 3; d])
        } else {
            Phase::foreground(image)
        }
    }

    #[test]
    fn a_neck_thins_the_phase_inside_its_slab_and_nowhere_else() {
        for (d, side, radius) in [(2, 24, 8.0), (3, 20, 6.5), (4, 16, 5.5)] {
            for carve in [false, true] {
                let image = ball(d, side, radius, carve);
                let mut phase = phase_of(&image, carve);
                phase.find_extent(&image);
                let middle = (side as f64 - 1.0) / 2.0;
                let mut normal = [0.0; 4];
                normal[0] = 1.0;
                let slab = Slab {
                    normal,
                    offset: middle.floor(),
                    half: SLAB_HALF,
                };
                // The phase's voxels in the slab, but not the background outside a
                // carved cube.
                let in_phase = |img: &BinaryImage| {
                    let inner = |c: [usize; 4]| c[..d].iter().all(|&x| x > 0 && x + 1 < side);
                    (0..img.len())
                        .filter(|&v| img.data()[v] == phase.value)
                        .filter(|&v| slab.holds(img.coords(v)) && inner(img.coords(v)))
                        .count()
                };
                let mut out = image.clone();
                let report = morphology::run(
                    &mut out,
                    &mut Morphology {
                        phase: &mut phase.clone(),
                        grow: false,
                        steps: side as u32,
                        growth_probability: 1.0,
                        noise_frequency: 0.2,
                        octaves: 2,
                        seed: 3,
                        slab: Some(slab),
                    },
                    None,
                )
                .unwrap();
                let case = format!("{d}D side {side} carve {carve}");
                assert!(report.applied > 0, "{case}: {report:?}");
                for v in 0..out.len() {
                    if out.data()[v] != image.data()[v] {
                        assert!(
                            slab.holds(out.coords(v)),
                            "{case}: a voxel outside the slab"
                        );
                    }
                }
                assert_eq!(topology(&out).betti, topology(&image).betti, "{case}");
                // The slab's section of the ball thins to a neck a few voxels across.
                let (before, after) = (in_phase(&image), in_phase(&out));
                assert!(
                    after > 0 && after * 4 <= before,
                    "{case}: {before} -> {after}"
                );
                assert!(
                    after <= 3usize.pow(d as u32 - 1),
                    "{case}: {before} -> {after}"
                );
            }
        }
    }

    #[test]
    fn necks_are_drawn_from_the_seed_alone_on_any_thread_count() {
        let image = ball(4, 16, 5.5, false);
        let mut settings = DeformSettings::new(Method::Pinch, 4);
        settings.count = 2;
        let outputs: Vec<BinaryImage> = [1, 2, 4]
            .iter()
            .map(|&n| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap();
                let mut out = image.clone();
                let report = pool
                    .install(|| crate::deform(&mut out, &settings, 9))
                    .unwrap();
                assert!(report.foreground_after < report.foreground_before);
                out
            })
            .collect();
        assert!(outputs.iter().all(|o| o.data() == outputs[0].data()));
        let mut other = image.clone();
        crate::deform(&mut other, &settings, 10).unwrap();
        assert_ne!(other.data(), outputs[0].data(), "another seed, other necks");
        assert_eq!(topology(&outputs[0]).betti, topology(&image).betti);
    }
}
