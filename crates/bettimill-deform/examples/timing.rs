//! Prints wall-clock timings and reports of the benchmark workloads (one run each).
//!
//! The scenes come from the shape library: a 4D scene of S1xB3, S2xB2, T2xB2 and a curve
//! at 32^4, and the paper's 3D seed scene at 128^3.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]
use bettimill_deform::{deform, DeformSettings, Method};
use bettimill_grid::{BinaryImage, Dim};
use bettimill_shapes::{generate, paper_scene_3d, Family, Mode};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

fn main() {
    let t = Instant::now();
    let _ = bettimill_homology::simple::SimpleTester::new(Dim::Three).is_simple_configuration(0);
    println!("3D table: {:?}", t.elapsed());
    let mut disc = BinaryImage::zeros(&[64, 64]).unwrap();
    for y in 0..64 {
        for x in 0..64 {
            let (dx, dy) = (x as f64 - 31.5, y as f64 - 31.5);
            if dx * dx + dy * dy <= 225.0 {
                disc.set(&[y, x], true);
            }
        }
    }
    let moves = |steps| DeformSettings {
        method: Method::Moves,
        steps,
        ..DeformSettings::default()
    };
    for _ in 0..3 {
        let mut img = disc.clone();
        let t = Instant::now();
        let r = deform(&mut img, &moves(600), 7).unwrap();
        println!("2D disc 600 moves: {:?} {r:?}", t.elapsed());
    }
    let family = Family::Scene {
        objects: vec![Family::Handle, Family::S2xB2, Family::T2xB2, Family::Curve],
    };
    let t = Instant::now();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let scene = generate(&family, Dim::Four, 32, Mode::Embed, &mut rng).unwrap();
    println!(
        "4D scene: {:?} {} betti {:?}",
        t.elapsed(),
        family,
        scene.betti
    );
    let mut img = scene.image;
    let grow = DeformSettings {
        method: Method::Dilate,
        steps: 1,
        ..DeformSettings::default()
    };
    let t = Instant::now();
    let r = deform(&mut img, &grow, 2).unwrap();
    println!("4D dilate 1: {:?} {r:?}", t.elapsed());
    for _ in 0..3 {
        let mut m = img.clone();
        let t = Instant::now();
        let r = deform(&mut m, &moves(10_000), 7).unwrap();
        println!("4D 10000 moves: {:?} {r:?}", t.elapsed());
    }
    let t = Instant::now();
    let scene = paper_scene_3d(128, &mut ChaCha8Rng::seed_from_u64(1)).unwrap();
    println!("3D scene: {:?} betti {:?}", t.elapsed(), scene.betti);
    for p in [1.0, 0.5] {
        let mut img = scene.image.clone();
        let s = DeformSettings {
            method: Method::Dilate,
            steps: 3,
            growth_probability: p,
            ..DeformSettings::default()
        };
        let t = Instant::now();
        let r = deform(&mut img, &s, 7).unwrap();
        println!("3D dilate 3 (p={p}): {:?} {r:?}", t.elapsed());
    }
}
