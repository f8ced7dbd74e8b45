//! Sizing: the smallest instance of a family, and drawing a random instance that fits.
//!
//! The smallest bounding radius of a family is its recipe at the minimum tube radius and
//! no growth ([`min_extent`]); plan-time feasibility compares it with the room an image
//! offers. Drawing an instance picks a target bounding radius between that minimum and the
//! room available, then finds the tube radius and the growth by bisection ([`build`]), so
//! size is random but never needs an open-ended retry. Tentacles are added to their host
//! here, in the room the host leaves.

use crate::curves;
use crate::geometry::{round6, uniform, Piece, Solid, TubeFloor, TUBE_MIN};
use crate::recipes::{make, share_count, tube_range, Shares};
use crate::rotation::Rotation;
use crate::Family;
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

/// How an instance's size is measured against the room it is given.
#[derive(Clone, Copy)]
pub(crate) enum Fit<'a> {
    /// The radius of its bounding ball: it fits a box of that half-width whatever its
    /// rotation (plan-time feasibility, tentacles, which grow into a ball around their
    /// host).
    Ball,
    /// Its largest half-width along the image's axes once rotated: a ring in a slanted
    /// plane is narrower along every axis than its radius, so it may be larger than a
    /// ball of the room would allow.
    Axes(&'a Rotation, usize),
}

impl Fit<'_> {
    /// The room `solid` needs about its centre along each of the first `dim` image axes.
    pub(crate) fn half_widths(&self, solid: &Solid, dim: usize) -> Vec<f64> {
        let extent = solid.extent();
        match *self {
            Fit::Ball => vec![extent; dim],
            Fit::Axes(rotation, _) => (0..dim)
                .map(|k| solid.half_width(rotation.axis_in_local(k)).min(extent))
                .collect(),
        }
    }

    /// The largest of its half-widths: what sizing compares with the room.
    pub(crate) fn reach(&self, solid: &Solid) -> f64 {
        match *self {
            Fit::Ball => solid.extent(),
            Fit::Axes(_, dim) => self.half_widths(solid, dim).into_iter().fold(0.0, f64::max),
        }
    }
}

/// Room a tentacle needs beyond its host's extent: the gap and two steps past the host's
/// tube (`curves::add_tentacles`) plus its own radius, each tentacle radius at most
/// TUBE_MIN + 0.5.
fn tentacle_room(floor: TubeFloor) -> f64 {
    2.0 * (TUBE_MIN + 0.5) + floor.gap() + 0.5 + 2.5
}

/// The smallest bounding radius of one object of the family with tubes at least `floor`
/// (tentacles need none extra: they are added only where space remains; see
/// [`draw_target`]).
pub(crate) fn min_extent(family: &Family, dim: usize, floor: TubeFloor) -> Option<f64> {
    let family = match family {
        Family::Tentacled { object, .. } => object,
        other => other,
    };
    let (tube, _) = tube_range(family, floor);
    let shares = Shares::minimal(share_count(family));
    make(family, dim, tube, 0.0, &shares, floor.gap()).map(|s| s.extent())
}

/// A random bounding radius for `object` between `minimum` and `upper`. A tentacled
/// object draws from `minimum + tentacle_room(floor)` up when there is that much room, so that its
/// host leaves space for tentacles (draws near the minimum would place none in most
/// samples); where there is not, it keeps the plain range and places what fits.
pub(crate) fn draw_target(
    object: &Family,
    minimum: f64,
    upper: f64,
    floor: TubeFloor,
    rng: &mut ChaCha8Rng,
) -> f64 {
    let room = tentacle_room(floor);
    let lo = match object {
        Family::Tentacled { .. } if minimum + room <= upper => minimum + room,
        _ => minimum,
    };
    uniform(rng, lo, upper)
}

