//! The label table: the analytic Betti numbers of every family, and its knot type.
//!
//! A sample's label is stated by its construction, never computed from its voxels, so
//! this table is the contract the verifier in `bettimill-homology` checks every sample
//! against. Embed labels are written per family (S1 x B(d-1) has b = (1, 1, 0, ..), a
//! (d-1)-torus has binomial coefficients, ...); carve labels follow by the duality of
//! `notes/labels.md` (b0 = 1 + b_{d-1}, b_k = b_{d-1-k}, b_{d-1} = b0), except for tunnels,
//! which reach the cube's boundary and have their own formula ([`tunnel_betti`]). The
//! table also rejects families that do not exist in a dimension or whose parameters are out
//! of range, which is why it is consulted before anything is built.

use crate::geometry::gcd;
use crate::{Dim, Family, Mode, ShapeError};

pub(crate) type Betti = (Vec<u64>, Option<Vec<u64>>);

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
pub(crate) fn embed_betti(family: &Family, dim: Dim) -> Result<Betti, ShapeError> {
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
        Family::Split { parts } => {
            if !(2..=4).contains(parts) {
                return Err(invalid(family, "parts must be between 2 and 4"));
            }
            unit(d, &[*parts as u64])
        }
        Family::Handle | Family::Loop => unit(d, &[1, 1]),
        Family::Shell | Family::BumpyShell => {
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
        Family::BumpyS2xB2 => {
            only_4d("bumpy_s2_x_b2 is four-dimensional; in 3D use bumpy_shell")?;
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
            | Family::Loop
            | Family::Knot { .. }
            | Family::TorusKnot { .. }
            | Family::Link { .. }
    )
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
pub(crate) fn tunnel_cycles(family: &Family) -> u32 {
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
    // A carved family is refused in the mode the manifest asked for, not in the embed
    // mode its numbers are derived from.
    let (z2, q) = embed_betti(family, dim).map_err(|err| match err {
        ShapeError::Unsupported {
            family,
            dim,
            reason,
            ..
        } => ShapeError::Unsupported {
            family,
            dim,
            mode,
            reason,
        },
        other => other,
    })?;
    Ok(match mode {
        Mode::Embed => (z2, q),
        Mode::Carve => (dual(&z2), q.map(|q| dual(&q))),
    })
}

/// An error about the construction of a Betti class, told in terms of the class.
pub(crate) fn realised_as(err: ShapeError, class: &Family, realised: &Family) -> ShapeError {
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

/// The `knot_type` a sample of `family` records: the knot or link types of its objects
/// joined by `+`, or `"none"`. A class given as a Betti vector records that of its
/// realisation.
pub(crate) fn knot_type_label(family: &Family, dim: Dim, mode: Mode) -> String {
    if let Family::Betti { betti } = family {
        return match crate::betti_class::realise(betti, dim, mode) {
            Ok(realised) => knot_type_label(&realised, dim, mode),
            Err(_) => "none".to_string(),
        };
    }
    let objects: Vec<&Family> = match family {
        Family::Scene { objects } => objects.iter().collect(),
        other => vec![other],
    };
    let types: Vec<String> = objects
        .iter()
        .filter_map(|o| knot_type_of(o, dim.get()))
        .collect();
    if types.is_empty() {
        "none".to_string()
    } else {
        types.join("+")
    }
}

pub(crate) fn knot_type_of(family: &Family, dim: usize) -> Option<String> {
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
