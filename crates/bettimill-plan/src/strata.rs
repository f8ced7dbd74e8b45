//! Strata: the manifest's classes resolved into constructions, expanded over modes,
//! components and hypervolume bins, and checked for feasibility and reach (here only).

use crate::{reach, Infeasible, PlanError, Stratum};
use bettimill_grid::{Dim, Mode};
use bettimill_manifest::{ClassKind, ClassSpec, Manifest, ManifestError};
use bettimill_shapes::{Family, TubeFloor};
use bettimill_types::Solid;

/// The construction a class entry names, with every key written checked.
pub(crate) fn resolve_class(
    manifest: &Manifest,
    class: &ClassSpec,
) -> Result<Family, ManifestError> {
    let table = match &class.kind {
        ClassKind::Betti(betti) => {
            return Ok(Family::Betti {
                betti: betti.clone(),
            })
        }
        ClassKind::Family(table) => table,
    };
    let refuse = |reason: String| {
        manifest.class_error(class.entry, format!("class {}: {reason}", class.entry))
    };
    let family = <Family as serde::Deserialize>::deserialize(toml::Value::Table(table.clone()))
        .map_err(|err| refuse(err.to_string()))?;
    // serde ignores extra keys next to a unit variant (`{ family = "ball", radius = 3 }`);
    // a misspelt or unsupported parameter must never be silently dropped, so every key
    // written must survive a round trip.
    let known = toml::Value::try_from(&family)
        .ok()
        .and_then(|v| v.as_table().cloned())
        .unwrap_or_default();
    if let Some(extra) = table.keys().find(|k| !known.contains_key(*k)) {
        return Err(refuse(format!(
            "unknown field `{extra}` for family {}",
            family.label()
        )));
    }
    Ok(family)
}

/// The class object repeated `copies` times: itself for one copy, else a scene (the
/// objects of a scene class are repeated).
pub fn class_with_copies(class: &Family, copies: u32) -> Family {
    if copies == 1 {
        return class.clone();
    }
    let one: Vec<Family> = match class {
        Family::Scene { objects } => objects.clone(),
        other => vec![other.clone()],
    };
    Family::Scene {
        objects: (0..copies).flat_map(|_| one.iter().cloned()).collect(),
    }
}

/// The class object of a stratum's family: [`class_with_copies`] undone.
pub(crate) fn one_copy(family: &Family, copies: u32) -> Family {
    match family {
        Family::Scene { objects } if copies > 1 => {
            let per_copy = objects.len() / copies as usize;
            match &objects[..per_copy] {
                [one] => one.clone(),
                several => Family::Scene {
                    objects: several.to_vec(),
                },
            }
        }
        other => other.clone(),
    }
}

/// Expands the strata axes, dropping (and listing) combinations that cannot be built. A
/// class that no combination can build is refused with every distinct reason.
pub(crate) fn strata(
    manifest: &Manifest,
    classes: &[Family],
) -> Result<(Vec<Stratum>, Vec<Infeasible>), PlanError> {
    let components = manifest.components.clone().unwrap_or_else(|| vec![1]);
    let bins: Vec<Option<(u64, u64)>> = {
        let bins = manifest.hypervolume_voxel_bins();
        if bins.is_empty() {
            vec![None]
        } else {
            bins.into_iter().map(Some).collect()
        }
    };
    let side = manifest.side as usize;
    let mut strata = Vec::new();
    let mut infeasible = Vec::new();
    for (manifest_class, (class, spec)) in classes.iter().zip(&manifest.classes).enumerate() {
        let before = strata.len();
        let mut reasons: Vec<String> = Vec::new();
        for mode in manifest.mode.to_vec() {
            for &copies in &components {
                let family = class_with_copies(class, copies);
                // Whether a combination can be built does not depend on the bin.
                let dim = manifest.dimension;
                // Thick enough for the copies where that fits, else the usual floor
                // (the copies then record honestly whether they kept the topology).
                let floor = tube_floor_for(manifest, mode);
                let (tube_floor, fits) = match family.check_fits_with(dim, side, mode, floor) {
                    Err(_) if floor.thickens() => (
                        floor.thin(),
                        family.check_fits_with(dim, side, mode, floor.thin()),
                    ),
                    fits => (floor, fits),
                };
                let checked = family
                    .expected_label(dim, mode)
                    .and_then(|label| fits.map(|_| label))
                    .map_err(|err| err.to_string());
                for &bin in &bins {
                    let mut label = format!("{}/{}", class.label(), mode_name(mode));
                    if manifest.components.is_some() {
                        label.push_str(&format!("/x{copies}"));
                    }
                    if let Some((lo, hi)) = bin {
                        label.push_str(&format!("/hv{lo}-{hi}"));
                    }
                    match &checked {
                        Ok((betti, rational)) => strata.push(Stratum {
                            index: strata.len(),
                            manifest_class,
                            label,
                            family: family.clone(),
                            mode,
                            components: copies,
                            hypervolume: bin,
                            betti: betti.clone(),
                            betti_rational: rational.clone(),
                            knot_type: family.knot_type(dim, mode),
                            tube_floor,
                        }),
                        Err(reason) => {
                            if !reasons.contains(reason) {
                                reasons.push(reason.clone());
                            }
                            infeasible.push(Infeasible {
                                label,
                                reason: reason.clone(),
                            });
                        }
                    }
                }
            }
        }
        if strata.len() == before {
            // Every reason, so that a class refused in two modes for two different reasons
            // (too big here, impossible there) says both.
            return Err(manifest
                .class_error(
                    spec.entry,
                    format!(
                        "class {} ({}): {}",
                        manifest_class + 1,
                        class.label(),
                        reasons.join("; ")
                    ),
                )
                .into());
        }
    }
    Ok((strata, infeasible))
}

