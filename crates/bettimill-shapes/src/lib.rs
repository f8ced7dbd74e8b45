//! The shape library: voxel objects with analytically known Betti numbers.
//!
//! Every construction of the paper is a [`Family`]; [`generate`] draws one random instance
//! (random size, rotation and position from the caller's `ChaCha8Rng`) in a 2D, 3D or 4D
//! image, in one of two [`Mode`]s: the object(s) in empty space, or a solid cube with the
//! object(s) cut out as cavities. The label comes from the construction, not from a
//! computation: [`Family::expected_betti`] states it, and the verifier in
//! `bettimill-homology` checks every sample against it, because even well-conditioned
//! shapes can digitise with local defects.
//!
//! Model (see `notes/labels.md`): an image is the union of its closed foreground voxels,
//! foreground (3^d-1)-adjacency, background 2d-adjacency, Betti numbers over Z/2. Carve
//! labels follow from embed labels by the duality b0(C) = 1 + b_{d-1}(O),
//! b_k(C) = b_{d-1-k}(O), b_{d-1}(C) = b0(O).
//!
//! Every object is a skeleton (point, circle, sphere, torus, polyline, ...) thickened by a
//! radius of at least two voxels, or a thin shell around such a thickening; a thickening
//! thinner than the skeleton's feature size has the skeleton's homotopy type. A small 4D
//! 2-sphere times a disk sized for a volume may thin its tube to one voxel of radius
//! across its hole (widened back to two along the fourth axis), a small shell its wall to
//! two voxels across, which no path of face neighbours crosses. Objects keep
//! at least two background voxels to each other and (carve mode) to the cube's boundary,
//! and (embed mode) one to the border.

mod betti_class;
mod curves;
mod generate;
mod geometry;
mod labels;
mod place;
mod recipes;
mod rotation;
mod sizing;

pub use bettimill_grid::{BinaryImage, Dim};
pub use bettimill_types::Solid;
pub use generate::{paper_scene_3d, paper_scene_family};
pub use geometry::TubeFloor;

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::fmt;

pub use bettimill_grid::Mode;

/// Layers of a carved full cube, inside the image's empty border, that its cavities never
/// reach: they are placed and deformed only inside them, so the solid's faces stay as built.
pub const CAVITY_INSET: usize = geometry::GAP as usize;

/// Layers of a boxed solid ([`Solid::Box`]) around its cavities that stay as built.
pub const BOX_WALL: usize = generate::BOX_WALL as usize;

/// The largest bounding radius of a tunnel's cross-section in a carved cube of `side`: each
/// sample draws it uniformly between the family's smallest and this, whatever its bin.
pub fn largest_tunnel_radius(side: usize) -> f64 {
    place::Region::for_mode(side, Mode::Carve).budget()
}

/// A knot: the core curve of a knotted solid torus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KnotKind {
    /// A round circle.
    Unknot,
    /// The trefoil (3_1).
    Trefoil,
    /// The figure-eight knot (4_1).
    FigureEight,
    /// The cinquefoil, torus knot T(2,5) (5_1).
    Cinquefoil,
}

impl KnotKind {
    /// The knot's name as used in labels.
    pub fn name(self) -> &'static str {
        match self {
            KnotKind::Unknot => "unknot",
            KnotKind::Trefoil => "trefoil",
            KnotKind::FigureEight => "figure_eight",
            KnotKind::Cinquefoil => "cinquefoil",
        }
    }
}

/// A link of several closed curves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinkKind {
    /// Two circles linked once.
    Hopf,
    /// The Whitehead link: linking number zero, yet linked.
    Whitehead,
    /// Three rings, no two of them linked.
    Borromean,
    /// Solomon's knot, the torus link T(4,2).
    Solomon,
}

impl LinkKind {
    /// The link's name as used in labels.
    pub fn name(self) -> &'static str {
        match self {
            LinkKind::Hopf => "hopf",
            LinkKind::Whitehead => "whitehead",
            LinkKind::Borromean => "borromean",
            LinkKind::Solomon => "solomon",
        }
    }

    /// The number of closed curves.
    pub fn components(self) -> u64 {
        match self {
            LinkKind::Borromean => 3,
            _ => 2,
        }
    }
}

