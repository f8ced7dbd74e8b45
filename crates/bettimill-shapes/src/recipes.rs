//! The construction recipes: each family's local solid as a function of its sizes.
//!
//! Each family is a recipe `make(r, grow)`: the solid with tube radius `r` whose free
//! lengths (hole sizes, bar lengths, scales) are their minima plus shares of `grow`. At
//! `grow = 0` and `r` at its minimum the recipe is the smallest valid instance, which is
//! what plan-time feasibility checks (see `sizing.rs` for how a size is chosen). Holes are
//! at least `tube + INNER_GAP / 2` in radius, and bars between parts at least
//! [`bar_min`] long, so two parts of one object that must stay apart never touch. Knots,
//! links and open curves are polylines built in `curves.rs`.

use crate::curves;
use crate::geometry::{
    add, axis, narrowest_gap, uniform, Piece, Solid, TubeFloor, ORIGIN, P, SHELL_MIN, TUBE_MIN,
};
use crate::labels::tunnel_cycles;
use crate::Family;
use rand_chacha::ChaCha8Rng;

/// Random choices of a recipe that do not change its minimum size.
pub(crate) struct Shares(pub(crate) Vec<f64>);

impl Shares {
    pub(crate) fn draw(count: usize, rng: &mut ChaCha8Rng) -> Shares {
        let raw: Vec<f64> = (0..count).map(|_| uniform(rng, 0.2, 1.0)).collect();
        let total: f64 = raw.iter().sum();
        Shares(raw.iter().map(|x| x / total).collect())
    }

    pub(crate) fn minimal(count: usize) -> Shares {
        Shares(vec![1.0 / count as f64; count])
    }

    fn get(&self, k: usize) -> f64 {
        self.0[k]
    }
}

/// The shortest bar between two thickened parts. Shorter bars let the two parts' tubes
/// meet beside the bar in a cusp-shaped notch, and a digitised cusp can pinch off a
/// background voxel: an extra hole (seen in 1 of 20 2D scenes with bars of length 1).
/// With this length the notch beside the bar is at least `INNER_GAP` wide.
fn bar_min(tube: f64, gap: f64) -> f64 {
    2.0 * tube + gap
}

/// A row of `count` circles of radius `radius` in the (x0, x1)-plane along x0, centred on
/// the origin, joined by bars of length `bar` between neighbours: a thickened graph with
/// `count` independent cycles.
fn circle_row(count: u32, radius: f64, bar: f64, tube: f64) -> Vec<(Piece, f64)> {
    let pitch = 2.0 * radius + bar;
    let first = -(count as f64 - 1.0) * pitch / 2.0;
    let mut out = Vec::new();
    for k in 0..count {
        let cx = first + k as f64 * pitch;
        out.push((
            Piece::Circle {
                centre: [cx, 0.0, 0.0, 0.0],
                radius,
                u: axis(0),
                v: axis(1),
            },
            tube,
        ));
        if k + 1 < count {
            out.push((
                Piece::Segment(
                    [cx + radius, 0.0, 0.0, 0.0],
                    [cx + radius + bar, 0.0, 0.0, 0.0],
                ),
                tube,
            ));
        }
    }
    out
}

/// Half the x0-length of a circle row.
fn circle_row_half(count: u32, radius: f64, bar: f64) -> f64 {
    (count as f64 * 2.0 * radius + (count as f64 - 1.0) * bar) / 2.0
}

/// S1 x (boundary sum of j thickened circles): a circle row in the meridian half-space,
/// kept `tube + INNER_GAP / 2` away from the spinning axis, spun about x0 = x1 = 0 and
/// moved to `centre`. Returns the pieces and the largest spun radius of the skeleton.
fn spun_row(
    j: u32,
    radius: f64,
    bar: f64,
    (tube, gap): (f64, f64),
    axis_gap: f64,
    centre: P,
) -> (Piece, f64) {
    let half = circle_row_half(j, radius, bar);
    let shift = tube + gap / 2.0 + axis_gap + half;
    let inner: Vec<Piece> = circle_row(j, radius, bar, tube)
        .into_iter()
        .map(|(piece, _)| translate(piece, [shift, 0.0, 0.0, 0.0]))
        .collect();
    (Piece::Spun { centre, inner }, shift + half)
}