/// A random instance with bounding radius at most `target` (which must be at least the
/// minimum at `floor`) and tubes at least `floor`. Returns the solid and its parameters.
pub(crate) fn build(
    family: &Family,
    dim: usize,
    target: f64,
    floor: TubeFloor,
    fit: Fit,
    rng: &mut ChaCha8Rng,
) -> Option<(Solid, Value)> {
    if let Family::Tentacled { object, tentacles } = family {
        // The host takes a random part of the room; tentacles reach into the rest. A
        // tentacle must leave the host by a gap and a few steps before it counts, so the
        // host leaves that much room when the target allows it (see `draw_target`).
        let minimum = min_extent(object, dim, floor)?;
        let host_cap = (0.75 * target).min(target - tentacle_room(floor));
        let host_target = uniform(rng, minimum, minimum.max(host_cap));
        let (solid, params) = build(object, dim, host_target, floor, Fit::Ball, rng)?;
        let (solid, placed) =
            curves::add_tentacles(solid, dim, *tentacles, target, floor.gap(), rng);
        return Some((
            solid,
            json!({"host": params, "tentacles_requested": tentacles, "tentacles_placed": placed}),
        ));
    }
    let (tube_min, tube_cap) = tube_range(family, floor);
    let shares = Shares::draw(share_count(family), rng);
    let extent = |tube: f64, grow: f64| -> Option<f64> {
        make(family, dim, tube, grow, &shares, floor.gap()).map(|s| fit.reach(&s))
    };
    let base = extent(tube_min, 0.0)?;
    if base > target + 1e-9 {
        return None;
    }
    // Largest tube radius that still fits with no growth.
    let mut lo = tube_min;
    let mut hi = tube_cap;
    if extent(hi, 0.0).is_some_and(|e| e <= target) {
        lo = hi;
    } else {
        for _ in 0..40 {
            let mid = (lo + hi) / 2.0;
            match extent(mid, 0.0) {
                Some(e) if e <= target => lo = mid,
                _ => hi = mid,
            }
        }
    }
    let tube = uniform(rng, tube_min, lo);
    // Largest growth that fits at that radius.
    let mut lo = 0.0;
    let mut hi = target.max(1.0) * 2.0;
    for _ in 0..50 {
        let mid = (lo + hi) / 2.0;
        match extent(tube, mid) {
            Some(e) if e <= target => lo = mid,
            _ => hi = mid,
        }
    }
    let solid = make(family, dim, tube, lo, &shares, floor.gap())?;
    let params = json!({
        "tube_radius": round6(tube),
        "grow": round6(lo),
        "shares": shares.0.iter().map(|&x| round6(x)).collect::<Vec<_>>(),
    });
    Some((solid, params))
}

/// Growth every instance sized for a volume keeps at least (shared out among its holes,
/// bars and offsets by the recipe), so a thick tube never closes a hole to its minimum:
/// holes that stay a few voxels wide survive downscaling.
pub(crate) const VOLUME_GROW_MIN: f64 = 12.0;

/// The range the tube thickness of an object with a hole is drawn from, as a share of the
/// thickest that fits, where the object brings the count to its bin: thin, so that its
/// volume goes into the size of its hole (and, where the family allows, into a tube
/// widened away from the hole, [`Piece::flattened`]) rather than into a thick tube around
/// a hole that one dilation closes.
const THIN_THICKNESS: (f64, f64) = (0.0, 0.35);

/// Growth of its hole ([`hole_share`] of the growth) a widened instance keeps at least,
/// the most first: its hole stays about `INNER_GAP / 2` plus this in radius (3.75 voxels
/// where the room allows; 2.0 is still wider than the thickened tube's 1.25).
const HOLE_KEEPS: [f64; 3] = [2.5, 1.5, 0.75];

/// The least tube radius of a small instance sized for a volume ([`thins`]): two voxels
/// across, which no path of face neighbours crosses (it changes the distance to the
/// skeleton by at most one voxel a step).
const THIN_TUBE: f64 = 1.0;

/// Bisection steps for the thickest thin tube whose smallest instance fits a volume.
const THIN_STEPS: usize = 8;

/// Whether a small instance of `family` may draw a tube thinner than the family's minimum,
/// down to [`THIN_TUBE`]: a 4D 2-sphere times a disk, whose tube is widened back to the
/// minimum along the fourth axis ([`flattens`]), or a shell, whose wall closes its cavity
/// at two voxels across: for these the thin tube or wall is what keeps most small holes
/// wider than one dilation closes. Loops and handles keep the minimum: a thinner tube
/// widens few of their holes, and it would make them the only tubes thinner than an open
/// curve's (the ball class's), a width that tells the class instead of the hole.
fn thins(family: &Family, dim: usize) -> bool {
    match family {
        Family::S2xB2 | Family::BumpyS2xB2 => flattens(family, dim).is_some(),
        Family::Shell | Family::BumpyShell => true,
        _ => false,
    }
}

