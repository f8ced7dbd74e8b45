//! Per-family geometry, labels and the generation driver.
//!
//! Each family is a recipe `make(r, grow)`: the solid with tube radius `r` whose free
//! lengths (hole sizes, bar lengths, scales) are their minima plus shares of `grow`. At
//! `grow = 0` and `r` at its minimum the recipe is the smallest valid instance, which is
//! what plan-time feasibility checks; drawing an instance picks a target bounding radius
//! between that minimum and the space available and then finds `r` and `grow` by
//! bisection, so size is random but never needs an open-ended retry.
//!
//! Minimum sizes: tubes have radius >= 2 voxels, shells half-thickness >= 1.5, and two parts
//! of one object that must stay apart (the two sides of a hole, two strands of a knot)
//! keep a gap of at least `INNER_GAP` = 2.5 between their surfaces. 2.5 exceeds the
//! diagonal of a 4D voxel (2), so the foreground never bridges a gap, and exceeds the L1
//! width a digital plane needs to separate background in 4D.

use crate::curves;
use crate::geometry::{add, axis, round6, uniform, uniform_int, Piece, Rotation, Solid, ORIGIN, P};
use crate::place::{
    cell_width, cells_per_axis, grid_cell, random_centre, rasterise, rasterise_unless_blocked,
    Occupancy, Placed, Region, CUBE_MARGIN,
};
use crate::{BinaryImage, Dim, Family, Generated, KnotKind, LinkKind, Mode, ShapeError};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Map, Value};

/// Smallest tube radius (labels note: tubes need a radius of at least 2 voxels).
pub(crate) const TUBE_MIN: f64 = 2.0;
/// Smallest half-thickness of a shell.
const SHELL_MIN: f64 = 1.5;
/// Smallest gap between surfaces of two parts of one object that must not touch.
pub(crate) const INNER_GAP: f64 = 2.5;
/// Random placements tried per object in one round.
const PLACEMENT_ATTEMPTS: usize = 40;
/// Rounds of random placement before the grid or canonical fallback.
const RANDOM_ROUNDS: usize = 6;

type Betti = (Vec<u64>, Option<Vec<u64>>);

fn unit(dim: usize, values: &[u64]) -> Vec<u64> {
    let mut out = vec![0; dim];
    out[..values.len()].copy_from_slice(values);
    out
}

fn unsupported(family: &Family, dim: Dim, mode: Mode, reason: &str) -> ShapeError {
    ShapeError::Unsupported {
        family: family.label(),
        dim: dim.get(),
        mode,
        reason: reason.into(),
    }
}

fn invalid(family: &Family, reason: &str) -> ShapeError {
    ShapeError::InvalidParameters {
        family: family.label(),
        reason: reason.into(),
    }
}