fn translate(piece: Piece, by: P) -> Piece {
    match piece {
        Piece::Point(c) => Piece::Point(add(c, by)),
        Piece::Segment(a, b) => Piece::Segment(add(a, by), add(b, by)),
        Piece::Circle {
            centre,
            radius,
            u,
            v,
        } => Piece::Circle {
            centre: add(centre, by),
            radius,
            u,
            v,
        },
        Piece::Sphere {
            centre,
            radius,
            axes,
        } => Piece::Sphere {
            centre: add(centre, by),
            radius,
            axes,
        },
        Piece::Polyline { points, closed, .. } => {
            Piece::polyline(points.into_iter().map(|p| add(p, by)).collect(), closed)
        }
        Piece::Spun { centre, inner } => Piece::Spun {
            centre: add(centre, by),
            inner,
        },
        Piece::Prism { inner, keep } => Piece::Prism {
            inner: Box::new(translate(*inner, by)),
            keep,
        },
        // The stretch is about the origin: this moves the tube by `by` only where `by`
        // lies in the unstretched axes (the only use, spun rows, moves along the first).
        Piece::Flat {
            inner,
            stretch,
            from,
        } => Piece::Flat {
            inner: Box::new(translate(*inner, by)),
            stretch,
            from,
        },
        Piece::Bumpy {
            centre,
            radius,
            axes,
            stretches,
            lumps,
            bend,
        } => Piece::Bumpy {
            centre: add(centre, by),
            radius,
            axes,
            stretches,
            lumps,
            bend,
        },
        other @ (Piece::Torus { .. } | Piece::Klein { .. }) => other,
    }
}

/// The bumps of a bumpy sphere together, at most, as a share of its radius.
const BUMPS: f64 = 0.35;

/// A sphere in the first `axes` axes that is `hole` plus half of `grow` in radius, with
/// stretches along its axes, two lumps and (when there is an axis beyond the sphere's) a
/// bend drawn from `shares` (13 of them) and scaled with `grow`: at `grow` = 0 it is the
/// round sphere of radius `hole` whatever the shares, so the smallest instance is the
/// round family's. The tube is measured along rays from the centre, so it is thinner where
/// the sphere is steep (by the cosine of the slope); the bumps together stay within
/// [`BUMPS`] of the radius, which keeps the slope under about 30 degrees and the tube at
/// least 0.85 of its radius thick.
fn bumpy_sphere(dim: usize, axes: usize, hole: f64, grow: f64, shares: &Shares) -> Piece {
    let count = shares.0.len() as f64;
    let random = |k: usize| shares.get(k % shares.0.len()) * count;
    let mut stretches: Vec<(P, f64)> = (0..axes)
        .map(|k| (axis(k), grow * 0.2 * random(k)))
        .collect();
    // A lump's direction: two angles from the shares, in the sphere's first three axes
    // (the random rotation at placement turns it anywhere).
    let direction = |k: usize| -> P {
        let theta = std::f64::consts::PI * (random(k) / 2.5).min(1.0);
        let phi = 2.0 * std::f64::consts::PI * (random(k + 1) / 2.5).min(1.0);
        let mut v = [0.0; 4];
        v[0] = libm::cos(theta);
        v[1] = libm::sin(theta) * libm::cos(phi);
        if axes > 2 {
            v[2] = libm::sin(theta) * libm::sin(phi);
        }
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        // In 2D both in-plane terms vanish when theta is a right angle and phi too.
        if n < 1e-9 {
            return axis(0);
        }
        [v[0] / n, v[1] / n, v[2] / n, 0.0]
    };
    let mut lumps = vec![
        (direction(4), grow * 0.3 * random(6)),
        (direction(7), grow * 0.3 * random(9)),
    ];
    let mut bend = if axes < dim {
        (direction(10), grow * 0.25 * (random(12) - 1.0))
    } else {
        (ORIGIN, 0.0)
    };
    let radius = hole + 0.5 * grow;
    let bulge: f64 = stretches.iter().chain(&lumps).map(|&(_, a)| a).sum::<f64>() + bend.1.abs();
    if bulge > BUMPS * radius {
        let factor = BUMPS * radius / bulge;
        for (_, a) in stretches.iter_mut().chain(lumps.iter_mut()) {
            *a *= factor;
        }
        bend.1 *= factor;
    }
    Piece::Bumpy {
        centre: ORIGIN,
        radius,
        axes,
        stretches,
        lumps,
        bend,
    }
}