/// The most a tube is widened away from its hole.
const STRETCH_MAX: f64 = 6.0;

/// The share of its volume a widened instance reaches at least; short of it the tube
/// thickens instead.
const FLAT_REACHED: f64 = 0.75;

/// Whether `family` has a hole its tube's thickness narrows: not a ball (a fixed tube)
/// nor an open curve.
fn with_hole(family: &Family, floor: TubeFloor) -> bool {
    let (tube_min, tube_cap) = tube_range(family, floor);
    tube_cap > tube_min && !matches!(family, Family::Curve)
}

/// The first axis along which `family`'s tube can widen away from its hole in dimension
/// `dim`, if any: the third for a handle (whose circle lies in the plane of the first
/// two), the fourth for a 2-sphere times a disk, round or bumpy. A loop keeps a round tube
/// and puts its volume into its ring and tube: its class then holds both cross-sections,
/// the handle's slab and the loop's round tube, rather than one shape a network could
/// learn for the class.
fn flattens(family: &Family, dim: usize) -> Option<usize> {
    match family {
        Family::Handle if dim >= 3 => Some(2),
        Family::S2xB2 | Family::BumpyS2xB2 if dim == 4 => Some(3),
        _ => None,
    }
}

/// The share of its growth that widens a widened `family`'s hole: a bumpy 2-sphere puts
/// half into its radius and the rest into bumps that bulge outwards
/// (`recipes::bumpy_sphere`).
fn hole_share(family: &Family) -> f64 {
    match family {
        Family::BumpyS2xB2 => 0.5,
        _ => 1.0,
    }
}

/// The range the scale of an instance sized for a volume is drawn from when the room, not
/// the volume, limits it.
const ROOM_SCALE: (f64, f64) = (0.3, 1.0);

/// Bisection steps on the scale of an instance sized for a volume.
const VOLUME_STEPS: usize = 12;

/// The lattice points a volume estimate tests at most (the spacing grows with the object).
const VOLUME_POINTS: f64 = 120_000.0;

/// Estimated voxel count of a local solid: lattice points of spacing `h` (chosen so that
/// at most about [`VOLUME_POINTS`] are tested) in its bounding box, times `h^dim`. Cheap
/// enough to bisect on, and within a fraction of a percent of the rasterised count for
/// objects large enough to need a coarse lattice.
pub(crate) fn estimate_volume(solid: &Solid, dim: usize) -> f64 {
    let extent = solid.extent();
    let width = 2.0 * extent + 1.0;
    let h = libm::ceil(width / libm::pow(VOLUME_POINTS, 1.0 / dim as f64)).max(1.0);
    let n = libm::ceil(width / h) as i64;
    let start = -extent + h / 2.0;
    let mut count = 0u64;
    let mut c = [0i64; 4];
    loop {
        let mut p = [0.0; 4];
        for k in 0..dim {
            p[k] = start + c[k] as f64 * h;
        }
        if solid.contains(p) {
            count += 1;
        }
        let mut k = dim;
        loop {
            if k == 0 {
                return count as f64 * libm::pow(h, dim as f64);
            }
            k -= 1;
            if c[k] + 1 < n {
                c[k] += 1;
                break;
            }
            c[k] = 0;
        }
    }
}

/// A random instance whose estimated voxel count is as close to `volume` as the room
/// allows, with bounding radius at most `upper`: the sizes come from one scale
/// parameter found by bisection on [`estimate_volume`]. How thick the tube is relative to
/// what fits, and how the growth is shared, are drawn from `rng`, so instances of one
/// volume still differ in shape. Where even the largest instance stays below `volume`,
/// `draw_scale` draws the scale from [`ROOM_SCALE`] (a carved cavity, whose box takes up
/// the rest); otherwise the largest instance is taken (an embedded object or a full
/// cube's cavity, which brings the count to its bin), its tube widened away from its hole
/// where the family allows and the hole stays open ([`flattens`], [`HOLE_KEEPS`]), else
/// thickened towards the volume. Such an instance with a hole draws a thin tube
/// ([`THIN_THICKNESS`]); where the volume, not the room, limits it, a family that
/// [`thins`] draws its tube below the family's minimum. `None` where [`build`] would give
/// none. Tentacled objects are drawn as [`build`] draws them where `draw_scale` or their
/// host has no hole; otherwise their host is sized for the volume.
#[allow(clippy::too_many_arguments)] // One sizing: what, in which room, how large, how measured.
pub(crate) fn build_volume(
    family: &Family,
    dim: usize,
    upper: f64,
    volume: f64,
    floor: TubeFloor,
    draw_scale: bool,
    fit: Fit,
    rng: &mut ChaCha8Rng,
) -> Option<(Solid, Value)> {
    sized_for_volume(
        family, dim, upper, volume, floor, draw_scale, true, fit, rng,
    )
}

