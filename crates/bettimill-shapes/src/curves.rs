//! Closed and open curves: knots, links, tentacles and free curves, as polylines.
//!
//! A knot or link is a set of closed polylines sampled from a parametric curve (libm
//! sin/cos) at unit scale. A tube of radius r around it has the curve's homotopy type when
//! (1) the curve bends with radius at least r + INNER_GAP/2 and (2) any two points that are
//! far apart along the curve (arc length at least pi/2 times the needed gap) are at least
//! 2r + INNER_GAP apart in space, and different components are that far apart everywhere.
//! Both conditions scale linearly with the curve, so the smallest admissible scale is
//! `sigma * (2r + INNER_GAP)` for a constant `sigma` per curve, computed once by a sweep
//! over "forbidden scale intervals" of all point pairs and cached.

use crate::geometry::{add, dot, gcd, norm, scale, sub, uniform, Piece, Solid, P, TUBE_MIN};
use crate::{KnotKind, LinkKind};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::sync::{Mutex, OnceLock};

/// A smooth open curve: the graph of gentle sine waves over the x0-axis, thickened. A
/// graph never meets itself, and bounding its curvature by 1 / (tube + INNER_GAP / 2)
/// keeps the tube from folding onto itself, so the solid is a ball up to homotopy.
/// `shares` (which sum to 1) supply its random amplitudes and phases.
pub(crate) fn open_curve(dim: usize, tube: f64, grow: f64, shares: &[f64], gap: f64) -> Solid {
    let count = shares.len() as f64;
    let random = |k: usize| shares[k % shares.len()] * count;
    let half = tube + grow * (0.5 + 0.25 * random(0));
    let max_curvature = 1.0 / (tube + gap / 2.0);
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
    Solid::Tube(vec![(Piece::polyline(points, false), tube)])
}

/// Points of a [`wavy_loop`]'s closed curve: about one per [`LOOP_SPACING`] voxels of its
/// length (bounded from above), within these bounds (the clearance check compares every
/// pair of them, and the sizing builds an instance hundreds of times).
const LOOP_SAMPLES: (f64, f64) = (48.0, 240.0);
/// Voxels of a loop's length between two of its points.
const LOOP_SPACING: f64 = 0.75;

/// A thickened closed curve that is not round: a circle of radius `tube + INNER_GAP / 2 +
/// grow` (the handle's) stretched along one axis, with lobes in its plane and waves out of
/// it, amplitudes and phases from `shares`. The waves scale with `grow`, so the smallest
/// instance is the handle's circle whatever the shares. The curve's shadow on its plane is
/// star-shaped about the centre (the radius stays positive and the angle turns one way),
/// so it never crosses itself and in 3D it is unknotted: the solid is S1 x B(d-1). When a
/// draw would bring two far-apart stretches of the tube within INNER_GAP (or bend it
/// tighter than the tube), the waves are halved until it does not; without waves it is the
/// handle's circle, which is clear.
pub(crate) fn wavy_loop(dim: usize, tube: f64, grow: f64, shares: &[f64], gap: f64) -> Solid {
    let count = shares.len() as f64;
    let random = |k: usize| shares[k % shares.len()] * count;
    let radius = tube + gap / 2.0 + grow;
    // Lobes in the plane (2 or 3 of them), a squeeze of one in-plane axis, and one wave per
    // further axis (1 to 3 periods around the loop).
    // Each choice reads its own share: 0-3 the lobes and the squeeze, 4-5 the waves'
    // heights, 6-7 their periods, 8-9 their phases.
    let lobes = 2.0 + (libm::floor(random(1) * 7.0) % 2.0);
    let lobe = (grow * 0.35 * random(0)).min(0.45 * radius);
    let squeeze = (grow / radius) * 0.4 * (random(2) / 2.5).min(1.0);
    let phase = |k: usize| 2.0 * PI * random(k) / count;
    let mut wave = [0.0; 4];
    let mut periods = [0.0; 4];
    for k in 2..dim {
        wave[k] = grow * 0.3 * random(k + 2);
        periods[k] = 1.0 + (libm::floor(random(k + 4) * 7.0) % 3.0);
    }
    // The length of the curve at most: the lobed circle's, and 4 heights a period of each
    // wave.
    let length = 2.0 * PI * (radius + lobe) * (1.0 + lobes * lobe / radius)
        + (2..dim).map(|k| 4.0 * wave[k] * periods[k]).sum::<f64>();
    let samples = (length / LOOP_SPACING)
        .ceil()
        .clamp(LOOP_SAMPLES.0, LOOP_SAMPLES.1) as usize;
    let round = lobe == 0.0 && squeeze == 0.0 && wave.iter().all(|&h| h == 0.0);
    let mut damp = 1.0;
    loop {
        let points = closed_curve_of(samples, |t| {
            let r = radius + damp * lobe * libm::sin(lobes * t + phase(3));
            let mut p = [
                r * libm::cos(t),
                r * (1.0 - damp * squeeze) * libm::sin(t),
                0.0,
                0.0,
            ];
            for k in 2..dim {
                p[k] = damp * wave[k] * libm::sin(periods[k] * t + phase(k + 6));
            }
            p
        });
        // The round circle is the handle's, clear by construction.
        if damp == 0.0 || round || clear_at(&points, tube, gap) {
            return Solid::Tube(vec![(Piece::polyline(points, true), tube)]);
        }
        // Eight halvings leave waves well under a voxel; then the plain circle.
        damp = if damp < 0.01 { 0.0 } else { damp * 0.5 };
    }
}

