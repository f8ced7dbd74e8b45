//! The pose of an object: a rotation of R^4 from its local frame to the image's, built from
//! plane rotations (and, for tunnels, an axis permutation) and recorded with the angles
//! that made it. Computed with `libm` only, as the geometry is, so every platform places
//! the same voxels.

use crate::geometry::{dot, round6, uniform, ORIGIN, P};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

/// A rotation of R^4 (acting on the first `dim` axes), local frame to image frame.
#[derive(Clone, Debug)]
pub(crate) struct Rotation {
    /// Row-major matrix: `world = m * local`.
    m: [[f64; 4]; 4],
    /// The axis permutation applied first (tunnels), for the construction record.
    permutation: Option<Vec<usize>>,
    /// The Givens angles that built it, for the construction record.
    angles: Vec<(usize, usize, f64)>,
}

impl Rotation {
    pub(crate) fn identity() -> Rotation {
        let mut m = [[0.0; 4]; 4];
        for (k, row) in m.iter_mut().enumerate() {
            row[k] = 1.0;
        }
        Rotation {
            m,
            permutation: None,
            angles: Vec::new(),
        }
    }

    /// A product of plane rotations with uniform angles, one for every pair of the
    /// given axes (all axes for a free object; only the cross-section axes for a tunnel,
    /// which must stay aligned with the faces it passes through).
    pub(crate) fn random(axes: &[usize], rng: &mut ChaCha8Rng) -> Rotation {
        let mut rotation = Rotation::identity();
        for (k, &i) in axes.iter().enumerate() {
            for &j in &axes[k + 1..] {
                let angle = uniform(rng, 0.0, 2.0 * std::f64::consts::PI);
                rotation.then_plane(i, j, angle);
            }
        }
        rotation
    }

    /// The axis permutation sending local axis k to image axis `perm[k]`.
    pub(crate) fn permutation(perm: &[usize]) -> Rotation {
        let mut m = [[0.0; 4]; 4];
        let mut used = [false; 4];
        for (local, &world) in perm.iter().enumerate() {
            m[world][local] = 1.0;
            used[world] = true;
        }
        // Axes beyond the image's dimension stay fixed.
        for (k, row) in m.iter_mut().enumerate().skip(perm.len()) {
            row[k] = 1.0;
        }
        debug_assert!(used.iter().take(perm.len()).all(|&u| u));
        Rotation {
            m,
            permutation: Some(perm.to_vec()),
            angles: Vec::new(),
        }
    }

    /// Follows the rotation with random plane rotations among the given image axes.
    pub(crate) fn randomise(&mut self, axes: &[usize], rng: &mut ChaCha8Rng) {
        for (k, &i) in axes.iter().enumerate() {
            for &j in &axes[k + 1..] {
                let angle = uniform(rng, 0.0, 2.0 * std::f64::consts::PI);
                self.then_plane(i, j, angle);
            }
        }
    }

    fn then_plane(&mut self, i: usize, j: usize, angle: f64) {
        let c = libm::cos(angle);
        let s = libm::sin(angle);
        // Left-multiply by the Givens rotation G(i, j, angle).
        for col in 0..4 {
            let a = self.m[i][col];
            let b = self.m[j][col];
            self.m[i][col] = c * a - s * b;
            self.m[j][col] = s * a + c * b;
        }
        self.angles.push((i, j, angle));
    }

    /// The world offset of a local point.
    /// World axis `k` as a unit vector in local coordinates.
    pub(crate) fn axis_in_local(&self, k: usize) -> P {
        self.m[k]
    }

    pub(crate) fn to_world(&self, local: P) -> P {
        let mut out = ORIGIN;
        for (k, slot) in out.iter_mut().enumerate() {
            *slot = dot(self.m[k], local);
        }
        out
    }

    /// Local coordinates of a world offset (the transpose is the inverse).
    pub(crate) fn to_local(&self, world: P) -> P {
        let mut out = ORIGIN;
        for (k, slot) in out.iter_mut().enumerate() {
            *slot = self.m[0][k] * world[0]
                + self.m[1][k] * world[1]
                + self.m[2][k] * world[2]
                + self.m[3][k] * world[3];
        }
        out
    }

    pub(crate) fn describe(&self) -> Value {
        let planes: Vec<Value> = self
            .angles
            .iter()
            .map(|&(i, j, a)| json!({"plane": [i, j], "angle": round6(a)}))
            .collect();
        match &self.permutation {
            Some(perm) => json!({"axis_permutation": perm, "planes": planes}),
            None => json!({"planes": planes}),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{axis, norm};
    use rand::SeedableRng;

    #[test]
    fn rotation_is_orthogonal() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let rotation = Rotation::random(&[0, 1, 2, 3], &mut rng);
        for i in 0..4 {
            let li = rotation.to_local(axis(i));
            assert!((norm(li) - 1.0).abs() < 1e-12);
            for j in 0..i {
                assert!(dot(li, rotation.to_local(axis(j))).abs() < 1e-12);
            }
        }
    }
}