/// [`build_volume`], with tubes widened away from their holes only when `widen`: a
/// tentacle's path is checked against its host's round tubes (`curves::add_tentacles`),
/// so a host stays round.
#[allow(clippy::too_many_arguments)]
fn sized_for_volume(
    family: &Family,
    dim: usize,
    upper: f64,
    volume: f64,
    floor: TubeFloor,
    draw_scale: bool,
    widen: bool,
    fit: Fit,
    rng: &mut ChaCha8Rng,
) -> Option<(Solid, Value)> {
    if let Family::Tentacled { object, tentacles } = family {
        let minimum = min_extent(family, dim, floor)?;
        let target = draw_target(family, minimum, upper.max(minimum), floor, rng);
        // A host without a hole is drawn as `build` draws it, and targeting's noise-led
        // growth makes a lumpy body of it.
        if draw_scale || !with_hole(object, floor) {
            return build(family, dim, target, floor, Fit::Ball, rng);
        }
        // A host with a hole, in the part of the room `build` gives it, carries the
        // volume; its tentacles add a little, which targeting takes off again. Where the
        // room holds no tentacle, the host takes all of it (rather than its minimum, whose
        // hole targeting's growth would fill) and is sized as the object alone.
        let host_minimum = min_extent(object, dim, floor)?;
        let (solid, params, placed) = if target - tentacle_room(floor) >= host_minimum {
            let cap = (0.75 * target).min(target - tentacle_room(floor));
            let host_upper = uniform(rng, host_minimum, host_minimum.max(cap));
            let (solid, params) = sized_for_volume(
                object,
                dim,
                host_upper,
                volume,
                floor,
                false,
                false,
                Fit::Ball,
                rng,
            )?;
            let (solid, placed) =
                curves::add_tentacles(solid, dim, *tentacles, target, floor.gap(), rng);
            (solid, params, placed)
        } else {
            let room = upper.max(host_minimum);
            let (solid, params) = sized_for_volume(
                object,
                dim,
                room,
                volume,
                floor,
                false,
                widen,
                Fit::Ball,
                rng,
            )?;
            (solid, params, 0)
        };
        return Some((
            solid,
            json!({"host": params, "tentacles_requested": tentacles, "tentacles_placed": placed}),
        ));
    }
    let (tube_min, tube_cap) = tube_range(family, floor);
    // A family with a fixed tube (a ball) grows by `grow`; the others may thicken up to
    // what fits, keeping `VOLUME_GROW_MIN` of growth.
    let fixed_tube = tube_cap <= tube_min;
    // Where the instance is the foreground itself (or a full cube's cavity), a family
    // with a hole draws a thin tube, so that its volume goes into the size of the hole,
    // and one that can widens its tube away from the hole before thickening it.
    let thin = !draw_scale && with_hole(family, floor);
    let flat_from = if draw_scale || !widen {
        None
    } else {
        flattens(family, dim)
    };
    let shares = Shares::draw(share_count(family), rng);
    let drawn_thickness = if thin {
        uniform(rng, THIN_THICKNESS.0, THIN_THICKNESS.1)
    } else {
        uniform(rng, 0.15, 0.85)
    };
    let made = |tube: f64, grow: f64, stretch: f64| -> Option<Solid> {
        let solid = make(family, dim, tube, grow, &shares, floor.gap())?;
        if stretch <= 1.0 {
            return Some(solid);
        }
        let (Solid::Tube(parts), Some(from)) = (solid, flat_from) else {
            return None;
        };
        parts
            .into_iter()
            .map(|(piece, r)| Piece::flattened(piece, stretch, from).map(|p| (p, r)))
            .collect::<Option<Vec<_>>>()
            .map(Solid::Tube)
    };
    let extent = |tube: f64, grow: f64, stretch: f64| -> Option<f64> {
        made(tube, grow, stretch).map(|s| fit.reach(&s))
    };
    let base = extent(tube_min, 0.0, 1.0)?;
    if base > upper + 1e-9 {
        return None;
    }
    let grow_floor = if fixed_tube { 0.0 } else { VOLUME_GROW_MIN };
    // The instance at scale s in [0, 1]: bounding radius from the minimum to `upper`,
    // its tube widened by `stretch` away from its plane.
    // The tube radius goes from `least` (the family's minimum, or a thin widened tube's
    // radius) by `thickness` towards the thickest that fits.
    let sized =
        |target: f64, least: f64, thickness: f64, stretch: f64| -> Option<(Solid, f64, f64)> {
            let floor = if extent(least, grow_floor, 1.0).is_some_and(|e| e <= target) {
                grow_floor
            } else {
                0.0
            };
            let tube = if fixed_tube {
                tube_min
            } else if thickness == 0.0 {
                least
            } else {
                // Largest tube radius that fits with the floor of growth.
                let (mut lo, mut hi) = (least, target.max(least));
                for _ in 0..30 {
                    let mid = (lo + hi) / 2.0;
                    match extent(mid, floor, 1.0) {
                        Some(e) if e <= target => lo = mid,
                        _ => hi = mid,
                    }
                }
                least + thickness * (lo - least)
            };
            if stretch > 1.0 && !extent(tube, 0.0, stretch).is_some_and(|e| e <= target) {
                return None;
            }
            let (mut lo, mut hi) = (0.0, target.max(1.0) * 2.0);
            for _ in 0..40 {
                let mid = (lo + hi) / 2.0;
                match extent(tube, mid, stretch) {
                    Some(e) if e <= target => lo = mid,
                    _ => hi = mid,
                }
            }
            made(tube, lo, stretch).map(|solid| (solid, tube, lo))
        };
    let at_scale = |s: f64, lowest: f64| lowest + s * (upper - lowest);
    let instance = |s: f64, thickness: f64, stretch: f64| {
        sized(at_scale(s, base), tube_min, thickness, stretch)
    };
    let volume_at = |s: f64, thickness: f64, stretch: f64| {
        instance(s, thickness, stretch).map(|(solid, _, _)| estimate_volume(&solid, dim))
    };
    // The scale first, at the drawn thickness. Where even the largest instance the room
    // allows stays below the volume (the room, not the volume, decides the size: most
    // non-ball cavities of a binned carve sample), a cavity's scale is drawn from
    // [`ROOM_SCALE`] and its thickness stays as drawn: taking the largest instance, as
    // 0.2.0 did, gave every sample of a stratum the same size (scale 1 and, for tubes,
    // thickness 1), and the solid box around the cavities takes up the difference anyway.
    let bisect = |f: &dyn Fn(f64) -> Option<f64>, lo: f64, hi: f64| -> f64 {
        let (mut lo, mut hi) = (lo, hi);
        for _ in 0..VOLUME_STEPS {
            let mid = (lo + hi) / 2.0;
            match f(mid) {
                Some(v) if v <= volume => lo = mid,
                _ => hi = mid,
            }
        }
        lo
    };
    // An embedded object that the room leaves short of its volume widens its tube away
    // from its hole first, keeping the widest hole of `HOLE_KEEPS` with which it comes
    // close to the volume; thickening the tube, which narrows the hole to its least, is
    // the last resort.
    let widened = |thickness: f64| -> Option<f64> {
        HOLE_KEEPS.iter().find_map(|&keep| {
            let keeps = |stretch: f64| {
                instance(1.0, thickness, stretch)
                    .filter(|&(_, _, grow)| hole_share(family) * grow >= keep)
                    .map(|(solid, _, _)| estimate_volume(&solid, dim))
            };
            keeps(1.0)?;
            let stretch = bisect(&keeps, 1.0, STRETCH_MAX);
            // Close enough to the volume that targeting's growth adds little.
            let reached = keeps(stretch)? >= FLAT_REACHED * volume;
            (stretch > 1.0 && reached).then_some(stretch)
        })
    };
    let (s, lowest, least, thickness, stretch) =
        if volume_at(1.0, drawn_thickness, 1.0).is_some_and(|v| v <= volume) {
            let thicker = |t: f64| volume_at(1.0, t, 1.0);
            let (s, thickness, stretch) = if draw_scale {
                (
                    uniform(rng, ROOM_SCALE.0, ROOM_SCALE.1),
                    drawn_thickness,
                    1.0,
                )
            } else if let Some(stretch) = flat_from.and_then(|_| widened(drawn_thickness)) {
                (1.0, drawn_thickness, stretch)
            } else if fixed_tube || thicker(1.0).is_some_and(|v| v <= volume) {
                (1.0, if fixed_tube { drawn_thickness } else { 1.0 }, 1.0)
            } else {
                (1.0, bisect(&thicker, drawn_thickness, 1.0), 1.0)
            };
            (s, base, tube_min, thickness, stretch)
        } else if thin && widen && !floor.thickens() && thins(family, dim) {
            // The volume, not the room, limits a small instance, whose tube at the
            // family's minimum would take up most of its size and leave a narrow hole: its
            // tube is drawn thinner, down to THIN_TUBE (and widened back to the minimum
            // along the flat axes, where it has them), so the volume goes into the size of
            // the hole. A thin instance's scale runs from its own smallest instance,
            // smaller than the minimum's.
            let thin_at = |least: f64, s: f64| {
                let stretch = if flat_from.is_some() {
                    tube_min / least
                } else {
                    1.0
                };
                let lowest = extent(least, 0.0, stretch).unwrap_or(base).min(base);
                let made = sized(at_scale(s, lowest), least, 0.0, stretch)?;
                Some((estimate_volume(&made.0, dim), lowest, stretch))
            };
            let fits = |least: f64| thin_at(least, 0.0).is_some_and(|(v, _, _)| v <= volume);
            // The radius is drawn up to the thickest whose smallest instance fits the
            // volume (a thinner tube leaves a wider hole).
            let mut chosen = None;
            if fits(THIN_TUBE) {
                let (mut thickest, mut above) = (THIN_TUBE, tube_min);
                for _ in 0..THIN_STEPS {
                    let mid = (thickest + above) / 2.0;
                    if fits(mid) {
                        thickest = mid;
                    } else {
                        above = mid;
                    }
                }
                let least = uniform(rng, THIN_TUBE, thickest);
                let thin_volume = |s: f64| thin_at(least, s).map(|(v, _, _)| v);
                let s = bisect(&thin_volume, 0.0, 1.0);
                // Close to the volume without passing it: targeting's growth adds little.
                if let Some((v, lowest, stretch)) = thin_at(least, s) {
                    if (FLAT_REACHED * volume..=volume).contains(&v) {
                        chosen = Some((s, lowest, least, 0.0, stretch));
                    }
                }
            }
            // Where no thin instance fits (even the thinnest's smallest instance is larger
            // than the volume, and its wider hole would keep shrinking from reaching counts
            // the minimum reaches), the tube stays at the minimum.
            chosen.unwrap_or_else(|| {
                let s = bisect(&|s| volume_at(s, drawn_thickness, 1.0), 0.0, 1.0);
                (s, base, tube_min, drawn_thickness, 1.0)
            })
        } else {
            (
                bisect(&|s| volume_at(s, drawn_thickness, 1.0), 0.0, 1.0),
                base,
                tube_min,
                drawn_thickness,
                1.0,
            )
        };
    let (solid, tube, grow) = sized(at_scale(s, lowest), least, thickness, stretch)?;
    let mut params = json!({
        "tube_radius": round6(tube),
        "grow": round6(grow),
        "shares": shares.0.iter().map(|&x| round6(x)).collect::<Vec<_>>(),
        "scale": round6(s),
        "thickness": round6(thickness),
        "volume_target": libm::round(volume),
    });
    if stretch > 1.0 {
        params["stretch"] = json!(round6(stretch));
    }
    Some((solid, params))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::INNER_GAP;
    use rand::SeedableRng;

    /// A 4D instance of `family` sized for `volume` within a ball of radius 11 (the room of
    /// a side-24 image), widened or kept round, from `seed`.
    fn sized_in_room_11(family: &Family, seed: u64, volume: f64, widen: bool) -> (Solid, Value) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let floor = TubeFloor::USUAL;
        sized_for_volume(
            family,
            4,
            11.0,
            volume,
            floor,
            false,
            widen,
            Fit::Ball,
            &mut rng,
        )
        .unwrap()
    }

    /// An embedded 4D handle of 2-9% of a side-24 image: widened away from its hole it
    /// reaches the volume and keeps the hole open, where a round tube of that volume (what
    /// a tentacle's host still is) closes the hole towards its minimum.
    #[test]
    fn embedded_handles_widen_their_tube_instead_of_closing_their_hole() {
        // The volumes, and the narrowest kept hole each reaches with (the largest needs
        // the room's whole width).
        for (volume, keep) in [(8_000.0, 0), (15_000.0, 0), (24_000.0, 0), (30_000.0, 2)] {
            // The same draws, widened (as `build_volume` sizes it) or kept round.
            let sized = |widen| sized_in_room_11(&Family::Handle, 1, volume, widen);
            let (solid, params) = sized(true);
            assert!(solid.extent() <= 11.0 + 1e-9);
            assert!(params["stretch"].as_f64().unwrap() > 1.0, "{params}");
            let wide = params["grow"].as_f64().unwrap();
            assert!(wide >= HOLE_KEEPS[keep], "{params}");
            let reached = estimate_volume(&solid, 4);
            assert!(reached >= FLAT_REACHED * volume, "{params}");

            let (round, params) = sized(false);
            assert!(params.get("stretch").is_none());
            let narrow = params["grow"].as_f64().unwrap();
            assert!(narrow < wide, "{params}");
            assert!(narrow < HOLE_KEEPS[0] || volume < 10_000.0, "{params}");
            assert!(round.extent() <= 11.0 + 1e-9);
        }
    }

    /// An embedded bumpy 2-sphere of 4-9% of a side-24 image widens its tube along the
    /// fourth axis and keeps its hole, where kept round it thickens its tube around a small
    /// sphere whose hole one dilation closes.
    #[test]
    fn embedded_bumpy_spheres_widen_their_tube_instead_of_closing_their_hole() {
        for (seed, volume) in [(1, 15_000.0), (2, 24_000.0), (3, 28_000.0)] {
            let sized = |widen| sized_in_room_11(&Family::BumpyS2xB2, seed, volume, widen);
            let (solid, params) = sized(true);
            assert!(solid.extent() <= 11.0 + 1e-9);
            assert!(params["stretch"].as_f64().unwrap() > 1.0, "{params}");
            let hole = 0.5 * params["grow"].as_f64().unwrap();
            assert!(hole >= HOLE_KEEPS[1], "{params}");
            assert!(
                estimate_volume(&solid, 4) >= FLAT_REACHED * volume,
                "{params}"
            );

            let (_, params) = sized(false);
            let narrow = 0.5 * params["grow"].as_f64().unwrap();
            assert!(narrow < hole, "{params}");
        }
    }

    /// Small embedded 2-spheres and shells (0.3-1% of a side-24 image, volumes the room
    /// exceeds) draw tubes thinner than their minimum, widened back along the fourth axis
    /// where they have it, and their holes come out wider than at the minimum tube; with
    /// the thicker floor that downscaled copies ask for, they do not. Loops and handles of
    /// those volumes keep the minimum.
    #[test]
    fn small_instances_thin_their_tube_to_widen_their_hole() {
        for dim in 2..=4 {
            assert!(!thins(&Family::Handle, dim) && !thins(&Family::Loop, dim));
            assert!(thins(&Family::Shell, dim) && thins(&Family::BumpyShell, dim));
            assert_eq!(thins(&Family::S2xB2, dim), dim == 4);
        }
        for family in [Family::Handle, Family::Loop] {
            let (least, _) = tube_range(&family, TubeFloor::USUAL);
            for seed in 0..8 {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let (_, params) = build_volume(
                    &family,
                    4,
                    11.0,
                    1_000.0,
                    TubeFloor::USUAL,
                    false,
                    Fit::Ball,
                    &mut rng,
                )
                .unwrap();
                let tube = params["tube_radius"].as_f64().unwrap();
                assert!(tube >= least, "{family:?}: {params}");
                assert!(params["thickness"].as_f64().unwrap() > 0.0, "{params}");
                assert!(params.get("stretch").is_none(), "{params}");
            }
        }
        for (family, volume) in [
            (Family::S2xB2, 1_000.0),
            (Family::S2xB2, 3_000.0),
            (Family::BumpyS2xB2, 3_000.0),
            (Family::Shell, 1_500.0),
            (Family::Shell, 3_000.0),
        ] {
            let (least, _) = tube_range(&family, TubeFloor::USUAL);
            let mut thinner = 0;
            for seed in 0..8 {
                let sized = |floor| {
                    let mut rng = ChaCha8Rng::seed_from_u64(seed);
                    build_volume(&family, 4, 11.0, volume, floor, false, Fit::Ball, &mut rng)
                        .unwrap()
                };
                let (solid, params) = sized(TubeFloor::USUAL);
                let tube = params["tube_radius"].as_f64().unwrap();
                assert!((THIN_TUBE..=least).contains(&tube), "{params}");
                assert!(solid.extent() <= 11.0 + 1e-9);
                let estimated = estimate_volume(&solid, 4);
                assert!(estimated >= FLAT_REACHED * volume, "{estimated}: {params}");
                match params.get("stretch").and_then(Value::as_f64) {
                    // Widened back to the family's minimum along the fourth axis.
                    Some(stretch) => assert!((stretch * tube - least).abs() < 1e-5, "{params}"),
                    None => assert_eq!(family, Family::Shell, "{params}"),
                }
                // At the family's minimum tube the same volume leaves a narrower hole.
                if tube < least - 0.1 {
                    thinner += 1;
                    let shares = Shares::minimal(share_count(&family));
                    let at = |grow| {
                        let solid = make(&family, 4, least, grow, &shares, INNER_GAP).unwrap();
                        estimate_volume(&solid, 4)
                    };
                    let (mut lo, mut hi) = (0.0, 10.0);
                    for _ in 0..30 {
                        let mid = (lo + hi) / 2.0;
                        if at(mid) <= estimated {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    let grow = params["grow"].as_f64().unwrap();
                    assert!(grow > lo, "{grow} against {lo} at the minimum: {params}");
                }
                let copies = TubeFloor::for_copies(bettimill_grid::Dim::Four, 2);
                let (_, params) = sized(copies);
                assert!(params["tube_radius"].as_f64().unwrap() >= copies.radius());
            }
            assert!(
                thinner >= 4,
                "{family:?} at {volume}: {thinner} of 8 thinner"
            );
        }
    }

    /// A tentacled handle with no room for tentacles (4D side 24) is its host sized for the
    /// volume, widened, not the smallest handle; a tentacled ball is drawn as `build` draws
    /// it, for targeting to grow into a lumpy body.
    #[test]
    fn tentacled_hosts_with_a_hole_are_sized_for_the_volume() {
        let tentacled = |object| Family::Tentacled {
            object: Box::new(object),
            tentacles: 2,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut built = |object| {
            let family = tentacled(object);
            build_volume(
                &family,
                4,
                10.5,
                15_000.0,
                TubeFloor::USUAL,
                false,
                Fit::Ball,
                &mut rng,
            )
            .unwrap()
        };
        let (solid, params) = built(Family::Handle);
        assert_eq!(params["tentacles_placed"], 0, "{params}");
        assert!(
            params["host"]["stretch"].as_f64().unwrap() > 1.0,
            "{params}"
        );
        assert!(estimate_volume(&solid, 4) >= FLAT_REACHED * 15_000.0);
        let (_, params) = built(Family::Ball);
        assert!(params["host"].get("volume_target").is_none(), "{params}");
    }

    /// Carved cavities of a boxed solid keep their drawn scale and thickness: no widening.
    #[test]
    fn cavities_of_a_box_are_not_widened() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let (_, params) = build_volume(
            &Family::Handle,
            4,
            11.0,
            24_000.0,
            TubeFloor::USUAL,
            true,
            Fit::Ball,
            &mut rng,
        )
        .unwrap();
        assert!(params.get("stretch").is_none(), "{params}");
    }
}
