use super::*;
use rand::SeedableRng;

/// A flattened tube: holds its skeleton, reaches `stretch` times its radius along the
/// stretched axes and its radius across the skeleton's plane, and `reach` bounds the
/// norm of every point in it while some point comes within a voxel of that bound.
#[test]
fn flattened_tubes_widen_away_from_their_plane_within_their_reach() {
    let circle = Piece::Circle {
        centre: ORIGIN,
        radius: 7.0,
        u: axis(0),
        v: axis(1),
    };
    let wavy = Piece::polyline(
        (0..40)
            .map(|k| {
                let t = 2.0 * std::f64::consts::PI * k as f64 / 40.0;
                [
                    6.0 * libm::cos(t),
                    5.0 * libm::sin(t),
                    libm::sin(2.0 * t),
                    0.5,
                ]
            })
            .collect(),
        true,
    );
    let sphere = Piece::Sphere {
        centre: ORIGIN,
        radius: 5.0,
        axes: 3,
    };
    // Bumps and a lift into the stretched axis, all largest along the first axis, so
    // that the bound is reached there.
    let bumpy = Piece::Bumpy {
        centre: ORIGIN,
        radius: 5.0,
        axes: 3,
        stretches: vec![(axis(0), 1.0), (axis(1), 0.5)],
        lumps: vec![(axis(0), 0.8)],
        bend: (axis(0), 1.5),
    };
    // Its skeleton stays where it was, lift included.
    let tip = [6.8, 0.0, 0.0, 1.5];
    assert!(bumpy.distance(tip) < 1e-12);
    assert!(Piece::flattened(bumpy.clone(), 3.0, 3)
        .unwrap()
        .within(tip, 1e-9));
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for (piece, from, stretch, r) in [
        (circle, 2, 3.0, 2.0),
        (wavy, 2, 2.5, 1.5),
        (sphere, 3, 4.0, 2.0),
        (bumpy, 3, 3.0, 2.0),
    ] {
        let flat = Piece::flattened(piece.clone(), stretch, from).unwrap();
        let reach = flat.reach(r);
        for point in piece.sample_points() {
            assert!(flat.within(point, r), "{point:?} of the skeleton");
        }
        // Across the plane at the skeleton's first axis point, and along the first
        // stretched axis.
        let start = [piece.extent().min(7.0), 0.0, 0.0, 0.0];
        if flat.within(start, 0.0) {
            let mut along = start;
            along[from] = 0.99 * stretch * r;
            assert!(flat.within(along, r));
            along[from] = 1.01 * stretch * r;
            assert!(!flat.within(along, r));
            assert!(flat.within(add(start, scale(axis(0), 0.99 * r)), r));
            assert!(!flat.within(add(start, scale(axis(0), 1.01 * r)), r));
        }
        let mut farthest: f64 = 0.0;
        for _ in 0..200_000 {
            let p = [0, 1, 2, 3].map(|_| uniform(&mut rng, -reach - 1.0, reach + 1.0));
            if flat.within(p, r) {
                assert!(norm(p) <= reach + 1e-9, "{p:?} beyond the reach {reach}");
                farthest = farthest.max(norm(p));
            }
        }
        assert!(farthest > reach - 1.0, "reach {reach} is loose: {farthest}");
    }
}

#[test]
fn tube_floors_for_copies() {
    let floor = |dim, factor| TubeFloor::for_copies(dim, factor).radius();
    assert_eq!(floor(Dim::Four, 2), 3.0);
    assert_eq!(floor(Dim::Four, 4), 7.0);
    assert!((floor(Dim::Three, 2) - 1.5 * 3f64.sqrt()).abs() < 1e-12);
    // Never below the usual 2 voxels.
    assert_eq!(floor(Dim::Two, 1), TubeFloor::USUAL.radius());
    assert_eq!(TubeFloor::default(), TubeFloor::USUAL);
    // A family's range is raised, never lowered.
    assert_eq!(
        TubeFloor::for_copies(Dim::Four, 2).raise((2.0, 4.0)),
        (3.0, 4.0)
    );
    assert_eq!(
        TubeFloor::for_copies(Dim::Four, 2).raise((1.5, 3.0)),
        (3.0, 3.0)
    );
    assert_eq!(TubeFloor::USUAL.raise((1.5, 3.0)), (1.5, 3.0));
}

#[test]
fn distances_of_simple_pieces() {
    let circle = Piece::Circle {
        centre: ORIGIN,
        radius: 5.0,
        u: axis(0),
        v: axis(1),
    };
    assert!((circle.distance([0.0, 0.0, 0.0, 0.0]) - 5.0).abs() < 1e-12);
    assert!((circle.distance([5.0, 0.0, 3.0, 0.0]) - 3.0).abs() < 1e-12);
    let torus = Piece::Torus {
        major: 6.0,
        minor: 2.0,
    };
    assert!(torus.distance([8.0, 0.0, 0.0, 0.0]).abs() < 1e-12);
    assert!((torus.distance([6.0, 0.0, 0.0, 1.0]) - 5.0f64.sqrt()).abs() < 1e-12);
    let klein = Piece::Klein {
        major: 6.0,
        minor: 2.0,
    };
    // u = 0, v = pi/2 lies on the surface: (6, 0, 2, 0).
    assert!(klein.distance([6.0, 0.0, 2.0, 0.0]).abs() < 1e-12);
    // u = pi, v = pi/2: (-6, 0, 0, 2).
    assert!(klein.distance([-6.0, 1e-12, 0.0, 2.0]).abs() < 1e-9);
    let spun = Piece::Spun {
        centre: ORIGIN,
        inner: vec![Piece::Point([4.0, 1.0, 0.0, 0.0])],
    };
    assert!(spun.distance([0.0, 4.0, 1.0, 0.0]).abs() < 1e-12);
}