/// The foreground counts a stratum's samples can reach ([`reach::reach`]).
pub fn stratum_reach(manifest: &Manifest, stratum: &Stratum) -> reach::Reach {
    reach_in(
        manifest.dimension,
        manifest.side,
        manifest.solid.unwrap_or_default(),
        stratum,
    )
}

/// [`stratum_reach`] of a stratum in images of `dim` axes and `side` voxels per axis,
/// carved from `solid` in carve mode.
pub(crate) fn reach_in(dim: Dim, side: u32, solid: Solid, stratum: &Stratum) -> reach::Reach {
    let d = dim.get();
    let tunnel = match stratum.family {
        Family::Tunnel { intervals, .. } => Some(intervals),
        _ => None,
    };
    // The phase's Betti numbers: the objects' in embed mode; in carve mode the cavities',
    // which duality gives from the solid's (each cavity encloses a void of the solid, and
    // the solid's last number counts them); a tunnel encloses none.
    let b = &stratum.betti;
    let phase_betti = match stratum.mode {
        Mode::Embed => b.clone(),
        Mode::Carve if tunnel.is_some() => vec![1],
        Mode::Carve => (0..d)
            .map(|k| match k {
                0 => b[d - 1],
                k if k == d - 1 => b[0].saturating_sub(1),
                k => b[d - 1 - k],
            })
            .collect(),
    };
    let smallest_radius =
        stratum
            .family
            .smallest_object_radius(dim, stratum.mode, stratum.tube_floor.thin());
    // A scene's holes are its objects' own, each at its own size, and a Betti class's
    // those of the construction it is built as.
    let parts = match objects(&stratum.family, dim, stratum.mode) {
        several if several.len() > 1 && tunnel.is_none() => several
            .iter()
            .map(|object| reach::Part {
                betti: object
                    .expected_betti(dim, Mode::Embed)
                    .unwrap_or_else(|_| vec![1]),
                radius: object.smallest_object_radius(dim, stratum.mode, stratum.tube_floor.thin()),
                shape: part_shape(object, dim),
            })
            .collect(),
        one => vec![reach::Part {
            betti: phase_betti.clone(),
            radius: smallest_radius,
            shape: one
                .first()
                .map_or(reach::PartShape::Other, |o| part_shape(o, dim)),
        }],
    };
    reach::reach(&reach::Stratum {
        dim: d,
        side,
        mode: stratum.mode,
        solid,
        phase_betti,
        tunnel,
        smallest_radius,
        largest_radius: tunnel.map(|_| bettimill_shapes::largest_tunnel_radius(side as usize)),
        parts,
        solid_betti: match stratum.mode {
            Mode::Carve => b.clone(),
            Mode::Embed => Vec::new(),
        },
    })
}