/// The label of one object in empty space (Z/2, and Q when it differs).
fn embed_betti(family: &Family, dim: Dim) -> Result<Betti, ShapeError> {
    let d = dim.get();
    let only_4d = |reason: &str| {
        if d == 4 {
            Ok(())
        } else {
            Err(unsupported(family, dim, Mode::Embed, reason))
        }
    };
    let not_2d = |reason: &str| {
        if d >= 3 {
            Ok(())
        } else {
            Err(unsupported(family, dim, Mode::Embed, reason))
        }
    };
    let z2 = match family {
        Family::Ball | Family::Curve => unit(d, &[1]),
        Family::Handle => unit(d, &[1, 1]),
        Family::Shell => {
            let mut b = unit(d, &[1]);
            b[d - 1] += 1;
            b
        }
        Family::TorusShell => {
            // The (d-1)-torus: b_k = binomial(d-1, k).
            match d {
                2 => vec![1, 1],
                3 => vec![1, 2, 1],
                _ => vec![1, 3, 3, 1],
            }
        }
        Family::Handlebody { genus } => {
            if *genus == 0 || *genus > 8 {
                return Err(invalid(family, "genus must be between 1 and 8"));
            }
            unit(d, &[1, *genus as u64])
        }
        Family::S2xB2 => {
            only_4d("S2xB2 is four-dimensional; in 3D use shell")?;
            vec![1, 0, 1, 0]
        }
        Family::T2xB2 => {
            only_4d("T2xB2 is four-dimensional; in 3D use torus_shell")?;
            vec![1, 2, 1, 0]
        }
        Family::S1xHandlebody { j } => {
            not_2d("spinning needs at least three dimensions")?;
            if *j == 0 || *j > 4 {
                return Err(invalid(family, "j must be between 1 and 4"));
            }
            unit(d, &[1, *j as u64 + 1, *j as u64])
        }
        Family::ConnectedSum { g, h, i, j } => {
            not_2d("the summands S2xB and S1x(...) need at least three dimensions")?;
            if g + h + i == 0 {
                return Err(invalid(family, "g + h + i must be positive"));
            }
            if *i > 0 && *j == 0 {
                return Err(invalid(family, "j must be positive when i is"));
            }
            if g + h + i > 6 || *j > 4 {
                return Err(invalid(family, "at most 6 summands and j at most 4"));
            }
            let (g, h, i, j) = (*g as u64, *h as u64, *i as u64, *j as u64);
            unit(d, &[1, g + i * (j + 1), h + i * j])
        }
        Family::Tunnel { .. } => {
            return Err(unsupported(
                family,
                dim,
                Mode::Embed,
                "a tunnel is a cavity that reaches the cube's boundary: carve mode only",
            ))
        }
        Family::Knot { .. } => {
            not_2d("closed curves are circles in 2D; use handle")?;
            unit(d, &[1, 1])
        }
        Family::TorusKnot { p, q } => {
            not_2d("closed curves are circles in 2D; use handle")?;
            if *p == 0 || *q == 0 || *p > 7 || *q > 7 {
                return Err(invalid(family, "p and q must be between 1 and 7"));
            }
            let c = gcd(*p, *q) as u64;
            unit(d, &[c, c])
        }
        Family::Link { link } => {
            not_2d("links need at least three dimensions")?;
            let c = link.components();
            unit(d, &[c, c])
        }
        Family::SpunKnot { .. } => {
            only_4d("spinning an arc about a plane needs four dimensions")?;
            vec![1, 0, 1, 0]
        }
        Family::SpunLink { link } => {
            only_4d("spinning a link about a plane needs four dimensions")?;
            let c = link.components();
            vec![c, 2 * c, c, 0]
        }
        Family::KleinBottle => {
            only_4d("the Klein bottle embeds in R^4, not in R^3")?;
            return Ok((vec![1, 2, 1, 0], Some(vec![1, 1, 0, 0])));
        }
        Family::Tentacled { object, tentacles } => {
            if *tentacles > 8 {
                return Err(invalid(family, "at most 8 tentacles"));
            }
            if !tentacle_host(object) {
                return Err(invalid(
                    family,
                    "tentacles attach to ball, handle, handlebody, curve, knot, torus_knot or link",
                ));
            }
            return embed_betti(object, dim);
        }
        Family::Betti { .. } => {
            return Err(invalid(
                family,
                "a class given by its Betti vector stands alone: it cannot be a scene object, \
                 carry tentacles or be repeated by `components` (write the whole vector instead)",
            ))
        }
        Family::Scene { objects } => {
            if objects.is_empty() || objects.len() > 64 {
                return Err(invalid(family, "a scene holds 1 to 64 objects"));
            }
            let mut z2 = vec![0; d];
            let mut q = vec![0; d];
            let mut differs = false;
            for object in objects {
                if matches!(object, Family::Scene { .. } | Family::Tunnel { .. }) {
                    return Err(invalid(family, "scenes cannot hold scenes or tunnels"));
                }
                let (a, b) = embed_betti(object, dim)?;
                differs |= b.is_some();
                let b = b.unwrap_or_else(|| a.clone());
                for k in 0..d {
                    z2[k] += a[k];
                    q[k] += b[k];
                }
            }
            return Ok((z2, differs.then_some(q)));
        }
    };
    Ok((z2, None))
}

fn tentacle_host(family: &Family) -> bool {
    matches!(
        family,
        Family::Ball
            | Family::Handle
            | Family::Handlebody { .. }
            | Family::Curve
            | Family::Knot { .. }
            | Family::TorusKnot { .. }
            | Family::Link { .. }
    )
}

