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
fn split_balls_come_in_their_pieces() {
    for parts in 2..=4 {
        // Four parts fit a 4D carved cube from side 36: a costly case that tells nothing
        // the others do not.
        let mut cases = vec![(Dim::Two, 40, 20), (Dim::Three, 40, 10)];
        if parts < 4 {
            cases.push((Dim::Four, 16 + 4 * parts as usize, 2));
        }
        check(Family::Split { parts }, &cases);
    }
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
        (r#"{"family":"split"}"#, Family::Split { parts: 2 }),
        (
            r#"{"family":"split","parts":3}"#,
            Family::Split { parts: 3 },
        ),
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
fn a_construction_that_does_not_fit_names_the_smallest_side_that_does() {
    let (dim, mode) = (Dim::Four, Mode::Embed);
    let smallest = Family::T2xB2.min_side(dim, mode).unwrap();
    assert!(Family::T2xB2.check_fits(dim, smallest, mode).is_ok());
    let message = Family::T2xB2
        .check_fits(dim, smallest - 1, mode)
        .unwrap_err()
        .to_string();
    assert!(
        message.ends_with(&format!("; the smallest side that fits is {smallest}")),
        "{message}"
    );
    let message = Family::T2xB2
        .check_fits(dim, 16, mode)
        .unwrap_err()
        .to_string();
    assert!(message.contains("side 16"), "{message}");
    assert!(message.contains(&format!("the smallest side that fits is {smallest}")));
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

#[test]
fn labels_of_the_paper_tables() {
    let b = |family: Family, dim: Dim, mode: Mode| family.expected_betti(dim, mode).unwrap();
    // Table I: the cube minus the boundary sum has (1, h + ij, g + i(j+1), 1).
    for (g, h, i, j) in [(1, 0, 0, 0), (0, 1, 0, 0), (2, 1, 1, 2), (0, 0, 2, 3)] {
        let family = Family::ConnectedSum { g, h, i, j };
        let (g, h, i, j) = (g as u64, h as u64, i as u64, j as u64);
        assert_eq!(
            b(family.clone(), Dim::Four, Mode::Carve),
            vec![1, h + i * j, g + i * (j + 1), 1]
        );
        assert_eq!(
            b(family, Dim::Four, Mode::Embed),
            vec![1, g + i * (j + 1), h + i * j, 0]
        );
    }
    assert_eq!(
        b(Family::S1xHandlebody { j: 3 }, Dim::Four, Mode::Embed),
        vec![1, 4, 3, 0]
    );
    assert_eq!(b(Family::T2xB2, Dim::Four, Mode::Carve), vec![1, 1, 2, 1]);
    assert_eq!(
        b(Family::TorusShell, Dim::Four, Mode::Carve),
        vec![2, 3, 3, 1]
    );
    assert_eq!(
        b(Family::TorusShell, Dim::Three, Mode::Embed),
        vec![1, 2, 1]
    );
    assert_eq!(b(Family::Shell, Dim::Four, Mode::Carve), vec![2, 0, 0, 1]);
    let hopf = LinkKind::Hopf;
    assert_eq!(
        b(Family::SpunLink { link: hopf }, Dim::Four, Mode::Embed),
        vec![2, 4, 2, 0]
    );
    assert_eq!(
        b(Family::SpunLink { link: hopf }, Dim::Four, Mode::Carve),
        vec![1, 2, 4, 2]
    );
    assert_eq!(
        b(
            Family::Link {
                link: LinkKind::Borromean
            },
            Dim::Three,
            Mode::Carve
        ),
        vec![1, 3, 3]
    );
    assert_eq!(
        b(
            Family::SpunKnot {
                knot: KnotKind::Trefoil
            },
            Dim::Four,
            Mode::Carve
        ),
        vec![1, 1, 0, 1]
    );
    assert_eq!(
        b(Family::TorusKnot { p: 4, q: 6 }, Dim::Three, Mode::Embed),
        vec![2, 2, 0]
    );
    // Tunnels: the square cut in two, a solid torus, R^4 minus a line (~S2) or a plane (~S1).
    let tunnel = |intervals, circle| Family::Tunnel {
        intervals,
        circle,
        genus: 0,
    };
    assert_eq!(b(tunnel(1, false), Dim::Two, Mode::Carve), vec![2, 0]);
    assert_eq!(b(tunnel(1, false), Dim::Three, Mode::Carve), vec![1, 1, 0]);
    assert_eq!(b(tunnel(2, false), Dim::Three, Mode::Carve), vec![2, 0, 0]);
    assert_eq!(b(tunnel(1, true), Dim::Three, Mode::Carve), vec![2, 1, 0]);
    assert_eq!(
        b(tunnel(1, false), Dim::Four, Mode::Carve),
        vec![1, 0, 1, 0]
    );
    assert_eq!(
        b(tunnel(2, false), Dim::Four, Mode::Carve),
        vec![1, 1, 0, 0]
    );
    assert_eq!(b(tunnel(1, true), Dim::Four, Mode::Carve), vec![1, 1, 1, 0]);
    // I x (boundary sum of g S1xB2) through a 4-cube: (1, g, 1, 0).
    let genus = |g| Family::Tunnel {
        intervals: 1,
        circle: false,
        genus: g,
    };
    assert_eq!(b(genus(3), Dim::Four, Mode::Carve), vec![1, 3, 1, 0]);
    assert_eq!(b(genus(2), Dim::Three, Mode::Carve), vec![3, 1, 0]);
    // The Klein bottle: Z/2 and Q differ, in both modes.
    assert_eq!(
        b(Family::KleinBottle, Dim::Four, Mode::Embed),
        vec![1, 2, 1, 0]
    );
    assert_eq!(
        Family::KleinBottle
            .expected_betti_rational(Dim::Four, Mode::Embed)
            .unwrap(),
        vec![1, 1, 0, 0]
    );
    assert_eq!(
        Family::KleinBottle
            .expected_betti_rational(Dim::Four, Mode::Carve)
            .unwrap(),
        vec![1, 0, 1, 1]
    );
    // The paper's 3D scene: b0 = 5, b1 = 5.
    assert_eq!(
        b(paper_scene_family(), Dim::Three, Mode::Embed),
        vec![5, 5, 0]
    );
}

#[test]
fn records_describe_the_sample() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let family = Family::Scene {
        objects: vec![
            Family::Link {
                link: LinkKind::Hopf,
            },
            Family::Ball,
        ],
    };
    let g = generate(&family, Dim::Three, 48, Mode::Embed, &mut rng).unwrap();
    assert_eq!(g.components, 3);
    assert_eq!(g.knot_type, "hopf");
    assert_eq!(g.betti_rational, None);
    let objects = g.construction["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 2);
    let strategy = g.construction["placement"].as_str().unwrap();
    assert!(
        ["random", "grid", "canonical"].contains(&strategy),
        "{strategy}"
    );
    // Keys are sorted at every level we build.
    let keys: Vec<&String> = g.construction.as_object().unwrap().keys().collect();
    let mut sorted_keys = keys.clone();
    sorted_keys.sort();
    assert_eq!(keys, sorted_keys);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let klein = generate(&Family::KleinBottle, Dim::Four, 30, Mode::Embed, &mut rng).unwrap();
    assert_eq!(klein.betti_rational, Some(vec![1, 1, 0, 0]));
    assert_eq!(klein.knot_type, "none");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let knot = Family::Knot {
        knot: KnotKind::Trefoil,
    };
    let four = generate(&knot, Dim::Four, 46, Mode::Embed, &mut rng).unwrap();
    assert_eq!(four.knot_type, "trefoil_x_interval");
}

#[test]
fn tentacles_are_placed_and_keep_the_label() {
    let family = Family::Tentacled {
        object: Box::new(Family::Handlebody { genus: 2 }),
        tentacles: 3,
    };
    let mut placed_total = 0;
    for seed in 0..6 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let g = generate(&family, Dim::Three, 48, Mode::Embed, &mut rng).unwrap();
        placed_total += g.construction["objects"][0]["params"]["tentacles_placed"]
            .as_u64()
            .unwrap();
        assert_eq!(summary(&g.image), summary_of(&g.betti));
    }
    assert!(
        placed_total >= 6,
        "only {placed_total} tentacles placed in 6 samples"
    );
}

#[test]
fn a_feasible_request_always_generates() {
    // check_fits is a promise: at the smallest accepted side every seed must succeed.
    for family in [
        Family::Handlebody { genus: 3 },
        Family::Link {
            link: LinkKind::Hopf,
        },
        Family::Scene {
            objects: vec![Family::Handle; 5],
        },
        Family::Tunnel {
            intervals: 1,
            circle: true,
            genus: 0,
        },
    ] {
        for mode in [Mode::Embed, Mode::Carve] {
            let dim = Dim::Three;
            let Ok(side) = family.min_side(dim, mode) else {
                continue;
            };
            assert!(family.check_fits(dim, side - 1, mode).is_err() || side <= 8);
            for seed in 0..4 {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let g = generate(&family, dim, side, mode, &mut rng)
                    .unwrap_or_else(|e| panic!("{family} side {side} {mode}: {e}"));
                assert_eq!(
                    summary(&g.image),
                    summary_of(&g.betti),
                    "{family} {mode} {seed}"
                );
            }
        }
    }
}

#[test]
fn a_planned_request_draws_the_same_voxels_as_a_checked_one() {
    for (family, dim, side, mode) in [
        (Family::Handle, Dim::Three, 24, Mode::Embed),
        (Family::Handlebody { genus: 2 }, Dim::Two, 40, Mode::Carve),
        (Family::S2xB2, Dim::Four, 24, Mode::Carve),
        (
            Family::Betti {
                betti: vec![1, 1, 0],
            },
            Dim::Three,
            24,
            Mode::Embed,
        ),
    ] {
        family.check_fits(dim, side, mode).unwrap();
        for seed in 0..3u64 {
            let a = generate(
                &family,
                dim,
                side,
                mode,
                &mut ChaCha8Rng::seed_from_u64(seed),
            )
            .unwrap();
            let b = generate_planned(
                &family,
                dim,
                side,
                mode,
                &mut ChaCha8Rng::seed_from_u64(seed),
            )
            .unwrap();
            assert_eq!(a.image.data(), b.image.data(), "{family:?} seed {seed}");
            assert_eq!(
                (a.betti, a.construction),
                (b.betti, b.construction),
                "{family:?}"
            );
        }
    }
}

#[test]
fn a_raised_tube_floor_is_kept_by_every_object_and_recorded() {
    let floor = TubeFloor::for_copies(Dim::Four, 2);
    for (family, foreground) in [
        (Family::Handle, None),
        (Family::S2xB2, Some(20_000_000)),
        (
            Family::Scene {
                objects: vec![Family::Ball, Family::Handle],
            },
            Some(18_000_000),
        ),
    ] {
        family
            .check_fits_with(Dim::Four, 72, Mode::Carve, floor)
            .unwrap();
        for seed in 0..2u64 {
            let generated = generate_planned_for(
                &family,
                Dim::Four,
                72,
                Mode::Carve,
                foreground,
                Solid::Box,
                floor,
                &mut ChaCha8Rng::seed_from_u64(seed),
            )
            .unwrap();
            let record = &generated.construction;
            assert_eq!(record["tube_floor"], 3.0, "{family:?}");
            for object in record["objects"].as_array().unwrap() {
                let tube = object["params"]["tube_radius"].as_f64().unwrap();
                assert!(tube >= 3.0, "{family:?} seed {seed}: tube {tube}");
            }
        }
    }
    // The usual floor is not recorded (the records of samples without copies are as
    // before).
    let usual = generate_planned_for(
        &Family::Handle,
        Dim::Four,
        72,
        Mode::Carve,
        None,
        Solid::Cube,
        TubeFloor::USUAL,
        &mut ChaCha8Rng::seed_from_u64(0),
    )
    .unwrap();
    assert!(usual.construction.get("tube_floor").is_none());
}

/// The smallest Chebyshev distance between foreground voxels of different components
/// ((3^d - 1)-adjacency) of a small image, by brute force over pairs.
fn closest_parts(image: &BinaryImage) -> i64 {
    let shape = image.shape().to_vec();
    let d = shape.len();
    let coords = |mut v: usize| {
        let mut c = vec![0i64; d];
        for a in (0..d).rev() {
            c[a] = (v % shape[a]) as i64;
            v /= shape[a];
        }
        c
    };
    let on: Vec<Vec<i64>> = (0..image.len())
        .filter(|&v| image.data()[v] == 1)
        .map(coords)
        .collect();
    let far = |a: &[i64], b: &[i64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).max().unwrap();
    // Components by flood fill over the voxel list.
    let mut label = vec![usize::MAX; on.len()];
    let mut parts = 0;
    for start in 0..on.len() {
        if label[start] != usize::MAX {
            continue;
        }
        label[start] = parts;
        let mut stack = vec![start];
        while let Some(i) = stack.pop() {
            for j in 0..on.len() {
                if label[j] == usize::MAX && far(&on[i], &on[j]) == 1 {
                    label[j] = parts;
                    stack.push(j);
                }
            }
        }
        parts += 1;
    }
    let mut closest = i64::MAX;
    for i in 0..on.len() {
        for j in i + 1..on.len() {
            if label[i] != label[j] {
                closest = closest.min(far(&on[i], &on[j]));
            }
        }
    }
    closest
}

#[test]
fn split_pieces_keep_the_narrowest_gap_at_any_slant() {
    // The usual inner gap keeps 2 voxels between pieces; a widened one (6.5) keeps 4, as
    // its scenes do. The gap the sample records (which growth then keeps) is the same.
    // In 3D a slab's slant may shorten its width along the axes by sqrt(3).
    for (inner_gap, kept) in [(None, 2), (Some(6.5), 4)] {
        let floor = inner_gap.map_or(TubeFloor::USUAL, |g| TubeFloor::USUAL.with_gap(g));
        for seed in 0..12u64 {
            let generated = generate_planned_for(
                &Family::Split { parts: 2 },
                Dim::Three,
                32,
                Mode::Embed,
                None,
                Solid::Cube,
                floor,
                &mut ChaCha8Rng::seed_from_u64(seed),
            )
            .unwrap();
            assert_eq!(generated.gap, kept);
            let closest = closest_parts(&generated.image);
            // Never closer than the gap, and never so far that the pieces stop facing
            // each other closely (an axis-aligned slab leaves at most twice the gap).
            assert!(
                (kept as i64 + 1..=2 * kept as i64 + 2).contains(&closest),
                "seed {seed}: pieces {closest} apart"
            );
        }
    }
}
