//! Sizing: the smallest instance of a family, and drawing a random instance that fits.
//!
//! The smallest bounding radius of a family is its recipe at the minimum tube radius and
//! no growth ([`min_extent`]); plan-time feasibility compares it with the room an image
//! offers. Drawing an instance picks a target bounding radius between that minimum and the
//! room available, then finds the tube radius and the growth by bisection ([`build`]), so
//! size is random but never needs an open-ended retry. Tentacles are added to their host
//! here, in the room the host leaves.

use crate::curves;
use crate::geometry::{round6, uniform, Solid, INNER_GAP, TUBE_MIN};
use crate::recipes::{make, share_count, tube_range, Shares};
use crate::Family;
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

/// Room a tentacle needs beyond its host's extent: the gap and two steps past the host's
/// tube (`curves::add_tentacles`) plus its own radius, each tentacle radius at most
/// TUBE_MIN + 0.5.
const TENTACLE_ROOM: f64 = 2.0 * (TUBE_MIN + 0.5) + INNER_GAP + 0.5 + 2.5;

/// The smallest bounding radius of one object of the family (tentacles need none extra:
/// they are added only where space remains; see [`draw_target`]).
pub(crate) fn min_extent(family: &Family, dim: usize) -> Option<f64> {
    let family = match family {
        Family::Tentacled { object, .. } => object,
        other => other,
    };
    let (tube, _) = tube_range(family);
    let shares = Shares::minimal(share_count(family));
    make(family, dim, tube, 0.0, &shares).map(|s| s.extent())
}

/// A random bounding radius for `object` between `minimum` and `upper`. A tentacled
/// object draws from `minimum + TENTACLE_ROOM` up when there is that much room, so that its
/// host leaves space for tentacles (draws near the minimum used to place none in most
/// samples); where there is not, it keeps the plain range and places what fits.
pub(crate) fn draw_target(object: &Family, minimum: f64, upper: f64, rng: &mut ChaCha8Rng) -> f64 {
    let lo = match object {
        Family::Tentacled { .. } if minimum + TENTACLE_ROOM <= upper => minimum + TENTACLE_ROOM,
        _ => minimum,
    };
    uniform(rng, lo, upper)
}

/// A random instance with bounding radius at most `target` (which must be at least the
/// minimum). Returns the solid and its parameters.
pub(crate) fn build(
    family: &Family,
    dim: usize,
    target: f64,
    rng: &mut ChaCha8Rng,
) -> Option<(Solid, Value)> {
    if let Family::Tentacled { object, tentacles } = family {
        // The host takes a random part of the room; tentacles reach into the rest. A
        // tentacle must leave the host by a gap and a few steps before it counts, so the
        // host leaves that much room when the target allows it (see `draw_target`).
        let minimum = min_extent(object, dim)?;
        let host_cap = (0.75 * target).min(target - TENTACLE_ROOM);
        let host_target = uniform(rng, minimum, minimum.max(host_cap));
        let (solid, params) = build(object, dim, host_target, rng)?;
        let (solid, placed) = curves::add_tentacles(solid, dim, *tentacles, target, rng);
        return Some((
            solid,
            json!({"host": params, "tentacles_requested": tentacles, "tentacles_placed": placed}),
        ));
    }
    let (tube_min, tube_cap) = tube_range(family);
    let shares = Shares::draw(share_count(family), rng);
    let extent = |tube: f64, grow: f64| -> Option<f64> {
        make(family, dim, tube, grow, &shares).map(|s| s.extent())
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
    let solid = make(family, dim, tube, lo, &shares)?;
    let params = json!({
        "tube_radius": round6(tube),
        "grow": round6(lo),
        "shares": shares.0.iter().map(|&x| round6(x)).collect::<Vec<_>>(),
    });
    Some((solid, params))
}
