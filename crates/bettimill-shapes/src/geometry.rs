//! Continuous geometry: skeletons and their distance functions.
//!
//! Every object is described in its own local frame as a *skeleton* (points, segments,
//! circles, spheres, polylines, surfaces) thickened by a radius, or as a thin shell around
//! such a thickening. The homotopy type of a thickening equals that of its skeleton as long
//! as the radius stays below the skeleton's feature size, which is what makes the Betti
//! numbers analytic. Points always carry four coordinates; lower-dimensional objects leave
//! the trailing ones at zero, so one code path serves 2D, 3D and 4D.
//!
//! Only `+ - * /`, `f64::sqrt` and the `libm` crate are used, so every platform computes the
//! same bits and rasterises the same voxels.

use bettimill_grid::Dim;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

/// A point or vector in up to four dimensions (unused axes are zero).
pub(crate) type P = [f64; 4];

pub(crate) const ORIGIN: P = [0.0; 4];

// Minimum sizes, shared by every construction: tubes have radius >= 2 voxels, shells
// half-thickness >= 1.5, and two parts of one object that must stay apart (the two sides
// of a hole, two strands of a knot) keep a gap of at least `INNER_GAP` = 2.5 between their
// surfaces. 2.5 exceeds the diagonal of a 4D voxel (2), so the foreground never bridges a
// gap, and exceeds the L1 width a digital plane needs to separate background in 4D.

/// Smallest tube radius (labels note: tubes need a radius of at least 2 voxels).
pub(crate) const TUBE_MIN: f64 = 2.0;
/// Smallest half-thickness of a shell.
pub(crate) const SHELL_MIN: f64 = 1.5;
/// Smallest gap between surfaces of two parts of one object that must not touch.
pub(crate) const INNER_GAP: f64 = bettimill_types::MIN_INNER_GAP;

/// Background voxels kept between two objects, at least, and between a cavity and the
/// solid cube's boundary.
pub(crate) const GAP: i64 = 2;

/// The narrowest gap between two parts (a scene's objects, a split ball's pieces) under a
/// floor whose inner gap is `inner_gap`: half of it, rounded up, and never below [`GAP`].
/// Along a 4D diagonal a dilation step covers two voxels' width, so parts this far apart
/// merge after as many dilations as it takes to close the narrowest hole an object may
/// have; a manifest that widens its holes (`inner_gap`) widens the gaps between parts
/// alike. The usual inner gap (2.5) gives [`GAP`].
pub(crate) fn narrowest_gap(inner_gap: f64) -> i64 {
    (libm::ceil(inner_gap / 2.0) as i64).max(GAP)
}

/// The thinnest tube (or shell half-thickness, or ball radius) a construction may have:
/// [`TubeFloor::USUAL`] (the labels note's 2 voxels), or thicker so that a max-pooled
/// downscaled copy keeps the construction's topology ([`TubeFloor::for_copies`]). Where a
/// family's own range starts higher, its range is kept.
///
/// It also carries the narrowest gap between two parts of one object that must stay
/// apart (across a hole, inside a shell, between strands): `INNER_GAP` = 2.5 voxels
/// unless a manifest asks for wider ([`TubeFloor::with_gap`]). The two floors travel
/// together because every construction is sized from both.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TubeFloor {
    tube: f64,
    gap: f64,
}

impl Default for TubeFloor {
    fn default() -> TubeFloor {
        TubeFloor::USUAL
    }
}

impl TubeFloor {
    /// Tubes of radius at least 2 voxels (shells 1.5): every construction's minimum, but
    /// for small instances sized for a volume (`sizing`'s thin tubes).
    pub const USUAL: TubeFloor = TubeFloor {
        tube: TUBE_MIN,
        gap: INNER_GAP,
    };

