//! Classes given by their Betti vector: which construction realises a requested label.
//!
//! A manifest may ask for "samples with Betti numbers (1, 2, 1, 0)" instead of naming a
//! family. [`realise`] turns such a vector into a concrete family (one object, or a scene
//! of several) whose analytic label is exactly that vector in the requested mode; the
//! caller then checks the result against the ordinary label table, so a mistake here can
//! only make a class infeasible, never mislabel a sample.
//!
//! The rule, in object terms (carve mode first translates the cube's label into the label
//! of the cavities through the duality of the labels note):
//! - the object has `b0` components; `b_{d-1}` of them are shells (a thickened
//!   (d-1)-sphere encloses one void; 2D has no middle numbers, so there the holes go to
//!   disks with holes instead);
//! - the middle numbers (b1 in 3D; b1 and b2 in 4D) are dealt greedily to the remaining
//!   components as handlebodies (3D) or Table I boundary sums of g S1xB3 and h S2xB2 (4D),
//!   at most 8 handles (3D) or 6 summands (4D) per component;
//! - every other component is a ball; and where a single family has the label of a
//!   boundary sum and is smaller (T2xB2 for two S1xB3 and one S2xB2), it is used instead.
//!
//! The choice is canonical (the same vector always gives the same construction), so a
//! Betti class is one stratum with one recipe; the sample's random rotation, scale,
//! position and deformation still vary per sample.

use crate::{Dim, Family, Mode, ShapeError};

/// Most handles of one 2D or 3D handlebody (the family's own limit).
const MAX_GENUS: u64 = 8;
/// Most summands of one 4D boundary connected sum (the family's own limit).
const MAX_SUMMANDS: u64 = 6;
/// Most objects of one scene (the family's own limit).
const MAX_OBJECTS: u64 = 64;

/// The family realising `betti` (b_0..b_{d-1}) in `dim` and `mode`, or why there is none.
pub(crate) fn realise(betti: &[u64], dim: Dim, mode: Mode) -> Result<Family, ShapeError> {
    let d = dim.get();
    let class = Family::Betti {
        betti: betti.to_vec(),
    };
    let impossible = |reason: String| ShapeError::Unsupported {
        family: class.label(),
        dim: d,
        mode,
        reason,
    };
    if betti.len() != d {
        return Err(ShapeError::InvalidParameters {
            family: class.label(),
            reason: format!(
                "has {} entries; a {d}D image has Betti numbers b0..b{} ({d} entries)",
                betti.len(),
                d - 1
            ),
        });
    }
    // The object's (or the cavities') label.
    let object = match mode {
        Mode::Embed => {
            if betti[0] == 0 {
                return Err(impossible("b0 = 0 is the empty image".into()));
            }
            betti.to_vec()
        }
        Mode::Carve => {
            // Inverse of the duality cube minus X: (1 + x_{d-1}, x_{d-2}, ..., x_1, x_0).
            if betti[0] == 0 {
                return Err(impossible(
                    "a carved cube always has b0 >= 1 (the cube itself)".into(),
                ));
            }
            if betti[d - 1] == 0 {
                return Err(impossible(format!(
                    "every cavity encloses a void, so a carved sample has b{} >= 1 \
                     ([1, 0, ...] is the solid cube with no cavity)",
                    d - 1
                )));
            }
            let mut x = vec![0; d];
            x[0] = betti[d - 1];
            x[d - 1] = betti[0] - 1;
            for k in 1..d - 1 {
                x[k] = betti[d - 1 - k];
            }
            x
        }
    };
    let what = match mode {
        Mode::Embed => "objects",
        Mode::Carve => "cavities",
    };
    let components = object[0];
    if components > MAX_OBJECTS {
        return Err(impossible(format!(
            "{components} {what}; a scene holds at most {MAX_OBJECTS}"
        )));
    }
    let mut objects = Vec::new();
    let (shells, middle) = if d == 2 {
        // In 2D the top number counts holes, carried by disks with holes.
        (0, vec![object[1]])
    } else {
        (object[d - 1], object[1..d - 1].to_vec())
    };
    if shells > components {
        return Err(impossible(format!(
            "{shells} enclosed voids need {shells} shells, but there are only {components} {what} \
             (a component with several voids is not in the shape library)"
        )));
    }
    for _ in 0..shells {
        objects.push(Family::Shell);
    }
    let mut remaining = middle;
    let free = components - shells;
    for _ in 0..free {
        objects.push(take_handles(&mut remaining, d));
    }
    if remaining.iter().any(|&r| r > 0) {
        let names: Vec<String> = (1..d - usize::from(d > 2))
            .map(|k| format!("b{k}"))
            .collect();
        let names = names.join(", ");
        return Err(impossible(if free == 0 {
            format!(
                "each of the {components} {what} must be a shell (one per enclosed void), so none is left \
                 to carry {names} (a shell with handles is not in the shape library)"
            )
        } else {
            format!(
                "{names} do not fit on {free} non-shell {what} (at most {} per component)",
                if d == 4 {
                    format!("{MAX_SUMMANDS} summands")
                } else {
                    format!("{MAX_GENUS} handles")
                },
            )
        }));
    }
    Ok(if objects.len() == 1 {
        objects.pop().expect("one object")
    } else {
        Family::Scene { objects }
    })
}