/// A family of constructions, as written in a manifest class: e.g. TOML
/// `{ family = "ball" }`, `{ family = "handlebody", genus = 2 }`,
/// `{ family = "connected_sum", g = 1, h = 0, i = 1, j = 2 }`,
/// `{ family = "knot", knot = "trefoil" }`, `{ family = "scene", objects = [...] }`.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(tag = "family", rename_all = "snake_case", deny_unknown_fields)]
pub enum Family {
    /// A d-ball.
    Ball,
    /// S1 x B(d-1): an annulus in 2D, a solid torus in 3D, S1xB3 in 4D.
    Handle,
    /// A thickened (d-1)-sphere: annulus, spherical shell, thickened S3.
    Shell,
    /// A thickened (d-1)-torus: annulus in 2D, torus shell in 3D, thickened T3 in 4D.
    TorusShell,
    /// A thickened graph with `genus` independent cycles (circles joined by bars): a disk
    /// with holes in 2D, a genus-g handlebody in 3D, a boundary sum of S1xB3 in 4D.
    Handlebody {
        /// Number of handles (at least 1).
        genus: u32,
    },
    /// 4D: a thickened 2-sphere, S2xB2.
    #[serde(rename = "s2_x_b2")]
    S2xB2,
    /// 4D: a thickened torus, T2xB2 = S1xS1xB2.
    #[serde(rename = "t2_x_b2")]
    T2xB2,
    /// A `shell` whose sphere is not round: stretched along its axes, with lumps, drawn
    /// per sample.
    BumpyShell,
    /// 4D: an `s2_x_b2` whose 2-sphere is not round: stretched, with lumps, and bent into
    /// the fourth axis, drawn per sample.
    #[serde(rename = "bumpy_s2_x_b2")]
    BumpyS2xB2,
    /// S1 x (boundary sum of j copies of S1xB(d-2)), built by spinning a thickened planar
    /// graph with j cycles about a plane (3D: about an axis).
    #[serde(rename = "s1_x_handlebody")]
    S1xHandlebody {
        /// Cycles of the spun graph (at least 1).
        j: u32,
    },
    /// Table I of the paper: the boundary connected sum of g copies of S1xB(d-1), h of
    /// S2xB(d-2) and i of S1 x (boundary sum of j S1xB(d-2)), in 4D (and its 3D analogue).
    ConnectedSum {
        /// Copies of S1xB(d-1).
        g: u32,
        /// Copies of S2xB(d-2).
        h: u32,
        /// Copies of S1 x (boundary sum of j copies of S1xB(d-2)).
        i: u32,
        /// Cycles in each of the i summands.
        j: u32,
    },
    /// Carve mode only: a tunnel through the cube, I^intervals x K, where the cross-section
    /// K is a ball, or (with `circle`) a thickened circle S1xB, or (with `genus` = g) a
    /// boundary sum of g thickened circles, so that I x K is the paper's
    /// I x (boundary sum of g S1xB2). The I factors run from face to face.
    Tunnel {
        /// Interval factors (1 or 2).
        intervals: u32,
        /// Whether the cross-section is a thickened circle instead of a ball (the same as
        /// `genus = 1`).
        #[serde(default)]
        circle: bool,
        /// Independent cycles of the cross-section (a row of circles joined by bars);
        /// 0 means a ball unless `circle` is set.
        #[serde(default)]
        genus: u32,
    },
    /// A ball cut through by `parts - 1` parallel slabs: `parts` pieces whose flat faces
    /// face each other across gaps as narrow as the scenes' narrowest gap between objects
    /// (and no narrower, whatever the slabs' slant). The other side of a neck: two parts
    /// close together, where a neck is one part narrowed to a thread.
    Split {
        /// The pieces (2 to 4).
        #[serde(default = "two_parts")]
        parts: u32,
    },
    /// A thickened smooth open curve (contractible).
    Curve,
    /// A thickened closed curve that is not round (lobes, a squeeze, waves out of its
    /// plane): S1 x B(d-1), the handle's topology, never knotted.
    Loop,
    /// A knotted solid torus in 3D; in 4D the knot times an interval (circles do not knot
    /// in 4D).
    Knot {
        /// Which knot.
        knot: KnotKind,
    },
    /// The torus knot or link T(p,q): gcd(p,q) thickened components.
    TorusKnot {
        /// Turns around the torus' axis.
        p: u32,
        /// Turns through the torus' hole.
        q: u32,
    },
    /// A link of thickened closed curves in 3D; in 4D the link times an interval.
    Link {
        /// Which link.
        link: LinkKind,
    },
    /// 4D: Artin's spun knot, a knotted 2-sphere (thickened): a knotted arc with its ends
    /// on a plane, spun about that plane.
    SpunKnot {
        /// The knot whose arc is spun.
        knot: KnotKind,
    },
    /// 4D: a link spun about a plane: every component becomes a (thickened) torus; the
    /// spun Hopf link is two linked T2xB2.
    SpunLink {
        /// The link that is spun.
        link: LinkKind,
    },
    /// 4D: a thickened Klein bottle. Over Z/2 its Betti numbers are (1,2,1,0); over Q
    /// they are (1,1,0,0).
    KleinBottle,
    /// An object with thickened curves ("tentacles") attached at one end: same topology.
    Tentacled {
        /// The object (a tube-like family: ball, handle, handlebody, curve, knot, link).
        object: Box<Family>,
        /// Number of tentacles.
        tentacles: u32,
    },
    /// Several objects, each with a random rotation, scale and position, kept apart by at
    /// least two background voxels.
    Scene {
        /// The objects to place.
        objects: Vec<Family>,
    },
    /// A class given by its label: Betti numbers b_0..b_{d-1} of the image, realised by a
    /// canonical construction (one object or a scene; see the `betti_class` module) whose
    /// analytic label is exactly this vector in the requested mode.
    Betti {
        /// b_0..b_{d-1} of the image (of the carved cube in carve mode).
        betti: Vec<u64>,
    },
}

