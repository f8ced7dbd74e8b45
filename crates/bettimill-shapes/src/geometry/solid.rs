//! Solids: a skeleton with a thickening rule, the set an object occupies in its local frame.

use super::{norm_of, round6, scale, Piece, P};
use serde_json::{json, Value};

/// A skeleton with a thickening rule: the set an object occupies in its local frame.
#[derive(Clone, Debug)]
pub(crate) enum Solid {
    /// Points within `radius` of some piece (each piece has its own radius).
    Tube(Vec<(Piece, f64)>),
    /// Points whose distance to `piece` lies in `[offset - radius, offset + radius]`: a
    /// thickened boundary of the `offset`-neighbourhood of the piece.
    Shell {
        piece: Piece,
        offset: f64,
        radius: f64,
    },
    /// Points within `round` of a slice `lo <= x0 <= hi` of the ball of radius `core`
    /// about the origin, for some `(lo, hi)` of `slices`: a ball sliced across the local
    /// x0-axis, each slice with its edges rounded (no knife edge where a slice's face
    /// meets the sphere, which would digitise into lace).
    Slices {
        core: f64,
        slices: Vec<(f64, f64)>,
        round: f64,
    },
}

/// The distance from `(x, r)` (with `r >= 0`) to the half-disk slice `lo <= x <= hi`,
/// `x^2 + y^2 <= core^2`, `y >= 0` (where `-core <= lo <= hi <= core`): 0 inside, else
/// the distance to the nearest of its boundary's arc, two edges and corners (the nearest
/// point of a convex set to a point outside it lies on its boundary). Revolved about the
/// x-axis, it is the distance to a slice of a ball.
fn slice_distance(x: f64, r: f64, core: f64, (lo, hi): (f64, f64)) -> f64 {
    let n = (x * x + r * r).sqrt();
    if (lo..=hi).contains(&x) && n <= core {
        return 0.0;
    }
    let mut best = f64::INFINITY;
    if n > 0.0 && (lo..=hi).contains(&(core * x / n)) {
        best = (n - core).abs();
    }
    for edge in [lo, hi] {
        let top = (core * core - edge * edge).max(0.0).sqrt();
        let y = r.clamp(0.0, top);
        best = best.min(((x - edge) * (x - edge) + (r - y) * (r - y)).sqrt());
    }
    best
}

impl Solid {
    pub(crate) fn contains(&self, p: P) -> bool {
        match self {
            Solid::Tube(parts) => parts.iter().any(|(piece, r)| piece.within(p, *r)),
            Solid::Shell {
                piece,
                offset,
                radius,
            } => (piece.distance(p) - offset).abs() <= *radius,
            Solid::Slices {
                core,
                slices,
                round,
            } => {
                let r = norm_of(&p[1..]);
                slices
                    .iter()
                    .any(|&slice| slice_distance(p[0], r, *core, slice) <= *round)
            }
        }
    }

    /// Radius of a ball around the local origin that contains the solid.
    pub(crate) fn extent(&self) -> f64 {
        match self {
            Solid::Tube(parts) => parts
                .iter()
                .map(|(piece, r)| piece.reach(*r))
                .fold(0.0, f64::max),
            Solid::Shell {
                piece,
                offset,
                radius,
            } => piece.extent() + offset + radius,
            Solid::Slices { core, round, .. } => core + round,
        }
    }

    /// An upper bound of `|x . e|` over the solid: its half-width along the unit vector
    /// `e` about the local origin.
    pub(crate) fn half_width(&self, e: P) -> f64 {
        let minus = scale(e, -1.0);
        let both = |piece: &Piece, r: f64| piece.support(e, r).max(piece.support(minus, r));
        match self {
            Solid::Tube(parts) => parts
                .iter()
                .map(|(piece, r)| both(piece, *r))
                .fold(0.0, f64::max),
            Solid::Shell {
                piece,
                offset,
                radius,
            } => both(piece, offset + radius),
            Solid::Slices { core, round, .. } => core + round,
        }
    }

    pub(crate) fn describe(&self, dim: usize) -> Value {
        match self {
            Solid::Tube(parts) => json!({
                "kind": "tube",
                "parts": parts.iter().map(|(piece, r)| {
                    json!({"skeleton": piece.describe(dim), "radius": round6(*r)})
                }).collect::<Vec<_>>()
            }),
            Solid::Shell {
                piece,
                offset,
                radius,
            } => json!({
                "kind": "shell", "skeleton": piece.describe(dim),
                "offset": round6(*offset), "radius": round6(*radius)
            }),
            Solid::Slices {
                core,
                slices,
                round,
            } => json!({
                "kind": "slices", "core": round6(*core), "radius": round6(*round),
                "slices": slices.iter().map(|&(lo, hi)| [round6(lo), round6(hi)]).collect::<Vec<_>>()
            }),
        }
    }
}
