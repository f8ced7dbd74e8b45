//! Which foreground counts a binned stratum's samples can reach, decided from the geometry
//! alone, so that it costs the same at any side (one pilot sample of a 128^4 stratum costs
//! seconds, and the plan is made by every command).
//!
//! A sample's count moves only by simple-point flips of its phase (the objects in embed
//! mode, the cavities in carve mode) inside the phase's box, so:
//!
//! - what lies outside the box never changes. Carve mode with the full cube keeps the
//!   solid's outer [`bettimill_shapes::CAVITY_INSET`] layers inside the empty border (a
//!   tunnel opens them on its axes; their edges and corners stay). A boxed solid keeps
//!   [`bettimill_shapes::BOX_WALL`] layers: its box is at least that wall on both sides of
//!   the smallest cavity, and where no box holds the cavities the full cube is used with
//!   the same wall. These are bounds no sample can cross.
//! - the phase grows until its components meet: targeting grows all of them together, in
//!   the order of one smooth noise, so two components end apart by a wall across the box
//!   (one layer of `(box side)^(d-1)` voxels per extra component). An estimate of where
//!   growth stops, not a bound.
//! - the phase shrinks until it is thin: each component keeps a voxel, and every hole or
//!   void it holds a thin loop or closed surface around the hole of the smallest instance
//!   (the construction is built at its smallest size for a small phase): the area of a
//!   round k-sphere of the instance's core radius per Betti number b_k, half of it in embed
//!   mode, where diagonal steps make thin foreground sparser than thin background. Also an
//!   estimate.
//!
//! A bin that lies wholly outside these bounds cannot be built (the estimates are drawn to
//! refuse only bins that measured builds at small sides never reached), so the plan
//! refuses it by name instead of every shard failing later.

use bettimill_grid::Mode;
use bettimill_types::Solid;

/// What the bounds of one stratum depend on.
#[derive(Clone, Debug, PartialEq)]
pub struct Stratum {
    /// Number of axes.
    pub dim: usize,
    /// Voxels per axis.
    pub side: u32,
    /// Objects or cavities.
    pub mode: Mode,
    /// Carve mode's solid.
    pub solid: Solid,
    /// Betti numbers of the phase (the objects in embed mode, the cavities in carve mode);
    /// `phase_betti[0]` is its number of components.
    pub phase_betti: Vec<u64>,
    /// A cavity that is a tunnel through the solid's faces: along how many axes.
    pub tunnel: Option<u32>,
    /// The smallest bounding radius of one object with the usual tubes (of a tunnel's
    /// cross-section), if known.
    pub smallest_radius: Option<f64>,
}

/// Inclusive foreground-count bounds of a stratum's samples, with what sets each.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reach {
    /// No sample has fewer foreground voxels.
    pub lowest: u64,
    /// Why the count does not fall below [`Reach::lowest`].
    pub lowest_why: String,
    /// No sample has more foreground voxels.
    pub highest: u64,
    /// Why the count does not rise above [`Reach::highest`].
    pub highest_why: String,
}

/// `base^exp` for the small exponents of image dimensions, saturating.
fn power(base: u64, exp: usize) -> u64 {
    (0..exp).fold(1u64, |acc, _| acc.saturating_mul(base))
}

/// The surface area of a round k-sphere of radius `r` (k = 1: 2 pi r; k = 2: 4 pi r^2;
/// k = 3: 2 pi^2 r^3).
fn sphere_area(k: usize, r: f64) -> f64 {
    use std::f64::consts::PI;
    match k {
        0 => 2.0,
        1 => 2.0 * PI * r,
        2 => 4.0 * PI * r * r,
        _ => 2.0 * PI * PI * r * r * r,
    }
}

/// The volume of a round k-ball of radius `r` (k = 1: 2r; k = 2: pi r^2; k = 3:
/// 4/3 pi r^3).
fn ball_volume(k: usize, r: f64) -> f64 {
    use std::f64::consts::PI;
    match k {
        0 => 1.0,
        1 => 2.0 * r,
        2 => PI * r * r,
        _ => 4.0 / 3.0 * PI * r * r * r,
    }
}