/// A split ball's usual number of pieces.
fn two_parts() -> u32 {
    2
}

/// Why a shape could not be generated.
#[derive(Debug, thiserror::Error, Clone, PartialEq, Eq)]
pub enum ShapeError {
    /// The family does not exist in this dimension or mode.
    #[error("{family} is not available in {dim}D {mode} mode: {reason}")]
    Unsupported {
        /// The family's label.
        family: String,
        /// The requested dimension.
        dim: usize,
        /// The requested mode.
        mode: Mode,
        /// What is missing.
        reason: String,
    },
    /// The parameters are outside the family's domain.
    #[error("invalid parameters for {family}: {reason}")]
    InvalidParameters {
        /// The family's label.
        family: String,
        /// What is wrong.
        reason: String,
    },
    /// The construction cannot fit at this side length.
    #[error("{family} does not fit in a {dim}D image of side {side} ({mode} mode): {reason}")]
    DoesNotFit {
        /// The family's label.
        family: String,
        /// The requested dimension.
        dim: usize,
        /// The requested side length.
        side: usize,
        /// The requested mode.
        mode: Mode,
        /// Sizes involved.
        reason: String,
    },
}

/// One random instance with its label.
#[derive(Clone, Debug)]
pub struct Generated {
    /// The image, shape `[side; dim]`.
    pub image: BinaryImage,
    /// Analytic Betti numbers over Z/2 (len == dim).
    pub betti: Vec<u64>,
    /// Analytic Betti numbers over Q when they differ (Klein bottle), else None.
    pub betti_rational: Option<Vec<u64>>,
    /// How it was built (families, parameters, placement, rotation); keys sorted.
    pub construction: serde_json::Value,
    /// Knot/link type label ("unknot", "trefoil", "hopf", ...), or "none".
    pub knot_type: String,
    /// Number of objects placed (b0 of the object in Embed mode).
    pub components: u64,
    /// Carve mode: the box (inclusive bounds per axis) inside the solid where its cavities
    /// may be deformed; the solid's outer layers beyond it stay as built. `None` in embed
    /// mode, where the objects may be deformed anywhere but the outermost layer.
    pub phase_box: Option<(Vec<usize>, Vec<usize>)>,
    /// The background voxels placement kept between any two objects (the construction's
    /// `gap_voxels`): drawn per sample in a scene, so growth that keeps it (see
    /// `bettimill_deform::Apart::keeping`) leaves parts at many distances.
    pub gap: usize,
}