/// The boundary connected sum of Table I laid out along x0: summands joined by bars from
/// the rightmost skeleton point of one to the leftmost of the next. Every summand's
/// extreme points lie on the x0-axis, and each bar leaves its summand along the outward
/// normal there, so each bar meets each summand in a contractible blob: the union is
/// homotopy equivalent to the wedge of the summands.
fn connected_sum(
    (g, h, i, j): (u32, u32, u32, u32),
    dim: usize,
    tube: f64,
    grow: f64,
    shares: &Shares,
    gap: f64,
) -> Vec<(Piece, f64)> {
    let n = (g + h + i) as f64;
    // Shares: 0 = hole sizes, 1 = bars, 2 = spun offsets.
    let radius = tube + gap / 2.0 + shares.get(0) * grow / n;
    let bar = bar_min(tube, gap) + shares.get(1) * grow / n.max(1.0);
    let axis_gap = shares.get(2) * grow / n;
    // Summand kinds in a fixed order: g circles, h spheres, i spun rows.
    let mut kinds = Vec::new();
    kinds.extend(std::iter::repeat_n(0u8, g as usize));
    kinds.extend(std::iter::repeat_n(1u8, h as usize));
    kinds.extend(std::iter::repeat_n(2u8, i as usize));
    let half_width = |kind: u8| -> f64 {
        match kind {
            0 | 1 => radius,
            _ => {
                let (_, reach) =
                    spun_row(j, radius, bar_min(tube, gap), (tube, gap), axis_gap, ORIGIN);
                reach
            }
        }
    };
    let total: f64 =
        kinds.iter().map(|&k| 2.0 * half_width(k)).sum::<f64>() + (kinds.len() as f64 - 1.0) * bar;
    let mut x = -total / 2.0;
    let mut out = Vec::new();
    for (index, &kind) in kinds.iter().enumerate() {
        let half = half_width(kind);
        let centre = [x + half, 0.0, 0.0, 0.0];
        let piece = match kind {
            0 => Piece::Circle {
                centre,
                radius,
                u: axis(0),
                v: axis(1),
            },
            // In 3D the 2-sphere is the full boundary sphere (S2 x B1, a thick shell).
            1 => Piece::Sphere {
                centre,
                radius,
                axes: 3.min(dim),
            },
            _ => spun_row(j, radius, bar_min(tube, gap), (tube, gap), axis_gap, centre).0,
        };
        out.push((piece, tube));
        x += 2.0 * half;
        if index + 1 < kinds.len() {
            out.push((
                Piece::Segment([x, 0.0, 0.0, 0.0], [x + bar, 0.0, 0.0, 0.0]),
                tube,
            ));
            x += bar;
        }
    }
    out
}

