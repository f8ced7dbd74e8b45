//! Cross-check of every family against the homology crate: generate random instances in
//! 2D, 3D and 4D, in both modes, and compare the analytic label with the computed Betti
//! numbers. A mismatch is a digitisation defect the pipeline would catch and regenerate;
//! the tests bound the rate, and the ignored `mismatch_rates` test prints it per family.

use bettimill_shapes::{generate, Dim, Family, KnotKind, LinkKind, Mode};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

/// Generates `count` instances (seeds `first..first+count`) and returns how many
/// disagree with the homology crate; `None` if the family does not fit.
fn mismatches(
    family: &Family,
    dim: Dim,
    side: usize,
    mode: Mode,
    first: u64,
    count: u64,
) -> Option<u64> {
    if family.check_fits(dim, side, mode).is_err() {
        return None;
    }
    let mut bad = 0;
    for seed in first..first + count {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let g = generate(family, dim, side, mode, &mut rng)
            .unwrap_or_else(|e| panic!("{family} {dim}D side {side} {mode} seed {seed}: {e}"));
        let t = bettimill_homology::topology(&g.image);
        if t.betti != g.betti {
            eprintln!(
                "MISMATCH {family} {dim}D side {side} {mode} seed {seed}: computed {:?}, label {:?}",
                t.betti, g.betti
            );
            bad += 1;
        }
    }
    Some(bad)
}