/// The bounds of `s` (see the module documentation).
pub fn reach(s: &Stratum) -> Reach {
    let d = s.dim;
    let side = s.side as u64;
    // The image's outermost layer is always empty.
    let inside_side = side.saturating_sub(2);
    let inside = power(inside_side, d);
    let components = s.phase_betti.first().copied().unwrap_or(1);
    let walls = components.saturating_sub(1);
    // The thinnest the phase gets: a voxel per component and a thin cycle around every
    // hole or void of the smallest instance.
    let core = s
        .smallest_radius
        .map(|r| (r - bettimill_shapes::TubeFloor::USUAL.radius()).max(1.0))
        .unwrap_or(1.0);
    let density = match s.mode {
        Mode::Embed => 0.5,
        Mode::Carve => 1.0,
    };
    let cycles: f64 = s
        .phase_betti
        .iter()
        .enumerate()
        .skip(1)
        .map(|(k, &b)| b as f64 * density * sphere_area(k, core))
        .sum();
    let thinnest = components + cycles.floor() as u64;
    let thin_why = if cycles >= 1.0 {
        format!(
            "shrinking keeps a voxel of each of its {components} component(s) and a thin \
             cycle around each of its holes and voids, about {thinnest} voxels at the least"
        )
    } else {
        format!("shrinking keeps a voxel of each of its {components} component(s)")
    };
    match s.mode {
        Mode::Embed => {
            let wall = walls.saturating_mul(power(inside_side, d - 1));
            Reach {
                lowest: thinnest,
                lowest_why: format!("the objects' {thin_why}"),
                highest: inside.saturating_sub(wall),
                highest_why: if walls > 0 {
                    format!(
                        "only that many voxels lie inside the always-empty border, less a \
                         wall of about {wall} voxels where its {components} objects meet"
                    )
                } else {
                    "only that many voxels lie inside the always-empty border".into()
                },
            }
        }
        Mode::Carve => {
            let (lowest, lowest_why) = carve_lowest(s, walls);
            let (thinnest, thin_why) = match s.tunnel {
                // A tunnel keeps its openings in the layers, and a line (a sheet, along two
                // axes) across the box.
                Some(axes) => {
                    let inset = bettimill_shapes::CAVITY_INSET as u64;
                    let across = power(
                        inside_side.saturating_sub(2 * inset),
                        (axes as usize).clamp(1, d - 1),
                    );
                    // Thin background runs diagonally in steps when the tunnel is
                    // turned, which about doubles it.
                    let kept = 2 * (tunnel_openings(s, axes, 0.5) + across);
                    (
                        kept,
                        format!(
                            "tunnel keeps where it opens the solid's faces and a thin cut \
                             across, about {kept} voxels at the least"
                        ),
                    )
                }
                None => (thinnest, thin_why),
            };
            Reach {
                lowest,
                lowest_why,
                highest: inside.saturating_sub(thinnest),
                highest_why: format!(
                    "the solid fills at most the inside of the border, and its cavities' \
                     {thin_why}"
                ),
            }
        }
    }
}

/// The voxels of the solid's outer layers that a tunnel of the smallest cross-section
/// along `axes` axes opens: on both faces of each axis, its cross-section (a round
/// (d - axes)-ball, its radius widened by `round` for the voxels its edge touches) times
/// the other axes it runs along.
fn tunnel_openings(s: &Stratum, axes: u32, round: f64) -> u64 {
    let d = s.dim;
    let inside_side = (s.side as u64).saturating_sub(2);
    let axes = (axes as usize).clamp(1, d - 1);
    let opening = ball_volume(d - axes, s.smallest_radius.unwrap_or(0.0) + round)
        * power(inside_side, axes - 1) as f64;
    let inset = bettimill_shapes::CAVITY_INSET as f64;
    (2.0 * axes as f64 * inset * opening).ceil() as u64
}

