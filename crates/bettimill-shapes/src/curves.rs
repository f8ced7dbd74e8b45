//! Closed and open curves: knots, links, tentacles and free curves, as polylines.
//!
//! (being written)

use crate::families::INNER_GAP;
use crate::geometry::{Piece, Solid, P};
use crate::{KnotKind, LinkKind};
use rand_chacha::ChaCha8Rng;

/// A smooth open curve: the graph of gentle sine waves over the x0-axis, thickened. A
/// graph never meets itself, and bounding its curvature by 1 / (tube + INNER_GAP / 2)
/// keeps the tube from folding onto itself, so the solid is a ball up to homotopy.
/// `shares` (which sum to 1) supply its random amplitudes and phases.
pub(crate) fn open_curve(dim: usize, tube: f64, grow: f64, shares: &[f64]) -> Solid {
    let count = shares.len() as f64;
    let random = |k: usize| shares[k % shares.len()] * count;
    let half = tube + grow * (0.5 + 0.25 * random(0));
    let max_curvature = 1.0 / (tube + INNER_GAP / 2.0);
    let mut amplitude = [0.0; 4];
    let mut frequency = [0.0; 4];
    let mut phase = [0.0; 4];
    for k in 1..dim {
        amplitude[k] = grow * 0.2 * random(k);
        if amplitude[k] > 0.0 {
            // Each lateral axis gets an equal share of the curvature bound.
            let bound = (max_curvature / ((dim - 1) as f64 * amplitude[k])).sqrt();
            frequency[k] = bound.min(2.0 * std::f64::consts::PI / half.max(1.0));
        }
        phase[k] = 2.0 * std::f64::consts::PI * random(k + 3) / count;
    }
    let samples = (2.0 * half / 0.4).ceil() as usize + 2;
    let points: Vec<P> = (0..samples)
        .map(|n| {
            let x = -half + 2.0 * half * n as f64 / (samples - 1) as f64;
            let mut p = [x, 0.0, 0.0, 0.0];
            for k in 1..dim {
                p[k] = amplitude[k] * libm::sin(frequency[k] * x + phase[k]);
            }
            p
        })
        .collect();
    Solid::Tube(vec![(
        Piece::Polyline {
            points,
            closed: false,
        },
        tube,
    )])
}
pub(crate) fn knot_solid(_k: KnotKind, _dim: usize, _tube: f64, _grow: f64) -> Option<Solid> {
    None
}
pub(crate) fn torus_knot_solid(
    _p: u32,
    _q: u32,
    _dim: usize,
    _tube: f64,
    _grow: f64,
) -> Option<Solid> {
    None
}
pub(crate) fn link_solid(_k: LinkKind, _dim: usize, _tube: f64, _grow: f64) -> Option<Solid> {
    None
}
pub(crate) fn spun_knot_solid(_k: KnotKind, _tube: f64, _grow: f64) -> Option<Solid> {
    None
}
pub(crate) fn spun_link_solid(_k: LinkKind, _tube: f64, _grow: f64) -> Option<Solid> {
    None
}
pub(crate) fn add_tentacles(
    solid: Solid,
    _dim: usize,
    _n: u32,
    _target: f64,
    _rng: &mut ChaCha8Rng,
) -> (Solid, u32) {
    (solid, 0)
}