impl Family {
    /// Analytic Betti numbers over Z/2 for this family in `dim` and `mode`; Err if the
    /// family does not exist in that dimension.
    pub fn expected_betti(&self, dim: Dim, mode: Mode) -> Result<Vec<u64>, ShapeError> {
        labels::expected(self, dim, mode).map(|(z2, _)| z2)
    }

    /// Analytic Betti numbers over Z/2 and, where they differ (the Klein bottle), over Q:
    /// what every sample of this family records in `betti` and `betti_rational`.
    pub fn expected_label(
        &self,
        dim: Dim,
        mode: Mode,
    ) -> Result<(Vec<u64>, Option<Vec<u64>>), ShapeError> {
        labels::expected(self, dim, mode)
    }

    /// Analytic Betti numbers over Q (differ from Z/2 only for the Klein bottle).
    pub fn expected_betti_rational(&self, dim: Dim, mode: Mode) -> Result<Vec<u64>, ShapeError> {
        labels::expected(self, dim, mode).map(|(z2, q)| q.unwrap_or(z2))
    }

    /// Plan-time feasibility: Err with a clear reason if the construction cannot fit at
    /// this side length (never an endless retry later).
    pub fn check_fits(&self, dim: Dim, side: usize, mode: Mode) -> Result<(), ShapeError> {
        generate::check_fits(self, dim, side, mode, TubeFloor::USUAL)
    }

    /// [`Family::check_fits`] for instances whose tubes are at least `floor`
    /// ([`generate_planned_for`] with the same floor then always builds).
    pub fn check_fits_with(
        &self,
        dim: Dim,
        side: usize,
        mode: Mode,
        floor: TubeFloor,
    ) -> Result<(), ShapeError> {
        generate::check_fits(self, dim, side, mode, floor)
    }

    /// The smallest bounding radius, in voxels, that one object of this family (the
    /// smallest of a scene's) has with tubes at least `floor`; `None` where the family has
    /// no instance in `dim` and `mode`.
    pub fn smallest_object_radius(&self, dim: Dim, mode: Mode, floor: TubeFloor) -> Option<f64> {
        if let Family::Betti { betti } = self {
            let realised = betti_class::realise(betti, dim, mode).ok()?;
            return realised.smallest_object_radius(dim, mode, floor);
        }
        let objects = match self {
            Family::Scene { objects } => objects.clone(),
            other => vec![other.clone()],
        };
        objects
            .iter()
            .filter_map(|o| sizing::min_extent(o, dim.get(), floor))
            .reduce(f64::min)
    }

    /// The construction a Betti class is built as in `dim` and `mode` (shells, handlebodies
    /// or sums and balls, a scene of them when there are several); `None` for a named
    /// family, or a class no construction gives.
    pub fn realisation(&self, dim: Dim, mode: Mode) -> Option<Family> {
        match self {
            Family::Betti { betti } => betti_class::realise(betti, dim, mode).ok(),
            _ => None,
        }
    }

    /// The smallest side length at which [`Family::check_fits`] succeeds (up to 1024).
    pub fn min_side(&self, dim: Dim, mode: Mode) -> Result<usize, ShapeError> {
        labels::expected(self, dim, mode)?;
        generate::smallest_side(self, dim, mode, TubeFloor::USUAL, 4).ok_or_else(|| {
            ShapeError::DoesNotFit {
                family: self.label(),
                dim: dim.get(),
                side: generate::MAX_SEARCHED_SIDE,
                mode,
                reason: format!(
                    "does not fit at any side up to {}",
                    generate::MAX_SEARCHED_SIDE
                ),
            }
        })
    }

    /// The `knot_type` every sample of this family records in `mode`: the knot or link
    /// types of its objects joined by `+` (`"trefoil"`, `"hopf_x_interval"`), or `"none"`.
    pub fn knot_type(&self, dim: Dim, mode: Mode) -> String {
        labels::knot_type_label(self, dim, mode)
    }

