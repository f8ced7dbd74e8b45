//! The family cases shared by `tests/verify.rs` (bounded, with every `cargo test`) and
//! `examples/shape_report.rs` (the long sweeps that print rates, sides and tables), and
//! the one function that compares a family's label with the homology crate.

use bettimill_shapes::{generate, Dim, Family, KnotKind, LinkKind, Mode};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Generates `count` instances (seeds `first..first+count`) and returns one line per
/// instance that disagrees with the homology crate; `None` if the family does not fit.
pub fn mismatches(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    first: u64,
    count: u64,
) -> Option<Vec<String>> {
    if family.check_fits(dim, side, mode).is_err() {
        return None;
    }
    let mut bad = Vec::new();
    for seed in first..first + count {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let g = generate(family, dim, side, mode, &mut rng)
            .unwrap_or_else(|e| panic!("{family} {dim}D side {side} {mode} seed {seed}: {e}"));
        let t = bettimill_homology::topology(&g.image);
        if t.betti != g.betti {
            bad.push(format!(
                "MISMATCH {family} {dim}D side {side} {mode} seed {seed}: computed {:?}, label {:?}",
                t.betti, g.betti
            ));
        }
    }
    Some(bad)
}

/// Every family with the side it is tested at in each dimension (0 = not tested there).
/// Sides are modest: 2D 32-48, 3D 32-64, 4D 16-32 (larger 4D constructions are listed in
/// `large_4d` of the example).
pub fn cases() -> Vec<(Family, [usize; 3])> {
    use Family::*;
    let knot = |knot| Knot { knot };
    let link = |link| Link { link };
    vec![
        (Ball, [32, 32, 16]),
        (Handle, [32, 32, 20]),
        (Shell, [32, 32, 20]),
        (Split { parts: 2 }, [32, 32, 24]),
        (TorusShell, [32, 40, 0]),
        (Handlebody { genus: 2 }, [32, 40, 32]),
        (Handlebody { genus: 3 }, [48, 48, 0]),
        (S2xB2, [0, 0, 20]),
        (BumpyShell, [32, 32, 20]),
        (BumpyS2xB2, [0, 0, 20]),
        (T2xB2, [0, 0, 32]),
        (S1xHandlebody { j: 1 }, [0, 40, 32]),
        (S1xHandlebody { j: 2 }, [0, 64, 0]),
        (
            ConnectedSum {
                g: 1,
                h: 1,
                i: 0,
                j: 0,
            },
            [0, 40, 32],
        ),
        (
            ConnectedSum {
                g: 1,
                h: 0,
                i: 1,
                j: 1,
            },
            [0, 48, 0],
        ),
        (
            ConnectedSum {
                g: 1,
                h: 1,
                i: 1,
                j: 1,
            },
            [0, 64, 0],
        ),
        (
            Tunnel {
                intervals: 1,
                circle: false,
                genus: 0,
            },
            [32, 32, 16],
        ),
        (
            Tunnel {
                intervals: 2,
                circle: false,
                genus: 0,
            },
            [0, 32, 16],
        ),
        (
            Tunnel {
                intervals: 1,
                circle: true,
                genus: 0,
            },
            [0, 32, 20],
        ),
        (
            Tunnel {
                intervals: 2,
                circle: true,
                genus: 0,
            },
            [0, 0, 20],
        ),
        (
            Tunnel {
                intervals: 1,
                circle: false,
                genus: 2,
            },
            [0, 40, 32],
        ),
        (Curve, [32, 32, 16]),
        (Loop, [32, 32, 20]),
        (knot(KnotKind::Unknot), [0, 32, 20]),
        (knot(KnotKind::Trefoil), [0, 48, 0]),
        (knot(KnotKind::FigureEight), [0, 48, 0]),
        (knot(KnotKind::Cinquefoil), [0, 48, 0]),
        (TorusKnot { p: 2, q: 3 }, [0, 48, 0]),
        (TorusKnot { p: 3, q: 3 }, [0, 40, 0]),
        (link(LinkKind::Hopf), [0, 40, 0]),
        (link(LinkKind::Whitehead), [0, 56, 0]),
        (link(LinkKind::Borromean), [0, 48, 0]),
        (link(LinkKind::Solomon), [0, 48, 0]),
        (
            SpunKnot {
                knot: KnotKind::Unknot,
            },
            [0, 0, 32],
        ),
        (KleinBottle, [0, 0, 32]),
        (
            Tentacled {
                object: Box::new(Handle),
                tentacles: 2,
            },
            [40, 40, 0],
        ),
        (
            Tentacled {
                object: Box::new(knot(KnotKind::Trefoil)),
                tentacles: 2,
            },
            [0, 56, 0],
        ),
        (
            Scene {
                objects: vec![Ball, Handle, Handlebody { genus: 2 }],
            },
            [48, 48, 0],
        ),
        (bettimill_shapes::paper_scene_family(), [0, 64, 0]),
    ]
}