pub(crate) fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The cube minus an object strictly inside it (labels note, duality).
fn dual(object: &[u64]) -> Vec<u64> {
    let d = object.len();
    let mut out = vec![0; d];
    out[0] = 1 + object[d - 1];
    for k in 1..d - 1 {
        out[k] = object[d - 1 - k];
    }
    out[d - 1] = object[0];
    out
}

/// Cycles of a tunnel's cross-section.
fn tunnel_cycles(family: &Family) -> u32 {
    match family {
        Family::Tunnel { circle, genus, .. } => (*genus).max(*circle as u32),
        _ => 0,
    }
}

/// The cube minus a tunnel I^a x K whose interval factors run face to face. The
/// complement of cube-minus-tunnel in S^d is a ball with I^a x K attached along
/// (boundary of I^a) x K, homotopy equivalent to S^a smash K_+, so Alexander duality gives
/// b0 = 1 + H^{d-1-a}(K) and b_k = H^{d-1-k-a}(K) for k >= 1.
fn tunnel_betti(
    family: &Family,
    dim: Dim,
    intervals: u32,
    cycles: u32,
) -> Result<Vec<u64>, ShapeError> {
    let d = dim.get() as i64;
    if cycles > 4 {
        return Err(invalid(
            family,
            "a tunnel cross-section has at most 4 cycles",
        ));
    }
    let a = intervals as i64;
    if !(1..=2).contains(&a) || d - a < 1 {
        return Err(invalid(
            family,
            "intervals must be 1 or 2 and below the dimension",
        ));
    }
    if cycles > 0 && d - a < 2 {
        return Err(unsupported(
            family,
            dim,
            Mode::Carve,
            "a circle cross-section needs at least two cross-section axes",
        ));
    }
    // Cohomology of the cross-section: a ball, or a thickened graph with `cycles` cycles.
    let h = |k: i64| -> u64 {
        match k {
            0 => 1,
            1 => cycles as u64,
            _ => 0,
        }
    };
    let mut out = vec![0; d as usize];
    out[0] = 1 + h(d - 1 - a);
    for k in 1..d {
        out[k as usize] = h(d - 1 - k - a);
    }
    Ok(out)
}

pub(crate) fn expected(family: &Family, dim: Dim, mode: Mode) -> Result<Betti, ShapeError> {
    if let Family::Betti { betti } = family {
        let realised = crate::betti_class::realise(betti, dim, mode)?;
        let label =
            expected(&realised, dim, mode).map_err(|err| realised_as(err, family, &realised))?;
        if label.0 != *betti {
            return Err(invalid(
                family,
                &format!(
                    "realised as {} whose label is {:?} (a bug: please report)",
                    realised.label(),
                    label.0
                ),
            ));
        }
        return Ok(label);
    }
    if let Family::Tunnel { intervals, .. } = family {
        return match mode {
            Mode::Carve => Ok((
                tunnel_betti(family, dim, *intervals, tunnel_cycles(family))?,
                None,
            )),
            Mode::Embed => embed_betti(family, dim),
        };
    }
    let (z2, q) = embed_betti(family, dim)?;
    Ok(match mode {
        Mode::Embed => (z2, q),
        Mode::Carve => (dual(&z2), q.map(|q| dual(&q))),
    })
}

/// An error about the construction of a Betti class, told in terms of the class.
fn realised_as(err: ShapeError, class: &Family, realised: &Family) -> ShapeError {
    let name = format!("{} (realised as {})", class.label(), realised.label());
    match err {
        ShapeError::Unsupported {
            dim, mode, reason, ..
        } => ShapeError::Unsupported {
            family: name,
            dim,
            mode,
            reason,
        },
        ShapeError::InvalidParameters { reason, .. } => ShapeError::InvalidParameters {
            family: name,
            reason,
        },
        ShapeError::DoesNotFit {
            dim,
            side,
            mode,
            reason,
            ..
        } => ShapeError::DoesNotFit {
            family: name,
            dim,
            side,
            mode,
            reason,
        },
    }
}

// ---------------------------------------------------------------------------------------
// Recipes

/// Random choices of a recipe that do not change its minimum size.
struct Shares(Vec<f64>);

