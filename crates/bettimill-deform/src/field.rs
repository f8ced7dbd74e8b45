//! A lazily evaluated noise field over an image.
//!
//! Deformations only look at the noise next to the object's boundary, a small fraction of
//! the voxels of a 3D or 4D image, so values are computed on first use and cached rather
//! than filling the whole field up front (a full 32^4 field with 3 octaves costs more than
//! the 10,000 moves that read it). The values are those of
//! [`bettimill_noise::noise_field`] with the same seed, frequency and octaves, so the two
//! are interchangeable.

use bettimill_grid::BinaryImage;
use bettimill_noise::{Fractal, NoiseError};

/// Noise values per flat voxel index, computed on demand.
pub(crate) struct NoiseCache {
    fractal: Fractal,
    strides: [usize; 4],
    d: usize,
    // NaN marks "not computed yet"; the noise itself is never NaN.
    values: Vec<f32>,
}

impl NoiseCache {
    pub(crate) fn new(
        image: &BinaryImage,
        seed: u64,
        frequency: f64,
        octaves: u32,
    ) -> Result<NoiseCache, NoiseError> {
        let fractal = Fractal::new(image.dim(), seed, frequency, octaves)?;
        let mut strides = [0usize; 4];
        strides[..image.dim().get()].copy_from_slice(image.strides());
        Ok(NoiseCache {
            fractal,
            strides,
            d: image.dim().get(),
            values: vec![f32::NAN; image.len()],
        })
    }

    /// The noise at flat index `index`.
    #[inline]
    pub(crate) fn get(&mut self, index: usize) -> f32 {
        let v = self.values[index];
        if !v.is_nan() {
            return v;
        }
        let mut coords = [0usize; 4];
        let mut rest = index;
        for (axis, c) in coords.iter_mut().enumerate().take(self.d) {
            *c = rest / self.strides[axis];
            rest %= self.strides[axis];
        }
        let v = self.fractal.sample(coords) as f32;
        self.values[index] = v;
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bettimill_grid::Dim;

    #[test]
    fn cache_agrees_with_the_full_field() {
        let image = BinaryImage::zeros(&[6, 5, 7]).unwrap();
        let full = bettimill_noise::noise_field(Dim::Three, &[6, 5, 7], 9, 0.21, 2).unwrap();
        let mut cache = NoiseCache::new(&image, 9, 0.21, 2).unwrap();
        for i in (0..image.len()).rev() {
            assert_eq!(cache.get(i).to_bits(), full[i].to_bits(), "voxel {i}");
        }
    }
}

/// [`bettimill_noise::Fractal::sample`] with the same seed, frequency and octaves,
/// evaluated with the same floating-point operations in the same order (so bit for bit the
/// same values) but without branches on the gradient hashes in 4D, where the reference's
/// data-dependent branches make it several times slower. 2D and 3D use the reference.
pub(crate) struct FastFractal {
    reference: Fractal,
    four: Option<Box<Fast4>>,
}

struct Fast4 {
    p: [u8; 512],
    frequency: f64,
    octaves: u32,
    normaliser: f64,
    /// Per 4D gradient index (hash & 31): the factor of each coordinate, +1, -1, or 0 for
    /// the zero axis (bits 3-4 name the zero axis, bits 0-2 the signs of the other three
    /// axes in increasing axis order).
    gradients: [[f64; 4]; 32],
}

impl FastFractal {
    pub(crate) fn new(
        dim: bettimill_grid::Dim,
        seed: u64,
        frequency: f64,
        octaves: u32,
    ) -> Result<FastFractal, NoiseError> {
        let reference = Fractal::new(dim, seed, frequency, octaves)?;
        let four = (dim == bettimill_grid::Dim::Four).then(|| {
            let perm = bettimill_noise::Perlin::from_seed(seed);
            let mut p = [0u8; 512];
            p[..256].copy_from_slice(perm.permutation());
            p[256..].copy_from_slice(perm.permutation());
            let mut gradients = [[0.0f64; 4]; 32];
            for (g, row) in gradients.iter_mut().enumerate() {
                let zero_axis = g >> 3;
                let mut bit = 0;
                for (axis, factor) in row.iter_mut().enumerate() {
                    if axis == zero_axis {
                        continue;
                    }
                    *factor = if g >> bit & 1 == 0 { 1.0 } else { -1.0 };
                    bit += 1;
                }
            }
            Box::new(Fast4 {
                p,
                frequency,
                octaves,
                normaliser: (0..octaves).map(|o| 0.5f64.powi(o as i32)).sum(),
                gradients,
            })
        });
        Ok(FastFractal { reference, four })
    }

