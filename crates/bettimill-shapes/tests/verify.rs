//! Cross-check of every family against the homology crate: generate random instances in
//! 2D, 3D and 4D, in both modes, and compare the analytic label with the computed Betti
//! numbers. A mismatch is a digitisation defect the pipeline would catch and regenerate;
//! the tests require none. `examples/shape_report.rs` runs the longer sweeps (many
//! instances, large 4D sides, crowded scenes) and prints the rates.

mod families;

use bettimill_shapes::{generate, Dim, Family, Mode};
use families::{cases, mismatches};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

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
                    Some(bad) if bad.is_empty() => {}
                    Some(bad) => failures.push(format!("{family} {dim}D {mode}: {bad:?}")),
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

/// Loops, bumpy shells and bumpy S2xB2 draw their shapes per instance (a loop's draw is
/// damped when its tube would come too close to itself): many draws in each dimension and
/// mode, each labelled right.
#[test]
fn drawn_shapes_match_the_homology_crate_draw_after_draw() {
    let mut failures = Vec::new();
    let cases = [
        (Family::Loop, Dim::Two, 32, 40),
        (Family::Loop, Dim::Three, 32, 40),
        (Family::Loop, Dim::Four, 20, 12),
        (Family::BumpyShell, Dim::Two, 32, 40),
        (Family::BumpyShell, Dim::Three, 32, 40),
        (Family::BumpyShell, Dim::Four, 20, 12),
        (Family::BumpyS2xB2, Dim::Four, 20, 12),
    ];
    for (family, dim, side, count) in cases {
        for mode in [Mode::Embed, Mode::Carve] {
            match mismatches(&family, dim, side, mode, 100, count) {
                Some(bad) => failures.extend(bad),
                None => failures.push(format!("{family} {dim}D side {side} {mode}: does not fit")),
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