/// Carve mode's least count: the solid's layers outside the cavities' box, and walls
/// between cavities that meet.
fn carve_lowest(s: &Stratum, walls: u64) -> (u64, String) {
    let d = s.dim;
    let inside_side = (s.side as u64).saturating_sub(2);
    // Layers `inset` thick inside a solid of `width` per axis, and the walls between
    // cavities across its box.
    let kept = |width: u64, inset: u64| -> (u64, u64) {
        let box_side = width.saturating_sub(2 * inset);
        let layers = power(width, d) - power(box_side, d);
        (layers, walls.saturating_mul(power(box_side, d - 1)))
    };
    let with_walls = |what: String, wall: u64| -> String {
        if wall > 0 {
            format!("{what}, and its cavities meet along walls of about {wall} voxels")
        } else {
            what
        }
    };
    let inset = bettimill_shapes::CAVITY_INSET as u64;
    if let Some(axes) = s.tunnel {
        // The tunnel opens the layers where it leaves the solid: on both faces of each of
        // its axes, its cross-section (a round (d - axes)-ball, at least the smallest
        // one's) times the other axes it runs along. It is not sized for the bin, so a
        // sample whose tunnel is drawn thin keeps nearly all of the layers.
        let (layers, _) = kept(inside_side, inset);
        return (
            layers.saturating_sub(tunnel_openings(s, axes, 0.0)),
            format!(
                "the solid's outer {inset} layers inside the border stay as built, less \
                 where a tunnel of the smallest cross-section opens them"
            ),
        );
    }
    if s.solid == Solid::Cube {
        let (layers, wall) = kept(inside_side, inset);
        return (
            layers + wall,
            with_walls(
                format!(
                    "the solid's outer {inset} layers inside the border stay as built (only \
                     the cavities inside them are reshaped)"
                ),
                wall,
            ),
        );
    }
    let wall_layers = bettimill_shapes::BOX_WALL as u64;
    // Where no box holds the cavities, the full cube with the box's walls.
    let (layers, wall) = kept(inside_side, wall_layers);
    let mut best = (
        layers + wall,
        with_walls(
            format!(
                "the solid's outer {wall_layers} layers inside the border stay as built (the \
                 full cube, where no smaller box holds the cavities)"
            ),
            wall,
        ),
    );
    // The smallest box: the walls on both sides of the cavities (as many smallest ones
    // in a row as a cube of them needs, with the gap between them), and a voxel for the
    // box's nearly equal sides (some axes are one longer than others).
    let per_row = (1..).find(|&n: &u64| power(n, d) > walls).unwrap_or(1);
    let gap = bettimill_shapes::CAVITY_INSET as f64;
    let cavity =
        per_row as f64 * 2.0 * s.smallest_radius.unwrap_or(0.0) + (per_row - 1) as f64 * gap;
    let smallest = 2 * wall_layers + 2 + cavity.ceil() as u64;
    if smallest < inside_side {
        let (layers, wall) = kept(smallest, wall_layers);
        if layers + wall < best.0 {
            best = (
                layers + wall,
                with_walls(
                    format!(
                        "a solid box is at least {smallest} voxels on every axis (its cavity \
                         and {wall_layers}-voxel walls that stay as built)"
                    ),
                    wall,
                ),
            );
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stratum(dim: usize, side: u32, mode: Mode, phase_betti: &[u64]) -> Stratum {
        Stratum {
            dim,
            side,
            mode,
            solid: Solid::Cube,
            phase_betti: phase_betti.to_vec(),
            tunnel: None,
            smallest_radius: Some(4.0),
        }
    }

    #[test]
    fn a_carved_cube_keeps_its_outer_layers() {
        // 3D side 24: 22^3 inside the border, 18^3 of it the cavities' box.
        let r = reach(&stratum(3, 24, Mode::Carve, &[1, 0, 0]));
        assert_eq!(r.lowest, 22 * 22 * 22 - 18 * 18 * 18);
        assert_eq!(r.highest, 22 * 22 * 22 - 1);
        // Two cavities meet along a wall across the box.
        let two = reach(&stratum(3, 24, Mode::Carve, &[2, 0, 0]));
        assert_eq!(two.lowest, r.lowest + 18 * 18);
        // A tunnel keeps only the layers' edges and corners: in 2D the four 2x2 corners.
        // A tunnel along one axis opens both layers of two faces where it leaves: 2r = 8
        // voxels of each.
        let t = reach(&Stratum {
            tunnel: Some(1),
            ..stratum(2, 30, Mode::Carve, &[1, 0])
        });
        assert_eq!(t.lowest, 28 * 28 - 24 * 24 - 2 * 2 * 8);
    }

    #[test]
    fn a_boxed_solid_keeps_its_walls() {
        let boxed = |side| {
            reach(&Stratum {
                solid: Solid::Box,
                ..stratum(3, side, Mode::Carve, &[1, 0, 0])
            })
        };
        // The smallest box: 8 + 8 + 2 + 8 (a cavity of radius 4) voxels a side.
        assert_eq!(boxed(64).lowest, 26 * 26 * 26 - 10 * 10 * 10);
        // No such box fits inside a 24-side image: the full cube with 8-voxel walls.
        assert_eq!(boxed(24).lowest, 22 * 22 * 22 - 6 * 6 * 6);
    }

    #[test]
    fn thin_phases_keep_their_holes() {
        let ball = reach(&stratum(3, 24, Mode::Embed, &[2, 0, 0]));
        assert_eq!(ball.lowest, 2);
        // Two objects meet along a wall across the image.
        assert_eq!(ball.highest, 22 * 22 * 22 - 22 * 22);
        // A shell keeps half a sphere of its core radius (4 - 2) in embed mode, a whole one
        // as a cavity.
        let shell = reach(&stratum(3, 24, Mode::Embed, &[1, 0, 1]));
        let area = 4.0 * std::f64::consts::PI * 4.0;
        assert_eq!(shell.lowest, 1 + (area / 2.0).floor() as u64);
        let cavity = reach(&stratum(3, 24, Mode::Carve, &[1, 0, 1]));
        assert_eq!(cavity.highest, 22 * 22 * 22 - 1 - area.floor() as u64);
    }
}
