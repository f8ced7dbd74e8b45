//! The generation driver: feasibility at plan time, and one labelled instance at build time.
//!
//! [`check_fits`] is a promise: if it accepts a request (every object fits the image on
//! its own, and all of them together fit a grid of cells or the canonical layout of
//! `place.rs`), [`generate`] succeeds for every seed. [`generate`] looks the label up
//! (`labels.rs`), places the objects (`place.rs`), writes their voxels into an empty image
//! or clears them from a solid cube (carve mode), and records how every object was built,
//! with its JSON keys in sorted order so the record's bytes never depend on serde_json's
//! features.

use crate::geometry::{round6, uniform, uniform_int, TubeFloor};
use crate::labels::{embed_betti, expected, knot_type_label, realised_as};
use crate::place::{
    canonical_layout, grid_fits, place_objects, place_tunnel, PlacementArea, Region, CUBE_MARGIN,
};
use crate::sizing::min_extent;
use crate::{BinaryImage, Dim, Family, Generated, KnotKind, LinkKind, Mode, ShapeError, Solid};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Map, Value};

fn objects_of(family: &Family) -> Vec<Family> {
    match family {
        Family::Scene { objects } => objects.clone(),
        other => vec![other.clone()],
    }
}

/// Plan-time feasibility ([`crate::Family::check_fits_with`]): the label exists, every
/// object fits on its own with tubes at least `floor`, and all of them fit together.
pub(crate) fn check_fits(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    floor: TubeFloor,
) -> Result<(), ShapeError> {
    check_sizes(family, dim, side, mode, floor, true).map_err(|err| match err {
        // A refusal names the way on: the smallest side that fits.
        ShapeError::DoesNotFit {
            family: label,
            dim: d,
            side,
            mode,
            reason,
        } => {
            let mut way_on = match smallest_side(family, dim, mode, floor, side + 1) {
                Some(fits) => format!("the smallest side that fits is {fits}"),
                None => format!("no side up to {MAX_SEARCHED_SIDE} fits"),
            };
            // A gap the manifest widened is part of the reason and of the way on.
            if floor.widens() {
                let usual = floor.with_gap(TubeFloor::USUAL.gap());
                let without = check_sizes(family, dim, side, mode, usual, true).is_ok();
                way_on.push_str(&format!(
                    " with holes at least inner_gap = {} voxels wide{}",
                    round6(floor.gap()),
                    if without {
                        " (it fits with the usual gap)"
                    } else {
                        ""
                    }
                ));
            }
            ShapeError::DoesNotFit {
                family: label,
                dim: d,
                side,
                mode,
                reason: format!("{reason}; {way_on}"),
            }
        }
        other => other,
    })
}

/// The largest side [`smallest_side`] tries.
pub(crate) const MAX_SEARCHED_SIDE: usize = 1024;

/// The smallest side from `from` up to [`MAX_SEARCHED_SIDE`] at which the construction
/// fits, if any.
pub(crate) fn smallest_side(
    family: &Family,
    dim: Dim,
    mode: Mode,
    floor: TubeFloor,
    from: usize,
) -> Option<usize> {
    (from..=MAX_SEARCHED_SIDE)
        .find(|&side| check_sizes(family, dim, side, mode, floor, true).is_ok())
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
    floor: TubeFloor,
    packing: bool,
) -> Result<(), ShapeError> {
    expected(family, dim, mode)?;
    if let Family::Betti { betti } = family {
        let realised = crate::betti_class::realise(betti, dim, mode)?;
        return check_sizes(&realised, dim, side, mode, floor, packing)
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
        let need = min_extent(family, d, floor).unwrap_or(f64::INFINITY);
        let budget = region.budget();
        if need > budget {
            return Err(does_not_fit(format!(
                "the cross-section needs radius {need:.2}, the cube offers {budget:.2}"
            )));
        }
        return Ok(());
    }
    let objects = objects_of(family);
    let minima = object_minima(&objects, d, floor, &does_not_fit)?;
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
        || canonical_layout(&objects, &minima, (d, side, mode), region, floor).is_some()
    {
        return Ok(());
    }
    Err(does_not_fit(format!(
        "{} objects with bounding radii {:?} could not be packed with {} background voxels between them",
        objects.len(),
        minima.iter().map(|&m| round6(m)).collect::<Vec<_>>(),
        crate::geometry::GAP
    )))
}

fn object_minima(
    objects: &[Family],
    dim: usize,
    floor: TubeFloor,
    does_not_fit: &dyn Fn(String) -> ShapeError,
) -> Result<Vec<f64>, ShapeError> {
    objects
        .iter()
        .map(|o| {
            min_extent(o, dim, floor)
                .ok_or_else(|| does_not_fit(format!("{} has no valid instance", o.label())))
        })
        .collect()
}