/// Whether a tube of radius `tube` around the closed polyline `points` (at its own scale)
/// meets the two conditions of the module documentation.
fn clear_at(points: &[P], tube: f64, gap: f64) -> bool {
    let gap = need(tube, gap);
    let n = points.len();
    let bends = (0..n).all(|k| {
        circumradius(points[(k + n - 1) % n], points[k], points[(k + 1) % n]) >= gap / 2.0
    });
    if !bends {
        return false;
    }
    let (arc, total) = arc_lengths(points);
    (0..n).all(|i| {
        (i + 1..n).all(|j| {
            let along = (arc[j] - arc[i]).min(total - (arc[j] - arc[i]));
            along < PI / 2.0 * gap || norm(sub(points[i], points[j])) >= gap
        })
    })
}

/// Samples per closed component at unit scale.
const SAMPLES: usize = 360;

/// Closed curves at unit scale, centred on their bounding box.
#[derive(Clone, Debug)]
struct CurveSet {
    components: Vec<Vec<P>>,
}

fn closed_curve(f: impl Fn(f64) -> P) -> Vec<P> {
    closed_curve_of(SAMPLES, f)
}

fn closed_curve_of(samples: usize, f: impl Fn(f64) -> P) -> Vec<P> {
    (0..samples)
        .map(|k| f(2.0 * PI * k as f64 / samples as f64))
        .collect()
}

