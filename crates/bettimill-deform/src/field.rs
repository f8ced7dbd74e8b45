//! A lazily evaluated noise field over an image.
//!
//! Deformations only look at the noise next to the phase's boundary, a small fraction of
//! the voxels of a 3D or 4D image, so values are computed on first use and kept in a map
//! keyed by voxel, rather than filling (or even allocating) the whole field: a 128^4
//! field would be a gigabyte. The map is only looked up, never iterated, so its order
//! cannot reach a result; its hash is rustc-hash's multiply (keys are voxel indices of
//! one image, not input an attacker picks), a few instructions where SipHash costs tens. The values are those of [`bettimill_noise::noise_field`] with
//! the same seed, frequency and octaves, so the two are interchangeable.

use bettimill_grid::BinaryImage;
use bettimill_noise::{Fractal, NoiseError};
use rustc_hash::FxHashMap;

/// Noise values per flat voxel index, computed on demand.
pub(crate) struct NoiseCache {
    fractal: Fractal,
    strides: [usize; 4],
    d: usize,
    values: FxHashMap<usize, f32>,
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
            values: FxHashMap::default(),
        })
    }

    /// The noise at flat index `index`.
    #[inline]
    pub(crate) fn get(&mut self, index: usize) -> f32 {
        if let Some(&v) = self.values.get(&index) {
            return v;
        }
        let mut coords = [0usize; 4];
        let mut rest = index;
        for (axis, c) in coords.iter_mut().enumerate().take(self.d) {
            *c = rest / self.strides[axis];
            rest %= self.strides[axis];
        }
        let v = self.fractal.sample(coords) as f32;
        self.values.insert(index, v);
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