/// The smallest and largest share of the image the cavities of a sample sized for a
/// hypervolume take in a boxed solid ([`Solid::Box`]); the box is sized around them. The
/// same range for every family, so neither the cavities' volume nor the box's size tells
/// the class.
pub(crate) const CAVITY_SHARE: (f64, f64) = (0.002, 0.01);

/// How large a construction is made.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sizing {
    /// The foreground count to come near, if binned.
    pub(crate) foreground: Option<u64>,
    /// Carve mode's solid.
    pub(crate) solid: Solid,
    /// The thinnest tube.
    pub(crate) floor: TubeFloor,
}

impl Sizing {
    /// Unbinned, the full cube, the usual tubes.
    pub(crate) const USUAL: Sizing = Sizing {
        foreground: None,
        solid: Solid::Cube,
        floor: TubeFloor::USUAL,
    };
}

/// One random instance with its label ([`crate::generate`]), with the size checks
/// (`check`) or without them, for a request [`check_fits`] has accepted
/// ([`crate::generate_planned`]; the checks draw nothing from `rng`, so both give the same
/// voxels); and with a `foreground` count the construction sized so that its foreground
/// count lands near that many voxels: in carve mode with [`Solid::Cube`] the full cube's
/// cavities sized by bisection for the rest of its volume; with [`Solid::Box`] a solid box
/// of nearly equal sides sized around cavities of a random share [`CAVITY_SHARE`] of the
/// image; in embed mode the objects sized for the count. Sizes that cannot reach it come
/// as close as the room allows.
pub(crate) fn generate_for(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    rng: &mut ChaCha8Rng,
    check: bool,
    sizing: Sizing,
) -> Result<Generated, ShapeError> {
    let Sizing {
        foreground,
        solid: solid_kind,
        floor,
    } = sizing;
    if let Family::Betti { betti } = family {
        // The realisation is generated as itself; its record says which class it serves.
        let realised = crate::betti_class::realise(betti, dim, mode)?;
        let mut generated = generate_for(&realised, dim, side, mode, rng, check, sizing)
            .map_err(|err| realised_as(err, family, &realised))?;
        if let Value::Object(map) = &mut generated.construction {
            map.insert("class".into(), json!(family.label()));
        }
        generated.construction = sort_keys(generated.construction);
        return Ok(generated);
    }
    if check {
        check_sizes(family, dim, side, mode, floor, false)?;
    }
    let (betti, betti_rational) = expected(family, dim, mode)?;
    let d = dim.get();
    let objects = objects_of(family);
    let tunnel = matches!(family, Family::Tunnel { .. });
    let full = full_box(d, side);
    // The solid (carve mode) and the objects' voxel count, when sized for a hypervolume.
    let mut axes = Vec::new();
    let boxed = solid_kind == Solid::Box;
    let (solid, volume) = match (mode, foreground) {
        (Mode::Carve, Some(target)) if !tunnel && !boxed => {
            (full, Some(full.count().saturating_sub(target) as f64))
        }
        (Mode::Carve, Some(target)) if !tunnel => {
            let (solid, order) = solid_box(d, side, target, rng);
            axes = order;
            (solid, Some(solid.count().saturating_sub(target) as f64))
        }
        (Mode::Embed, Some(target)) if !tunnel => (full, Some(target as f64)),
        _ => (full, None),
    };
    // A binned carve sample keeps `BOX_WALL` between its cavities and the outside; other
    // samples use the mode's usual region.
    let placement =
        |region: Region, volume: Option<f64>, floor: TubeFloor, rng: &mut ChaCha8Rng| {
            if tunnel {
                Ok((
                    vec![place_tunnel(family, d, side, region, floor, rng)?],
                    "tunnel",
                    crate::geometry::GAP,
                ))
            } else {
                let canvas = PlacementArea {
                    dim: d,
                    side,
                    mode,
                    region,
                    volume,
                    floor,
                    draw_scale: mode == Mode::Carve && boxed,
                };
                place_objects(family, &objects, canvas, rng)
            }
        };
    let usual = Region::for_mode(side, mode);
    let binned_carve = mode == Mode::Carve && volume.is_some() && boxed;
    let region = if binned_carve { solid.region() } else { usual };
    // A box too small for the objects falls back to the usual tubes in the same box (when
    // the floor was raised for the copies: they may then not keep the topology, and their
    // labels say so), then to the full cube and the usual region, whose foreground needs
    // millions of flips to come down to the bin.
    let mut floor = floor;
    let in_box = match placement(region, volume, floor, rng) {
        Err(_) if binned_carve && floor.thickens() => {
            let thin = placement(region, volume, floor.thin(), rng);
            if thin.is_ok() {
                floor = floor.thin();
            }
            thin
        }
        other => other,
    };
    let (solid, (placed, strategy, gap)) = match in_box {
        Ok(found) if binned_carve => {
            let target = foreground.expect("sized for a foreground count");
            (refit_box(d, side, target, &found.0, &axes), found)
        }
        Ok(found) => (solid, found),
        Err(_) if binned_carve => {
            let volume = foreground.map(|t| full.count().saturating_sub(t) as f64);
            (full, placement(usual, volume, floor, rng)?)
        }
        Err(err) => return Err(err),
    };
    let mut image = BinaryImage::cube(dim, side).expect("check_fits rejects sides below 8");
    // Carve mode clears object voxels from the cube; a tunnel's voxels beyond the cube
    // are background already.
    let value = match mode {
        Mode::Embed => 1u8,
        Mode::Carve => {
            solid.fill(&mut image, d, side);
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
    let knot_type = knot_type_label(family, dim, mode);
    let components = objects
        .iter()
        .map(|o| embed_betti(o, dim).map(|(b, _)| b[0]).unwrap_or(0))
        .sum::<u64>();
    let components = if let Family::Tunnel { .. } = family {
        1
    } else {
        components
    };
    let mut entries = vec![
        ("family", json!(family.label())),
        ("dim", json!(d)),
        ("side", json!(side)),
        ("mode", json!(mode.to_string())),
        ("objects", Value::Array(records)),
        // How the layout was found: "random" (the normal case), "grid" or "canonical"
        // (fallbacks that keep a feasible request from failing), or "tunnel".
        ("placement", json!(strategy)),
        ("betti_field", json!("z2")),
        ("gap_voxels", json!(gap)),
        (
            "cube_margin",
            json!(if mode == Mode::Carve { CUBE_MARGIN } else { 0 }),
        ),
    ];
    if floor.thickens() {
        entries.push(("tube_floor", json!(round6(floor.radius()))));
    }
    if floor.widens() {
        entries.push(("inner_gap", json!(round6(floor.gap()))));
    }
    if let Some(target) = foreground {
        entries.push(("foreground_target", json!(target)));
        if mode == Mode::Carve {
            entries.push(("solid_box", solid.describe(d)));
        }
    }
    // The cavities may be deformed up to `GAP` layers from the solid's faces, or up to the
    // boxed solid's own wall: the solid's outside stays as built.
    let phase_box = (mode == Mode::Carve).then(|| {
        let inset = if binned_carve {
            crate::BOX_WALL
        } else {
            crate::CAVITY_INSET
        };
        let lo = (0..d).map(|k| solid.lo[k] + inset).collect();
        let hi = (0..d).map(|k| solid.hi[k].saturating_sub(inset)).collect();
        (lo, hi)
    });
    let construction = sorted(entries);
    Ok(Generated {
        phase_box,
        image,
        betti,
        betti_rational,
        construction: sort_keys(construction),
        knot_type,
        components,
        gap: gap as usize,
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

/// The solid of carve mode: a box with inclusive voxel bounds per axis.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SolidBox {
    lo: [usize; 4],
    hi: [usize; 4],
    dim: usize,
}

/// The least wall between a cavity and the outside of a solid box: 7 layers keep a
/// whole block of foreground in the wall when the image is pooled by 4 (a 128-side sample's
/// 32-side copy), one more for the rounding of the cavity's surface.
pub(crate) const BOX_WALL: i64 = 8;

/// The full cube: `CUBE_MARGIN` background layers on every face.
fn full_box(dim: usize, side: usize) -> SolidBox {
    let m = CUBE_MARGIN as usize;
    SolidBox {
        lo: [m; 4],
        hi: [side - 1 - m; 4],
        dim,
    }
}

/// A box of nearly equal sides (each `l` or `l + 1`, centred in the image) with about
/// `foreground` voxels plus a cavity share drawn from [`CAVITY_SHARE`], at most the full
/// cube: its count minus `foreground` is what the cavities are sized for. Also returns the
/// axis order its lengths were grown in, for [`refit_box`].
fn solid_box(
    dim: usize,
    side: usize,
    foreground: u64,
    rng: &mut ChaCha8Rng,
) -> (SolidBox, Vec<usize>) {
    let image = libm::pow(side as f64, dim as f64);
    let share = uniform(rng, CAVITY_SHARE.0, CAVITY_SHARE.1);
    let mut axes: Vec<usize> = (0..dim).collect();
    for k in (1..dim).rev() {
        let j = uniform_int(rng, 0, k as u64) as usize;
        axes.swap(k, j);
    }
    let want = foreground as f64 + share * image;
    let floor = foreground as f64 + 0.5 * share * image;
    (box_for(dim, side, want, floor, &axes), axes)
}

/// The centred box of nearly equal sides whose count is the largest at most `want` (at
/// most the full cube), lengthened further while it is below `floor`.
fn box_for(dim: usize, side: usize, want: f64, floor: f64, axes: &[usize]) -> SolidBox {
    let full = side - 2 * CUBE_MARGIN as usize;
    let want = want.min(libm::pow(full as f64, dim as f64));
    let mut lengths = [1usize; 4];
    let l = (libm::floor(libm::pow(want, 1.0 / dim as f64)) as usize).clamp(1, full);
    lengths[..dim].fill(l);
    let product = |lengths: &[usize; 4]| lengths[..dim].iter().map(|&n| n as f64).product::<f64>();
    // Lengthen axes (in the given order) one voxel at a time while the count stays at
    // most `want`, then while it is below `floor`.
    for _ in 0..2 {
        for &k in axes {
            let mut longer = lengths;
            longer[k] += 1;
            if longer[k] <= full && (product(&longer) <= want || product(&lengths) < floor) {
                lengths = longer;
            }
        }
    }
    let mut lo = [0usize; 4];
    let mut hi = [0usize; 4];
    for k in 0..dim {
        lo[k] = (side - lengths[k]) / 2;
        hi[k] = lo[k] + lengths[k] - 1;
    }
    SolidBox { lo, hi, dim }
}

/// The box for the cavities as rasterised: sized for `foreground` plus their actual voxel
/// count (they may fall short of the volume they were sized for, when the room or the
/// family's shape limits them), then widened where needed to keep [`BOX_WALL`] layers
/// around every cavity voxel (they were placed inside the first box's region, so the
/// first box always qualifies).
fn refit_box(
    dim: usize,
    side: usize,
    foreground: u64,
    placed: &[(Family, crate::place::Placed, Value, Vec<usize>)],
    axes: &[usize],
) -> SolidBox {
    let cavity: usize = placed.iter().map(|p| p.3.len()).sum();
    let want = (foreground + cavity as u64) as f64;
    let mut solid = box_for(dim, side, want, want, axes);
    let full = full_box(dim, side);
    for (_, _, _, voxels) in placed {
        for &v in voxels {
            let mut rest = v;
            for k in (0..dim).rev() {
                let c = rest % side;
                rest /= side;
                let wall = BOX_WALL as usize;
                solid.lo[k] = solid.lo[k].min(c.saturating_sub(wall)).max(full.lo[k]);
                solid.hi[k] = solid.hi[k].max(c + wall).min(full.hi[k]);
            }
        }
    }
    solid
}

impl SolidBox {
    fn count(&self) -> u64 {
        (0..self.dim)
            .map(|k| (self.hi[k] - self.lo[k] + 1) as u64)
            .product()
    }

    /// Where cavities may go: [`BOX_WALL`] layers inside the box on every face (one
    /// range for every axis, so the tightest axis decides).
    fn region(&self) -> Region {
        let lo = self.lo[..self.dim].iter().max().copied().unwrap_or(0) as i64;
        let hi = self.hi[..self.dim].iter().min().copied().unwrap_or(0) as i64;
        Region {
            lo: lo + BOX_WALL,
            hi: hi - BOX_WALL,
        }
    }

    fn describe(&self, dim: usize) -> Value {
        json!((0..dim)
            .map(|k| [self.lo[k], self.hi[k]])
            .collect::<Vec<_>>())
    }

    /// Fills the box with foreground, row by row along the last (contiguous) axis.
    fn fill(&self, image: &mut BinaryImage, dim: usize, side: usize) {
        let (lo, hi) = (self.lo[dim - 1], self.hi[dim - 1]);
        for start in (0..image.len()).step_by(side) {
            let c = image.coords(start);
            if (0..dim - 1).all(|k| c[k] >= self.lo[k] && c[k] <= self.hi[k]) {
                image.data_mut()[start + lo..=start + hi].fill(1);
            }
        }
    }
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
    generate_for(
        &paper_scene_family(),
        Dim::Three,
        side,
        Mode::Embed,
        rng,
        true,
        Sizing::USUAL,
    )
}