fn centred(components: Vec<Vec<P>>) -> CurveSet {
    let mut lo = [f64::INFINITY; 4];
    let mut hi = [f64::NEG_INFINITY; 4];
    for p in components.iter().flatten() {
        for k in 0..4 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let mid = scale(add(lo, hi), 0.5);
    CurveSet {
        components: components
            .into_iter()
            .map(|c| c.into_iter().map(|p| sub(p, mid)).collect())
            .collect(),
    }
}

/// Torus knot or link T(p, q) on the torus with radii 2 and 1: the components of
/// {q theta - p psi in 2 pi Z}, one per residue m < gcd(p, q), shifted by 2 pi m / q.
fn torus_components(p: u32, q: u32) -> Vec<Vec<P>> {
    let c = gcd(p, q);
    let (pp, qq) = ((p / c) as f64, (q / c) as f64);
    (0..c)
        .map(|m| {
            let shift = 2.0 * PI * m as f64 / q as f64;
            closed_curve(|t| {
                let theta = pp * t + shift;
                let psi = qq * t;
                let radial = 2.0 + libm::cos(psi);
                [
                    radial * libm::cos(theta),
                    radial * libm::sin(theta),
                    libm::sin(psi),
                    0.0,
                ]
            })
        })
        .collect()
}

fn knot_components(knot: KnotKind) -> Vec<Vec<P>> {
    match knot {
        KnotKind::Unknot => vec![closed_curve(|t| [libm::cos(t), libm::sin(t), 0.0, 0.0])],
        KnotKind::Trefoil => vec![closed_curve(|t| {
            [
                libm::sin(t) + 2.0 * libm::sin(2.0 * t),
                libm::cos(t) - 2.0 * libm::cos(2.0 * t),
                -libm::sin(3.0 * t),
                0.0,
            ]
        })],
        KnotKind::FigureEight => vec![closed_curve(|t| {
            let radial = 2.0 + libm::cos(2.0 * t);
            [
                radial * libm::cos(3.0 * t),
                radial * libm::sin(3.0 * t),
                libm::sin(4.0 * t),
                0.0,
            ]
        })],
        KnotKind::Cinquefoil => torus_components(2, 5),
    }
}

fn link_components(link: LinkKind) -> Vec<Vec<P>> {
    match link {
        LinkKind::Hopf => torus_components(2, 2),
        LinkKind::Solomon => torus_components(4, 2),
        // Three mutually perpendicular ellipses: each passes twice through the next one's
        // disk (linking number 0) and none through the previous one's.
        LinkKind::Borromean => {
            let (a, b) = (1.0, 0.55);
            vec![
                closed_curve(|t| [a * libm::cos(t), b * libm::sin(t), 0.0, 0.0]),
                closed_curve(|t| [0.0, a * libm::cos(t), b * libm::sin(t), 0.0]),
                closed_curve(|t| [b * libm::sin(t), 0.0, a * libm::cos(t), 0.0]),
            ]
        }
        // A figure-eight curve (lemniscate of Gerono, its crossing resolved by height) and
        // a second component whose shadow is a circle around the crossing and whose
        // height H sin(2s) makes all five crossings alternate: the alternating
        // 5-crossing diagram of the Whitehead link (L5a1). The proportions were chosen by
        // a small grid search for the smallest admissible size.
        LinkKind::Whitehead => vec![
            closed_curve(|t| {
                [
                    1.6 * libm::cos(t),
                    1.6 * libm::sin(t) * libm::cos(t),
                    0.3 * libm::sin(t),
                    0.0,
                ]
            }),
            closed_curve(|s| {
                [
                    1.1 * libm::cos(s),
                    1.1 * libm::sin(s),
                    0.9 * libm::sin(2.0 * s),
                    0.0,
                ]
            }),
        ],
    }
}

/// Cumulative arc length along a closed polyline, and its total.
fn arc_lengths(points: &[P]) -> (Vec<f64>, f64) {
    let mut out = Vec::with_capacity(points.len());
    let mut total = 0.0;
    for k in 0..points.len() {
        out.push(total);
        total += norm(sub(points[(k + 1) % points.len()], points[k]));
    }
    (out, total)
}

/// Radius of the circle through three points (infinite when collinear).
fn circumradius(a: P, b: P, c: P) -> f64 {
    let u = sub(a, b);
    let v = sub(c, b);
    let w = sub(c, a);
    let cross2 = dot(u, u) * dot(v, v) - dot(u, v) * dot(u, v);
    if cross2 <= 1e-18 {
        return f64::INFINITY;
    }
    norm(u) * norm(v) * norm(w) / (2.0 * cross2.sqrt())
}

/// The smallest scale at which the unit curves are clear for a needed gap of 1 (see the
/// module docs).
fn sigma_of(set: &CurveSet) -> f64 {
    let mut start: f64 = 0.0;
    let mut forbidden: Vec<(f64, f64)> = Vec::new();
    for (ci, comp) in set.components.iter().enumerate() {
        let n = comp.len();
        for k in 0..n {
            let r = circumradius(comp[(k + n - 1) % n], comp[k], comp[(k + 1) % n]);
            start = start.max(0.5 / r);
        }
        let (arc, total) = arc_lengths(comp);
        for i in 0..n {
            for j in i + 1..n {
                let along = (arc[j] - arc[i]).min(total - (arc[j] - arc[i]));
                let apart = norm(sub(comp[i], comp[j]));
                let from = PI / (2.0 * along);
                let to = 1.0 / apart.max(1e-12);
                if to > from {
                    forbidden.push((from, to));
                }
            }
        }
        for other in &set.components[ci + 1..] {
            for &p in comp {
                for &q in other {
                    start = start.max(1.0 / norm(sub(p, q)).max(1e-12));
                }
            }
        }
    }
    forbidden.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut s = start;
    for (from, to) in forbidden {
        if from > s {
            break;
        }
        if to > s {
            s = to;
        }
    }
    s
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum CurveKey {
    Knot(KnotKind),
    Torus(u32, u32),
    Link(LinkKind),
}

fn curve_set(key: CurveKey) -> CurveSet {
    centred(match key {
        CurveKey::Knot(k) => knot_components(k),
        CurveKey::Torus(p, q) => torus_components(p, q),
        CurveKey::Link(l) => link_components(l),
    })
}

/// The curves and their sigma; sigma is cached because recipes are evaluated many times
/// while a size is fitted. The cache holds pure functions of the key, so it cannot make
/// results depend on call order.
fn curves_with_sigma(key: CurveKey) -> (CurveSet, f64) {
    static CACHE: OnceLock<Mutex<BTreeMap<CurveKey, f64>>> = OnceLock::new();
    let set = curve_set(key);
    let cache = CACHE.get_or_init(|| Mutex::new(BTreeMap::new()));
    let cached = cache.lock().ok().and_then(|m| m.get(&key).copied());
    let sigma = match cached {
        Some(s) => s,
        None => {
            let s = sigma_of(&set);
            if let Ok(mut m) = cache.lock() {
                m.insert(key, s);
            }
            s
        }
    };
    (set, sigma)
}

fn need(tube: f64, gap: f64) -> f64 {
    2.0 * tube + gap
}

/// The curves scaled to the smallest admissible size plus `grow` voxels of extent.
fn scaled(key: CurveKey, tube: f64, grow: f64, gap: f64) -> Vec<Vec<P>> {
    let (set, sigma) = curves_with_sigma(key);
    let reach = set
        .components
        .iter()
        .flatten()
        .map(|&p| norm(p))
        .fold(0.0, f64::max);
    let factor = sigma * need(tube, gap) + grow / reach;
    set.components
        .into_iter()
        .map(|c| c.into_iter().map(|p| scale(p, factor)).collect())
        .collect()
}

fn tube_of(components: Vec<Vec<P>>, tube: f64) -> Solid {
    Solid::Tube(
        components
            .into_iter()
            .map(|points| (Piece::polyline(points, true), tube))
            .collect(),
    )
}

/// A knotted solid torus (3D) or the knot thickened in 4D, which is homeomorphic to
/// knot x B2 x I.
pub(crate) fn knot_solid(
    knot: KnotKind,
    _dim: usize,
    tube: f64,
    grow: f64,
    gap: f64,
) -> Option<Solid> {
    Some(tube_of(scaled(CurveKey::Knot(knot), tube, grow, gap), tube))
}

pub(crate) fn torus_knot_solid(
    p: u32,
    q: u32,
    _dim: usize,
    tube: f64,
    grow: f64,
    gap: f64,
) -> Option<Solid> {
    Some(tube_of(
        scaled(CurveKey::Torus(p, q), tube, grow, gap),
        tube,
    ))
}

pub(crate) fn link_solid(
    link: LinkKind,
    _dim: usize,
    tube: f64,
    grow: f64,
    gap: f64,
) -> Option<Solid> {
    Some(tube_of(scaled(CurveKey::Link(link), tube, grow, gap), tube))
}

/// Moves curves into the meridian half-space x0 >= tube + INNER_GAP / 2 (so the spun
/// copies stay apart across the axis) and spins them: each component becomes a torus.
pub(crate) fn spun_link_solid(link: LinkKind, tube: f64, grow: f64, gap: f64) -> Option<Solid> {
    let components = scaled(CurveKey::Link(link), tube, grow, gap);
    let low = components
        .iter()
        .flatten()
        .map(|p| p[0])
        .fold(f64::INFINITY, f64::min);
    let shift = tube + gap / 2.0 - low;
    let inner: Vec<Piece> = components
        .into_iter()
        .map(|c| {
            Piece::polyline(
                c.into_iter()
                    .map(|p| add(p, [shift, 0.0, 0.0, 0.0]))
                    .collect(),
                true,
            )
        })
        .collect();
    Some(Solid::Tube(vec![(
        Piece::Spun {
            centre: [0.0; 4],
            inner,
        },
        tube,
    )]))
}

/// Artin's spun knot: cut the knot open at its leftmost point, run both ends straight
/// to the plane x0 = 0, and spin the resulting knotted arc: a knotted 2-sphere. The cut
/// widens until the two straight ends are a full gap apart and clear of the rest of the
/// arc; if no cut works at the smallest scale, the scale grows.
pub(crate) fn spun_knot_solid(knot: KnotKind, tube: f64, grow: f64, gap: f64) -> Option<Solid> {
    // How far apart two strands' axes stay.
    let apart = need(tube, gap);
    for attempt in 0..24 {
        let extra = grow + attempt as f64 * 0.5 * tube;
        let comp = scaled(CurveKey::Knot(knot), tube, extra, gap).remove(0);
        let n = comp.len();
        let leftmost = (0..n)
            .min_by(|&a, &b| comp[a][0].total_cmp(&comp[b][0]))
            .unwrap_or(0);
        for window in 1..n / 4 {
            let first = (leftmost + n - window) % n;
            let last = (leftmost + window) % n;
            // The kept arc runs from `last` forward to `first`.
            let kept: Vec<P> = (0..=(n - 2 * window))
                .map(|k| comp[(last + k) % n])
                .collect();
            let ends = [comp[last], comp[first]];
            let lateral = |a: P, b: P| {
                let d = sub(a, b);
                (d[1] * d[1] + d[2] * d[2] + d[3] * d[3]).sqrt()
            };
            if lateral(ends[0], ends[1]) < apart {
                continue;
            }
            let low = kept.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
            let shift = tube + gap / 2.0 - low;
            let kept: Vec<P> = kept
                .into_iter()
                .map(|p| add(p, [shift, 0.0, 0.0, 0.0]))
                .collect();
            let feet: Vec<P> = kept
                .iter()
                .take(1)
                .chain(kept.last())
                .map(|&p| [0.0, p[1], p[2], p[3]])
                .collect();
            // Each straight end must keep the gap to every arc point that is far from
            // its own foot along the arc.
            let clear = [(0usize, 0usize), (1, kept.len() - 1)]
                .iter()
                .all(|&(e, root)| {
                    let seg_a = feet[e];
                    let seg_b = kept[root];
                    kept.iter().enumerate().all(|(k, &p)| {
                        let along = arc_index_distance(k, root, &kept);
                        along < PI * apart / 2.0
                            || crate::geometry::segment_distance(p, seg_a, seg_b) >= apart
                    })
                });
            if !clear {
                continue;
            }
            let mut points = vec![feet[0]];
            points.extend(kept.iter().copied());
            points.push(feet[1]);
            return Some(Solid::Tube(vec![(
                Piece::Spun {
                    centre: [0.0; 4],
                    inner: vec![Piece::polyline(points, false)],
                },
                tube,
            )]));
        }
    }
    None
}

/// Arc length along an open polyline between vertices `a` and `b`.
fn arc_index_distance(a: usize, b: usize, points: &[P]) -> f64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    (lo..hi).map(|k| norm(sub(points[k + 1], points[k]))).sum()
}

/// Attaches up to `count` tentacles (thickened random curves) to a tube-like solid,
/// staying within `target` of the origin. A tentacle starts at the skeleton point s that
/// is extreme in a random direction u and only moves with a positive component along
/// u, so every later point q satisfies |q - x| >= (q - s).u for every skeleton point x:
/// once it is a gap beyond the host's tubes it can never come back to the host, and it
/// cannot meet itself. Other hosts' parts and earlier tentacles are checked explicitly
/// (two tentacles keep a gap everywhere outside the host).
/// Returns the solid and how many tentacles were placed; the topology is unchanged
/// because each tentacle is attached along one contractible blob.
pub(crate) fn add_tentacles(
    solid: Solid,
    dim: usize,
    count: u32,
    target: f64,
    gap: f64,
    rng: &mut ChaCha8Rng,
) -> (Solid, u32) {
    let Solid::Tube(mut parts) = solid else {
        return (solid, 0);
    };
    let samples: Vec<(P, f64)> = parts
        .iter()
        .flat_map(|(piece, r)| piece.sample_points().into_iter().map(move |p| (p, *r)))
        .collect();
    if samples.is_empty() {
        return (Solid::Tube(parts), 0);
    }
    let host_radius = parts.iter().map(|(_, r)| *r).fold(0.0, f64::max);
    let host_thinnest = parts.iter().map(|(_, r)| *r).fold(f64::INFINITY, f64::min);
    // A tentacle point this close to its root has its whole ball inside the host's tube
    // there (tentacle radii are at most TUBE_MIN + 0.5).
    let inside_host = |q: P, root: P| norm(sub(q, root)) + TUBE_MIN + 0.5 <= host_thinnest;
    let mut tentacles: Vec<(Vec<P>, P)> = Vec::new();
    let mut placed = 0;
    for _ in 0..count {
        for _attempt in 0..24 {
            let radius = uniform(rng, TUBE_MIN, TUBE_MIN + 0.5);
            let direction = random_unit(dim, rng);
            let (root, _) = samples
                .iter()
                .copied()
                .max_by(|a, b| dot(a.0, direction).total_cmp(&dot(b.0, direction)))
                .unwrap_or(samples[0]);
            let clearance = host_radius + radius + gap + 0.5;
            let length = uniform(rng, clearance + 3.0, clearance + 16.0);
            let mut points = vec![root];
            let mut heading = direction;
            let mut here = root;
            let mut travelled = 0.0;
            while travelled < length {
                if travelled >= clearance {
                    // Wander, but keep moving outward along the tentacle's direction.
                    let kick = random_unit(dim, rng);
                    let mut next = add(heading, scale(kick, 0.35));
                    let along = dot(next, direction);
                    if along < 0.5 {
                        next = add(next, scale(direction, 0.5 - along));
                    }
                    heading = scale(next, 1.0 / norm(next));
                }
                let step = add(here, heading);
                if norm(step) + radius > target {
                    break;
                }
                here = step;
                travelled += 1.0;
                points.push(here);
            }
            if travelled < clearance + 2.0 {
                continue;
            }
            // Near its root a tentacle is inside the host; past it, keep the gap to every
            // host sample that is not near the root, and to earlier tentacles.
            let far_from_root = |q: P, s: P| norm(sub(q, s)) >= clearance;
            let host_ok = points.iter().all(|&q| {
                samples
                    .iter()
                    .all(|&(x, r)| !far_from_root(x, root) || norm(sub(q, x)) >= r + radius + gap)
            });
            // Two tentacles may only come close where both are still inside the host:
            // meeting outside it, even near their roots, closes a loop through the host
            // (seen in 3 of 500 3D handles with three tentacles), and two tubes from one
            // root at a shallow angle can trap background between them once digitised
            // (3 of 500 balls when that was allowed).
            let others_ok = tentacles.iter().all(|(other, other_root)| {
                points.iter().all(|&q| {
                    other.iter().all(|&x| {
                        (inside_host(q, root) && inside_host(x, *other_root))
                            || norm(sub(q, x)) >= 2.0 * (TUBE_MIN + 0.5) + gap
                    })
                })
            });
            if !host_ok || !others_ok {
                continue;
            }
            parts.push((Piece::polyline(points.clone(), false), radius));
            tentacles.push((points, root));
            placed += 1;
            break;
        }
    }
    (Solid::Tube(parts), placed)
}

fn random_unit(dim: usize, rng: &mut ChaCha8Rng) -> P {
    loop {
        let mut v = [0.0; 4];
        for slot in v.iter_mut().take(dim) {
            *slot = uniform(rng, -1.0, 1.0);
        }
        let n = norm(v);
        if n > 0.1 && n <= 1.0 {
            return scale(v, 1.0 / n);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::INNER_GAP;

    /// Linking number of two closed polylines by the discrete Gauss integral.
    fn linking_number(a: &[P], b: &[P]) -> f64 {
        let mut total = 0.0;
        for i in 0..a.len() {
            let da = sub(a[(i + 1) % a.len()], a[i]);
            let ma = scale(add(a[(i + 1) % a.len()], a[i]), 0.5);
            for j in 0..b.len() {
                let db = sub(b[(j + 1) % b.len()], b[j]);
                let mb = scale(add(b[(j + 1) % b.len()], b[j]), 0.5);
                let r = sub(ma, mb);
                let cross = [
                    da[1] * db[2] - da[2] * db[1],
                    da[2] * db[0] - da[0] * db[2],
                    da[0] * db[1] - da[1] * db[0],
                    0.0,
                ];
                total += dot(r, cross) / norm(r).powi(3);
            }
        }
        total / (4.0 * PI)
    }

    #[test]
    fn links_have_the_expected_linking_numbers() {
        let lk = |link| {
            let c = link_components(link);
            linking_number(&c[0], &c[1]).abs()
        };
        assert!((lk(LinkKind::Hopf) - 1.0).abs() < 0.05);
        assert!((lk(LinkKind::Solomon) - 2.0).abs() < 0.05);
        assert!(lk(LinkKind::Whitehead) < 0.05);
        let b = link_components(LinkKind::Borromean);
        for (i, j) in [(0, 1), (1, 2), (0, 2)] {
            assert!(linking_number(&b[i], &b[j]).abs() < 0.05);
        }
    }

    #[test]
    fn scaled_curves_keep_their_strands_apart() {
        for key in [
            CurveKey::Knot(KnotKind::Trefoil),
            CurveKey::Knot(KnotKind::FigureEight),
            CurveKey::Link(LinkKind::Borromean),
            CurveKey::Link(LinkKind::Whitehead),
        ] {
            let (set, sigma) = curves_with_sigma(key);
            assert!(sigma.is_finite() && sigma > 0.0, "{key:?}");
            // At the admissible scale different components keep the full gap.
            let comps = scaled(key, 2.0, 0.0, INNER_GAP);
            for (i, a) in comps.iter().enumerate() {
                for b in &comps[i + 1..] {
                    for &p in a {
                        for &q in b {
                            assert!(norm(sub(p, q)) >= need(2.0, INNER_GAP) - 1e-9);
                        }
                    }
                }
            }
            assert_eq!(set.components.len(), comps.len());
        }
    }
}
