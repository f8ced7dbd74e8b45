//! How the places of the grid are laid out in bricks, a cell's name, and the check that
//! the places fit 32 bits.

/// How places are laid out (module docs), and the steps from a cell to its facets and
/// cofacets: small and `Copy`, so that each half of a split reduction holds its own.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Grid {
    pub(super) d: usize,
    /// Per axis: the shift of its two local bits, and the step from one brick to the next.
    pub(super) shift: [u32; 4],
    pub(super) brick_step: [usize; 4],
    /// Per axis, for [`Grid::forward`] and [`Grid::back`]: the two local bits in place, the
    /// step to the next voxel inside a brick (one at the shift) and the step from the last
    /// voxel of a brick to the first of the next (a brick on, three back inside).
    pub(super) local_bits: [usize; 4],
    pub(super) inner_step: [usize; 4],
    pub(super) brick_over: [usize; 4],
    /// Per local code: the codes of its cofacets (facets) held by the same owner.
    pub(super) up_same: [u16; 16],
    pub(super) down_same: [u16; 16],
    /// The local codes' bits: 2^d - 1.
    pub(super) all_codes: u32,
}

impl Grid {
    /// The layout of the places of the grid of an image of `shape` (1 to 4 axes), whose
    /// `places` [`check_grid`] counted.
    pub(super) fn new(shape: &[usize], places: usize) -> Grid {
        let d = shape.len();
        let mut shift = [0u32; 4];
        let mut brick_step = [0usize; 4];
        let mut bricks = 1;
        for axis in (0..d).rev() {
            shift[axis] = 2 * (d - 1 - axis) as u32;
            brick_step[axis] = bricks << (2 * d);
            bricks *= shape[axis].div_ceil(4);
        }
        debug_assert_eq!(places, bricks << (2 * d));
        let all_codes = (1u32 << d) - 1;
        let mut up_same = [0u16; 16];
        let mut down_same = [0u16; 16];
        for code in 0..=all_codes {
            for axis in 0..d {
                if code >> axis & 1 == 1 {
                    up_same[code as usize] |= 1 << (code ^ 1 << axis);
                } else {
                    down_same[code as usize] |= 1 << (code | 1 << axis);
                }
            }
        }
        Grid {
            d,
            shift,
            brick_step,
            local_bits: shift.map(|shift| 3 << shift),
            inner_step: shift.map(|shift| 1 << shift),
            brick_over: std::array::from_fn(|axis| brick_step[axis].wrapping_sub(3 << shift[axis])),
            up_same,
            down_same,
            all_codes,
        }
    }

    /// The place of the voxel at `coords`.
    pub(crate) fn place(&self, coords: &[usize]) -> usize {
        (0..self.d)
            .map(|a| (coords[a] / 4) * self.brick_step[a] + ((coords[a] % 4) << self.shift[a]))
            .sum()
    }

    /// The place one voxel further along `axis`.
    #[inline]
    pub(super) fn forward(&self, place: usize, axis: usize) -> usize {
        let bits = self.local_bits[axis];
        place.wrapping_add(if place & bits == bits {
            self.brick_over[axis]
        } else {
            self.inner_step[axis]
        })
    }

    /// The place one voxel back along `axis`.
    #[inline]
    pub(super) fn back(&self, place: usize, axis: usize) -> usize {
        place.wrapping_sub(if place & self.local_bits[axis] == 0 {
            self.brick_over[axis]
        } else {
            self.inner_step[axis]
        })
    }

    /// The owners of the cells of the voxel at `place`: entry s is the voxel one step back
    /// along every axis in the set s (bit a = axis a), entry 0 the voxel itself.
    pub(crate) fn owners_around(&self, place: usize) -> [usize; 16] {
        let mut around = [place; 16];
        for s in 1..1usize << self.d {
            let axis = s.trailing_zeros() as usize;
            around[s] = self.back(around[s & (s - 1)], axis);
        }
        around
    }

    /// For each boundary face of a voxel, named by the offset of the neighbour that shares
    /// it (each component -1, 0 or 1), its owner as an entry of [`Grid::owners_around`]
    /// (the axes where the offset is -1) and its local code (every nonzero component is an
    /// even axis).
    pub(crate) fn face_places(&self, offsets: &[[i8; 4]]) -> Vec<(usize, u32)> {
        offsets
            .iter()
            .map(|offset| {
                let mut back = 0usize;
                let mut code = 0u32;
                for (axis, &t) in offset[..self.d].iter().enumerate() {
                    if t == -1 {
                        back |= 1 << axis;
                    }
                    if t != 0 {
                        code |= 1 << axis;
                    }
                }
                (back, code)
            })
            .collect()
    }

    /// The first place of the brick row (four planes across the first axis) of `place`.
    pub(crate) fn row_start(&self, place: usize) -> usize {
        place - place % self.brick_step[0]
    }

    /// The coordinates of the voxel at `place` (the inverse of [`Grid::place`]).
    #[inline]
    pub(super) fn coords(&self, place: usize) -> [usize; 4] {
        let mut coords = [0usize; 4];
        let mut brick = place >> (2 * self.d);
        for (axis, coord) in coords.iter_mut().enumerate().take(self.d) {
            let bricks = self.brick_step[axis] >> (2 * self.d);
            *coord = 4 * (brick / bricks) + (place >> self.shift[axis] & 3);
            brick %= bricks;
        }
        coords
    }
}

/// [`DenseComplex::new`](super::DenseComplex::new) refused a grid: its places would not fit 32 bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct GridTooLarge {
    /// The places the grid needs (voxels, each side rounded up to a multiple of 4; at most
    /// `u64::MAX`).
    pub(crate) places: u64,
}

/// The places of the grid of an image of `shape` (its voxels, rounded up to whole bricks of
/// 4^d), or an error when they would not fit 32 bits.
pub(crate) fn check_grid(shape: &[usize]) -> Result<usize, GridTooLarge> {
    let places = shape.iter().fold(1u128, |n, &side| {
        n.saturating_mul((side as u128).next_multiple_of(4))
    });
    if places > 1 << 32 {
        Err(GridTooLarge {
            places: u64::try_from(places).unwrap_or(u64::MAX),
        })
    } else {
        Ok(places as usize)
    }
}

#[inline]
pub(super) fn cell(owner: usize, code: u32) -> u64 {
    (owner as u64) << 4 | code as u64
}

#[inline]
pub(super) fn split(cell: u64) -> (usize, u32) {
    ((cell >> 4) as usize, (cell & 15) as u32)
}
