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
//!   (one layer of `(box side)^(d-1)` voxels per extra component). As the cavities of carve
//!   mode grow, the solid keeps its own topology too: a voxel of each piece of it inside a
//!   cavity, and a thin sheet across the box through every hole of the cavities (its
//!   Betti numbers b_k, 1 <= k <= d - 2: a line of `(box side)` voxels through a 3D handle,
//!   a plane of `(box side)^2` through a 4D one). Estimates of where growth stops, not
//!   bounds.
//! - the phase shrinks until it is thin: each component keeps a voxel, and every hole or
//!   void of each object (a scene's objects each at their own size, a Betti class's as
//!   the construction it is built as) a thin loop or closed surface around it, on the
//!   smallest instance (the construction is built at its smallest size for a small phase).
//!   For round tubes and shells that is a round k-sphere per Betti number b_k, half a
//!   voxel inside the middle of the tube or shell, at the density of a digital surface one
//!   voxel thick (`thin_density`): thin foreground joins across corners, so it needs one
//!   voxel per row along the axis nearest the normal; thin background joins only across
//!   faces, so it needs one along every axis. Where shrinking stops varies with the noise
//!   order, so the count is raised to the upper quartile the sweep measured
//!   (`thin_margin`). An embedded 3D torus shell keeps a thin torus about its middle. Other
//!   objects (4D tori, handlebodies, sums, knots, carved torus shells) keep the plain
//!   sphere model at half a voxel per unit area (one in carve mode), which the sweep's
//!   builds of them stopped near or below. Also an estimate.
//!
//! A bin that lies wholly outside these bounds cannot be built, so the plan refuses it by
//! name, with the bin end that works, instead of every shard failing later. The estimates
//! come from a sweep of small sides in 2D, 3D and 4D, both modes (the example
//! `cargo run --release -p bettimill-sample --example reach -- MANIFEST` measures a
//! manifest's strata against them): a bin just past an estimate is reached in most attempts,
//! so all 16 attempts of a sample failing is rare. A tunnel's cross-section is drawn per
//! sample whatever the bin, so its samples stop over a wide range; the estimate takes the
//! median cross-section, which about half the attempts reach.

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
    /// A tunnel's largest cross-section radius: each sample draws its own uniformly from
    /// [`Stratum::smallest_radius`] up to this.
    pub largest_radius: Option<f64>,
    /// The objects (cavities) that make up the phase, each with the Betti numbers and
    /// smallest bounding radius of its own: a scene's holes are those of its objects, at
    /// their own sizes.
    pub parts: Vec<Part>,
    /// Carve mode: the Betti numbers of the carved solid (the whole image's).
    pub solid_betti: Vec<u64>,
}

/// One object (cavity) of a phase.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// Its own Betti numbers, as an object in empty space.
    pub betti: Vec<u64>,
    /// Its smallest bounding radius with the usual tubes, if known.
    pub radius: Option<f64>,
    /// What its holes and voids are wrapped in.
    pub shape: PartShape,
}