    /// The floor for a sample whose copies are max-pooled by `factor` (a block of
    /// `factor^d` voxels is foreground when any of its voxels is): a cavity survives in the
    /// copy only where whole blocks fit inside it. A block's voxel centres lie within
    /// `(factor - 1) sqrt(d) / 2` of its centre, and block centres within
    /// `factor sqrt(d) / 2` of any point, so a tube of radius `(2 factor - 1) sqrt(d) / 2`
    /// holds a whole block near every point of its skeleton (3 voxels for a 4D sample
    /// pooled by 2). That aims at, but does not prove, a copy with the same topology: the
    /// copies' labels are computed, and on the 4D mixed 128 preset every 64-side copy
    /// measured kept it. Never below [`TubeFloor::USUAL`].
    pub fn for_copies(dim: Dim, factor: usize) -> TubeFloor {
        let d = dim.get() as f64;
        let radius = (2.0 * factor as f64 - 1.0) * libm::sqrt(d) / 2.0;
        TubeFloor {
            tube: radius.max(TUBE_MIN),
            gap: INNER_GAP,
        }
    }

    /// This floor with gaps at least `gap` voxels wide (never below `INNER_GAP`): holes,
    /// the insides of shells and the space between strands are built that wide, so that
    /// they survive dilations a narrower gap would not.
    pub fn with_gap(self, gap: f64) -> TubeFloor {
        TubeFloor {
            gap: gap.max(INNER_GAP),
            ..self
        }
    }

    /// This floor with the usual tubes and the same gaps: what a stratum falls back to
    /// where thicker tubes do not fit.
    pub fn thin(self) -> TubeFloor {
        TubeFloor {
            tube: TUBE_MIN,
            ..self
        }
    }

    /// Whether tubes are raised above the usual 2 voxels.
    pub fn thickens(self) -> bool {
        self.tube > TUBE_MIN
    }

    /// Whether gaps are raised above the usual 2.5 voxels (a manifest's `inner_gap`).
    pub fn widens(self) -> bool {
        self.gap > INNER_GAP
    }

    /// The narrowest gap between parts of one object that must stay apart, in voxels.
    pub fn gap(self) -> f64 {
        self.gap
    }

    /// The least tube radius, in voxels.
    pub fn radius(self) -> f64 {
        self.tube
    }

    /// A family's `(minimum, cap)` tube range raised to this floor. The usual floor leaves
    /// every range as it is (shells keep their 1.5-voxel half-thickness).
    pub(crate) fn raise(self, (minimum, cap): (f64, f64)) -> (f64, f64) {
        if !self.thickens() {
            return (minimum, cap);
        }
        (minimum.max(self.tube), cap.max(self.tube))
    }
}

/// Greatest common divisor (the number of components of the torus link T(a, b)).
pub(crate) fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

pub(crate) fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
}

pub(crate) fn add(a: P, b: P) -> P {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]]
}

pub(crate) fn scale(a: P, s: f64) -> P {
    [a[0] * s, a[1] * s, a[2] * s, a[3] * s]
}

pub(crate) fn dot(a: P, b: P) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

pub(crate) fn norm(a: P) -> f64 {
    dot(a, a).sqrt()
}

pub(crate) fn axis(i: usize) -> P {
    let mut p = ORIGIN;
    p[i] = 1.0;
    p
}

/// Uniform in `[lo, hi]`; written out (instead of `gen_range`) so the mapping from random
/// bits to values is ours and cannot change with a `rand` release.
pub(crate) fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    if hi <= lo {
        return lo;
    }
    let u: f64 = rng.gen::<f64>();
    lo + (hi - lo) * u
}

/// Uniform integer in `lo..=hi`.
pub(crate) fn uniform_int(rng: &mut ChaCha8Rng, lo: u64, hi: u64) -> u64 {
    if hi <= lo {
        return lo;
    }
    lo + rng.gen::<u64>() % (hi - lo + 1)
}

/// Rounds for the construction record, so it stays readable; the geometry itself keeps
/// full precision.
pub(crate) fn round6(x: f64) -> f64 {
    libm::round(x * 1e6) / 1e6
}

pub(crate) fn point_json(p: P, dim: usize) -> Value {
    Value::Array(p[..dim].iter().map(|&x| json!(round6(x))).collect())
}