/// One component carrying as many of the `remaining` middle Betti numbers as one object
/// can (2D/3D: holes or handles; 4D: (b1, b2) as g S1xB3 and h S2xB2 summands).
fn take_handles(remaining: &mut [u64], d: usize) -> Family {
    if d < 4 {
        let genus = remaining[0].min(MAX_GENUS);
        remaining[0] -= genus;
        return match genus {
            0 => Family::Ball,
            1 => Family::Handle,
            g => Family::Handlebody { genus: g as u32 },
        };
    }
    let g = remaining[0].min(MAX_SUMMANDS);
    let h = remaining[1].min(MAX_SUMMANDS - g);
    remaining[0] -= g;
    remaining[1] -= h;
    match (g, h) {
        (0, 0) => Family::Ball,
        (1, 0) => Family::Handle,
        (0, 1) => Family::S2xB2,
        // T2xB2 has the label of S1xB3 # S1xB3 # S2xB2 and fits in a smaller image.
        (2, 1) => Family::T2xB2,
        (g, 0) => Family::Handlebody { genus: g as u32 },
        (g, h) => Family::ConnectedSum {
            g: g as u32,
            h: h as u32,
            i: 0,
            j: 0,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every small vector either realises to a family whose own label is that vector, or
    /// is refused with a reason; never a family with another label.
    #[test]
    fn realised_families_carry_the_requested_label() {
        let mut realised = 0;
        for dim in Dim::ALL {
            let d = dim.get();
            let total = 5u64.pow(d as u32);
            for code in 0..total {
                let betti: Vec<u64> = (0..d).map(|k| code / 5u64.pow(k as u32) % 5).collect();
                for mode in [Mode::Embed, Mode::Carve] {
                    match realise(&betti, dim, mode) {
                        Ok(family) => {
                            let label = family.expected_betti(dim, mode).unwrap();
                            assert_eq!(label, betti, "{d}D {mode} {}", family.label());
                            realised += 1;
                        }
                        Err(err) => assert!(!err.to_string().is_empty()),
                    }
                }
            }
        }
        assert!(realised > 300, "{realised}");
    }

    #[test]
    fn typical_vectors() {
        let four = Dim::new(4).unwrap();
        assert_eq!(
            realise(&[1, 2, 1, 0], four, Mode::Embed).unwrap(),
            Family::T2xB2
        );
        assert_eq!(
            realise(&[1, 1, 1, 0], four, Mode::Embed).unwrap(),
            Family::ConnectedSum {
                g: 1,
                h: 1,
                i: 0,
                j: 0
            }
        );
        // A cube with one cavity S2xB2: (1, 1, 0, 1).
        assert_eq!(
            realise(&[1, 1, 0, 1], four, Mode::Carve).unwrap(),
            Family::S2xB2
        );
        let err = realise(&[1, 0, 0, 0], four, Mode::Carve).unwrap_err();
        assert!(err.to_string().contains("solid cube"), "{err}");
        let err = realise(&[1, 1, 0, 1], four, Mode::Embed).unwrap_err();
        assert!(err.to_string().contains("must be a shell"), "{err}");
        let err = realise(&[1, 1], four, Mode::Embed).unwrap_err();
        assert!(err.to_string().contains("entries"), "{err}");
        let three = Dim::new(3).unwrap();
        assert_eq!(
            realise(&[2, 3, 1], three, Mode::Embed).unwrap(),
            Family::Scene {
                objects: vec![Family::Shell, Family::Handlebody { genus: 3 }]
            }
        );
    }
}
