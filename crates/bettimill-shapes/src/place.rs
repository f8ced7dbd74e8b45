//! Placing objects in the image: rasterisation, margins, minimum gaps and the layout
//! search.
//!
//! An object is rasterised by testing every voxel centre in its bounding box against its
//! solid (after undoing its rotation and translation). Several objects are placed one by
//! one: after each placement the occupied set is dilated by the gap (a cube structuring
//! element, as in the paper's morphology section), and a new object is accepted only if
//! none of its voxels falls into that dilation. With a gap of 2 any two objects keep at
//! least two background voxels between them in every direction, which is what the
//! labels note asks for (touching cavities gave wrong labels). A scene draws its gap per
//! sample, from [`narrowest_gap`] to [`widest_gap`]: parts that always stand two voxels
//! apart would teach a network that two components meet across a narrow gap, where shapes
//! made any other way stand at every distance.
//!
//! The layout search ([`place_objects`]) tries random sizes, rotations and positions,
//! largest object first, for a few rounds (the later ones at minimum sizes); then falls
//! back to one object per cell of a grid, or, where the grid cannot hold them, to a
//! canonical layout found with fixed seeds ([`canonical_layout`]), so a request that
//! passed plan-time feasibility always produces a sample. Tunnels, which run from face to
//! face, have their own placement ([`place_tunnel`]).

use crate::geometry::{
    add, narrowest_gap, round6, sub, uniform, uniform_int, Solid, TubeFloor, GAP, P,
};
use crate::rotation::Rotation;
use crate::sizing::{build, build_volume, draw_target, min_extent, Fit};
use crate::{Family, Mode, ShapeError};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

/// Background layers kept between an object and the border in embed mode: the one layer
/// deformations never touch (the simple-point test reads all 3^d neighbours). A wider
/// border would only shrink the room: in a 4D image of side 24 a second layer costs a
/// tenth of an object's reach, and a ring of a few percent of the image must then be a
/// fat one with a narrow hole.
pub(crate) const BORDER: i64 = 1;

/// The widest gap a scene draws between its objects, in background voxels. Growth keeps
/// the gap by reading every voxel within it of a voxel about to join near another part
/// (`bettimill_deform::Apart`), a window of (2 * gap + 1)^d voxels.
const GAP_MAX: i64 = 6;

/// The widest gap drawn between the objects of a scene in an image of side `side`: a
/// quarter of the side, from [`GAP`] up to [`GAP_MAX`].
pub(crate) fn widest_gap(side: usize) -> i64 {
    (side as i64 / 4).clamp(GAP, GAP_MAX)
}

/// The largest ratio between two objects' shares of a scene's voxel count. Components
/// of one sample range from a few voxels to most of the count, as they do in shapes made
/// any other way; shares within a factor of two would teach a network that the
/// components of one image are alike in size.
const SHARE_RATIO: f64 = 16.0;

/// Background layers around the solid cube in carve mode.
pub(crate) const CUBE_MARGIN: i64 = 1;

/// The inclusive voxel range (same on every axis) that object voxels may occupy.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Region {
    pub(crate) lo: i64,
    pub(crate) hi: i64,
}

