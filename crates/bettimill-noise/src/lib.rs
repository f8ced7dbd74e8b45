//! Ken Perlin's Improved Noise (SIGGRAPH 2002) in 2D, 3D and 4D, and fractal noise fields.
//!
//! The deformations in `bettimill-deform` move and grow voxels towards high noise, so the
//! noise decides what every deformed sample looks like. We implement it ourselves rather
//! than use the `noise` crate because that crate's 4D Perlin gradient table reaches only 21
//! of the 32 hypercube-edge directions, which biases 4D samples along some axes.
//!
//! * [`Perlin::reference`] uses Perlin's published permutation, so [`Perlin::noise3`] is
//!   the reference Java `ImprovedNoise.noise` (same operations in the same order, hence the
//!   same bits).
//! * [`Perlin::from_seed`] shuffles 0..256 with a Fisher-Yates shuffle driven by a
//!   `ChaCha8Rng` seeded from a `u64`, so a seed names the same noise on every machine.
//! * Gradients: 2D uses 8 directions 45 degrees apart, all of length sqrt 2; 3D uses
//!   Perlin's 12 cube edges (hash & 15, four repeated); 4D uses the 32 hypercube edges
//!   (0, +-1, +-1, +-1) and their coordinate permutations, selected by hash & 31 so that
//!   all 32 are reachable with equal frequency.
//! * [`Fractal`] sums octaves (lacunarity 2, gain 0.5) and divides by the sum of the
//!   amplitudes, so it stays in the range of one octave (roughly [-1, 1]).
//! * [`Fractal::sample_memo`] is [`Fractal::sample`] bit for bit, keeping from one 4D point
//!   to the next what depends only on the first three coordinates (the corner hashes and
//!   three of the four terms of each gradient product): a frontier in C order visits runs
//!   of neighbours along the last axis.
//! * [`noise_field`] evaluates a fractal field at every voxel in C order. It runs on rayon
//!   but each value is a pure function of its coordinate, so the output is bit-identical
//!   whatever the number of threads.
//!
//! Only `floor` and arithmetic are used (no transcendental functions), so results do not
//! depend on the platform's maths library.

use bettimill_grid::Dim;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Ken Perlin's reference permutation of 0..256 (from `ImprovedNoise.java`).
pub const REFERENCE_PERMUTATION: [u8; 256] = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69,
    142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219,
    203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230,
    220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76,
    132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173,
    186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206,
    59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163,
    70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232,
    178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162,
    241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204,
    176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141,
    128, 195, 78, 66, 215, 61, 156, 180,
];

/// The most octaves a [`Fractal`] accepts; beyond about 30 the finest octave's frequency
/// overflows the lattice wrap-around and adds nothing.
pub const MAX_OCTAVES: u32 = 24;

/// Why a noise field could not be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum NoiseError {
    /// The shape does not have `dim` axes.
    #[error("a {dim}D noise field needs {dim} axis lengths, got {found:?}")]
    ShapeMismatch {
        /// The requested dimension.
        dim: Dim,
        /// The shape that was supplied.
        found: Vec<usize>,
    },
    /// The voxel count overflows `usize`.
    #[error("shape {0:?} has too many voxels")]
    TooLarge(Vec<usize>),
    /// The frequency is not a finite number greater than zero.
    #[error("noise frequency must be finite and > 0, got {0}")]
    BadFrequency(f64),
    /// Zero octaves, or more than [`MAX_OCTAVES`].
    #[error("octaves must be between 1 and {MAX_OCTAVES}, got {0}")]
    BadOctaves(u32),
}

/// One Improved Noise function: a doubled permutation table.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Perlin {
    // Doubled so that `p[p[x] + y]` never needs a wrap (indices reach 511).
    p: [u8; 512],
}

#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[inline]
fn lerp(t: f64, a: f64, b: f64) -> f64 {
    a + t * (b - a)
}

/// Integer lattice cell (wrapped to 0..256) and the fractional position inside it.
#[inline]
fn split(x: f64) -> (usize, f64) {
    let f = libm::floor(x);
    // `as i64` saturates for huge inputs; the wrap keeps the index in range either way.
    ((f as i64 & 255) as usize, x - f)
}