/// A ball sliced across the local x0-axis into `parts` pieces with rounded edges
/// ([`Solid::Slices`]): cores of `2 * grow` shared out, each thickened by `tube`. The
/// slabs between the pieces keep [`narrowest_gap`] background voxels between them (the
/// gap of the narrowest scene under the same inner gap) whatever the rotation: two voxels
/// on either side of a slab `2 * half` wide differ by more than `2 * half` along its unit
/// normal `n`, at most `|n|_1 <= sqrt(d)` times their Chebyshev distance, so with
/// `half = gap * sqrt(d) / 2` they are more than `gap` apart. An axis-aligned slab leaves
/// up to twice that.
fn split_ball(parts: u32, dim: usize, tube: f64, grow: f64, shares: &Shares, gap: f64) -> Solid {
    let kept = narrowest_gap(gap) as f64;
    // The slack keeps a voxel centre on the slab's edge out by far more than the rotation's
    // rounding error.
    let half = kept * libm::sqrt(dim as f64) / 2.0 + 1e-6;
    let parts = parts as usize;
    let core_of = |k: usize| 2.0 * grow * shares.get(k);
    let between = 2.0 * (half + tube);
    let core = ((0..parts).map(core_of).sum::<f64>() + between * (parts - 1) as f64) / 2.0;
    let mut lo = -core;
    let mut slices = Vec::new();
    for k in 0..parts {
        let hi = (lo + core_of(k)).min(core);
        slices.push((lo, hi));
        lo = hi + between;
    }
    Solid::Slices {
        core,
        slices,
        round: tube,
    }
}

/// The tube radius range of a family, `(minimum, cap)`, raised to `floor`.
pub(crate) fn tube_range(family: &Family, floor: TubeFloor) -> (f64, f64) {
    floor.raise(match family {
        Family::Ball | Family::Split { .. } => (TUBE_MIN, TUBE_MIN),
        Family::Shell | Family::TorusShell | Family::BumpyShell => (SHELL_MIN, 3.0),
        Family::Tunnel { .. } if tunnel_cycles(family) == 0 => (TUBE_MIN, TUBE_MIN),
        Family::Knot { .. }
        | Family::TorusKnot { .. }
        | Family::Link { .. }
        | Family::SpunKnot { .. }
        | Family::SpunLink { .. }
        | Family::Curve
        | Family::Loop => (TUBE_MIN, 3.0),
        _ => (TUBE_MIN, 4.0),
    })
}

/// How many random shares a family's recipe uses.
pub(crate) fn share_count(family: &Family) -> usize {
    match family {
        Family::TorusShell | Family::T2xB2 | Family::KleinBottle => 3,
        Family::Handlebody { .. } | Family::S1xHandlebody { .. } => 3,
        Family::ConnectedSum { .. } => 3,
        Family::Tunnel { .. } => 2,
        Family::Split { parts } => *parts as usize,
        Family::Curve => 8,
        Family::Loop => 10,
        Family::BumpyShell | Family::BumpyS2xB2 => 13,
        _ => 1,
    }
}

