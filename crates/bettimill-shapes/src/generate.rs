//! The generation driver: feasibility at plan time, and one labelled instance at build time.
//!
//! [`check_fits`] is a promise: if it accepts a request (every object fits the image on
//! its own, and all of them together fit a grid of cells or the canonical layout of
//! `place.rs`), [`generate`] succeeds for every seed. [`generate`] looks the label up
//! (`labels.rs`), places the objects (`place.rs`), writes their voxels into an empty image
//! or clears them from a solid cube (carve mode), and records how every object was built,
//! with its JSON keys in sorted order so the record's bytes never depend on serde_json's
//! features.

use crate::geometry::round6;
use crate::labels::{embed_betti, expected, knot_type_label, realised_as};
use crate::place::{
    canonical_layout, grid_fits, place_objects, place_tunnel, PlacementArea, Region, CUBE_MARGIN,
};
use crate::sizing::min_extent;
use crate::{BinaryImage, Dim, Family, Generated, KnotKind, LinkKind, Mode, ShapeError};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Map, Value};

fn objects_of(family: &Family) -> Vec<Family> {
    match family {
        Family::Scene { objects } => objects.clone(),
        other => vec![other.clone()],
    }
}

/// Plan-time feasibility ([`crate::Family::check_fits`]): the label exists, every object
/// fits on its own, and all of them fit together.
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

/// One random instance with its label ([`crate::generate`]).
pub(crate) fn generate(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    rng: &mut ChaCha8Rng,
) -> Result<Generated, ShapeError> {
    generate_sized(family, dim, side, mode, rng, true)
}

/// [`generate`], with the size checks (`check`) or without them, for a request
/// [`check_fits`] has accepted ([`crate::generate_planned`]). The checks draw nothing from
/// `rng`, so both give the same voxels.
pub(crate) fn generate_sized(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    rng: &mut ChaCha8Rng,
    check: bool,
) -> Result<Generated, ShapeError> {
    if let Family::Betti { betti } = family {
        // The realisation is generated as itself; its record says which class it serves.
        let realised = crate::betti_class::realise(betti, dim, mode)?;
        let mut generated = generate_sized(&realised, dim, side, mode, rng, check)
            .map_err(|err| realised_as(err, family, &realised))?;
        if let Value::Object(map) = &mut generated.construction {
            map.insert("class".into(), json!(family.label()));
        }
        generated.construction = sort_keys(generated.construction);
        return Ok(generated);
    }
    if check {
        check_sizes(family, dim, side, mode, false)?;
    }
    let (betti, betti_rational) = expected(family, dim, mode)?;
    let d = dim.get();
    let region = Region::for_mode(side, mode);
    let objects = objects_of(family);
    let (placed, strategy) = if let Family::Tunnel { .. } = family {
        (vec![place_tunnel(family, d, side, region, rng)?], "tunnel")
    } else {
        let canvas = PlacementArea {
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