/// Every family with the side it is tested at in each dimension (0 = not tested there).
/// Sides are modest: 2D 32-48, 3D 32-64, 4D 16-32 (larger 4D constructions are listed in
/// `large_4d`).
fn cases() -> Vec<(Family, [usize; 3])> {
    use Family::*;
    let knot = |knot| Knot { knot };
    let link = |link| Link { link };
    vec![
        (Ball, [32, 32, 16]),
        (Handle, [32, 32, 20]),
        (Shell, [32, 32, 20]),
        (TorusShell, [32, 40, 0]),
        (Handlebody { genus: 2 }, [32, 40, 32]),
        (Handlebody { genus: 3 }, [48, 48, 0]),
        (S2xB2, [0, 0, 20]),
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

/// 4D constructions that need sides above 32; one instance each, at the smallest side
/// each mode accepts.
fn large_4d() -> Vec<Family> {
    use Family::*;
    vec![
        Link {
            link: LinkKind::Hopf,
        },
        TorusShell,
        Knot {
            knot: KnotKind::Trefoil,
        },
        SpunLink {
            link: LinkKind::Hopf,
        },
        SpunKnot {
            knot: KnotKind::Trefoil,
        },
    ]
}

#[test]
#[ignore = "very slow: large 4D constructions, one instance each"]
fn large_4d_instances() {
    for family in large_4d() {
        for mode in [Mode::Embed, Mode::Carve] {
            let side = family.min_side(Dim::Four, mode).unwrap();
            let start = Instant::now();
            let bad = mismatches(&family, Dim::Four, side, mode, 1000, 1).unwrap();
            println!(
                "RATE {:<40} 4D side {side:>3} {mode:<5} {bad}/1 mismatched  {:.1}s",
                family.label(),
                start.elapsed().as_secs_f64()
            );
        }
    }
}

/// The bounded version that runs with every `cargo test`: every case once per mode,
/// 4D only where the side is at most 20 (4D homology of larger images takes seconds).
#[test]
fn every_family_matches_the_homology_crate() {
    let mut failures = Vec::new();
    for (family, sides) in cases() {
        for (dim, &side) in Dim::ALL.iter().zip(&sides) {
            if side == 0 || (*dim == Dim::Four && side > 20) {
                continue;
            }
            for mode in [Mode::Embed, Mode::Carve] {
                match mismatches(&family, *dim, side, mode, 0, 1) {
                    Some(0) => {}
                    Some(_) => failures.push(format!("{family} {dim}D {mode}")),
                    None => {
                        // Tunnels exist only in carve mode; everything else must fit.
                        if !matches!(family, Family::Tunnel { .. }) || mode == Mode::Carve {
                            failures
                                .push(format!("{family} {dim}D side {side} {mode}: does not fit"));
                        }
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
#[ignore = "slow: prints the mismatch rate per family; run with --ignored --nocapture"]
fn mismatch_rates() {
    let count: u64 = std::env::var("SHAPES_RATE_COUNT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    for (family, sides) in cases() {
        for (dim, &side) in Dim::ALL.iter().zip(&sides) {
            if side == 0 {
                continue;
            }
            for mode in [Mode::Embed, Mode::Carve] {
                let start = Instant::now();
                if let Some(bad) = mismatches(&family, *dim, side, mode, 1000, count) {
                    println!(
                        "RATE {:<40} {}D side {:>3} {:<5} {:>3}/{} mismatched  {:.1}s",
                        family.label(),
                        dim,
                        side,
                        mode,
                        bad,
                        count,
                        start.elapsed().as_secs_f64()
                    );
                }
            }
        }
    }
}

/// Every family the library offers, for tables.
fn all_families() -> Vec<Family> {
    use Family::*;
    let mut out = vec![
        Ball,
        Handle,
        Shell,
        TorusShell,
        Handlebody { genus: 1 },
        Handlebody { genus: 2 },
        S2xB2,
        T2xB2,
        S1xHandlebody { j: 1 },
        S1xHandlebody { j: 2 },
        ConnectedSum {
            g: 2,
            h: 0,
            i: 0,
            j: 0,
        },
        ConnectedSum {
            g: 1,
            h: 1,
            i: 0,
            j: 0,
        },
        ConnectedSum {
            g: 0,
            h: 0,
            i: 1,
            j: 1,
        },
        ConnectedSum {
            g: 1,
            h: 1,
            i: 1,
            j: 1,
        },
        Tunnel {
            intervals: 1,
            circle: false,
            genus: 0,
        },
        Tunnel {
            intervals: 2,
            circle: false,
            genus: 0,
        },
        Tunnel {
            intervals: 1,
            circle: true,
            genus: 0,
        },
        Tunnel {
            intervals: 2,
            circle: true,
            genus: 0,
        },
        Tunnel {
            intervals: 1,
            circle: false,
            genus: 2,
        },
        Curve,
        TorusKnot { p: 2, q: 5 },
        TorusKnot { p: 3, q: 3 },
        KleinBottle,
        bettimill_shapes::paper_scene_family(),
    ];
    for knot in [
        KnotKind::Unknot,
        KnotKind::Trefoil,
        KnotKind::FigureEight,
        KnotKind::Cinquefoil,
    ] {
        out.push(Knot { knot });
        out.push(SpunKnot { knot });
    }
    for link in [
        LinkKind::Hopf,
        LinkKind::Whitehead,
        LinkKind::Borromean,
        LinkKind::Solomon,
    ] {
        out.push(Link { link });
        out.push(SpunLink { link });
    }
    out
}

#[test]
#[ignore = "prints the smallest side per family, dimension and mode"]
fn min_sides() {
    for family in all_families() {
        let mut line = format!("{:<45}", family.label());
        for dim in Dim::ALL {
            for mode in [Mode::Embed, Mode::Carve] {
                let cell = match family.min_side(dim, mode) {
                    Ok(side) => format!("{side}"),
                    Err(_) => "-".into(),
                };
                line.push_str(&format!(" {dim}D/{mode}:{cell:>4}"));
            }
        }
        println!("SIDE {line}");
    }
}

#[test]
#[ignore = "prints the README table of families"]
fn readme_table() {
    println!("TABLE | family | dim | embed (Z/2) | carve (Z/2) | min side embed / carve |");
    println!("TABLE |---|---|---|---|---|");
    for family in all_families() {
        for dim in Dim::ALL {
            let Ok(embed) = family
                .expected_betti(dim, Mode::Embed)
                .or_else(|_| family.expected_betti(dim, Mode::Carve).map(|_| Vec::new()))
            else {
                continue;
            };
            let carve = family.expected_betti(dim, Mode::Carve).unwrap_or_default();
            let side = |mode| {
                family
                    .min_side(dim, mode)
                    .map(|s| s.to_string())
                    .unwrap_or("-".into())
            };
            let show = |b: &Vec<u64>| {
                if b.is_empty() {
                    "-".to_string()
                } else {
                    format!("{b:?}")
                }
            };
            println!(
                "TABLE | `{}` | {dim}D | {} | {} | {} / {} |",
                serde_json::to_string(&family).unwrap(),
                show(&embed),
                show(&carve),
                side(Mode::Embed),
                side(Mode::Carve)
            );
        }
    }
}

#[test]
#[ignore = "prints generation times (no homology)"]
fn generation_times() {
    use Family::*;
    let cases: Vec<(Family, Dim, usize)> = vec![
        (Handle, Dim::Three, 64),
        (
            Knot {
                knot: KnotKind::Trefoil,
            },
            Dim::Three,
            64,
        ),
        (bettimill_shapes::paper_scene_family(), Dim::Three, 64),
        (Handle, Dim::Four, 32),
        (T2xB2, Dim::Four, 32),
        (
            ConnectedSum {
                g: 1,
                h: 1,
                i: 1,
                j: 1,
            },
            Dim::Four,
            64,
        ),
        (
            SpunLink {
                link: LinkKind::Hopf,
            },
            Dim::Four,
            64,
        ),
    ];
    for (family, dim, side) in cases {
        for mode in [Mode::Embed, Mode::Carve] {
            let start = Instant::now();
            let n = 3;
            for seed in 0..n {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                generate(&family, dim, side, mode, &mut rng).unwrap();
            }
            println!(
                "TIME {:<40} {dim}D side {side} {mode}: {:.3}s per sample",
                family.label(),
                start.elapsed().as_secs_f64() / n as f64
            );
        }
    }
}

#[test]
#[ignore = "crowded scenes: the gap logic under pressure"]
fn crowded_scenes() {
    use Family::*;
    let count: u64 = std::env::var("SHAPES_RATE_COUNT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let cases: Vec<(Family, Dim, usize)> = vec![
        (
            Scene {
                objects: vec![Handle; 8],
            },
            Dim::Two,
            48,
        ),
        (
            Scene {
                objects: vec![Shell, Handlebody { genus: 2 }, Curve, Ball, Handle, Handle],
            },
            Dim::Two,
            48,
        ),
        (
            Scene {
                objects: vec![
                    Link {
                        link: LinkKind::Hopf,
                    },
                    Knot {
                        knot: KnotKind::Trefoil,
                    },
                    TorusShell,
                    Shell,
                    Handle,
                    Tentacled {
                        object: Box::new(Ball),
                        tentacles: 3,
                    },
                ],
            },
            Dim::Three,
            64,
        ),
        (
            Scene {
                objects: vec![Ball, Ball, Handle, Shell],
            },
            Dim::Four,
            24,
        ),
    ];
    for (family, dim, side) in cases {
        for mode in [Mode::Embed, Mode::Carve] {
            let start = Instant::now();
            let bad = mismatches(&family, dim, side, mode, 2000, count).expect("fits");
            println!(
                "RATE {:<40} {dim}D side {side:>3} {mode:<5} {bad:>3}/{count} mismatched  {:.1}s",
                family.label().chars().take(40).collect::<String>(),
                start.elapsed().as_secs_f64()
            );
        }
    }
}

/// Classes given by their Betti vector: the realised construction's image has exactly the
/// requested Betti numbers (computed), and its record names the class.
#[test]
fn betti_classes_match_the_homology_crate() {
    let cases: [(usize, usize, Mode, &[&[u64]]); 6] = [
        (2, 48, Mode::Embed, &[&[1, 0], &[1, 3], &[2, 1], &[3, 3]]),
        (2, 48, Mode::Carve, &[&[1, 1], &[2, 2], &[1, 3]]),
        (3, 48, Mode::Embed, &[&[1, 2, 0], &[2, 1, 1], &[3, 0, 2]]),
        (3, 48, Mode::Carve, &[&[1, 0, 1], &[1, 2, 2], &[2, 1, 2]]),
        (
            4,
            20,
            Mode::Embed,
            &[&[1, 1, 0, 0], &[1, 0, 0, 1], &[1, 0, 1, 0]],
        ),
        (
            4,
            20,
            Mode::Carve,
            &[&[1, 0, 0, 1], &[1, 1, 0, 1], &[1, 0, 1, 1]],
        ),
    ];
    for (d, side, mode, vectors) in cases {
        let dim = Dim::new(d).unwrap();
        for betti in vectors {
            let class = Family::Betti {
                betti: betti.to_vec(),
            };
            class
                .check_fits(dim, side, mode)
                .unwrap_or_else(|e| panic!("{class} {d}D side {side} {mode}: {e}"));
            for seed in 0..2 {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let g = generate(&class, dim, side, mode, &mut rng).unwrap();
                assert_eq!(g.betti, betti.to_vec(), "{class} {mode}");
                assert_eq!(g.construction["class"], class.label());
                let t = bettimill_homology::topology(&g.image);
                assert_eq!(t.betti, betti.to_vec(), "{class} {d}D {mode} seed {seed}");
            }
        }
    }
}
