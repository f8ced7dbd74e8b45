use super::*;
use rand::{Rng, SeedableRng};

/// Every family the placement tests build, as manifests spell them.
const FAMILIES: [&str; 15] = [
    r#"{"family":"ball"}"#,
    r#"{"family":"handle"}"#,
    r#"{"family":"shell"}"#,
    r#"{"family":"torus_shell"}"#,
    r#"{"family":"handlebody","genus":2}"#,
    r#"{"family":"curve"}"#,
    r#"{"family":"loop"}"#,
    r#"{"family":"knot","knot":"trefoil"}"#,
    r#"{"family":"link","link":"hopf"}"#,
    r#"{"family":"s2_x_b2"}"#,
    r#"{"family":"bumpy_shell"}"#,
    r#"{"family":"bumpy_s2_x_b2"}"#,
    r#"{"family":"t2_x_b2"}"#,
    r#"{"family":"connected_sum","g":1,"h":1,"i":1,"j":2}"#,
    r#"{"family":"spun_knot","knot":"trefoil"}"#,
];

/// Clipping the scanned rows to each bounding ball keeps every voxel of every solid
/// the library builds, rotated and placed at random, in every dimension.
#[test]
fn clipping_rows_to_the_ball_changes_no_voxel() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let side = 40usize;
    let region = Region::for_mode(side, Mode::Embed);
    let (mut built, mut voxels) = (0, 0);
    for text in FAMILIES {
        let family: Family = serde_json::from_str(text).unwrap();
        for dim in 2..=4 {
            let Some(minimum) = min_extent(&family, dim, TubeFloor::USUAL) else {
                continue;
            };
            for _ in 0..6 {
                let target = rng.gen_range(minimum..=minimum.max(region.budget()));
                let Some((solid, _)) =
                    build(&family, dim, target, TubeFloor::USUAL, Fit::Ball, &mut rng)
                else {
                    continue;
                };
                let rotation = Rotation::random(&free_axes(&family, dim), &mut rng);
                let extent = solid.extent();
                let Some(centre) =
                    random_centre(dim, region.lo - 4, region.hi + 4, extent * 0.8, &mut rng)
                else {
                    continue;
                };
                let placed = Placed::bounded(solid, rotation, centre);
                let (lo, hi) = (region.lo, region.hi);
                let clipped = rasterise_clipped(&placed, dim, side, lo, hi, None, true);
                let whole = rasterise_clipped(&placed, dim, side, lo, hi, None, false);
                assert_eq!(clipped, whole, "{text} {dim}D");
                built += 1;
                voxels += whole.unwrap().len();
            }
        }
    }
    assert!(
        built > 100 && voxels > 100_000,
        "{built} solids, {voxels} voxels"
    );
}

/// An object sized for its rotated half-widths stays inside them: every voxel of
/// every family, rotated at random, lies within its half-width of the centre along
/// each axis. A 4D loop or curve, narrower along the axes than its bounding ball, comes
/// out larger than one sized for the ball from the same draws.
#[test]
fn rotated_objects_stay_within_their_half_widths() {
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let side = 36usize;
    let (mut checked, mut ring_share) = (0, Vec::new());
    for text in FAMILIES {
        let family: Family = serde_json::from_str(text).unwrap();
        for dim in 2..=4 {
            for _ in 0..6 {
                let rotation = Rotation::random(&free_axes(&family, dim), &mut rng);
                let fit = Fit::Axes(&rotation, dim);
                let volume = rng.gen_range(200.0..6_000.0);
                let mut same_draws = rng.clone();
                let Some((solid, _)) = build_volume(
                    &family,
                    dim,
                    11.0,
                    volume,
                    TubeFloor::USUAL,
                    false,
                    fit,
                    &mut rng,
                ) else {
                    continue;
                };
                let widths: Vec<f64> = (0..dim)
                    .map(|k| solid.half_width(rotation.axis_in_local(k)))
                    .collect();
                assert!(fit.reach(&solid) <= 11.0 + 1e-9, "{text} {dim}D");
                if (text.contains("loop") || text.contains("curve")) && dim == 4 {
                    let floor = TubeFloor::USUAL;
                    let (in_ball, _) = build_volume(
                        &family,
                        dim,
                        11.0,
                        volume,
                        floor,
                        false,
                        Fit::Ball,
                        &mut same_draws,
                    )
                    .unwrap();
                    ring_share.push(solid.extent() / in_ball.extent());
                }
                let mut centre = [0.0; 4];
                centre[..dim].fill((side as f64 - 1.0) / 2.0);
                let placed = Placed::bounded(solid, rotation, centre);
                let voxels = rasterise(&placed, dim, side, 0, side as i64 - 1);
                assert!(!voxels.is_empty(), "{text} {dim}D");
                for v in voxels {
                    let mut rest = v;
                    for k in (0..dim).rev() {
                        let x = (rest % side) as f64;
                        rest /= side;
                        let off = (x - centre[k]).abs();
                        assert!(off <= widths[k] + 1e-6, "{text} {dim}D axis {k}: {off}");
                    }
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 120, "{checked}");
    // Loops and curves sized for their half-widths come out larger than in a ball.
    let mean = ring_share.iter().sum::<f64>() / ring_share.len() as f64;
    assert!(ring_share.len() >= 8 && mean > 1.03, "{ring_share:?}");
}

/// Runs along the last axis (interior or touching faces, in any dimension, any gap)
/// block the same voxels as marking every voxel's cube one by one.
#[test]
fn blocking_runs_equals_blocking_each_voxel() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for (dim, side) in [(2usize, 17usize), (3, 11), (4, 9)] {
        for gap in [GAP, 3, GAP_MAX] {
            for _ in 0..20 {
                let mut voxels: Vec<usize> = (0..side.pow(dim as u32))
                    .filter(|_| rng.gen_bool(0.08))
                    .collect();
                // Long runs as well as scattered voxels.
                let start = rng.gen_range(0..side.pow(dim as u32) - side);
                voxels.extend(start..start + side);
                voxels.sort_unstable();
                voxels.dedup();
                let mut fast = Occupancy::new(dim, side, gap);
                fast.add(&voxels);
                let mut slow = Occupancy::new(dim, side, gap);
                for &v in &voxels {
                    slow.add_near_a_face(v);
                }
                assert_eq!(fast.blocked, slow.blocked, "{dim}D side {side} gap {gap}");
            }
        }
    }
}
