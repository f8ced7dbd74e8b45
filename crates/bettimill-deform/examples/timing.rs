//! Prints wall-clock timings and reports of the benchmark workloads (one run each).

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]
use bettimill_deform::seeds::{random_scene, SceneSpec};
use bettimill_deform::{deform, DeformSettings, Method};
use bettimill_grid::{BinaryImage, Dim};
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
    let spec = SceneSpec {
        curves: 2,
        circles: 3,
        spheres: 1,
        tori: 1,
        tentacles: 2,
        bridges: 1,
        ..SceneSpec::default()
    };
    let t = Instant::now();
    let scene = random_scene(&[32, 32, 32, 32], &spec, 2).unwrap();
    println!(
        "4D scene: {:?} placed {:?} betti {:?}",
        t.elapsed(),
        scene.placed,
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
    let spec3 = SceneSpec {
        curves: 4,
        circles: 6,
        knots: 2,
        bridges: 2,
        tentacles: 6,
        spheres: 1,
        tori: 2,
    };
    let t = Instant::now();
    let scene = random_scene(&[128, 128, 128], &spec3, 1).unwrap();
    println!(
        "3D scene: {:?} placed {:?} betti {:?}",
        t.elapsed(),
        scene.placed,
        scene.betti
    );
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