/// The local solid of a single (non-scene, non-tentacled) family. `None` when the
/// parameters give no valid instance (a curve whose strands would touch).
pub(crate) fn make(
    family: &Family,
    dim: usize,
    tube: f64,
    grow: f64,
    shares: &Shares,
    gap: f64,
) -> Option<Solid> {
    let hole = tube + gap / 2.0;
    Some(match family {
        Family::Ball => Solid::Tube(vec![(Piece::Point(ORIGIN), tube + grow)]),
        Family::Handle => Solid::Tube(vec![(
            Piece::Circle {
                centre: ORIGIN,
                radius: hole + grow,
                u: axis(0),
                v: axis(1),
            },
            tube,
        )]),
        Family::Shell => Solid::Shell {
            piece: Piece::Point(ORIGIN),
            offset: hole + grow,
            radius: tube,
        },
        Family::TorusShell => match dim {
            2 => Solid::Shell {
                piece: Piece::Point(ORIGIN),
                offset: hole + grow,
                radius: tube,
            },
            3 => {
                let minor = hole + shares.get(0) * grow;
                let major = minor + hole + (1.0 - shares.get(0)) * grow;
                Solid::Shell {
                    piece: Piece::Circle {
                        centre: ORIGIN,
                        radius: major,
                        u: axis(0),
                        v: axis(1),
                    },
                    offset: minor,
                    radius: tube,
                }
            }
            _ => {
                // T3 = boundary of the offset-neighbourhood of a T2 in R^3 x {0}.
                let offset = hole + shares.get(0) * grow;
                let minor = offset + hole + shares.get(1) * grow;
                let major = minor + offset + hole + shares.get(2) * grow;
                Solid::Shell {
                    piece: Piece::Torus { major, minor },
                    offset,
                    radius: tube,
                }
            }
        },
        Family::Handlebody { genus } => Solid::Tube(circle_row(
            *genus,
            hole + shares.get(0) * grow / *genus as f64,
            bar_min(tube, gap) + shares.get(1) * grow / (*genus as f64),
            tube,
        )),
        Family::S2xB2 => Solid::Tube(vec![(
            Piece::Sphere {
                centre: ORIGIN,
                radius: hole + grow,
                axes: 3,
            },
            tube,
        )]),
        Family::BumpyShell => Solid::Tube(vec![(bumpy_sphere(dim, dim, hole, grow, shares), tube)]),
        Family::BumpyS2xB2 => Solid::Tube(vec![(bumpy_sphere(dim, 3, hole, grow, shares), tube)]),
        Family::T2xB2 | Family::KleinBottle => {
            let minor = hole + shares.get(0) * grow;
            let major = minor + hole + (1.0 - shares.get(0)) * grow;
            let piece = if matches!(family, Family::T2xB2) {
                Piece::Torus { major, minor }
            } else {
                Piece::Klein { major, minor }
            };
            Solid::Tube(vec![(piece, tube)])
        }
        Family::S1xHandlebody { j } => {
            let (piece, _) = spun_row(
                *j,
                hole + shares.get(0) * grow / *j as f64,
                bar_min(tube, gap) + shares.get(1) * grow / *j as f64,
                (tube, gap),
                shares.get(2) * grow,
                ORIGIN,
            );
            Solid::Tube(vec![(piece, tube)])
        }
        Family::ConnectedSum { g, h, i, j } => Solid::Tube(connected_sum(
            (*g, *h, *i, *j),
            dim,
            tube,
            grow,
            shares,
            gap,
        )),
        Family::Tunnel { intervals, .. } => {
            let keep = dim - *intervals as usize;
            let cycles = tunnel_cycles(family);
            let cross_section = if cycles > 0 {
                circle_row(
                    cycles,
                    hole + shares.get(0) * grow / cycles as f64,
                    bar_min(tube, gap) + (1.0 - shares.get(0)) * grow / cycles as f64,
                    tube,
                )
            } else {
                vec![(Piece::Point(ORIGIN), tube + grow)]
            };
            Solid::Tube(
                cross_section
                    .into_iter()
                    .map(|(inner, radius)| {
                        (
                            Piece::Prism {
                                inner: Box::new(inner),
                                keep,
                            },
                            radius,
                        )
                    })
                    .collect(),
            )
        }
        Family::Split { parts } => split_ball(*parts, dim, tube, grow, shares, gap),
        Family::Curve => curves::open_curve(dim, tube, grow, &shares.0, gap),
        Family::Loop => curves::wavy_loop(dim, tube, grow, &shares.0, gap),
        Family::Knot { knot } => curves::knot_solid(*knot, dim, tube, grow, gap)?,
        Family::TorusKnot { p, q } => curves::torus_knot_solid(*p, *q, dim, tube, grow, gap)?,
        Family::Link { link } => curves::link_solid(*link, dim, tube, grow, gap)?,
        Family::SpunKnot { knot } => curves::spun_knot_solid(*knot, tube, grow, gap)?,
        Family::SpunLink { link } => curves::spun_link_solid(*link, tube, grow, gap)?,
        // Composite families are built from their parts, and a Betti class from its
        // realisation, never by this function.
        Family::Tentacled { .. } | Family::Scene { .. } | Family::Betti { .. } => return None,
    })
}