impl Shares {
    fn draw(count: usize, rng: &mut ChaCha8Rng) -> Shares {
        let raw: Vec<f64> = (0..count).map(|_| uniform(rng, 0.2, 1.0)).collect();
        let total: f64 = raw.iter().sum();
        Shares(raw.iter().map(|x| x / total).collect())
    }

    fn minimal(count: usize) -> Shares {
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
fn bar_min(tube: f64) -> f64 {
    2.0 * tube + INNER_GAP
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
fn spun_row(j: u32, radius: f64, bar: f64, tube: f64, axis_gap: f64, centre: P) -> (Piece, f64) {
    let half = circle_row_half(j, radius, bar);
    let shift = tube + INNER_GAP / 2.0 + axis_gap + half;
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
        other @ (Piece::Torus { .. } | Piece::Klein { .. }) => other,
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
) -> Vec<(Piece, f64)> {
    let n = (g + h + i) as f64;
    // Shares: 0 = hole sizes, 1 = bars, 2 = spun offsets.
    let radius = tube + INNER_GAP / 2.0 + shares.get(0) * grow / n;
    let bar = bar_min(tube) + shares.get(1) * grow / n.max(1.0);
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
                let (_, reach) = spun_row(j, radius, bar_min(tube), tube, axis_gap, ORIGIN);
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
            _ => spun_row(j, radius, bar_min(tube), tube, axis_gap, centre).0,
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

/// The tube radius range of a family: `(minimum, cap)`.
fn tube_range(family: &Family) -> (f64, f64) {
    match family {
        Family::Ball => (TUBE_MIN, TUBE_MIN),
        Family::Shell | Family::TorusShell => (SHELL_MIN, 3.0),
        Family::Tunnel { .. } if tunnel_cycles(family) == 0 => (TUBE_MIN, TUBE_MIN),
        Family::Knot { .. }
        | Family::TorusKnot { .. }
        | Family::Link { .. }
        | Family::SpunKnot { .. }
        | Family::SpunLink { .. }
        | Family::Curve => (TUBE_MIN, 3.0),
        _ => (TUBE_MIN, 4.0),
    }
}

/// How many random shares a family's recipe uses.
fn share_count(family: &Family) -> usize {
    match family {
        Family::TorusShell | Family::T2xB2 | Family::KleinBottle => 3,
        Family::Handlebody { .. } | Family::S1xHandlebody { .. } => 3,
        Family::ConnectedSum { .. } => 3,
        Family::Tunnel { .. } => 2,
        Family::Curve => 8,
        _ => 1,
    }
}

/// The local solid of a single (non-scene, non-tentacled) family. `None` when the
/// parameters give no valid instance (a curve whose strands would touch).
fn make(family: &Family, dim: usize, tube: f64, grow: f64, shares: &Shares) -> Option<Solid> {
    let hole = tube + INNER_GAP / 2.0;
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
            bar_min(tube) + shares.get(1) * grow / (*genus as f64),
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
                bar_min(tube) + shares.get(1) * grow / *j as f64,
                tube,
                shares.get(2) * grow,
                ORIGIN,
            );
            Solid::Tube(vec![(piece, tube)])
        }
        Family::ConnectedSum { g, h, i, j } => {
            Solid::Tube(connected_sum((*g, *h, *i, *j), dim, tube, grow, shares))
        }
        Family::Tunnel { intervals, .. } => {
            let keep = dim - *intervals as usize;
            let cycles = tunnel_cycles(family);
            let cross_section = if cycles > 0 {
                circle_row(
                    cycles,
                    hole + shares.get(0) * grow / cycles as f64,
                    bar_min(tube) + (1.0 - shares.get(0)) * grow / cycles as f64,
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
        Family::Curve => curves::open_curve(dim, tube, grow, &shares.0),
        Family::Knot { knot } => curves::knot_solid(*knot, dim, tube, grow)?,
        Family::TorusKnot { p, q } => curves::torus_knot_solid(*p, *q, dim, tube, grow)?,
        Family::Link { link } => curves::link_solid(*link, dim, tube, grow)?,
        Family::SpunKnot { knot } => curves::spun_knot_solid(*knot, tube, grow)?,
        Family::SpunLink { link } => curves::spun_link_solid(*link, tube, grow)?,
        // Composite families are built from their parts, and a Betti class from its
        // realisation, never by this function.
        Family::Tentacled { .. } | Family::Scene { .. } | Family::Betti { .. } => return None,
    })
}

/// Room a tentacle needs beyond its host's extent: the gap and two steps past the host's
/// tube (`curves::add_tentacles`) plus its own radius, each tentacle radius at most
/// TUBE_MIN + 0.5.
const TENTACLE_ROOM: f64 = 2.0 * (TUBE_MIN + 0.5) + INNER_GAP + 0.5 + 2.5;

/// The smallest bounding radius of one object of the family (tentacles need none extra:
/// they are added only where space remains; see [`draw_target`]).
fn min_extent(family: &Family, dim: usize) -> Option<f64> {
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
fn draw_target(object: &Family, minimum: f64, upper: f64, rng: &mut ChaCha8Rng) -> f64 {
    let lo = match object {
        Family::Tentacled { .. } if minimum + TENTACLE_ROOM <= upper => minimum + TENTACLE_ROOM,
        _ => minimum,
    };
    uniform(rng, lo, upper)
}

/// A random instance with bounding radius at most `target` (which must be at least the
/// minimum). Returns the solid and its parameters.
fn build(family: &Family, dim: usize, target: f64, rng: &mut ChaCha8Rng) -> Option<(Solid, Value)> {
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

// ---------------------------------------------------------------------------------------
// Feasibility and generation

fn objects_of(family: &Family) -> Vec<Family> {
    match family {
        Family::Scene { objects } => objects.clone(),
        other => vec![other.clone()],
    }
}

pub(crate) fn check_fits(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
) -> Result<(), ShapeError> {
    check_sizes(family, dim, side, mode, true)
}

/// Every object must fit the image on its own; with `packing`, all of them together
/// must fit too (by the grid, or by the canonical layout). `generate` skips the packing
/// search: its own placement ends in the same canonical layout when everything else
/// fails, so the answer is the same and the search is not run twice.
fn check_sizes(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    packing: bool,
) -> Result<(), ShapeError> {
    expected(family, dim, mode)?;
    if let Family::Betti { betti } = family {
        let realised = crate::betti_class::realise(betti, dim, mode)?;
        return check_sizes(&realised, dim, side, mode, packing)
            .map_err(|err| realised_as(err, family, &realised));
    }
    let d = dim.get();
    let does_not_fit = |reason: String| ShapeError::DoesNotFit {
        family: family.label(),
        dim: d,
        side,
        mode,
        reason,
    };
    if side < 8 {
        return Err(does_not_fit("sides below 8 hold no object".into()));
    }
    let region = Region::for_mode(side, mode);
    if let Family::Tunnel { .. } = family {
        let need = min_extent(family, d).unwrap_or(f64::INFINITY);
        let budget = region.budget();
        if need > budget {
            return Err(does_not_fit(format!(
                "the cross-section needs radius {need:.2}, the cube offers {budget:.2}"
            )));
        }
        return Ok(());
    }
    let objects = objects_of(family);
    let minima = object_minima(&objects, d, &does_not_fit)?;
    if let Some((label, need)) = objects
        .iter()
        .zip(&minima)
        .find(|(_, &need)| need > region.budget())
        .map(|(o, &need)| (o.label(), need))
    {
        return Err(does_not_fit(format!(
            "{label} needs a bounding radius of {need:.2} voxels, the image offers {:.2}",
            region.budget()
        )));
    }
    if !packing
        || grid_fits(&minima, d, region)
        || canonical_layout(&objects, &minima, d, side, region).is_some()
    {
        return Ok(());
    }
    Err(does_not_fit(format!(
        "{} objects with bounding radii {:?} could not be packed with {} background voxels between them",
        objects.len(),
        minima.iter().map(|&m| round6(m)).collect::<Vec<_>>(),
        crate::place::GAP
    )))
}

fn object_minima(
    objects: &[Family],
    dim: usize,
    does_not_fit: &dyn Fn(String) -> ShapeError,
) -> Result<Vec<f64>, ShapeError> {
    objects
        .iter()
        .map(|o| {
            min_extent(o, dim)
                .ok_or_else(|| does_not_fit(format!("{} has no valid instance", o.label())))
        })
        .collect()
}

/// Whether one object per grid cell fits, every object at its minimum size.
fn grid_fits(minima: &[f64], dim: usize, region: Region) -> bool {
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
fn canonical_layout(
    objects: &[Family],
    minima: &[f64],
    dim: usize,
    side: usize,
    region: Region,
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
            dim,
            side,
            region,
            &mut rng,
            true,
        )
    })
}

fn knot_type_of(family: &Family, dim: usize) -> Option<String> {
    let suffix = if dim == 4 { "_x_interval" } else { "" };
    match family {
        Family::Knot { knot } => Some(format!("{}{}", knot.name(), suffix)),
        Family::TorusKnot { p, q } => {
            let c = gcd(*p, *q);
            let name = if c == 1 && (*p == 1 || *q == 1) {
                "unknot".to_string()
            } else if c == 1 {
                format!("torus_knot({p},{q})")
            } else {
                format!("torus_link({p},{q})")
            };
            Some(format!("{name}{suffix}"))
        }
        Family::Link { link } => Some(format!("{}{}", link.name(), suffix)),
        Family::SpunKnot { knot } => Some(format!("spun_{}", knot.name())),
        Family::SpunLink { link } => Some(format!("spun_{}", link.name())),
        Family::Tentacled { object, .. } => knot_type_of(object, dim),
        _ => None,
    }
}

/// Local axes that may rotate: all of them, except the interval axes of a tunnel.
fn free_axes(family: &Family, dim: usize) -> Vec<usize> {
    match family {
        Family::Tunnel { intervals, .. } => (0..dim - *intervals as usize).collect(),
        _ => (0..dim).collect(),
    }
}

pub(crate) fn generate(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    rng: &mut ChaCha8Rng,
) -> Result<Generated, ShapeError> {
    if let Family::Betti { betti } = family {
        // The realisation is generated as itself; its record says which class it serves.
        let realised = crate::betti_class::realise(betti, dim, mode)?;
        let mut generated = generate(&realised, dim, side, mode, rng)
            .map_err(|err| realised_as(err, family, &realised))?;
        if let Value::Object(map) = &mut generated.construction {
            map.insert("class".into(), json!(family.label()));
        }
        generated.construction = sort_keys(generated.construction);
        return Ok(generated);
    }
    check_sizes(family, dim, side, mode, false)?;
    let (betti, betti_rational) = expected(family, dim, mode)?;
    let d = dim.get();
    let region = Region::for_mode(side, mode);
    let objects = objects_of(family);
    let (placed, strategy) = if let Family::Tunnel { .. } = family {
        (vec![place_tunnel(family, d, side, region, rng)?], "tunnel")
    } else {
        let canvas = Canvas {
            dim: d,
            side,
            mode,
            region,
        };
        place_objects(family, &objects, canvas, rng)?
    };
    let mut image = BinaryImage::cube(dim, side).expect("check_fits rejects sides below 8");
    // Carve mode clears object voxels from the cube; a tunnel's voxels beyond the cube
    // are background already.
    let value = match mode {
        Mode::Embed => 1u8,
        Mode::Carve => {
            fill_cube(&mut image, d, side);
            0u8
        }
    };
    let mut records = Vec::new();
    for (object, placement, params, voxels) in &placed {
        for &v in voxels {
            image.data_mut()[v] = value;
        }
        records.push(sorted(vec![
            ("family", json!(object.label())),
            ("params", params.clone()),
            ("placement", placement.describe(d)),
            ("voxels", json!(voxels.len())),
        ]));
    }
    let knot_types: Vec<String> = objects.iter().filter_map(|o| knot_type_of(o, d)).collect();
    let knot_type = if knot_types.is_empty() {
        "none".to_string()
    } else {
        knot_types.join("+")
    };
    let components = objects
        .iter()
        .map(|o| embed_betti(o, dim).map(|(b, _)| b[0]).unwrap_or(0))
        .sum::<u64>();
    let components = if let Family::Tunnel { .. } = family {
        1
    } else {
        components
    };
    let construction = sorted(vec![
        ("family", json!(family.label())),
        ("dim", json!(d)),
        ("side", json!(side)),
        ("mode", json!(mode.to_string())),
        ("objects", Value::Array(records)),
        // How the layout was found: "random" (the normal case), "grid" or "canonical"
        // (fallbacks that keep a feasible request from failing), or "tunnel".
        ("placement", json!(strategy)),
        ("betti_field", json!("z2")),
        ("gap_voxels", json!(crate::place::GAP)),
        (
            "cube_margin",
            json!(if mode == Mode::Carve { CUBE_MARGIN } else { 0 }),
        ),
    ]);
    Ok(Generated {
        image,
        betti,
        betti_rational,
        construction: sort_keys(construction),
        knot_type,
        components,
    })
}

/// Rebuilds every object of a JSON value with its keys inserted in sorted order: the
/// record is then the same bytes whether or not some crate in the build switches on
/// serde_json's `preserve_order` (which makes `json!` keep the written order).
fn sort_keys(value: Value) -> Value {
    match value {
        Value::Object(map) => {
            let mut entries: Vec<(String, Value)> = map.into_iter().collect();
            entries.sort_by(|a, b| a.0.cmp(&b.0));
            let mut out = Map::new();
            for (k, v) in entries {
                out.insert(k, sort_keys(v));
            }
            Value::Object(out)
        }
        Value::Array(items) => Value::Array(items.into_iter().map(sort_keys).collect()),
        other => other,
    }
}

/// A JSON object with keys inserted in sorted order, so the record is the same whether or
/// not serde_json keeps insertion order.
fn sorted(mut entries: Vec<(&str, Value)>) -> Value {
    entries.sort_by(|a, b| a.0.cmp(b.0));
    let mut map = Map::new();
    for (k, v) in entries {
        map.insert(k.to_string(), v);
    }
    Value::Object(map)
}

fn fill_cube(image: &mut BinaryImage, dim: usize, side: usize) {
    let lo = CUBE_MARGIN as usize;
    let hi = side - 1 - CUBE_MARGIN as usize;
    // Row by row along the last (contiguous) axis.
    for start in (0..image.len()).step_by(side) {
        let c = image.coords(start);
        if (0..dim - 1).all(|k| c[k] >= lo && c[k] <= hi) {
            image.data_mut()[start + lo..=start + hi].fill(1);
        }
    }
}

type PlacedObject = (Family, Placed, Value, Vec<usize>);

fn place_tunnel(
    family: &Family,
    dim: usize,
    side: usize,
    region: Region,
    rng: &mut ChaCha8Rng,
) -> Result<PlacedObject, ShapeError> {
    let Family::Tunnel { intervals, .. } = family else {
        unreachable!("place_tunnel is only called for tunnels")
    };
    let a = *intervals as usize;
    let budget = region.budget();
    let minimum = min_extent(family, dim).unwrap_or(f64::INFINITY);
    let target = uniform(rng, minimum, budget);
    let (solid, params) =
        build(family, dim, target, rng).ok_or_else(|| ShapeError::DoesNotFit {
            family: family.label(),
            dim,
            side,
            mode: Mode::Carve,
            reason: "no cross-section fits".into(),
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
/// object at its minimum size (the canonical layout). `None` if some object found no
/// place within `PLACEMENT_ATTEMPTS` tries.
fn place_random(
    objects: &[Family],
    minima: &[f64],
    dim: usize,
    side: usize,
    region: Region,
    rng: &mut ChaCha8Rng,
    at_minimum: bool,
) -> Option<Vec<PlacedObject>> {
    let count = objects.len();
    let budget = region.budget();
    // Each object may use a share of the room that shrinks with the number of objects,
    // so several of them are likely to fit.
    let share = if count == 1 {
        budget
    } else {
        (budget / libm::pow(count as f64, 1.0 / dim as f64) * 1.2).min(budget)
    };
    let mut occupancy = Occupancy::new(dim, side);
    let mut out = Vec::new();
    for (object, &minimum) in objects.iter().zip(minima) {
        if minimum > budget {
            return None;
        }
        let mut done = false;
        for attempt in 0..PLACEMENT_ATTEMPTS {
            // Later attempts draw smaller objects, which fit into smaller gaps.
            let shrink = 1.0 - attempt as f64 / PLACEMENT_ATTEMPTS as f64;
            let upper = minimum + (share.max(minimum) - minimum) * shrink;
            let target = if at_minimum {
                minimum
            } else {
                draw_target(object, minimum, upper, rng)
            };
            let Some((solid, params)) = build(object, dim, target, rng) else {
                continue;
            };
            let rotation = Rotation::random(&free_axes(object, dim), rng);
            let Some(centre) = random_centre(dim, region.lo, region.hi, solid.extent(), rng) else {
                continue;
            };
            let placed = Placed {
                solid,
                rotation,
                centre,
                through_axes: Vec::new(),
            };
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
            if count > 1 {
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
struct Canvas {
    dim: usize,
    side: usize,
    mode: Mode,
    region: Region,
}

fn place_objects(
    family: &Family,
    objects: &[Family],
    canvas: Canvas,
    rng: &mut ChaCha8Rng,
) -> Result<(Vec<PlacedObject>, &'static str), ShapeError> {
    let Canvas {
        dim,
        side,
        mode,
        region,
    } = canvas;
    let count = objects.len();
    let minima: Vec<f64> = objects
        .iter()
        .map(|o| min_extent(o, dim).unwrap_or(f64::INFINITY))
        .collect();
    // Largest first: big objects find room in the empty image, small ones fit into the
    // gaps left. Several rounds, the later ones at minimum sizes, before the fallbacks,
    // so that fallbacks (which are less diverse) stay rare.
    let mut order: Vec<usize> = (0..count).collect();
    order.sort_by(|&a, &b| minima[b].total_cmp(&minima[a]).then(a.cmp(&b)));
    let sorted_objects: Vec<Family> = order.iter().map(|&k| objects[k].clone()).collect();
    let sorted_minima: Vec<f64> = order.iter().map(|&k| minima[k]).collect();
    for round in 0..RANDOM_ROUNDS {
        let at_minimum = round >= RANDOM_ROUNDS / 2;
        if let Some(out) = place_random(
            &sorted_objects,
            &sorted_minima,
            dim,
            side,
            region,
            rng,
            at_minimum,
        ) {
            return Ok((out, "random"));
        }
    }
    let fits_grid = grid_fits(&minima, dim, region);
    if !fits_grid {
        return canonical_layout(objects, &minima, dim, side, region)
            .map(|out| (out, "canonical"))
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
        let target = draw_target(object, minimum, cell_budget.max(minimum), rng);
        let (solid, params) = build(object, dim, target, rng)
            .or_else(|| build(object, dim, minimum, rng))
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
        let placed = Placed {
            solid,
            rotation,
            centre,
            through_axes: Vec::new(),
        };
        // The centre keeps the bounding ball inside the cell; clipping to the region
        // only guards the image border.
        let voxels = rasterise(&placed, dim, side, region.lo, region.hi);
        out.push((object.clone(), placed, params, voxels));
    }
    Ok((out, "grid"))
}

/// The paper's 3D morphology example (its seed image): a curve, two connected circles, a
/// link and a trefoil knot, some with tentacles; b0 = 5, b1 = 5.
pub fn paper_scene_family() -> Family {
    Family::Scene {
        objects: vec![
            Family::Tentacled {
                object: Box::new(Family::Curve),
                tentacles: 1,
            },
            Family::Tentacled {
                object: Box::new(Family::Handlebody { genus: 2 }),
                tentacles: 2,
            },
            Family::Link {
                link: LinkKind::Hopf,
            },
            Family::Tentacled {
                object: Box::new(Family::Knot {
                    knot: KnotKind::Trefoil,
                }),
                tentacles: 1,
            },
        ],
    }
}

/// One random instance of [`paper_scene_family`] in a 3D image of side `side`, embed mode.
pub fn paper_scene_3d(side: usize, rng: &mut ChaCha8Rng) -> Result<Generated, ShapeError> {
    generate(&paper_scene_family(), Dim::Three, side, Mode::Embed, rng)
}