/// One coordinate of a noise point as the noise uses it: the lattice cell (wrapped to
/// 0..256), the fractional position inside it, and that position faded.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Axis {
    cell: usize,
    frac: f64,
    fade: f64,
}

impl Axis {
    #[inline]
    fn of(x: f64) -> Axis {
        let (cell, frac) = split(x);
        Axis {
            cell,
            frac,
            fade: fade(frac),
        }
    }
}

#[inline]
fn grad2(hash: u8, x: f64, y: f64) -> f64 {
    const S: f64 = core::f64::consts::SQRT_2;
    match hash & 7 {
        0 => x + y,
        1 => -x + y,
        2 => x - y,
        3 => -x - y,
        4 => S * x,
        5 => -S * x,
        6 => S * y,
        _ => -S * y,
    }
}

#[inline]
fn grad3(hash: u8, x: f64, y: f64, z: f64) -> f64 {
    // Perlin's reference code, verbatim in structure.
    let h = hash & 15;
    let u = if h < 8 { x } else { y };
    let v = if h < 4 {
        y
    } else if h == 12 || h == 14 {
        x
    } else {
        z
    };
    (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
}

/// Index of the 4D gradient (0..32) a hash selects: bits 3-4 name the zero axis, bits 0-2
/// the signs of the other three axes in increasing axis order.
#[inline]
fn gradient_index4(hash: u8) -> u8 {
    hash & 31
}

/// The 32 gradients of 4D Improved Noise as coordinate factors (+1, -1, and 0 on the zero
/// axis), so that a gradient dot product has no data-dependent branch.
const GRADIENTS4: [[f64; 4]; 32] = {
    let mut table = [[0.0f64; 4]; 32];
    let mut g = 0;
    while g < 32 {
        let zero_axis = g >> 3;
        let mut bit = 0;
        let mut axis = 0;
        while axis < 4 {
            if axis != zero_axis {
                table[g][axis] = if (g >> bit) & 1 == 0 { 1.0 } else { -1.0 };
                bit += 1;
            }
            axis += 1;
        }
        g += 1;
    }
    table
};

/// The dot product of the corner offset `p` with gradient `hash & 31`: the three non-zero
/// terms +-c summed from +0.0 in axis order, and on the zero axis c * 0.0 = +-0.0 in its
/// place. Adding +-0.0 changes no non-zero sum, and a running sum started at +0.0 is never
/// -0.0, so this is bit for bit the sum of the three terms alone (the golden values pin
/// it), without branches in the 4D noise's inner loop.
#[inline]
fn grad4(hash: u8, p: [f64; 4]) -> f64 {
    let g = &GRADIENTS4[gradient_index4(hash) as usize];
    let mut sum = 0.0;
    for axis in 0..4 {
        sum += p[axis] * g[axis];
    }
    sum
}

/// The 4D noise from its 16 corner values (corner bit 0 is w, bit 3 is x) and the fades
/// `[fx, fy, fz, fw]`: interpolated along w, then z, then y, then x.
#[inline]
fn interpolate4(values: [f64; 16], [fx, fy, fz, fw]: [f64; 4]) -> f64 {
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

/// [`grad4`] in two parts: the running sum over the first three axes, and the gradient's
/// factor on the fourth. `prefix + p[3] * factor` is the whole sum, the same operations in
/// the same order, so a point that only moves along the fourth axis reuses the prefix.
#[inline]
fn grad4_prefix(hash: u8, p: [f64; 3]) -> (f64, f64) {
    let g = &GRADIENTS4[gradient_index4(hash) as usize];
    let mut sum = 0.0;
    for axis in 0..3 {
        sum += p[axis] * g[axis];
    }
    (sum, g[3])
}

/// What the 4D noise of one octave needs from a point's first three coordinates and the
/// lattice cell of its fourth (see `Perlin::fill_row4`): points of a row along the fourth
/// axis inside one cell share it, and only the fourth axis's term and the interpolation
/// are left per point.
#[derive(Clone, Copy, Debug)]
struct Row4 {
    prefix: [f64; 16],
    w_factor: [f64; 16],
    /// The fades of the first three coordinates.
    fades: [f64; 3],
    w_cell: usize,
    filled: bool,
}

impl Default for Row4 {
    fn default() -> Row4 {
        Row4 {
            prefix: [0.0; 16],
            w_factor: [0.0; 16],
            fades: [0.0; 3],
            w_cell: 0,
            filled: false,
        }
    }
}

impl Row4 {
    /// The octave's noise at fourth coordinate `w`, in the cell the row was filled for.
    #[inline]
    fn noise(&self, w: Axis) -> f64 {
        let mut values = [0.0f64; 16];
        for (c, v) in values.iter_mut().enumerate() {
            let dw = (c & 1) as f64;
            *v = self.prefix[c] + (w.frac - dw) * self.w_factor[c];
        }
        let [fx, fy, fz] = self.fades;
        interpolate4(values, [fx, fy, fz, w.fade])
    }
}

impl Perlin {
    /// Noise with Ken Perlin's reference permutation.
    pub fn reference() -> Perlin {
        Perlin::from_permutation(&REFERENCE_PERMUTATION)
    }

    /// Noise with 0..256 shuffled by a Fisher-Yates shuffle driven by `ChaCha8Rng` seeded
    /// from `seed`. Part of the dataset contract: the same seed gives the same noise.
    pub fn from_seed(seed: u64) -> Perlin {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut perm: [u8; 256] = core::array::from_fn(|i| i as u8);
        for i in (1..256usize).rev() {
            // Drawn as u64, not usize: rand samples usize ranges with the platform's pointer
            // width, which would make the shuffle differ between 32- and 64-bit machines.
            let j = rng.gen_range(0..=i as u64) as usize;
            perm.swap(i, j);
        }
        Perlin::from_permutation(&perm)
    }

    /// Noise with a caller-supplied table. It should be a permutation of 0..256 for
    /// unbiased noise, but any table gives a deterministic function.
    pub fn from_permutation(perm: &[u8; 256]) -> Perlin {
        let mut p = [0u8; 512];
        p[..256].copy_from_slice(perm);
        p[256..].copy_from_slice(perm);
        Perlin { p }
    }

    /// The permutation (first half of the doubled table).
    pub fn permutation(&self) -> &[u8] {
        &self.p[..256]
    }

    #[inline]
    fn hash2(&self, x: usize, y: usize) -> u8 {
        self.p[self.p[x] as usize + y]
    }

    #[inline]
    fn hash3(&self, x: usize, y: usize, z: usize) -> u8 {
        self.p[self.p[self.p[x] as usize + y] as usize + z]
    }

    /// The corner hash [`Perlin::noise4`] computes as a tree; the tests use it directly.
    #[cfg(test)]
    fn hash4(&self, x: usize, y: usize, z: usize, w: usize) -> u8 {
        self.p[self.p[self.p[self.p[x] as usize + y] as usize + z] as usize + w]
    }

    /// 2D Improved Noise. Zero at every integer lattice point.
    pub fn noise2(&self, x: f64, y: f64) -> f64 {
        self.noise2_axes(Axis::of(x), Axis::of(y))
    }

    #[inline]
    fn noise2_axes(&self, x: Axis, y: Axis) -> f64 {
        let (xi, u, x) = (x.cell, x.fade, x.frac);
        let (yi, v, y) = (y.cell, y.fade, y.frac);
        lerp(
            v,
            lerp(
                u,
                grad2(self.hash2(xi, yi), x, y),
                grad2(self.hash2(xi + 1, yi), x - 1.0, y),
            ),
            lerp(
                u,
                grad2(self.hash2(xi, yi + 1), x, y - 1.0),
                grad2(self.hash2(xi + 1, yi + 1), x - 1.0, y - 1.0),
            ),
        )
    }

    /// 3D Improved Noise; with [`Perlin::reference`] this is Perlin's `ImprovedNoise`.
    pub fn noise3(&self, x: f64, y: f64, z: f64) -> f64 {
        self.noise3_axes(Axis::of(x), Axis::of(y), Axis::of(z))
    }

    #[inline]
    fn noise3_axes(&self, x: Axis, y: Axis, z: Axis) -> f64 {
        let (xi, u, x) = (x.cell, x.fade, x.frac);
        let (yi, v, y) = (y.cell, y.fade, y.frac);
        let (zi, w, z) = (z.cell, z.fade, z.frac);
        let g = |dx: usize, dy: usize, dz: usize| {
            grad3(
                self.hash3(xi + dx, yi + dy, zi + dz),
                x - dx as f64,
                y - dy as f64,
                z - dz as f64,
            )
        };
        lerp(
            w,
            lerp(
                v,
                lerp(u, g(0, 0, 0), g(1, 0, 0)),
                lerp(u, g(0, 1, 0), g(1, 1, 0)),
            ),
            lerp(
                v,
                lerp(u, g(0, 0, 1), g(1, 0, 1)),
                lerp(u, g(0, 1, 1), g(1, 1, 1)),
            ),
        )
    }

    /// 4D Improved Noise over the 32 hypercube-edge gradients.
    pub fn noise4(&self, x: f64, y: f64, z: f64, w: f64) -> f64 {
        self.noise4_axes([Axis::of(x), Axis::of(y), Axis::of(z), Axis::of(w)])
    }

    #[inline]
    fn noise4_axes(&self, [x, y, z, w]: [Axis; 4]) -> f64 {
        let (xi, fx, x) = (x.cell, x.fade, x.frac);
        let (yi, fy, y) = (y.cell, y.fade, y.frac);
        let (zi, fz, z) = (z.cell, z.fade, z.frac);
        let (wi, fw, w) = (w.cell, w.fade, w.frac);
        // Corner c = (dx, dy, dz, dw) in bits 3..0. The hash is built as a tree
        // (p[x] shared by 8 corners, p[p[x] + y] by 4, ...): 30 table reads instead of 64.
        // Every index is at most 255 + 255 + 1, so `& 511` keeps it and shows the
        // compiler it is in the table (no bounds checks in the inner loop).
        let p = &self.p;
        let mut values = [0.0f64; 16];
        for dx in 0..2 {
            let hx = p[(xi + dx) & 511] as usize;
            for dy in 0..2 {
                let hy = p[(hx + yi + dy) & 511] as usize;
                for dz in 0..2 {
                    let hz = p[(hy + zi + dz) & 511] as usize;
                    for dw in 0..2 {
                        let hash = p[(hz + wi + dw) & 511];
                        values[dx << 3 | dy << 2 | dz << 1 | dw] = grad4(
                            hash,
                            [x - dx as f64, y - dy as f64, z - dz as f64, w - dw as f64],
                        );
                    }
                }
            }
        }
        interpolate4(values, [fx, fy, fz, fw])
    }

    /// The part of the 4D noise that does not depend on the fourth coordinate's position
    /// inside its lattice cell: each corner's hash, the sum of its gradient's first three
    /// terms, and the factor of its fourth.
    #[inline]
    fn fill_row4(&self, row: &mut Row4, [x, y, z]: [Axis; 3], wi: usize) {
        let (x_fade, y_fade, z_fade) = (x.fade, y.fade, z.fade);
        let (xi, x) = (x.cell, x.frac);
        let (yi, y) = (y.cell, y.frac);
        let (zi, z) = (z.cell, z.frac);
        row.fades = [x_fade, y_fade, z_fade];
        // Corner c = (dx, dy, dz, dw) in bits 3..0. The hash is built as a tree
        // (p[x] shared by 8 corners, p[p[x] + y] by 4, ...): 30 table reads instead of 64.
        // Every index is at most 255 + 255 + 1, so `& 511` keeps it and shows the
        // compiler it is in the table (no bounds checks in the inner loop).
        let p = &self.p;
        for dx in 0..2 {
            let hx = p[(xi + dx) & 511] as usize;
            for dy in 0..2 {
                let hy = p[(hx + yi + dy) & 511] as usize;
                for dz in 0..2 {
                    let hz = p[(hy + zi + dz) & 511] as usize;
                    for dw in 0..2 {
                        let hash = p[(hz + wi + dw) & 511];
                        let c = dx << 3 | dy << 2 | dz << 1 | dw;
                        (row.prefix[c], row.w_factor[c]) =
                            grad4_prefix(hash, [x - dx as f64, y - dy as f64, z - dz as f64]);
                    }
                }
            }
        }
    }

    /// Noise of a 4D point through a [`Row4`] memo: the memo is refilled unless it holds
    /// this octave's lattice cell of the fourth coordinate and the same first three
    /// coordinates.
    #[inline]
    fn noise4_memo(&self, memo: &mut Row4, lead_same: bool, axes: [Axis; 4]) -> f64 {
        if !(lead_same && memo.filled && memo.w_cell == axes[3].cell) {
            self.fill_row4(memo, [axes[0], axes[1], axes[2]], axes[3].cell);
            memo.w_cell = axes[3].cell;
            memo.filled = true;
        }
        memo.noise(axes[3])
    }

    /// Noise of the first `dim` coordinates of `point`.
    #[inline]
    pub fn noise(&self, dim: Dim, point: [f64; 4]) -> f64 {
        match dim {
            Dim::Two => self.noise2(point[0], point[1]),
            Dim::Three => self.noise3(point[0], point[1], point[2]),
            Dim::Four => self.noise4(point[0], point[1], point[2], point[3]),
        }
    }

    /// [`Perlin::noise`] of a point whose coordinates are split already.
    #[inline]
    fn noise_axes(&self, dim: Dim, axes: [Axis; 4]) -> f64 {
        match dim {
            Dim::Two => self.noise2_axes(axes[0], axes[1]),
            Dim::Three => self.noise3_axes(axes[0], axes[1], axes[2]),
            Dim::Four => self.noise4_axes(axes),
        }
    }
}

/// Fractal (fBm) Improved Noise sampled at voxel coordinates.
///
/// `sample(c) = sum_o 0.5^o * noise(2^o * frequency * c) / sum_o 0.5^o` for octaves
/// `o = 0 .. octaves`. `frequency` is in lattice cells per voxel (1/16 gives features about
/// 16 voxels wide).
#[derive(Clone, Debug, PartialEq)]
pub struct Fractal {
    perlin: Perlin,
    dim: Dim,
    frequency: f64,
    octaves: u32,
    normaliser: f64,
    /// Every octave's [`Axis`] at the voxel coordinates `0..GRID`, octave after octave:
    /// a point of a voxel grid repeats one coordinate value on every axis and in many
    /// points, so its split and fade are worked out once here, by the same operations
    /// [`Fractal::sample`] would do (the same bits).
    grid: Vec<Axis>,
}

/// What [`Fractal::sample_memo`] keeps from the last point it was asked for: that point's
/// first three coordinates and, per octave, the corner terms that do not depend on where
/// the fourth coordinate lies inside its lattice cell. Belongs to one [`Fractal`]; a fresh
/// one (`FractalMemo::default()`) holds nothing.
#[derive(Clone, Debug, Default)]
pub struct FractalMemo {
    lead: [usize; 3],
    rows: Vec<Row4>,
}

/// How many voxel coordinates (`0..GRID`) a [`Fractal`] keeps split: the sides of the
/// images it serves. A point with a coordinate beyond takes the general path.
const GRID: usize = 256;

impl Fractal {
    /// A fractal noise with a seeded permutation; validates frequency and octaves.
    pub fn new(dim: Dim, seed: u64, frequency: f64, octaves: u32) -> Result<Fractal, NoiseError> {
        Fractal::with_perlin(Perlin::from_seed(seed), dim, frequency, octaves)
    }

    /// A fractal noise over a given [`Perlin`] function.
    pub fn with_perlin(
        perlin: Perlin,
        dim: Dim,
        frequency: f64,
        octaves: u32,
    ) -> Result<Fractal, NoiseError> {
        if !(frequency.is_finite() && frequency > 0.0) {
            return Err(NoiseError::BadFrequency(frequency));
        }
        if octaves == 0 || octaves > MAX_OCTAVES {
            return Err(NoiseError::BadOctaves(octaves));
        }
        let normaliser = (0..octaves).map(|o| 0.5f64.powi(o as i32)).sum();
        let mut grid = Vec::with_capacity(octaves as usize * GRID);
        let mut octave_frequency = frequency;
        for _ in 0..octaves {
            grid.extend((0..GRID).map(|c| Axis::of(c as f64 * octave_frequency)));
            octave_frequency *= 2.0;
        }
        Ok(Fractal {
            perlin,
            dim,
            frequency,
            octaves,
            normaliser,
            grid,
        })
    }

    /// The dimension this noise is sampled in.
    pub fn dim(&self) -> Dim {
        self.dim
    }

    /// The fractal value at voxel coordinate `coords` (first `dim` entries used).
    #[inline]
    pub fn sample(&self, coords: [usize; 4]) -> f64 {
        let d = self.dim.get();
        if coords[..d].iter().all(|&c| c < GRID) {
            let mut total = 0.0;
            let mut amplitude = 1.0;
            for octave in self.grid.chunks_exact(GRID) {
                let mut axes = [Axis::default(); 4];
                for a in 0..d {
                    axes[a] = octave[coords[a]];
                }
                total += amplitude * self.perlin.noise_axes(self.dim, axes);
                amplitude *= 0.5;
            }
            return total / self.normaliser;
        }
        self.sample_anywhere(coords)
    }

    /// [`Fractal::sample`], bit for bit, reusing what `memo` kept from the point before:
    /// in 4D, a point that shares the first three coordinates with it and, per octave, the
    /// lattice cell of the fourth skips the corner hashes and three of the four terms of
    /// every corner's gradient product. Points taken in C order (a phase's frontier) share
    /// them often; in any order the values are the same.
    #[inline]
    pub fn sample_memo(&self, coords: [usize; 4], memo: &mut FractalMemo) -> f64 {
        if self.dim != Dim::Four || !coords.iter().all(|&c| c < GRID) {
            return self.sample(coords);
        }
        let lead_same = memo.lead == [coords[0], coords[1], coords[2]];
        memo.lead = [coords[0], coords[1], coords[2]];
        if memo.rows.len() != self.octaves as usize {
            memo.rows = vec![Row4::default(); self.octaves as usize];
        }
        let mut total = 0.0;
        let mut amplitude = 1.0;
        for (octave, row) in self.grid.chunks_exact(GRID).zip(memo.rows.iter_mut()) {
            let axes = coords.map(|c| octave[c]);
            total += amplitude * self.perlin.noise4_memo(row, lead_same, axes);
            amplitude *= 0.5;
        }
        total / self.normaliser
    }

    /// [`Fractal::sample`] without the split coordinates: the definition, for any point.
    fn sample_anywhere(&self, coords: [usize; 4]) -> f64 {
        let mut total = 0.0;
        let mut amplitude = 1.0;
        let mut frequency = self.frequency;
        for _ in 0..self.octaves {
            let p = coords.map(|c| c as f64 * frequency);
            total += amplitude * self.perlin.noise(self.dim, p);
            amplitude *= 0.5;
            frequency *= 2.0;
        }
        total / self.normaliser
    }
}

/// One fractal noise value per voxel of `shape`, in C order, as `f32`.
///
/// Parallel over rows; bit-identical whatever the number of rayon threads, because every
/// value depends only on its own coordinate.
pub fn noise_field(
    dim: Dim,
    shape: &[usize],
    seed: u64,
    frequency: f64,
    octaves: u32,
) -> Result<Vec<f32>, NoiseError> {
    if shape.len() != dim.get() {
        return Err(NoiseError::ShapeMismatch {
            dim,
            found: shape.to_vec(),
        });
    }
    let len = shape
        .iter()
        .try_fold(1usize, |acc, &n| acc.checked_mul(n))
        .ok_or_else(|| NoiseError::TooLarge(shape.to_vec()))?;
    let fractal = Fractal::new(dim, seed, frequency, octaves)?;
    let mut out = vec![0f32; len];
    if len == 0 {
        return Ok(out);
    }
    let d = dim.get();
    let row = shape[d - 1];
    out.par_chunks_mut(row).enumerate().for_each(|(r, chunk)| {
        // Decode the row number into the leading coordinates.
        let mut coords = [0usize; 4];
        let mut rest = r;
        for axis in (0..d - 1).rev() {
            coords[axis] = rest % shape[axis];
            rest /= shape[axis];
        }
        for (i, v) in chunk.iter_mut().enumerate() {
            coords[d - 1] = i;
            *v = fractal.sample(coords) as f32;
        }
    });
    Ok(out)
}

#[cfg(test)]
mod tests;