/// One piece of a skeleton, in the object's local frame.
#[derive(Clone, Debug)]
pub(crate) enum Piece {
    /// A single point.
    Point(P),
    /// A straight segment.
    Segment(P, P),
    /// A circle of `radius` around `centre` in the plane spanned by orthonormal `u`, `v`.
    Circle { centre: P, radius: f64, u: P, v: P },
    /// The round sphere of `radius` around `centre` inside the span of the first
    /// `axes` coordinate axes (axes = 3 in 4D is a 2-sphere; axes = d is the full
    /// (d-1)-sphere).
    Sphere { centre: P, radius: f64, axes: usize },
    /// A star-shaped sphere inside the span of the first `axes` axes: in the direction u
    /// its radius is `radius + sum a (u . v)^2` over `stretches` (along orthogonal
    /// directions) plus `sum a max(0, u . v)^4` over `lumps` (never below `radius`), and it
    /// is lifted along the next axis by `bend.1 (u . bend.0)^2`. Its "distance" is measured
    /// in the half-plane of the point's direction: sqrt((|q| - r(u))^2 + (q_axes -
    /// h(u))^2 + the rest^2). A tube around it is a disk bundle over the sphere of
    /// directions, so it has the round sphere's tube's topology while `radius` exceeds the
    /// tube.
    Bumpy {
        centre: P,
        radius: f64,
        axes: usize,
        stretches: Vec<(P, f64)>,
        lumps: Vec<(P, f64)>,
        bend: (P, f64),
    },
    /// A polyline through `points`, closed when `closed`. Build it with
    /// [`Piece::polyline`], which also fills `chunks`: bounding balls of runs of
    /// `CHUNK` segments, so that most segments are skipped when testing a point.
    Polyline {
        points: Vec<P>,
        closed: bool,
        chunks: Vec<(P, f64)>,
        bound: (P, f64),
    },
    /// The torus of revolution in the first three axes: the circle of radius `minor`
    /// around the circle of radius `major` in the (x0, x1)-plane.
    Torus { major: f64, minor: f64 },
    /// The Klein bottle embedded in R^4 as
    /// `((R + a cos v) cos u, (R + a cos v) sin u, a sin v cos(u/2), a sin v sin(u/2))`.
    /// Its distance is measured inside the 3D half-space at the point's own angle u,
    /// which is not the Euclidean distance but gives a neighbourhood that is a fibre
    /// bundle over the circle with a thickened circle as fibre and a reflection as
    /// monodromy: homotopy equivalent to the Klein bottle.
    Klein { major: f64, minor: f64 },
    /// The inner skeleton rotated about the plane x0 = x1 = 0 (moved to `centre`): a
    /// point q = p - centre is evaluated at `(sqrt(q0^2 + q1^2), q2, q3)`. For an inner
    /// set in the half-space x0 > 0 this is the product with a circle; an arc whose ends
    /// lie on x0 = 0 becomes a 2-sphere.
    Spun { centre: P, inner: Vec<Piece> },
    /// The inner piece with the axes from `keep` on ignored: a cylinder over it (the
    /// cross-section of a tunnel).
    Prism { inner: Box<Piece>, keep: usize },
    /// The inner piece's tube stretched by `stretch` >= 1 along the axes from `from` on
    /// (about the origin): a point is evaluated with those coordinates divided by
    /// `stretch`. Build it with [`Piece::flattened`], which squeezes the skeleton so that it
    /// stays where it was. A tube of radius r around it is the
    /// inner piece's tube under a linear map, so it has the same topology, and its
    /// cross-section is r across the plane of the inner piece and `stretch` r away from
    /// it: volume goes where it does not narrow the piece's holes.
    Flat {
        inner: Box<Piece>,
        stretch: f64,
        from: usize,
    },
}

/// Grid steps over a quarter turn in [`Piece::reach`] of a flattened piece.
const REACH_STEPS: usize = 256;

/// Segments per bounding ball of a polyline.
const CHUNK: usize = 12;

/// `p` with its coordinates from `from` on divided by `stretch`: a point of a flattened
/// piece's tube in the frame of its inner piece.
fn squeezed(mut p: P, stretch: f64, from: usize) -> P {
    for x in p.iter_mut().skip(from) {
        *x /= stretch;
    }
    p
}