impl Region {
    /// Embed: [`BORDER`] background layers to the border. Carve: the cube fills
    /// `[CUBE_MARGIN, side - 1 - CUBE_MARGIN]` and cavities keep two cube layers to its
    /// boundary.
    pub(crate) fn for_mode(side: usize, mode: Mode) -> Region {
        let side = side as i64;
        let inset = match mode {
            Mode::Embed => BORDER,
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
    /// A solid bounded on every axis (not a tunnel), turned by `rotation` about `centre`.
    pub(crate) fn bounded(solid: Solid, rotation: Rotation, centre: P) -> Placed {
        Placed {
            solid,
            rotation,
            centre,
            through_axes: Vec::new(),
        }
    }

    pub(crate) fn describe(&self, dim: usize) -> Value {
        json!({
            "centre": self.centre[..dim].iter().map(|&x| round6(x)).collect::<Vec<_>>(),
            "rotation": self.rotation.describe(),
            "solid": self.solid.describe(dim),
        })
    }
}

/// Draws a centre so that a solid of half-width `widths[k]` along axis `k` stays in
/// `[lo, hi]` on every axis; `None` if it cannot.
fn centre_within(dim: usize, lo: i64, hi: i64, widths: &[f64], rng: &mut ChaCha8Rng) -> Option<P> {
    let mut centre = [0.0; 4];
    for (slot, &width) in centre.iter_mut().zip(widths).take(dim) {
        let low = lo as f64 + width;
        let high = hi as f64 - width;
        if low > high {
            return None;
        }
        *slot = uniform(rng, low, high);
    }
    Some(centre)
}

/// Draws a centre so that the bounding ball of radius `extent` stays in `[lo, hi]` on
/// every axis; `None` if it cannot.
fn random_centre(dim: usize, lo: i64, hi: i64, extent: f64, rng: &mut ChaCha8Rng) -> Option<P> {
    centre_within(dim, lo, hi, &[extent; 4], rng)
}

/// Flat indices (ascending) of the voxels whose centres lie in the placed solid, within
/// the inclusive box `[box_lo, box_hi]` on every axis.
fn rasterise(placed: &Placed, dim: usize, side: usize, box_lo: i64, box_hi: i64) -> Vec<usize> {
    rasterise_unless_blocked(placed, dim, side, box_lo, box_hi, None).unwrap_or_default()
}

/// As [`rasterise`], but `None` as soon as a voxel falls on a blocked one (so rejected
/// placements cost little). Tube solids are scanned part by part, each over the box of
/// its own bounding ball, which for spread-out objects (rows of summands, links,
/// tentacles) visits far fewer voxels than the box of the whole object.
fn rasterise_unless_blocked(
    placed: &Placed,
    dim: usize,
    side: usize,
    box_lo: i64,
    box_hi: i64,
    blocked: Option<&Occupancy>,
) -> Option<Vec<usize>> {
    rasterise_clipped(placed, dim, side, box_lo, box_hi, blocked, true)
}

/// [`rasterise_unless_blocked`], scanning each bounding ball's box whole when `clip` is
/// false (tests: clipping the rows to the ball changes no voxel).
fn rasterise_clipped(
    placed: &Placed,
    dim: usize,
    side: usize,
    box_lo: i64,
    box_hi: i64,
    blocked: Option<&Occupancy>,
    clip: bool,
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
                    (blocked, clip),
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
                placed,
                dim,
                side,
                box_lo,
                box_hi,
                ball,
                &test,
                (blocked, clip),
                &mut out,
            )?;
        }
    }
    Some(out)
}

/// How far beyond its bounding ball a voxel may lie and still be scanned. A voxel that
/// passes an object's test lies within the ball in exact arithmetic; the floating-point
/// error of the test, of the rotation and of the distances here is below 1e-9 voxels at
/// any image size this tool makes, so this slack keeps every such voxel by a wide margin.
const BALL_SLACK: f64 = 1e-3;

