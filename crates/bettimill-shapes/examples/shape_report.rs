//! Reports on the shape library for people (they print; the checks that can fail are in
//! `tests/verify.rs`). One report per run:
//!
//! ```text
//! cargo run --release -p bettimill-shapes --example shape_report -- REPORT
//! ```
//!
//! - `rates`: the mismatch rate per family, dimension and mode (`SHAPES_RATE_COUNT`
//!   instances each, default 20) at the sides of `tests/verify.rs`;
//! - `large-4d`: one instance per mode of the 4D constructions that need sides above 32,
//!   at the smallest side each mode accepts (very slow);
//! - `crowded`: scenes of 4-8 objects, the gap logic under pressure (`SHAPES_RATE_COUNT`,
//!   default 10);
//! - `min-sides`: the smallest side per family, dimension and mode;
//! - `table`: the README table of families;
//! - `times`: generation times (no homology).
//!
//! A report exits with status 1 when it saw a mismatch.

// A report for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]

#[path = "../tests/families/mod.rs"]
mod families;

use bettimill_shapes::{generate, Dim, Family, KnotKind, LinkKind, Mode};
use families::{cases, mismatches};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

const REPORTS: &str = "rates, large-4d, crowded, min-sides, table, times";

fn main() {
    let report = std::env::args().nth(1).unwrap_or_default();
    let bad = match report.as_str() {
        "rates" => mismatch_rates(),
        "large-4d" => large_4d_instances(),
        "crowded" => crowded_scenes(),
        "min-sides" => {
            min_sides();
            0
        }
        "table" => {
            readme_table();
            0
        }
        "times" => {
            generation_times();
            0
        }
        _ => {
            eprintln!("usage: shape_report REPORT (one of {REPORTS})");
            std::process::exit(2);
        }
    };
    if bad > 0 {
        eprintln!("{bad} mismatched instances");
        std::process::exit(1);
    }
}

/// Prints the mismatches of one run of `mismatches` and its rate line; returns the count.
fn rate_line(
    label: &str,
    dim: Dim,
    side: usize,
    mode: Mode,
    count: u64,
    bad: &[String],
    start: Instant,
) -> u64 {
    for line in bad {
        eprintln!("{line}");
    }
    println!(
        "RATE {label:<40} {dim}D side {side:>3} {mode:<5} {:>3}/{count} mismatched  {:.1}s",
        bad.len(),
        start.elapsed().as_secs_f64()
    );
    bad.len() as u64
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

fn large_4d_instances() -> u64 {
    let mut total = 0;
    for family in large_4d() {
        for mode in [Mode::Embed, Mode::Carve] {
            let side = family.min_side(Dim::Four, mode).unwrap();
            let start = Instant::now();
            let bad = mismatches(&family, Dim::Four, side, mode, 1000, 1).unwrap();
            total += rate_line(&family.label(), Dim::Four, side, mode, 1, &bad, start);
        }
    }
    total
}

fn count_from_env(default: u64) -> u64 {
    bettimill_env::number(bettimill_env::EnvVars::SHAPES_RATE_COUNT).unwrap_or(default)
}

fn mismatch_rates() -> u64 {
    let count = count_from_env(20);
    let mut total = 0;
    for (family, sides) in cases() {
        for (dim, &side) in Dim::ALL.iter().zip(&sides) {
            if side == 0 {
                continue;
            }
            for mode in [Mode::Embed, Mode::Carve] {
                let start = Instant::now();
                if let Some(bad) = mismatches(&family, *dim, side, mode, 1000, count) {
                    total += rate_line(&family.label(), *dim, side, mode, count, &bad, start);
                }
            }
        }
    }
    total
}

/// Every family the library offers, for tables.
fn all_families() -> Vec<Family> {
    use Family::*;
    let mut out = vec![
        Ball,
        Split { parts: 2 },
        Split { parts: 3 },
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

fn crowded_scenes() -> u64 {
    use Family::*;
    let count = count_from_env(10);
    let mut total = 0;
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
            let label: String = family.label().chars().take(40).collect();
            total += rate_line(&label, dim, side, mode, count, &bad, start);
        }
    }
    total
}
