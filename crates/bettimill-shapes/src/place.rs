//! Placing objects in the image: rasterisation, margins and minimum gaps.
//!
//! An object is rasterised by testing every voxel centre in its bounding box against its
//! solid (after undoing its rotation and translation). Several objects are placed one by
//! one: after each placement the occupied set is dilated by the gap (a cube structuring
//! element, as in the paper's morphology section), and a new object is accepted only if
//! none of its voxels falls into that dilation. With a gap of 2 any two objects keep at
//! least two background voxels between them in every direction, which is what the
//! labels note asks for (touching cavities gave wrong labels).

use crate::geometry::{add, round6, sub, uniform, Rotation, Solid, P};
use crate::Mode;
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

/// Background voxels kept between two objects, and between an object and the border.
pub(crate) const GAP: i64 = 2;

/// Background layers around the solid cube in carve mode.
pub(crate) const CUBE_MARGIN: i64 = 1;

/// The inclusive voxel range (same on every axis) that object voxels may occupy.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Region {
    pub(crate) lo: i64,
    pub(crate) hi: i64,
}

impl Region {
    /// Embed: two background layers to the border. Carve: the cube fills
    /// `[CUBE_MARGIN, side - 1 - CUBE_MARGIN]` and cavities keep two cube layers to its
    /// boundary.
    pub(crate) fn for_mode(side: usize, mode: Mode) -> Region {
        let side = side as i64;
        let inset = match mode {
            Mode::Embed => GAP,
            Mode::Carve => CUBE_MARGIN + GAP,
        };
        Region {
            lo: inset,
            hi: side - 1 - inset,
        }
    }

    /// The largest bounding radius an object centred anywhere valid may have.
    pub(crate) fn budget(&self) -> f64 {
        (self.hi - self.lo) as f64 / 2.0
    }

    pub(crate) fn width(&self) -> i64 {
        self.hi - self.lo + 1
    }
}

/// An object with its pose in the image.
#[derive(Clone, Debug)]
pub(crate) struct Placed {
    pub(crate) solid: Solid,
    pub(crate) rotation: Rotation,
    pub(crate) centre: P,
    /// Axes along which the object is unbounded (tunnels); they are rasterised over the
    /// whole image.
    pub(crate) through_axes: Vec<usize>,
}

impl Placed {
    pub(crate) fn describe(&self, dim: usize) -> Value {
        json!({
            "centre": self.centre[..dim].iter().map(|&x| round6(x)).collect::<Vec<_>>(),
            "rotation": self.rotation.describe(),
            "solid": self.solid.describe(dim),
        })
    }
}

/// Draws a centre so that the bounding ball of radius `extent` stays in `[lo, hi]` on
/// every axis; `None` if it cannot.
pub(crate) fn random_centre(
    dim: usize,
    lo: i64,
    hi: i64,
    extent: f64,
    rng: &mut ChaCha8Rng,
) -> Option<P> {
    let low = lo as f64 + extent;
    let high = hi as f64 - extent;
    if low > high {
        return None;
    }
    let mut centre = [0.0; 4];
    for slot in centre.iter_mut().take(dim) {
        *slot = uniform(rng, low, high);
    }
    Some(centre)
}

/// Flat indices (ascending) of the voxels whose centres lie in the placed solid, within
/// the inclusive box `[box_lo, box_hi]` on every axis.
pub(crate) fn rasterise(
    placed: &Placed,
    dim: usize,
    side: usize,
    box_lo: i64,
    box_hi: i64,
) -> Vec<usize> {
    rasterise_unless_blocked(placed, dim, side, box_lo, box_hi, None).unwrap_or_default()
}

/// As [`rasterise`], but `None` as soon as a voxel falls on a blocked one (so rejected
/// placements cost little). Tube solids are scanned part by part, each over the box of
/// its own bounding ball, which for spread-out objects (rows of summands, links,
/// tentacles) visits far fewer voxels than the box of the whole object.
pub(crate) fn rasterise_unless_blocked(
    placed: &Placed,
    dim: usize,
    side: usize,
    box_lo: i64,
    box_hi: i64,
    blocked: Option<&Occupancy>,
) -> Option<Vec<usize>> {
    let mut out = Vec::new();
    let by_parts = match &placed.solid {
        Solid::Tube(parts) if placed.through_axes.is_empty() => parts
            .iter()
            .map(|(piece, r)| piece.bounds().map(|(c, radius)| (c, radius + r)))
            .collect::<Option<Vec<_>>>(),
        _ => None,
    };
    match (by_parts, &placed.solid) {
        (Some(balls), Solid::Tube(parts)) => {
            for ((centre, reach), (piece, r)) in balls.iter().zip(parts) {
                let world = add(placed.centre, placed.rotation.to_world(*centre));
                let test = |local: P| piece.within(local, *r);
                scan_box(
                    placed,
                    dim,
                    side,
                    box_lo,
                    box_hi,
                    (world, *reach),
                    &test,
                    blocked,
                    &mut out,
                )?;
            }
            out.sort_unstable();
            out.dedup();
        }
        _ => {
            let test = |local: P| placed.solid.contains(local);
            let ball = (placed.centre, placed.solid.extent());
            scan_box(
                placed, dim, side, box_lo, box_hi, ball, &test, blocked, &mut out,
            )?;
        }
    }
    Some(out)
}

