//! Micro-benchmarks of bettimill-homology: exact Betti numbers of blob-like and random
//! images (3D 64^3, 4D 16^4 and 32^4) and the simple-point test per dimension.
//!
//! Blobs are uniform noise smoothed by three passes of a periodic box blur of radius 2 and
//! thresholded at the median (the same recipe as benches/compare_peers.py), so about half
//! of the voxels are foreground and the topology is rich. Everything is seeded ChaCha8, so
//! every run measures the same images.

// `criterion_group!` writes an undocumented `pub fn`.
#![allow(missing_docs)]

use bettimill_grid::{BinaryImage, Dim};
use bettimill_homology::simple::SimpleTester;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

fn blob(dim: Dim, side: usize, seed: u64) -> BinaryImage {
    let d = dim.get();
    let n = side.pow(d as u32);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut field: Vec<f32> = (0..n).map(|_| rng.gen::<f32>()).collect();
    let stride = |axis: usize| side.pow((d - 1 - axis) as u32);
    for _ in 0..3 {
        for axis in 0..d {
            let s = stride(axis);
            let mut out = vec![0f32; n];
            for (i, slot) in out.iter_mut().enumerate() {
                let c = i / s % side;
                let base = i - c * s;
                let mut sum = 0.0;
                for delta in 0..5 {
                    let cc = (c + side + delta - 2) % side;
                    sum += field[base + cc * s];
                }
                *slot = sum / 5.0;
            }
            field = out;
        }
    }
    let mut sorted = field.clone();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let median = sorted[n / 2];
    let data = field.iter().map(|&v| (v > median) as u8).collect();
    BinaryImage::from_vec(&vec![side; d], data).unwrap()
}

fn random(dim: Dim, side: usize, seed: u64) -> BinaryImage {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = side.pow(dim.get() as u32);
    let data = (0..n).map(|_| rng.gen_bool(0.5) as u8).collect();
    BinaryImage::from_vec(&vec![side; dim.get()], data).unwrap()
}

fn topology(c: &mut Criterion) {
    let mut group = c.benchmark_group("topology");
    group.sample_size(10);
    let cases = [
        ("3d_64_blob", blob(Dim::Three, 64, 1)),
        ("3d_64_random", random(Dim::Three, 64, 2)),
        ("4d_16_blob", blob(Dim::Four, 16, 3)),
        ("4d_32_blob", blob(Dim::Four, 32, 4)),
    ];
    for (name, image) in &cases {
        group.throughput(Throughput::Elements(image.len() as u64));
        group.bench_with_input(BenchmarkId::from_parameter(name), image, |b, image| {
            b.iter(|| bettimill_homology::topology(black_box(image)))
        });
    }
    group.finish();
}

fn simple_points(c: &mut Criterion) {
    let mut group = c.benchmark_group("simple_point");
    const N: usize = 4096;
    for dim in Dim::ALL {
        let tester = SimpleTester::new(dim);
        let n_neighbours = tester.offsets().len();
        let mut rng = ChaCha8Rng::seed_from_u64(dim.get() as u64);
        // Mixed densities, so that every early exit of the test is exercised.
        let configs: Vec<u128> = (0..N)
            .map(|_| {
                let density = rng.gen_range(0.1..0.9);
                (0..n_neighbours).fold(0u128, |acc, k| acc | ((rng.gen_bool(density) as u128) << k))
            })
            .collect();
        // Build the 3D table outside the measurement.
        black_box(tester.is_simple_configuration(0));
        group.throughput(Throughput::Elements(N as u64));
        group.bench_function(BenchmarkId::new("configuration", format!("{dim}d")), |b| {
            b.iter(|| {
                configs
                    .iter()
                    .filter(|&&c| tester.is_simple_configuration(black_box(c)))
                    .count()
            })
        });
        // The whole test on a real image: read the neighbourhood, then decide.
        let image = blob(dim, if dim == Dim::Four { 16 } else { 32 }, 7);
        let interior: Vec<usize> = (0..image.len())
            .filter(|&i| bettimill_grid::neighbourhood::is_interior(&image, i, 1))
            .take(N)
            .collect();
        group.throughput(Throughput::Elements(interior.len() as u64));
        group.bench_function(BenchmarkId::new("image", format!("{dim}d")), |b| {
            b.iter(|| {
                interior
                    .iter()
                    .filter(|&&i| tester.is_simple(black_box(&image), i))
                    .count()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, topology, simple_points);
criterion_main!(benches);