    /// The fractal value at voxel coordinate `coords` (first `dim` entries used).
    #[inline]
    pub(crate) fn sample(&self, coords: [usize; 4]) -> f64 {
        match &self.four {
            Some(f) => f.sample(coords),
            None => self.reference.sample(coords),
        }
    }
}

#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[inline]
fn lerp(t: f64, a: f64, b: f64) -> f64 {
    a + t * (b - a)
}

#[inline]
fn split(x: f64) -> (usize, f64) {
    let f = libm::floor(x);
    ((f as i64 & 255) as usize, x - f)
}

impl Fast4 {
    #[inline]
    fn sample(&self, coords: [usize; 4]) -> f64 {
        let mut total = 0.0;
        let mut amplitude = 1.0;
        let mut frequency = self.frequency;
        for _ in 0..self.octaves {
            let p = coords.map(|c| c as f64 * frequency);
            total += amplitude * self.noise4(p[0], p[1], p[2], p[3]);
            amplitude *= 0.5;
            frequency *= 2.0;
        }
        total / self.normaliser
    }

    /// The reference sums the three non-zero terms from 0.0; here the zero axis adds
    /// `c * 0.0 = ±0.0` in its place. A running sum started at +0.0 is never -0.0, and
    /// adding ±0.0 to anything else leaves it unchanged, so the sums are the same bits.
    #[inline]
    fn grad4(&self, hash: u8, p: [f64; 4]) -> f64 {
        let g = &self.gradients[(hash & 31) as usize];
        let mut sum = 0.0;
        for axis in 0..4 {
            sum += p[axis] * g[axis];
        }
        sum
    }

    #[inline]
    fn noise4(&self, x: f64, y: f64, z: f64, w: f64) -> f64 {
        let (xi, x) = split(x);
        let (yi, y) = split(y);
        let (zi, z) = split(z);
        let (wi, w) = split(w);
        let (fx, fy, fz, fw) = (fade(x), fade(y), fade(z), fade(w));
        let p = &self.p;
        let mut values = [0.0f64; 16];
        for dx in 0..2 {
            let hx = p[xi + dx] as usize;
            for dy in 0..2 {
                let hy = p[hx + yi + dy] as usize;
                for dz in 0..2 {
                    let hz = p[hy + zi + dz] as usize;
                    for dw in 0..2 {
                        let hash = p[hz + wi + dw];
                        values[dx << 3 | dy << 2 | dz << 1 | dw] = self.grad4(
                            hash,
                            [x - dx as f64, y - dy as f64, z - dz as f64, w - dw as f64],
                        );
                    }
                }
            }
        }
        let mut along_w = [0.0f64; 8];
        for (i, v) in along_w.iter_mut().enumerate() {
            *v = lerp(fw, values[2 * i], values[2 * i + 1]);
        }
        let mut along_z = [0.0f64; 4];
        for (i, v) in along_z.iter_mut().enumerate() {
            *v = lerp(fz, along_w[2 * i], along_w[2 * i + 1]);
        }
        let along_y = [
            lerp(fy, along_z[0], along_z[1]),
            lerp(fy, along_z[2], along_z[3]),
        ];
        lerp(fx, along_y[0], along_y[1])
    }
}

#[cfg(test)]
mod fast_tests {
    use super::*;
    use bettimill_grid::Dim;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn fast_fractal_is_the_reference_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for dim in [Dim::Two, Dim::Three, Dim::Four] {
            for (seed, frequency, octaves) in [(1u64, 1.0 / 16.0, 3u32), (77, 0.37, 5), (5, 3.0, 1)]
            {
                let fast = FastFractal::new(dim, seed, frequency, octaves).unwrap();
                let reference = Fractal::new(dim, seed, frequency, octaves).unwrap();
                for k in 0..20_000usize {
                    let coords: [usize; 4] = if k < 4096 {
                        // Every corner and lattice crossing of a small block.
                        [k >> 9 & 7, k >> 6 & 7, k >> 3 & 7, k & 7]
                    } else {
                        core::array::from_fn(|_| rng.gen_range(0..600))
                    };
                    assert_eq!(
                        fast.sample(coords).to_bits(),
                        reference.sample(coords).to_bits(),
                        "{dim:?} seed {seed} at {coords:?}"
                    );
                }
            }
        }
    }
}