/// Tests every voxel in the box around `ball` (clipped to `[box_lo, box_hi]`, and spanning
/// it entirely along through-axes) and appends those passing `test`.
#[allow(clippy::too_many_arguments)] // A private kernel; bundling would only rename them.
fn scan_box(
    placed: &Placed,
    dim: usize,
    side: usize,
    box_lo: i64,
    box_hi: i64,
    ball: (P, f64),
    test: &dyn Fn(P) -> bool,
    blocked: Option<&Occupancy>,
    out: &mut Vec<usize>,
) -> Option<()> {
    let (centre, extent) = ball;
    let mut lo = [0i64; 4];
    let mut hi = [0i64; 4];
    for k in 0..dim {
        if placed.through_axes.contains(&k) {
            lo[k] = box_lo;
            hi[k] = box_hi;
        } else {
            lo[k] = (libm::floor(centre[k] - extent) as i64).max(box_lo);
            hi[k] = (libm::ceil(centre[k] + extent) as i64).min(box_hi);
        }
    }
    let side = side as i64;
    if (0..dim).any(|k| lo[k] > hi[k]) {
        return Some(());
    }
    let mut c = lo;
    loop {
        let world = [c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64];
        let local = placed.rotation.to_local(sub(world, placed.centre));
        if test(local) {
            let mut index = 0i64;
            for &ck in c.iter().take(dim) {
                index = index * side + ck;
            }
            if blocked.is_some_and(|b| b.blocked[index as usize]) {
                return None;
            }
            out.push(index as usize);
        }
        // Odometer over the box, last axis fastest, so indices come out ascending.
        let mut k = dim;
        loop {
            if k == 0 {
                return Some(());
            }
            k -= 1;
            if c[k] < hi[k] {
                c[k] += 1;
                break;
            }
            c[k] = lo[k];
        }
    }
}

/// The occupied set dilated by the gap, grown object by object.
pub(crate) struct Occupancy {
    dim: usize,
    side: usize,
    blocked: Vec<bool>,
}

impl Occupancy {
    pub(crate) fn new(dim: usize, side: usize) -> Occupancy {
        Occupancy {
            dim,
            side,
            blocked: vec![false; side.pow(dim as u32)],
        }
    }

    /// Marks every voxel within Chebyshev distance `GAP` of the given ones.
    pub(crate) fn add(&mut self, voxels: &[usize]) {
        let side = self.side as i64;
        let dim = self.dim;
        let span = (2 * GAP + 1).pow(dim as u32);
        for &v in voxels {
            let mut coords = [0i64; 4];
            let mut rest = v as i64;
            for k in (0..dim).rev() {
                coords[k] = rest % side;
                rest /= side;
            }
            for code in 0..span {
                let mut index = 0i64;
                let mut inside = true;
                let mut rest = code;
                for &ck in coords.iter().take(dim) {
                    let offset = rest % (2 * GAP + 1) - GAP;
                    rest /= 2 * GAP + 1;
                    let x = ck + offset;
                    if x < 0 || x >= side {
                        inside = false;
                        break;
                    }
                    index = index * side + x;
                }
                if inside {
                    self.blocked[index as usize] = true;
                }
            }
        }
    }
}

/// The sub-box of one cell when the region is cut into `per_axis^dim` cells separated by
/// the gap. Used as the deterministic fallback when random placement keeps failing.
pub(crate) fn grid_cell(
    region: Region,
    per_axis: i64,
    cell: [i64; 4],
    dim: usize,
) -> ([i64; 4], [i64; 4]) {
    let width = cell_width(region, per_axis);
    let mut lo = [0i64; 4];
    let mut hi = [0i64; 4];
    for k in 0..dim {
        lo[k] = region.lo + cell[k] * (width + GAP);
        hi[k] = lo[k] + width - 1;
    }
    (lo, hi)
}

/// Voxels per cell edge when the region is split into `per_axis` cells per axis with
/// `GAP` background voxels between cells.
pub(crate) fn cell_width(region: Region, per_axis: i64) -> i64 {
    (region.width() + GAP) / per_axis - GAP
}

/// The smallest number of cells per axis that holds `count` cells in `dim` dimensions.
pub(crate) fn cells_per_axis(count: usize, dim: usize) -> i64 {
    let mut m = 1i64;
    while (m as usize).pow(dim as u32) < count {
        m += 1;
    }
    m
}