/// Tests every voxel in the box around `ball` (clipped to `[box_lo, box_hi]`, and spanning
/// it entirely along through-axes) and appends those passing `test`, in increasing flat
/// order; `None` as soon as one of them is blocked.
///
/// With `clip` (and no through-axes), each row along the last axis is cut to the part
/// within the ball's radius plus [`BALL_SLACK`], and rows that miss the ball are skipped:
/// `ball` bounds the solid (every piece's bounding ball contains all points within its
/// tube radius of the piece, and a solid's extent contains its pieces' balls), so no voxel
/// that passes `test` is left out, and the voxels that pass come out in the same order,
/// the first blocked one included. A 4D ball fills under a third of its box.
#[allow(clippy::too_many_arguments)] // A private kernel; bundling would only rename them.
fn scan_box(
    placed: &Placed,
    dim: usize,
    side: usize,
    box_lo: i64,
    box_hi: i64,
    ball: (P, f64),
    test: &dyn Fn(P) -> bool,
    (blocked, clip): (Option<&Occupancy>, bool),
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
    let clip = clip && placed.through_axes.is_empty();
    let reach = extent + BALL_SLACK;
    let last = dim - 1;
    let mut c = lo;
    loop {
        // The row's span along the last axis.
        let (mut from, mut to) = (lo[last], hi[last]);
        if clip {
            let mut q = 0.0;
            for k in 0..last {
                let x = c[k] as f64 - centre[k];
                q += x * x;
            }
            let room = reach * reach - q;
            if room < 0.0 {
                from = to + 1;
            } else {
                let half = room.sqrt();
                from = from.max(libm::floor(centre[last] - half) as i64);
                to = to.min(libm::ceil(centre[last] + half) as i64);
            }
        }
        for x in from..=to {
            c[last] = x;
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
        }
        // Odometer over the leading axes, so indices come out ascending.
        let mut k = last;
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
struct Occupancy {
    dim: usize,
    side: usize,
    /// The Chebyshev radius of the dilation: the background voxels kept between objects.
    gap: i64,
    blocked: Vec<bool>,
}

impl Occupancy {
    fn new(dim: usize, side: usize, gap: i64) -> Occupancy {
        Occupancy {
            dim,
            side,
            gap,
            blocked: vec![false; side.pow(dim as u32)],
        }
    }

    /// Marks every voxel within Chebyshev distance `gap` of the given ones (ascending flat
    /// indices). The cube of radius `gap` is the product of segments along the axes, so the
    /// voxels' box, grown by the gap, is dilated one axis at a time: a few passes over the
    /// box, whatever the gap, where marking each voxel's cube costs (2 gap + 1)^d.
    fn add(&mut self, voxels: &[usize]) {
        let Some(&first) = voxels.first() else {
            return;
        };
        let dim = self.dim;
        let side = self.side as i64;
        let gap = self.gap;
        let (mut lo, mut hi) = (self.coords(first), self.coords(first));
        for &v in voxels {
            let c = self.coords(v);
            for a in 0..dim {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        let mut extent = [1usize; 4];
        for a in 0..dim {
            lo[a] = (lo[a] - gap).max(0);
            hi[a] = (hi[a] + gap).min(side - 1);
            extent[a] = (hi[a] - lo[a] + 1) as usize;
        }
        let mut strides = [0usize; 4];
        let mut len = 1;
        for a in (0..dim).rev() {
            strides[a] = len;
            len *= extent[a];
        }
        let at = |c: &[i64; 4]| -> usize {
            (0..dim).map(|a| (c[a] - lo[a]) as usize * strides[a]).sum()
        };
        // 1: marked (a voxel, or marked along an earlier axis); 2: marked along this axis.
        let mut mask = vec![0u8; len];
        for &v in voxels {
            mask[at(&self.coords(v))] = 1;
        }
        for a in 0..dim {
            let (n, stride) = (extent[a], strides[a]);
            for base in 0..len {
                if (base / stride) % n != 0 {
                    continue;
                }
                for backwards in [false, true] {
                    let mut since = i64::MAX / 2;
                    for t in 0..n {
                        let i = base + stride * if backwards { n - 1 - t } else { t };
                        if mask[i] == 1 {
                            since = 0;
                        } else {
                            since += 1;
                            if since <= gap {
                                mask[i] = 2;
                            }
                        }
                    }
                }
            }
            for m in mask.iter_mut() {
                *m = u8::from(*m != 0);
            }
        }
        // Back into the image, one row of the box at a time.
        let row = extent[dim - 1];
        for (r, marks) in mask.chunks_exact(row).enumerate() {
            let mut c = lo;
            let mut rest = r;
            for a in (0..dim - 1).rev() {
                c[a] = lo[a] + (rest % extent[a]) as i64;
                rest /= extent[a];
            }
            let from = (0..dim).fold(0i64, |flat, a| flat * side + c[a]) as usize;
            for (b, &m) in self.blocked[from..from + row].iter_mut().zip(marks) {
                *b |= m != 0;
            }
        }
    }

    fn coords(&self, v: usize) -> [i64; 4] {
        let mut coords = [0i64; 4];
        let mut rest = v as i64;
        for k in (0..self.dim).rev() {
            coords[k] = rest % self.side as i64;
            rest /= self.side as i64;
        }
        coords
    }

    /// [`Occupancy::add`] for one voxel, its cube marked voxel by voxel (what the tests
    /// compare with).
    #[cfg(test)]
    fn add_near_a_face(&mut self, v: usize) {
        let side = self.side as i64;
        let coords = self.coords(v);
        let gap = self.gap;
        for code in 0..(2 * gap + 1).pow(self.dim as u32) {
            let mut index = 0i64;
            let mut inside = true;
            let mut rest = code;
            for &ck in coords.iter().take(self.dim) {
                let offset = rest % (2 * gap + 1) - gap;
                rest /= 2 * gap + 1;
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

/// The sub-box of one cell when the region is cut into `per_axis^dim` cells separated by
/// the gap. Used as the deterministic fallback when random placement keeps failing.
fn grid_cell(region: Region, per_axis: i64, cell: [i64; 4], dim: usize) -> ([i64; 4], [i64; 4]) {
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
fn cell_width(region: Region, per_axis: i64) -> i64 {
    (region.width() + GAP) / per_axis - GAP
}

/// The smallest number of cells per axis that holds `count` cells in `dim` dimensions.
fn cells_per_axis(count: usize, dim: usize) -> i64 {
    let mut m = 1i64;
    while (m as usize).pow(dim as u32) < count {
        m += 1;
    }
    m
}

/// Random placements tried per object in one round.
const PLACEMENT_ATTEMPTS: usize = 40;
/// Rounds of random placement before the grid or canonical fallback.
const RANDOM_ROUNDS: usize = 6;

/// Whether one object per grid cell fits, every object at its minimum size.
pub(crate) fn grid_fits(minima: &[f64], dim: usize, region: Region) -> bool {
    let per_axis = cells_per_axis(minima.len(), dim);
    let width = cell_width(region, per_axis);
    let budget = (width - 1) as f64 / 2.0;
    width > 0 && minima.iter().all(|&m| m <= budget)
}

/// Seeds of the canonical layout search (fixed, so feasibility is a pure function of the
/// request).
const CANONICAL_SEEDS: u64 = 6;

/// A layout found with fixed seeds, every object at its minimum size, largest first.
/// Plan-time feasibility for scenes that the grid cannot hold, and the generation-time
/// fallback for them: a request that passed `check_fits` always produces a sample.
pub(crate) fn canonical_layout(
    objects: &[Family],
    minima: &[f64],
    (dim, side, mode): (usize, usize, Mode),
    region: Region,
    floor: TubeFloor,
) -> Option<Vec<PlacedObject>> {
    use rand::SeedableRng;
    let mut order: Vec<usize> = (0..objects.len()).collect();
    order.sort_by(|&a, &b| minima[b].total_cmp(&minima[a]).then(a.cmp(&b)));
    let sorted_objects: Vec<Family> = order.iter().map(|&k| objects[k].clone()).collect();
    let sorted_minima: Vec<f64> = order.iter().map(|&k| minima[k]).collect();
    (0..CANONICAL_SEEDS).find_map(|seed| {
        let mut rng = ChaCha8Rng::seed_from_u64(0xB377_1000 + seed);
        place_random(
            &sorted_objects,
            &sorted_minima,
            None,
            (dim, side, mode, region, floor),
            &mut rng,
            true,
            GAP,
        )
    })
}

/// Local axes that may rotate: all of them, except the interval axes of a tunnel.
fn free_axes(family: &Family, dim: usize) -> Vec<usize> {
    match family {
        Family::Tunnel { intervals, .. } => (0..dim - *intervals as usize).collect(),
        _ => (0..dim).collect(),
    }
}

type PlacedObject = (Family, Placed, Value, Vec<usize>);

pub(crate) fn place_tunnel(
    family: &Family,
    dim: usize,
    side: usize,
    region: Region,
    floor: TubeFloor,
    rng: &mut ChaCha8Rng,
) -> Result<PlacedObject, ShapeError> {
    let Family::Tunnel { intervals, .. } = family else {
        unreachable!("place_tunnel is only called for tunnels")
    };
    let a = *intervals as usize;
    let budget = region.budget();
    let minimum = min_extent(family, dim, floor).unwrap_or(f64::INFINITY);
    let target = uniform(rng, minimum, budget);
    let (solid, params) = build(family, dim, target, floor, Fit::Ball, rng).ok_or_else(|| {
        ShapeError::DoesNotFit {
            family: family.label(),
            dim,
            side,
            mode: Mode::Carve,
            reason: "no cross-section fits".into(),
        }
    })?;
    // Choose which image axes the tunnel runs along: a random permutation maps local
    // axes (cross-section first, intervals last) to image axes.
    let mut perm: Vec<usize> = (0..dim).collect();
    for k in (1..dim).rev() {
        let j = uniform_int(rng, 0, k as u64) as usize;
        perm.swap(k, j);
    }
    let mut rotation = Rotation::permutation(&perm);
    let cross: Vec<usize> = perm[..dim - a].to_vec();
    rotation.randomise(&cross, rng);
    let through: Vec<usize> = perm[dim - a..].to_vec();
    let extent = solid.extent();
    let mut centre = random_centre(dim, region.lo, region.hi, extent, rng).ok_or_else(|| {
        ShapeError::DoesNotFit {
            family: family.label(),
            dim,
            side,
            mode: Mode::Carve,
            reason: "no cross-section fits".into(),
        }
    })?;
    for &k in &through {
        centre[k] = (side as f64 - 1.0) / 2.0;
    }
    let placed = Placed {
        solid,
        rotation,
        centre,
        through_axes: through.clone(),
    };
    let voxels = rasterise(&placed, dim, side, 0, side as i64 - 1);
    let params = json!({"shape": params, "through_axes": through});
    Ok((family.clone(), placed, params, voxels))
}

/// Objects placed one by one at random sizes, rotations and positions, each rejected
/// while it meets the gap-dilation of those already placed. `at_minimum` draws every
/// object at its minimum size (the canonical layout). `volumes` sizes each object for a
/// voxel count, with the flag `draw_scale` of `build_volume`. Objects keep `gap` background
/// voxels between them. `None` if some object found no place within `PLACEMENT_ATTEMPTS`
/// tries.
#[allow(clippy::too_many_arguments)] // One search: what, how large, where, how far apart.
fn place_random(
    objects: &[Family],
    minima: &[f64],
    volumes: Option<(&[f64], bool)>,
    (dim, side, _mode, region, floor): (usize, usize, Mode, Region, TubeFloor),
    rng: &mut ChaCha8Rng,
    at_minimum: bool,
    gap: i64,
) -> Option<Vec<PlacedObject>> {
    let count = objects.len();
    let budget = region.budget();
    // Each object may use a share of the room that shrinks with the number of objects,
    // so several of them are likely to fit.
    let share = if count == 1 {
        budget
    } else if volumes.is_some() {
        // Sized for a volume: each object takes a fair part of the room, so the last one
        // is not left a corner (it would come out at its minimum, far below its volume).
        budget / count as f64
    } else {
        (budget / libm::pow(count as f64, 1.0 / dim as f64) * 1.2).min(budget)
    };
    let mut occupancy = Occupancy::new(dim, side, gap);
    let mut out = Vec::new();
    for (n, (object, &minimum)) in objects.iter().zip(minima).enumerate() {
        if minimum > budget {
            return None;
        }
        let mut done = false;
        for attempt in 0..PLACEMENT_ATTEMPTS {
            // Later attempts draw smaller objects, which fit into smaller gaps.
            let shrink = 1.0 - attempt as f64 / PLACEMENT_ATTEMPTS as f64;
            let upper = minimum + (share.max(minimum) - minimum) * shrink;
            // The rotation comes first, so that the object is sized for the room its
            // rotated shape needs along each axis; a tentacled object is sized within a
            // ball, into which its tentacles grow.
            let rotation = Rotation::random(&free_axes(object, dim), rng);
            let fit = match object {
                Family::Tentacled { .. } => Fit::Ball,
                _ => Fit::Axes(&rotation, dim),
            };
            let built = match volumes {
                // Sized for a voxel count: the scale is solved for, within the room.
                // A cavity in a boxed solid may come out below its volume (the box around
                // it takes up the rest), so where the room limits it its scale is drawn;
                // an embedded object, or a cavity of the full cube, is what brings the
                // count to its bin and takes the largest that fits.
                Some((volumes, draw_scale)) if !at_minimum => {
                    build_volume(object, dim, upper, volumes[n], floor, draw_scale, fit, rng)
                }
                _ => {
                    let target = if at_minimum {
                        minimum
                    } else {
                        draw_target(object, minimum, upper, floor, rng)
                    };
                    build(object, dim, target, floor, fit, rng)
                }
            };
            let Some((solid, params)) = built else {
                continue;
            };
            let widths = fit.half_widths(&solid, dim);
            let Some(centre) = centre_within(dim, region.lo, region.hi, &widths, rng) else {
                continue;
            };
            let placed = Placed::bounded(solid, rotation, centre);
            let Some(voxels) = rasterise_unless_blocked(
                &placed,
                dim,
                side,
                region.lo,
                region.hi,
                Some(&occupancy),
            ) else {
                continue;
            };
            if voxels.is_empty() {
                continue;
            }
            // Only objects still to come need the room this one keeps free.
            if n + 1 < count {
                occupancy.add(&voxels);
            }
            out.push((object.clone(), placed, params, voxels));
            done = true;
            break;
        }
        if !done {
            return None;
        }
    }
    Some(out)
}

/// The image being filled.
#[derive(Clone, Copy)]
pub(crate) struct PlacementArea {
    pub(crate) dim: usize,
    pub(crate) side: usize,
    pub(crate) mode: Mode,
    pub(crate) region: Region,
    /// The voxel count all objects together should have, when sized for a hypervolume
    /// (shared among several objects at random); `None` draws sizes as usual.
    pub(crate) volume: Option<f64>,
    /// The thinnest tube any object may have.
    pub(crate) floor: TubeFloor,
    /// Whether an object the room keeps below its volume draws its scale (a cavity of a
    /// boxed solid, which the box makes up for) instead of taking the largest that fits.
    pub(crate) draw_scale: bool,
}

/// Places `objects` in `canvas`: the objects, how the layout was found, and the gap kept
/// between them (background voxels).
pub(crate) fn place_objects(
    family: &Family,
    objects: &[Family],
    canvas: PlacementArea,
    rng: &mut ChaCha8Rng,
) -> Result<(Vec<PlacedObject>, &'static str, i64), ShapeError> {
    let PlacementArea {
        dim,
        side,
        mode,
        region,
        volume,
        floor,
        draw_scale,
    } = canvas;
    let count = objects.len();
    let minima: Vec<f64> = objects
        .iter()
        .map(|o| min_extent(o, dim, floor).unwrap_or(f64::INFINITY))
        .collect();
    // Largest first: big objects find room in the empty image, small ones fit into the
    // gaps left. Several rounds, the later ones at minimum sizes, before the fallbacks,
    // so that fallbacks (which are less diverse) stay rare.
    let mut order: Vec<usize> = (0..count).collect();
    order.sort_by(|&a, &b| minima[b].total_cmp(&minima[a]).then(a.cmp(&b)));
    let sorted_objects: Vec<Family> = order.iter().map(|&k| objects[k].clone()).collect();
    let sorted_minima: Vec<f64> = order.iter().map(|&k| minima[k]).collect();
    // Each object's part of the volume: random shares, drawn once for every round,
    // log-uniform so that one object may be up to SHARE_RATIO times another's size.
    let volumes: Option<Vec<f64>> = volume.map(|total| {
        let low = -libm::log(SHARE_RATIO);
        let raw: Vec<f64> = (0..count)
            .map(|_| libm::exp(uniform(rng, low, 0.0)))
            .collect();
        let sum: f64 = raw.iter().sum();
        raw.iter().map(|x| total * x / sum).collect()
    });
    // The gap between objects, drawn per sample; the rounds at minimum sizes keep the
    // narrowest, and the fallbacks keep `GAP`, which the plan's feasibility check assumed.
    let narrowest = narrowest_gap(floor.gap());
    let drawn_gap = if count > 1 {
        uniform_int(
            rng,
            narrowest as u64,
            widest_gap(side).max(narrowest) as u64,
        ) as i64
    } else {
        GAP
    };
    // A split ball's pieces stand the narrowest gap apart (`recipes::split_ball`), and
    // growth keeps that gap between every two parts, not a scene's wider one.
    let split = objects.iter().any(|o| matches!(o, Family::Split { .. }));
    for round in 0..RANDOM_ROUNDS {
        let at_minimum = round >= RANDOM_ROUNDS / 2;
        let gap = if at_minimum { narrowest } else { drawn_gap };
        let kept = if split { narrowest } else { gap };
        if let Some(out) = place_random(
            &sorted_objects,
            &sorted_minima,
            volumes.as_deref().map(|v| (v, draw_scale)),
            (dim, side, mode, region, floor),
            rng,
            at_minimum,
            gap,
        ) {
            return Ok((out, "random", kept));
        }
    }
    let fits_grid = grid_fits(&minima, dim, region);
    if !fits_grid {
        return canonical_layout(objects, &minima, (dim, side, mode), region, floor)
            .map(|out| (out, "canonical", GAP))
            .ok_or_else(|| ShapeError::DoesNotFit {
                family: family.label(),
                dim,
                side,
                mode,
                reason: "the objects could not be packed with the required gaps".into(),
            });
    }
    // Fallback: one object per grid cell, cells separated by the gap. check_fits
    // guarantees every object's minimum fits a cell, so this always succeeds.
    let per_axis = cells_per_axis(count, dim);
    let width = cell_width(region, per_axis);
    let cell_budget = (width - 1) as f64 / 2.0;
    let total_cells = (per_axis as usize).pow(dim as u32);
    let mut cells: Vec<usize> = (0..total_cells).collect();
    for k in (1..total_cells).rev() {
        let j = uniform_int(rng, 0, k as u64) as usize;
        cells.swap(k, j);
    }
    let mut out = Vec::new();
    for (n, (object, &minimum)) in objects.iter().zip(&minima).enumerate() {
        let mut cell = [0i64; 4];
        let mut rest = cells[n] as i64;
        for slot in cell.iter_mut().take(dim) {
            *slot = rest % per_axis;
            rest /= per_axis;
        }
        let (lo, hi) = grid_cell(region, per_axis, cell, dim);
        let target = draw_target(object, minimum, cell_budget.max(minimum), floor, rng);
        let (solid, params) = build(object, dim, target, floor, Fit::Ball, rng)
            .or_else(|| build(object, dim, minimum, floor, Fit::Ball, rng))
            .ok_or_else(|| ShapeError::DoesNotFit {
                family: family.label(),
                dim,
                side,
                mode,
                reason: format!("{} has no instance of radius {target:.2}", object.label()),
            })?;
        let rotation = Rotation::random(&free_axes(object, dim), rng);
        let extent = solid.extent();
        let mut centre = [0.0; 4];
        for k in 0..dim {
            let low = lo[k] as f64 + extent;
            let high = hi[k] as f64 - extent;
            centre[k] = uniform(rng, low, high.max(low));
        }
        let placed = Placed::bounded(solid, rotation, centre);
        // The centre keeps the bounding ball inside the cell; clipping to the region
        // only guards the image border.
        let voxels = rasterise(&placed, dim, side, region.lo, region.hi);
        out.push((object.clone(), placed, params, voxels));
    }
    Ok((out, "grid", GAP))
}

#[cfg(test)]
mod tests;