/// What a part's holes and voids are wrapped in, which sets where its thin cycles sit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PartShape {
    /// A round tube (ball, handle, S2xB2, curve, loop): its cycles are round spheres about
    /// its middle, its bounding radius less the tube's.
    Tube,
    /// A round shell: a sphere about its middle, its bounding radius less the shell's
    /// 1.5-voxel half-thickness.
    Shell,
    /// A 3D torus shell: a thickened torus whose smallest instance has a tube hole `h`
    /// (its bounding radius less the shell's half-thickness, over 3) as its minor radius
    /// and `2h` as its major one. In embed mode its thin cycle is a torus about its middle;
    /// as a cavity it keeps [`PartShape::Other`]'s model, which its builds stopped around.
    TorusShell,
    /// Anything else (tori, handlebodies, sums, knots): spheres of its bounding radius less
    /// a tube, at half a voxel per unit of area in embed mode and one in carve mode. The
    /// round model overshoots these (a torus shell's thin surface is a torus, not a sphere
    /// of its bounding radius); the sweep's 3D torus shells stopped at 416-465 voxels
    /// against 427 here, its genus-2 handlebodies and 4D T2xB2 below this.
    Other,
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
    // hole or void of the smallest instance of each part.
    let cycles = thin_cycles(s);
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
                // axes) across the box. Its cross-section is drawn per sample whatever the
                // bin, so the openings are those of the median one: a sample reaches a bin
                // up to this count in about half its attempts (the sweep: 45-85%).
                Some(axes) => {
                    let inset = bettimill_shapes::CAVITY_INSET as u64;
                    let across = power(
                        inside_side.saturating_sub(2 * inset),
                        (axes as usize).clamp(1, d - 1),
                    );
                    let smallest = s.smallest_radius.unwrap_or(0.0);
                    let median = (smallest + s.largest_radius.unwrap_or(smallest)) / 2.0;
                    // Thin background runs diagonally in steps when the tunnel is
                    // turned, which about doubles the cut.
                    let kept = tunnel_openings(s, axes, median, 0.0) + 2 * across;
                    (
                        kept,
                        format!(
                            "tunnel keeps where it opens the solid's faces and a thin cut \
                             across, about {kept} voxels with the median cross-section \
                             (radius {median:.1}; a thinner one, drawn in fewer than half \
                             the attempts, keeps fewer)"
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

/// Voxels per unit of area of the thinnest cycle the flips leave, by mode and the cycle's
/// dimension `k`: the mean over directions of the largest (embed mode) or summed (carve
/// mode) component of a unit normal of a round k-sphere in k + 1 axes. Thin foreground
/// joins across corners, so a digital surface needs one voxel per row along the axis
/// nearest its normal; thin background (face steps only) needs one along every axis.
fn thin_density(mode: Mode, k: usize) -> f64 {
    let (largest, summed) = match k {
        0 | 1 => (0.9003, 1.2732),
        2 => (0.8311, 1.5),
        _ => (0.7789, 1.6977),
    };
    match mode {
        Mode::Embed => largest,
        Mode::Carve => summed,
    }
}

/// How much more the sweep of small sides measured than [`thin_density`] times the area:
/// the upper quartile of where shrinking stopped, so that a bin just above the estimate is
/// reached in most attempts, not one in two. Shrinking stops wherever the noise order
/// leaves the cycle between the part's inner and outer surface, so the count spreads (4D
/// side-16 shells in embed mode: 130-270 voxels, quartiles 164, 175, 195). Thin background
/// at these radii is thicker than its flat density: a carved shell keeps about 1.6 times
/// it (3D: 122-128 voxels, 4D: 550-614).
fn thin_margin(mode: Mode) -> f64 {
    match mode {
        Mode::Embed => 1.1,
        Mode::Carve => 1.7,
    }
}

/// The voxels of the thin cycles the phase keeps around its holes and voids: for each
/// part and each Betti number b_k (k >= 1), b_k round k-spheres of radius half a voxel
/// inside the middle of the smallest instance's tube or shell (its bounding radius less
/// the tube radius or the shell's half-thickness; the measured cycles sit that far inside,
/// where the inner side is shorter), at [`thin_density`] with [`thin_margin`]; a torus
/// for a 3D torus shell in embed mode; the plain model for [`PartShape::Other`].
fn thin_cycles(s: &Stratum) -> f64 {
    use std::f64::consts::PI;
    let tube = bettimill_shapes::TubeFloor::USUAL.radius();
    s.parts
        .iter()
        .map(|part| {
            let bound = part.radius.unwrap_or(0.0);
            if part.shape == PartShape::TorusShell && s.mode == Mode::Embed {
                // One thin torus carries both its loops and its void.
                let hole = (bound - SHELL_HALF) / 3.0;
                let area = 4.0 * PI * PI * (2.0 * hole) * (hole - 0.5).max(1.0);
                return area * thin_density(s.mode, 2) * thin_margin(s.mode);
            }
            let middle = match part.shape {
                PartShape::Tube => bound - tube - 0.5,
                PartShape::Shell => bound - SHELL_HALF - 0.5,
                PartShape::TorusShell | PartShape::Other => bound - tube,
            };
            let r = middle.max(1.0);
            let density = |k: usize| match (part.shape, s.mode) {
                (PartShape::Other | PartShape::TorusShell, Mode::Embed) => 0.5,
                (PartShape::Other | PartShape::TorusShell, Mode::Carve) => 1.0,
                _ => thin_density(s.mode, k) * thin_margin(s.mode),
            };
            part.betti
                .iter()
                .enumerate()
                .skip(1)
                .map(|(k, &b)| b as f64 * density(k) * sphere_area(k, r))
                .sum::<f64>()
        })
        .sum()
}

/// A shell's least half-thickness, as the constructions build it.
const SHELL_HALF: f64 = 1.5;

/// The voxels of the solid's outer layers that a tunnel of cross-section `radius` along
/// `axes` axes opens: on both faces of each axis, its cross-section (a round
/// (d - axes)-ball, its radius widened by `round` for the voxels its edge touches) times
/// the other axes it runs along.
fn tunnel_openings(s: &Stratum, axes: u32, radius: f64, round: f64) -> u64 {
    let d = s.dim;
    let inside_side = (s.side as u64).saturating_sub(2);
    let axes = (axes as usize).clamp(1, d - 1);
    let opening = ball_volume(d - axes, radius + round) * power(inside_side, axes - 1) as f64;
    let inset = bettimill_shapes::CAVITY_INSET as f64;
    (2.0 * axes as f64 * inset * opening).ceil() as u64
}

/// Carve mode's least count: the solid's layers outside the cavities' box, and walls
/// between cavities that meet.
fn carve_lowest(s: &Stratum, walls: u64) -> (u64, String) {
    let d = s.dim;
    let inside_side = (s.side as u64).saturating_sub(2);
    // The solid keeps its own topology as the cavities grow: a voxel of each component
    // inside a cavity, and a thin sheet across the box through every hole of the cavities
    // (a line through a 3D handle, a plane through a 4D one), attached to the layers.
    let solid = &s.solid_betti;
    let sheets = |box_side: u64| -> u64 {
        let inner = solid.first().copied().unwrap_or(1).saturating_sub(1);
        (1..d.saturating_sub(1)).fold(inner, |acc, k| {
            let b = solid.get(k).copied().unwrap_or(0);
            acc.saturating_add(b.saturating_mul(power(box_side, k)))
        })
    };
    // Layers `inset` thick inside a solid of `width` per axis, and the walls between
    // cavities and the sheets across its box.
    let kept = |width: u64, inset: u64| -> (u64, u64) {
        let box_side = width.saturating_sub(2 * inset);
        let layers = power(width, d) - power(box_side, d);
        let wall = walls.saturating_mul(power(box_side, d - 1));
        (layers, wall.saturating_add(sheets(box_side)))
    };
    let holes = (1..d.saturating_sub(1)).any(|k| solid.get(k).is_some_and(|&b| b > 0));
    let with_walls = |what: String, wall: u64| -> String {
        match (wall > 0, holes) {
            (false, _) => what,
            (true, false) => {
                format!("{what}, and its cavities meet along walls of about {wall} voxels")
            }
            (true, true) => format!(
                "{what}, and it keeps walls where its cavities meet and thin sheets across \
                 the box through their holes, about {wall} voxels"
            ),
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
            layers.saturating_sub(tunnel_openings(
                s,
                axes,
                s.smallest_radius.unwrap_or(0.0),
                0.0,
            )),
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
            largest_radius: None,
            parts: vec![Part {
                betti: phase_betti.to_vec(),
                radius: Some(4.0),
                shape: PartShape::Tube,
            }],
            solid_betti: Vec::new(),
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
    fn a_tunnel_s_thinnest_keeps_the_openings_of_its_median_cross_section() {
        // 2D side 30 along one axis, radius drawn in 4..12: the median 8 opens both layers
        // of two faces over 2 * 8 voxels, and the cut across the 24-voxel box is doubled.
        let t = reach(&Stratum {
            tunnel: Some(1),
            largest_radius: Some(12.0),
            ..stratum(2, 30, Mode::Carve, &[1, 0])
        });
        assert_eq!(t.highest, 28 * 28 - (2 * 2 * 16 + 2 * 24));
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
        // A shell of bounding radius 4 keeps a sphere of radius 4 - 1.5 - 0.5 = 2: one voxel
        // per row along the axis nearest its normal in embed mode, one along every axis
        // (and thicker, the margin) as a cavity.
        let shell = |mode| {
            reach(&Stratum {
                parts: vec![Part {
                    betti: vec![1, 0, 1],
                    radius: Some(4.0),
                    shape: PartShape::Shell,
                }],
                ..stratum(3, 24, mode, &[1, 0, 1])
            })
        };
        let area = 4.0 * std::f64::consts::PI * 4.0;
        assert_eq!(
            shell(Mode::Embed).lowest,
            1 + (area * 0.8311 * 1.1).floor() as u64
        );
        assert_eq!(
            shell(Mode::Carve).highest,
            22 * 22 * 22 - 1 - (area * 1.5 * 1.7).floor() as u64
        );
    }

    #[test]
    fn a_scene_s_holes_are_its_objects_own() {
        // A ball of radius 2 and a handle of radius 5.25 (a loop of radius 2.75): the
        // handle's loop, not one of the ball's size.
        let part = |betti: &[u64], radius| Part {
            betti: betti.to_vec(),
            radius: Some(radius),
            shape: PartShape::Tube,
        };
        let scene = reach(&Stratum {
            parts: vec![part(&[1, 0], 2.0), part(&[1, 1], 5.25)],
            ..stratum(2, 32, Mode::Embed, &[2, 1])
        });
        let r: f64 = 5.25 - 2.0 - 0.5;
        let loop_voxels = 2.0 * std::f64::consts::PI * r * 0.9003 * 1.1;
        assert_eq!(scene.lowest, 2 + loop_voxels.floor() as u64);
    }

    #[test]
    fn a_torus_shell_keeps_a_thin_torus() {
        // Bounding radius 9.75: hole 2.75, a thin torus of radii 5.5 and 2.25.
        let torus = reach(&Stratum {
            parts: vec![Part {
                betti: vec![1, 2, 1],
                radius: Some(9.75),
                shape: PartShape::TorusShell,
            }],
            ..stratum(3, 32, Mode::Embed, &[1, 2, 1])
        });
        let area = 4.0 * std::f64::consts::PI.powi(2) * 5.5 * 2.25;
        assert_eq!(torus.lowest, 1 + (area * 0.8311 * 1.1).floor() as u64);
    }

    #[test]
    fn a_carved_solid_keeps_a_sheet_through_each_hole() {
        // A handle cavity in 3D: the solid keeps a line across the 18-voxel box through
        // the handle's hole; in 4D a plane of 18 x 18.
        let handle = |dim, solid_betti: &[u64]| {
            reach(&Stratum {
                solid_betti: solid_betti.to_vec(),
                ..stratum(dim, 24, Mode::Carve, &[1; 2])
            })
        };
        let layers3 = 22 * 22 * 22 - 18 * 18 * 18;
        assert_eq!(handle(3, &[1, 1, 1]).lowest, layers3 + 18);
        let layers4 = 22u64.pow(4) - 18u64.pow(4);
        assert_eq!(handle(4, &[1, 0, 1, 1]).lowest, layers4 + 18 * 18);
        // A shell cavity leaves a ball of solid inside it, which shrinks to a voxel.
        assert_eq!(handle(3, &[2, 0, 1]).lowest, layers3 + 1);
    }
}
