//! `cargo run --release -p bettimill-homology --example make_image -- KIND DIM SIDE SEED OUT.npy`:
//! writes a test image for timing [`bettimill_homology::topology`]. KIND is `random` (each
//! voxel foreground with probability 0.5, or `random:P` for probability P) or `blob` (uniform
//! noise smoothed by three passes of a periodic box blur of radius 2 along every axis,
//! thresholded at its median, as in benches/compare_peers.py; not the same bytes as NumPy's
//! generator). ChaCha8 with the given seed, so the same arguments give the same bytes.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]

use bettimill_grid::npy::{write_bytes, Dtype};
use bettimill_grid::BinaryImage;
use rand::{Rng, SeedableRng};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [kind, dim, side, seed, out] = args.as_slice() else {
        return Err("usage: make_image random[:P]|blob DIM SIDE SEED OUT.npy".into());
    };
    let (d, side, seed): (usize, usize, u64) = (dim.parse()?, side.parse()?, seed.parse()?);
    let shape = vec![side; d];
    let len: usize = shape.iter().product();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let data: Vec<u8> = if let Some(p) = kind.strip_prefix("random") {
        let p: f64 = p.strip_prefix(':').map_or(Ok(0.5), str::parse)?;
        (0..len).map(|_| rng.gen_bool(p) as u8).collect()
    } else if kind == "blob" {
        let mut f: Vec<f32> = (0..len).map(|_| rng.gen::<f32>()).collect();
        let strides: Vec<usize> = (0..d).map(|a| shape[a + 1..].iter().product()).collect();
        for _ in 0..3 {
            for axis in 0..d {
                let (stride, n) = (strides[axis], shape[axis]);
                let mut g = vec![0f32; len];
                for (i, out) in g.iter_mut().enumerate() {
                    let x = (i / stride) % n;
                    let base = i - x * stride;
                    let sum: f32 = (0..5)
                        .map(|s| f[base + ((x + n + s - 2) % n) * stride])
                        .sum();
                    *out = sum / 5.0;
                }
                f = g;
            }
        }
        let mut sorted = f.clone();
        sorted.sort_by(f32::total_cmp);
        let median = sorted[len / 2];
        f.iter().map(|&v| (v > median) as u8).collect()
    } else {
        return Err(format!("unknown kind {kind}").into());
    };
    let image = BinaryImage::from_vec(&shape, data)?;
    std::fs::write(out, write_bytes(&image, Dtype::U8))?;
    Ok(())
}
