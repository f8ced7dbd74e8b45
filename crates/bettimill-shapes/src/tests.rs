//! Unit tests: every family against the simple topology checks of [`crate::check`], plus
//! determinism, serde names and feasibility errors.

use crate::check::{summary, summary_of};
use crate::*;
use rand::SeedableRng;

/// Generates `count` instances and compares the simple checks with the label; returns the
/// number of mismatches so callers can state a tolerated rate.
fn mismatches(family: &Family, dim: Dim, side: usize, mode: Mode, count: u64) -> usize {
    let mut bad = 0;
    for seed in 0..count {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let generated = generate(family, dim, side, mode, &mut rng)
            .unwrap_or_else(|e| panic!("{family} {dim}D side {side} {mode}: {e}"));
        assert_eq!(generated.image.shape(), vec![side; dim.get()].as_slice());
        assert_eq!(generated.betti, family.expected_betti(dim, mode).unwrap());
        assert!(generated.image.border_is_background());
        let found = summary(&generated.image);
        let want = summary_of(&generated.betti);
        if found != want {
            eprintln!("{family} {dim}D {mode} seed {seed}: found {found:?}, want {want:?}");
            bad += 1;
        }
    }
    bad
}

fn check(family: Family, cases: &[(Dim, usize, u64)]) {
    for &(dim, side, count) in cases {
        for mode in [Mode::Embed, Mode::Carve] {
            let bad = mismatches(&family, dim, side, mode, count);
            assert!(
                bad == 0,
                "{family} {dim}D {mode}: {bad} of {count} mismatched"
            );
        }
    }
}

#[test]
fn ball() {
    check(
        Family::Ball,
        &[(Dim::Two, 32, 20), (Dim::Three, 32, 10), (Dim::Four, 16, 3)],
    );
}

#[test]
fn handle() {
    check(
        Family::Handle,
        &[(Dim::Two, 32, 20), (Dim::Three, 32, 10), (Dim::Four, 20, 3)],
    );
}

#[test]
fn curve() {
    check(
        Family::Curve,
        &[(Dim::Two, 32, 10), (Dim::Three, 32, 5), (Dim::Four, 16, 2)],
    );
}

#[test]
fn scene_of_balls_and_handles_keeps_components_apart() {
    let scene = Family::Scene {
        objects: vec![Family::Ball, Family::Handle, Family::Ball, Family::Handle],
    };
    check(scene, &[(Dim::Two, 40, 20), (Dim::Three, 40, 5)]);
}

#[test]
fn same_seed_same_bytes() {
    let family = Family::Scene {
        objects: vec![Family::Handle, Family::Ball],
    };
    let run = |seed| {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let g = generate(&family, Dim::Three, 32, Mode::Carve, &mut rng).unwrap();
        (g.image, g.construction.to_string())
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5).0, run(6).0);
}

#[test]
fn serde_names_match_the_manifest_syntax() {
    let cases = [
        (r#"{"family":"ball"}"#, Family::Ball),
        (
            r#"{"family":"handlebody","genus":2}"#,
            Family::Handlebody { genus: 2 },
        ),
        (
            r#"{"family":"connected_sum","g":1,"h":0,"i":1,"j":2}"#,
            Family::ConnectedSum {
                g: 1,
                h: 0,
                i: 1,
                j: 2,
            },
        ),
        (
            r#"{"family":"knot","knot":"trefoil"}"#,
            Family::Knot {
                knot: KnotKind::Trefoil,
            },
        ),
        (r#"{"family":"s2_x_b2"}"#, Family::S2xB2),
        (
            r#"{"family":"scene","objects":[{"family":"ball"},{"family":"handle"}]}"#,
            Family::Scene {
                objects: vec![Family::Ball, Family::Handle],
            },
        ),
    ];
    for (text, family) in cases {
        let parsed: Family = serde_json::from_str(text).unwrap();
        assert_eq!(parsed, family);
        let back: Family = serde_json::from_str(&serde_json::to_string(&family).unwrap()).unwrap();
        assert_eq!(back, family);
    }
    // Unknown fields are refused on struct variants (serde ignores them on unit ones).
    assert!(serde_json::from_str::<Family>(r#"{"family":"handlebody","genus":2,"g":1}"#).is_err());
    assert!(serde_json::from_str::<Family>(r#"{"family":"teapot"}"#).is_err());
}

#[test]
fn infeasible_requests_are_refused_up_front() {
    assert!(matches!(
        Family::Handle.check_fits(Dim::Four, 12, Mode::Carve),
        Err(ShapeError::DoesNotFit { .. })
    ));
    assert!(matches!(
        Family::S2xB2.expected_betti(Dim::Three, Mode::Embed),
        Err(ShapeError::Unsupported { .. })
    ));
    assert!(matches!(
        Family::Handlebody { genus: 0 }.expected_betti(Dim::Three, Mode::Embed),
        Err(ShapeError::InvalidParameters { .. })
    ));
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    assert!(generate(&Family::Ball, Dim::Two, 5, Mode::Embed, &mut rng).is_err());
    // Too many objects for the room: refused, not retried forever.
    let crowd = Family::Scene {
        objects: vec![Family::Handle; 40],
    };
    assert!(crowd.check_fits(Dim::Two, 32, Mode::Embed).is_err());
    assert!(generate(&crowd, Dim::Two, 32, Mode::Embed, &mut rng).is_err());
}

#[test]
fn carve_labels_follow_the_duality() {
    assert_eq!(
        Family::Ball
            .expected_betti(Dim::Three, Mode::Carve)
            .unwrap(),
        vec![1, 0, 1]
    );
    assert_eq!(
        Family::Handle
            .expected_betti(Dim::Four, Mode::Carve)
            .unwrap(),
        vec![1, 0, 1, 1]
    );
    assert_eq!(
        Family::Handle
            .expected_betti(Dim::Two, Mode::Carve)
            .unwrap(),
        vec![2, 1]
    );
}