/// The objects a sample of `family` is built of in `dim` and `mode`: a scene's (each
/// Betti class among them as the construction it is built as), or the one.
fn objects(family: &Family, dim: Dim, mode: Mode) -> Vec<Family> {
    match family {
        Family::Scene { objects: several } => several
            .iter()
            .flat_map(|object| objects(object, dim, mode))
            .collect(),
        Family::Betti { .. } => match family.realisation(dim, mode) {
            Some(built) => objects(&built, dim, mode),
            None => vec![family.clone()],
        },
        one => vec![one.clone()],
    }
}

/// What the holes and voids of one object of `family` in `dim` axes are wrapped in.
fn part_shape(family: &Family, dim: Dim) -> reach::PartShape {
    match family {
        Family::Ball
        | Family::Split { .. }
        | Family::Handle
        | Family::S2xB2
        | Family::BumpyS2xB2
        | Family::Curve
        | Family::Loop => reach::PartShape::Tube,
        Family::Shell | Family::BumpyShell => reach::PartShape::Shell,
        // A 2D torus shell is an annulus, built as a shell.
        Family::TorusShell if dim.get() == 2 => reach::PartShape::Shell,
        Family::TorusShell if dim.get() == 3 => reach::PartShape::TorusShell,
        Family::Tentacled { object, .. } => part_shape(object, dim),
        _ => reach::PartShape::Other,
    }
}

/// Refuses a manifest with a binned stratum that no sample can bring into its bin: every
/// attempt of every shard holding it would fail, so nothing would be built.
pub(crate) fn check_reach(manifest: &Manifest, strata: &[Stratum]) -> Result<(), PlanError> {
    let voxels = manifest.voxels() as f64;
    let share = |count: u64| count as f64 / voxels;
    let mut refusals: Vec<String> = Vec::new();
    for stratum in strata {
        let Some((lo, hi)) = stratum.hypervolume else {
            continue;
        };
        let r = stratum_reach(manifest, stratum);
        // The way on, in both units: a fraction rounded outwards to the 4 decimals shown,
        // so that the one printed is itself a bin end that works.
        let why = if hi < r.lowest {
            let end = (share(r.lowest + 1) * 1e4).ceil() / 1e4;
            format!(
                "its samples keep at least {} foreground voxels ({:.4} of the image): {}; \
                 a bin must end above {} voxels (at {end:.4} or more as a fraction) to be \
                 built, or leave this combination out",
                r.lowest,
                share(r.lowest),
                r.lowest_why,
                r.lowest
            )
        } else if lo > r.highest {
            let start = (share(r.highest) * 1e4).floor() / 1e4;
            format!(
                "its samples have at most {} foreground voxels ({:.4} of the image): {}; \
                 a bin must start at or below {} voxels (at {start:.4} or less as a \
                 fraction) to be built, or leave this combination out",
                r.highest,
                share(r.highest),
                r.highest_why,
                r.highest
            )
        } else {
            continue;
        };
        refusals.push(format!(
            "stratum {} cannot reach its bin of {lo}-{hi} foreground voxels \
             ({:.4}-{:.4} of the image): {why}",
            stratum.label,
            share(lo),
            share(hi + 1)
        ));
    }
    if refusals.is_empty() {
        return Ok(());
    }
    let shown = 3;
    let mut reason = refusals[..refusals.len().min(shown)].join("; ");
    if refusals.len() > shown {
        reason.push_str(&format!(
            "; and {} more unreachable strata",
            refusals.len() - shown
        ));
    }
    Err(manifest.error("bins", reason).into())
}

/// The tube floor a manifest's constructions in `mode` aim for: carve mode with
/// downscaled copies pools them by max pooling ([`bettimill_format::Pooling`]), which fills a
/// cavity thinner than a few blocks, so its cavities are at least
/// [`TubeFloor::for_copies`] of the largest copy's pooling factor. Embed mode (objects grow
/// under max pooling; what closes is background between them) and manifests without
/// copies keep [`TubeFloor::USUAL`]. Gaps are the manifest's `inner_gap` in either mode.
pub fn tube_floor_for(manifest: &Manifest, mode: Mode) -> TubeFloor {
    match manifest.resolutions.iter().max() {
        Some(&largest) if mode == Mode::Carve => {
            TubeFloor::for_copies(manifest.dimension, (manifest.side / largest) as usize)
        }
        _ => TubeFloor::USUAL,
    }
    .with_gap(manifest.inner_gap.unwrap_or(bettimill_types::MIN_INNER_GAP))
}

/// The manifest spelling of a mode.
pub fn mode_name(mode: Mode) -> &'static str {
    mode.name()
}