    /// A short stable name for tables ("ball", "handlebody(genus=2)", ...).
    pub fn label(&self) -> String {
        match self {
            Family::Ball => "ball".into(),
            Family::Handle => "handle".into(),
            Family::Shell => "shell".into(),
            Family::TorusShell => "torus_shell".into(),
            Family::Handlebody { genus } => format!("handlebody(genus={genus})"),
            Family::S2xB2 => "s2_x_b2".into(),
            Family::T2xB2 => "t2_x_b2".into(),
            Family::BumpyShell => "bumpy_shell".into(),
            Family::BumpyS2xB2 => "bumpy_s2_x_b2".into(),
            Family::S1xHandlebody { j } => format!("s1_x_handlebody(j={j})"),
            Family::ConnectedSum { g, h, i, j } => {
                format!("connected_sum(g={g},h={h},i={i},j={j})")
            }
            Family::Tunnel {
                intervals,
                circle,
                genus,
            } => {
                if *genus > 0 {
                    format!("tunnel(intervals={intervals},genus={genus})")
                } else {
                    format!("tunnel(intervals={intervals},circle={circle})")
                }
            }
            Family::Split { parts } => format!("split(parts={parts})"),
            Family::Curve => "curve".into(),
            Family::Loop => "loop".into(),
            Family::Knot { knot } => format!("knot({})", knot.name()),
            Family::TorusKnot { p, q } => format!("torus_knot(p={p},q={q})"),
            Family::Link { link } => format!("link({})", link.name()),
            Family::SpunKnot { knot } => format!("spun_knot({})", knot.name()),
            Family::SpunLink { link } => format!("spun_link({})", link.name()),
            Family::KleinBottle => "klein_bottle".into(),
            Family::Tentacled { object, tentacles } => {
                format!("tentacled({},tentacles={tentacles})", object.label())
            }
            Family::Scene { objects } => {
                let inner: Vec<String> = objects.iter().map(Family::label).collect();
                format!("scene({})", inner.join(","))
            }
            Family::Betti { betti } => {
                let inner: Vec<String> = betti.iter().map(u64::to_string).collect();
                format!("betti({})", inner.join(","))
            }
        }
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.label())
    }
}

/// Draws one random instance. Image shape is `[side; dim]`.
pub fn generate(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    rng: &mut ChaCha8Rng,
) -> Result<Generated, ShapeError> {
    generate::generate_for(family, dim, side, mode, rng, true, generate::Sizing::USUAL)
}

/// [`generate`] for a request that [`Family::check_fits`] has accepted, as the plan does for
/// every stratum: the size checks are decided once, at plan time, not on every attempt. The
/// voxels are those [`generate`] draws (the checks draw nothing from `rng`); a request that
/// was never checked may fail later, in placement, with a less helpful error.
pub fn generate_planned(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    rng: &mut ChaCha8Rng,
) -> Result<Generated, ShapeError> {
    generate::generate_for(family, dim, side, mode, rng, false, generate::Sizing::USUAL)
}

/// [`generate_planned`] sized for a hypervolume: the construction's sizes are chosen so
/// that its foreground count lands near `foreground` voxels (carve mode with
/// [`Solid::Cube`]: the full cube with cavities of the rest of its volume; with
/// [`Solid::Box`]: a solid box of nearly equal sides around cavities of a random 0.2-1% of
/// the image; the cavities' scale found by bisection on a cheap voxel count; embed mode:
/// the objects' scale), as near as the room allows. The caller brings the count the rest of the way (the sample pipeline
/// does it with topology-preserving flips) and verifies the result. Tubes are at least
/// `floor` (the plan's [`Family::check_fits_with`] accepted that floor; tentacles keep their
/// own 2-2.5 voxels), except in a binned carve sample whose solid box cannot hold them: it
/// gets the usual tubes in that box (the record's `tube_floor` says which). `None` and
/// [`TubeFloor::USUAL`] are [`generate_planned`].
#[allow(clippy::too_many_arguments)] // One request: what, where, how large, how thick.
pub fn generate_planned_for(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    foreground: Option<u64>,
    solid: Solid,
    floor: TubeFloor,
    rng: &mut ChaCha8Rng,
) -> Result<Generated, ShapeError> {
    generate::generate_for(
        family,
        dim,
        side,
        mode,
        rng,
        false,
        generate::Sizing {
            foreground,
            solid,
            floor,
        },
    )
}

#[cfg(test)]
mod check;

#[cfg(test)]
mod tests;