fn norm_of(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

impl Piece {
    /// `piece` with its tube stretched by `stretch` along the axes from `from` on, about
    /// the origin: the inner piece is the given one with those coordinates divided by
    /// `stretch`, so the skeleton itself stays where it was and only the tube around it
    /// widens there. `None` for pieces other than points, segments, polylines, and
    /// circles and round or bumpy spheres that lie in the unstretched axes.
    pub(crate) fn flattened(piece: Piece, stretch: f64, from: usize) -> Option<Piece> {
        let squeeze = |p: P| squeezed(p, stretch, from);
        let inner = match piece {
            Piece::Point(c) => Piece::Point(squeeze(c)),
            Piece::Segment(a, b) => Piece::Segment(squeeze(a), squeeze(b)),
            Piece::Polyline { points, closed, .. } => {
                Piece::polyline(points.into_iter().map(squeeze).collect(), closed)
            }
            Piece::Circle {
                centre,
                radius,
                u,
                v,
            } if [u, v].iter().all(|q| q[from..].iter().all(|&x| x == 0.0)) => Piece::Circle {
                centre: squeeze(centre),
                radius,
                u,
                v,
            },
            Piece::Sphere {
                centre,
                radius,
                axes,
            } if axes <= from => Piece::Sphere {
                centre: squeeze(centre),
                radius,
                axes,
            },
            // Its bumps lie in its own axes; its lift along the next one, a stretched axis
            // when `axes == from`, is squeezed with it, so the skeleton stays where it was.
            mut bumpy @ Piece::Bumpy { axes, .. } if axes <= from => {
                if let Piece::Bumpy { centre, bend, .. } = &mut bumpy {
                    *centre = squeeze(*centre);
                    if axes == from {
                        bend.1 /= stretch;
                    }
                }
                bumpy
            }
            _ => return None,
        };
        Some(Piece::Flat {
            inner: Box::new(inner),
            stretch,
            from,
        })
    }

    /// A polyline piece with its chunk bounding balls.
    pub(crate) fn polyline(points: Vec<P>, closed: bool) -> Piece {
        let n = points.len();
        let segments = if closed { n } else { n.saturating_sub(1) };
        let mut chunks = Vec::new();
        let mut start = 0;
        while start < segments.max(1) {
            let end = (start + CHUNK).min(segments.max(1));
            // Vertices start..=end (wrapping) bound the segments start..end.
            let vertices: Vec<P> = (start..=end).map(|k| points[k % n]).collect();
            let mut centre = ORIGIN;
            for &v in &vertices {
                centre = add(centre, v);
            }
            centre = scale(centre, 1.0 / vertices.len() as f64);
            let radius = vertices
                .iter()
                .map(|&v| norm(sub(v, centre)))
                .fold(0.0, f64::max);
            chunks.push((centre, radius));
            start = end;
        }
        let mut centre = ORIGIN;
        for &v in &points {
            centre = add(centre, v);
        }
        centre = scale(centre, 1.0 / n.max(1) as f64);
        let radius = points
            .iter()
            .map(|&v| norm(sub(v, centre)))
            .fold(0.0, f64::max);
        Piece::Polyline {
            points,
            closed,
            chunks,
            bound: (centre, radius),
        }
    }

    /// A ball `(centre, radius)` containing the piece; `None` for prisms, which are
    /// unbounded along their free axes.
    pub(crate) fn bounds(&self) -> Option<(P, f64)> {
        match self {
            Piece::Point(c) => Some((*c, 0.0)),
            Piece::Segment(a, b) => Some((scale(add(*a, *b), 0.5), norm(sub(*b, *a)) / 2.0)),
            Piece::Circle { centre, radius, .. } | Piece::Sphere { centre, radius, .. } => {
                Some((*centre, *radius))
            }
            Piece::Polyline { bound, .. } => Some(*bound),
            Piece::Bumpy { centre, .. } => Some((*centre, self.extent() - norm(*centre))),
            Piece::Torus { major, minor } | Piece::Klein { major, minor } => {
                Some((ORIGIN, major + minor))
            }
            Piece::Spun { centre, inner } => {
                Some((*centre, inner.iter().map(Piece::extent).fold(0.0, f64::max)))
            }
            // A tube around it reaches farther than the radius the caller adds.
            Piece::Prism { .. } | Piece::Flat { .. } => None,
        }
    }

    /// Whether `p` is within `r` of the piece: [`Piece::distance`] `<= r`, with early
    /// exits for polylines.
    pub(crate) fn within(&self, p: P, r: f64) -> bool {
        match self {
            Piece::Polyline {
                points,
                closed,
                chunks,
                bound,
            } => {
                if norm(sub(p, bound.0)) - bound.1 > r {
                    return false;
                }
                let n = points.len();
                if n == 1 {
                    return norm(sub(p, points[0])) <= r;
                }
                let segments = if *closed { n } else { n - 1 };
                for (index, &(centre, radius)) in chunks.iter().enumerate() {
                    if norm(sub(p, centre)) - radius > r {
                        continue;
                    }
                    let start = index * CHUNK;
                    let end = (start + CHUNK).min(segments);
                    for k in start..end {
                        if segment_distance(p, points[k], points[(k + 1) % n]) <= r {
                            return true;
                        }
                    }
                }
                false
            }
            Piece::Spun { centre, inner } => {
                let q = sub(p, *centre);
                let rho = (q[0] * q[0] + q[1] * q[1]).sqrt();
                let meridian = [rho, q[2], q[3], 0.0];
                inner.iter().any(|piece| piece.within(meridian, r))
            }
            Piece::Flat {
                inner,
                stretch,
                from,
            } => inner.within(squeezed(p, *stretch, *from), r),
            other => other.distance(p) <= r,
        }
    }

    /// Distance from `p` to the piece (see [`Piece::Klein`] for the one exception).
    pub(crate) fn distance(&self, p: P) -> f64 {
        match self {
            Piece::Point(c) => norm(sub(p, *c)),
            Piece::Segment(a, b) => segment_distance(p, *a, *b),
            Piece::Circle {
                centre,
                radius,
                u,
                v,
            } => {
                let q = sub(p, *centre);
                let a = dot(q, *u);
                let b = dot(q, *v);
                let in_plane = (a * a + b * b).sqrt();
                let perp2 = (dot(q, q) - a * a - b * b).max(0.0);
                let radial = in_plane - radius;
                (radial * radial + perp2).sqrt()
            }
            Piece::Sphere {
                centre,
                radius,
                axes,
            } => {
                let q = sub(p, *centre);
                let mut inside = 0.0;
                let mut outside = 0.0;
                for (k, &x) in q.iter().enumerate() {
                    if k < *axes {
                        inside += x * x;
                    } else {
                        outside += x * x;
                    }
                }
                let radial = inside.sqrt() - radius;
                (radial * radial + outside).sqrt()
            }
            Piece::Bumpy {
                centre,
                radius,
                axes,
                stretches,
                lumps,
                bend,
            } => {
                let q = sub(p, *centre);
                let rho = q[..*axes].iter().map(|x| x * x).sum::<f64>().sqrt();
                // The centre's direction is arbitrary; any one gives a distance of at
                // least `radius` there, far outside every tube.
                let mut u = [0.0; 4];
                if rho > 0.0 {
                    for k in 0..*axes {
                        u[k] = q[k] / rho;
                    }
                } else {
                    u[0] = 1.0;
                }
                let mut r = *radius;
                for &(v, a) in stretches {
                    let c = dot(u, v);
                    r += a * c * c;
                }
                for &(v, a) in lumps {
                    let c = dot(u, v).max(0.0);
                    r += a * c * c * c * c;
                }
                let lift = {
                    let c = dot(u, bend.0);
                    bend.1 * c * c
                };
                let radial = rho - r;
                let mut rest = 0.0;
                for (k, &x) in q.iter().enumerate().skip(*axes) {
                    let x = if k == *axes { x - lift } else { x };
                    rest += x * x;
                }
                (radial * radial + rest).sqrt()
            }
            Piece::Polyline { points, closed, .. } => {
                let n = points.len();
                let segments = if *closed { n } else { n.saturating_sub(1) };
                let mut best = f64::INFINITY;
                for k in 0..segments {
                    let d = segment_distance(p, points[k], points[(k + 1) % n]);
                    if d < best {
                        best = d;
                    }
                }
                if n == 1 {
                    best = norm(sub(p, points[0]));
                }
                best
            }
            Piece::Torus { major, minor } => {
                let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
                let to_core = ((rho - major) * (rho - major) + p[2] * p[2]).sqrt();
                let radial = to_core - minor;
                (radial * radial + p[3] * p[3]).sqrt()
            }
            Piece::Klein { major, minor } => {
                let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
                let angle = libm::atan2(p[1], p[0]);
                let n0 = libm::cos(angle / 2.0);
                let n1 = libm::sin(angle / 2.0);
                // Coordinates in the 3D half-space at this angle: radial offset, the
                // component along the turning normal, and the one across it.
                let a = rho - major;
                let b = p[2] * n0 + p[3] * n1;
                let c = -p[2] * n1 + p[3] * n0;
                let radial = (a * a + b * b).sqrt() - minor;
                (radial * radial + c * c).sqrt()
            }
            Piece::Spun { centre, inner } => {
                let q = sub(p, *centre);
                let rho = (q[0] * q[0] + q[1] * q[1]).sqrt();
                let meridian = [rho, q[2], q[3], 0.0];
                inner
                    .iter()
                    .map(|piece| piece.distance(meridian))
                    .fold(f64::INFINITY, f64::min)
            }
            Piece::Prism { inner, keep } => {
                let mut q = p;
                for slot in q.iter_mut().skip(*keep) {
                    *slot = 0.0;
                }
                inner.distance(q)
            }
            Piece::Flat {
                inner,
                stretch,
                from,
            } => inner.distance(squeezed(p, *stretch, *from)),
        }
    }

    /// An upper bound of `|x|` over a tube of radius `r` around the piece.
    pub(crate) fn reach(&self, r: f64) -> f64 {
        match self {
            // A point c + S(r n) with c in the unstretched span and n a unit vector whose
            // unstretched part has length k: |.|^2 <= (|c| + r k)^2 + stretch^2 r^2 (1 - k^2),
            // largest at k = |c| / (r (stretch^2 - 1)) when that is below 1.
            Piece::Flat {
                inner,
                stretch,
                from,
            } => {
                // A point S(c + r n), c on the inner piece, n a unit vector whose
                // unstretched part has length cos t: its norm squared is at most
                // (a + r cos t)^2 + stretch^2 (b + r sin t)^2, with a and b the largest
                // norms of the inner piece's unstretched and stretched parts. The maximum
                // over t is taken on a grid, plus the most the function can rise between
                // two grid points.
                let (a, b) = inner.split_extent(*from);
                let s2 = stretch * stretch;
                let g = |t: f64| {
                    let u = a + r * libm::cos(t);
                    let f = b + r * libm::sin(t);
                    u * u + s2 * f * f
                };
                let step = std::f64::consts::FRAC_PI_2 / REACH_STEPS as f64;
                let top = (0..=REACH_STEPS)
                    .map(|k| g(k as f64 * step))
                    .fold(0.0, f64::max);
                let slope = 2.0 * r * ((a + r) + s2 * (b + r));
                (top + slope * step / 2.0).sqrt()
            }
            other => other.extent() + r,
        }
    }

    /// Upper bounds of the norms of the piece's parts in the axes before `from` and from
    /// `from` on.
    fn split_extent(&self, from: usize) -> (f64, f64) {
        let split = |p: &P| (norm_of(&p[..from]), norm_of(&p[from..]));
        match self {
            Piece::Point(c) => split(c),
            // A norm's largest value on a segment or a polyline is at a vertex.
            Piece::Segment(..) | Piece::Polyline { .. } => {
                let points = match self {
                    Piece::Segment(a, b) => vec![*a, *b],
                    Piece::Polyline { points, .. } => points.clone(),
                    _ => Vec::new(),
                };
                points.iter().map(split).fold((0.0, 0.0), |(a, b), (x, y)| {
                    (f64::max(a, x), f64::max(b, y))
                })
            }
            Piece::Circle {
                centre,
                radius,
                u,
                v,
                ..
            } => {
                // |cos t u + sin t v| restricted to some axes is at most the root of
                // the sum of the squares of u's and v's norms there.
                let (cu, cf) = split(centre);
                let (uu, uf) = split(u);
                let (vu, vf) = split(v);
                (
                    cu + radius * (uu * uu + vu * vu).sqrt().min(1.0),
                    cf + radius * (uf * uf + vf * vf).sqrt().min(1.0),
                )
            }
            Piece::Sphere {
                centre,
                radius,
                axes,
            } if *axes <= from => {
                let (cu, cf) = split(centre);
                (cu + radius, cf)
            }
            // Its bumps stay in its own axes, and its lift runs along the next one.
            Piece::Bumpy {
                centre, axes, bend, ..
            } if *axes <= from => {
                let (cu, cf) = split(centre);
                let bumps = self.extent() - norm(*centre) - bend.1.abs();
                if *axes < from {
                    (cu + bumps + bend.1.abs(), cf)
                } else {
                    (cu + bumps, cf + bend.1.abs())
                }
            }
            other => (other.extent(), other.extent()),
        }
    }

    /// An upper bound of `x . e` over a tube of radius `r` around the piece (its support
    /// function; `e` need not be a unit vector). Exact for the pieces a rotated object's
    /// room is measured on (points, segments, circles, round spheres, polylines, and
    /// these flattened); the others give `|e|` times their bounding ball.
    pub(crate) fn support(&self, e: P, r: f64) -> f64 {
        let tube = r * norm(e);
        match self {
            Piece::Point(c) => dot(*c, e) + tube,
            Piece::Segment(a, b) => dot(*a, e).max(dot(*b, e)) + tube,
            Piece::Circle {
                centre,
                radius,
                u,
                v,
            } => {
                let (eu, ev) = (dot(*u, e), dot(*v, e));
                dot(*centre, e) + radius * (eu * eu + ev * ev).sqrt() + tube
            }
            Piece::Sphere {
                centre,
                radius,
                axes,
            } => dot(*centre, e) + radius * norm_of(&e[..*axes]) + tube,
            Piece::Polyline { points, .. } => {
                points
                    .iter()
                    .map(|&q| dot(q, e))
                    .fold(f64::NEG_INFINITY, f64::max)
                    + tube
            }
            // A point of the tube is S q with q in the inner piece's tube, S the stretch,
            // so x . e = q . (S e).
            Piece::Flat {
                inner,
                stretch,
                from,
            } => {
                let mut stretched = e;
                for x in stretched.iter_mut().skip(*from) {
                    *x *= stretch;
                }
                inner.support(stretched, r)
            }
            // A prism is unbounded along its free axes.
            Piece::Prism { .. } => f64::INFINITY,
            other => other.reach(r) * norm(e),
        }
    }

    /// An upper bound of `|x|` over the piece (for bounding balls).
    pub(crate) fn extent(&self) -> f64 {
        match self {
            Piece::Point(c) => norm(*c),
            Piece::Segment(a, b) => norm(*a).max(norm(*b)),
            Piece::Circle { centre, radius, .. } => norm(*centre) + radius,
            Piece::Sphere { centre, radius, .. } => norm(*centre) + radius,
            Piece::Bumpy {
                centre,
                radius,
                stretches,
                lumps,
                bend,
                ..
            } => {
                // The stretches run along orthogonal axes, so their terms sum to at most
                // the largest of them (a unit vector's squared components sum to one); the
                // lumps may line up.
                let stretch = stretches.iter().map(|&(_, a)| a).fold(0.0, f64::max);
                let bulge: f64 = stretch + lumps.iter().map(|&(_, a)| a).sum::<f64>();
                norm(*centre) + radius + bulge + bend.1.abs()
            }
            Piece::Polyline { points, .. } => points.iter().map(|&q| norm(q)).fold(0.0, f64::max),
            Piece::Torus { major, minor } | Piece::Klein { major, minor } => major + minor,
            // Spinning maps (rho, x2, x3) to points of the same norm.
            Piece::Spun { centre, inner } => {
                norm(*centre) + inner.iter().map(Piece::extent).fold(0.0, f64::max)
            }
            // Only the kept axes are bounded; the others are handled by the caller.
            Piece::Prism { inner, .. } => inner.extent(),
            // The inner piece's parts along the stretched axes are stretched with them: its
            // tube of radius 0.
            Piece::Flat { .. } => self.reach(0.0),
        }
    }

    /// Points on the piece, for attaching tentacles. Empty for pieces where that is not
    /// offered.
    pub(crate) fn sample_points(&self) -> Vec<P> {
        match self {
            Piece::Point(c) => vec![*c],
            Piece::Segment(a, b) => (0..=8)
                .map(|k| add(*a, scale(sub(*b, *a), k as f64 / 8.0)))
                .collect(),
            Piece::Circle {
                centre,
                radius,
                u,
                v,
            } => (0..64)
                .map(|k| {
                    let t = 2.0 * std::f64::consts::PI * k as f64 / 64.0;
                    add(
                        *centre,
                        add(
                            scale(*u, radius * libm::cos(t)),
                            scale(*v, radius * libm::sin(t)),
                        ),
                    )
                })
                .collect(),
            Piece::Polyline { points, .. } => points.clone(),
            Piece::Flat { inner, .. } => inner.sample_points(),
            _ => Vec::new(),
        }
    }

    /// A compact description for the construction record.
    pub(crate) fn describe(&self, dim: usize) -> Value {
        match self {
            Piece::Point(c) => json!({"piece": "point", "at": point_json(*c, dim)}),
            Piece::Segment(a, b) => json!({
                "piece": "segment", "from": point_json(*a, dim), "to": point_json(*b, dim)
            }),
            Piece::Circle {
                centre,
                radius,
                u,
                v,
            } => json!({
                "piece": "circle", "centre": point_json(*centre, dim), "radius": round6(*radius),
                "u": point_json(*u, dim), "v": point_json(*v, dim)
            }),
            Piece::Sphere {
                centre,
                radius,
                axes,
            } => json!({
                "piece": "sphere", "centre": point_json(*centre, dim),
                "radius": round6(*radius), "axes": axes
            }),
            Piece::Bumpy {
                centre,
                radius,
                axes,
                stretches,
                lumps,
                bend,
            } => json!({
                "piece": "bumpy_sphere", "centre": point_json(*centre, dim),
                "radius": round6(*radius), "axes": axes,
                "stretches": stretches.iter().map(|&(_, a)| round6(a)).collect::<Vec<_>>(),
                "lumps": lumps.iter().map(|&(_, a)| round6(a)).collect::<Vec<_>>(),
                "bend": round6(bend.1)
            }),
            Piece::Polyline { points, closed, .. } => json!({
                "piece": "polyline", "closed": closed, "vertices": points.len(),
                "extent": round6(self.extent())
            }),
            Piece::Torus { major, minor } => json!({
                "piece": "torus", "major": round6(*major), "minor": round6(*minor)
            }),
            Piece::Klein { major, minor } => json!({
                "piece": "klein_bottle", "major": round6(*major), "minor": round6(*minor)
            }),
            Piece::Spun { centre, inner } => json!({
                "piece": "spun", "centre": point_json(*centre, dim),
                "inner": inner.iter().map(|q| q.describe(3)).collect::<Vec<_>>()
            }),
            Piece::Prism { inner, keep } => json!({
                "piece": "prism", "cross_section_axes": keep, "inner": inner.describe(*keep)
            }),
            Piece::Flat {
                inner,
                stretch,
                from,
            } => json!({
                "piece": "flattened", "stretch": round6(*stretch), "stretched_from_axis": from,
                "inner": inner.describe(dim)
            }),
        }
    }
}

pub(crate) fn segment_distance(p: P, a: P, b: P) -> f64 {
    let ab = sub(b, a);
    let ap = sub(p, a);
    let len2 = dot(ab, ab);
    let t = if len2 > 0.0 {
        (dot(ap, ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm(sub(ap, scale(ab, t)))
}

mod solid;
pub(crate) use solid::Solid;

#[cfg(test)]
mod tests;
