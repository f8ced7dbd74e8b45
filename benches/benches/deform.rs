//! Benchmarks of the deformation kernels against the paper's timings.
//!
//! - `moves/disc_64x64_600`: 600 hypervolume-preserving moves on a 64^2 disc (the paper's
//!   Figure; its Python took about fifty minutes). Target < 10 ms.
//! - `dilate/scene_128^3_3_iterations`: three iterations of the modified (simple-point)
//!   dilation of the paper's 3D seed scene (`bettimill_shapes::paper_scene_3d`; the
//!   paper's 3D figure took about five minutes). Target < 1 s.
//! - `moves/scene_32^4_10000`: 10,000 moves on a grown 4D scene of the shape library
//!   (S1xB3, S2xB2, T2xB2 and a curve). Target < 0.1 s.
//! - `noise/field_*`: full fractal noise fields, for scale.
//!
//! Every deformation is timed on a fresh clone of its input (cloning is excluded), and
//! the process-wide 3D simple-point table is built before timing starts.

// `criterion_group!` in its long form (for the config) writes an undocumented `pub fn`.
#![allow(missing_docs)]

use bettimill_deform::{deform, DeformSettings, Method};
use bettimill_grid::{BinaryImage, Dim};
use bettimill_homology::simple::SimpleTester;
use bettimill_shapes::{generate, paper_scene_3d, Family, Mode};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

fn disc(side: usize, radius: f64) -> BinaryImage {
    let mut image = BinaryImage::zeros(&[side, side]).expect("valid shape");
    let c = (side as f64 - 1.0) / 2.0;
    for y in 0..side {
        for x in 0..side {
            let (dx, dy) = (x as f64 - c, y as f64 - c);
            if dx * dx + dy * dy <= radius * radius {
                image.set(&[y, x], true);
            }
        }
    }
    image
}

fn scene_3d() -> BinaryImage {
    paper_scene_3d(128, &mut ChaCha8Rng::seed_from_u64(1))
        .expect("the paper scene fits 128^3")
        .image
}

fn scene_4d() -> BinaryImage {
    let family = Family::Scene {
        objects: vec![Family::Handle, Family::S2xB2, Family::T2xB2, Family::Curve],
    };
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let mut image = generate(&family, Dim::Four, 32, Mode::Embed, &mut rng)
        .expect("the scene fits 32^4")
        .image;
    let grow = DeformSettings {
        method: Method::Dilate,
        steps: 1,
        ..DeformSettings::default()
    };
    deform(&mut image, &grow, 2).expect("valid settings");
    image
}

fn run(c: &mut Criterion, name: &str, image: &BinaryImage, settings: &DeformSettings) {
    c.bench_function(name, |b| {
        b.iter_batched_ref(
            || image.clone(),
            |img| black_box(deform(img, settings, 7).expect("valid settings")),
            BatchSize::LargeInput,
        )
    });
}

fn benches(c: &mut Criterion) {
    // Build the 3D lookup table (process-wide, once) outside the timings.
    let _ = SimpleTester::new(Dim::Three).is_simple_configuration(0);

    let moves = |steps| DeformSettings {
        method: Method::Moves,
        steps,
        ..DeformSettings::default()
    };
    run(c, "moves/disc_64x64_600", &disc(64, 15.0), &moves(600));

    let dilate = DeformSettings {
        method: Method::Dilate,
        steps: 3,
        ..DeformSettings::default()
    };
    run(c, "dilate/scene_128^3_3_iterations", &scene_3d(), &dilate);
    let lumpy = DeformSettings {
        growth_probability: 0.5,
        ..dilate.clone()
    };
    run(
        c,
        "dilate_lumpy/scene_128^3_3_iterations",
        &scene_3d(),
        &lumpy,
    );
    run(c, "moves/scene_32^4_10000", &scene_4d(), &moves(10_000));

    c.bench_function("noise/field_3d_128^3_3_octaves", |b| {
        b.iter(|| {
            bettimill_noise::noise_field(Dim::Three, &[128, 128, 128], 1, 1.0 / 16.0, 3)
                .expect("valid")
        })
    });
    c.bench_function("noise/field_4d_32^4_3_octaves", |b| {
        b.iter(|| {
            bettimill_noise::noise_field(Dim::Four, &[32, 32, 32, 32], 1, 1.0 / 16.0, 3)
                .expect("valid")
        })
    });
}

criterion_group! {
    name = group;
    config = Criterion::default().sample_size(10);
    targets = benches
}
criterion_main!(group);
