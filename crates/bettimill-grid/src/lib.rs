//! The voxel grid: the one image type every other bettimill crate speaks.
//!
//! A [`BinaryImage`] is a 2-, 3- or 4-dimensional array of voxels stored in C order (last
//! axis fastest), one byte per voxel, each byte 0 (background) or 1 (foreground). Its shape
//! need not be a hypercube: `bettimill betti` accepts any user image. The [`npy`] module
//! reads and writes such images as `.npy` files, and [`neighbourhood`] holds the offset
//! tables of the (3^d-1)- and 2d-neighbourhoods that homology, shapes and deformations share.

pub mod neighbourhood;
pub mod npy;

use serde::{Deserialize, Serialize};
use std::fmt;

/// Which phase the objects of a sample are: the voxel model's two ways to draw a shape.
///
/// It lives beside [`Dim`] because the manifest, the plan, the constructions and the
/// labels all speak of it, and none of them should need another's crate to do so.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Objects (foreground) in empty space.
    Embed,
    /// A solid cube filling the image except a one-voxel margin, with the objects removed
    /// as cavities.
    Carve,
}

impl Mode {
    /// The manifest spelling: `embed` or `carve`.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Embed => "embed",
            Mode::Carve => "carve",
        }
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The number of axes of an image. Only 2, 3 and 4 exist, so every function that takes a
/// `Dim` can rely on that instead of re-checking it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub enum Dim {
    /// Planar images.
    Two,
    /// Volumes.
    Three,
    /// Four-dimensional images.
    Four,
}

impl Dim {
    /// All dimensions, in increasing order.
    pub const ALL: [Dim; 3] = [Dim::Two, Dim::Three, Dim::Four];

    /// The number of axes as a plain number.
    pub fn get(self) -> usize {
        match self {
            Dim::Two => 2,
            Dim::Three => 3,
            Dim::Four => 4,
        }
    }

    /// `Some(dim)` for 2, 3 and 4, `None` otherwise.
    pub fn new(n: usize) -> Option<Dim> {
        match n {
            2 => Some(Dim::Two),
            3 => Some(Dim::Three),
            4 => Some(Dim::Four),
            _ => None,
        }
    }
}

impl TryFrom<u8> for Dim {
    type Error = String;
    fn try_from(value: u8) -> Result<Self, Self::Error> {
        Dim::new(value as usize).ok_or_else(|| format!("dimension must be 2, 3 or 4, not {value}"))
    }
}

impl From<Dim> for u8 {
    fn from(dim: Dim) -> u8 {
        dim.get() as u8
    }
}

impl fmt::Display for Dim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.get())
    }
}

/// Why an image could not be made.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum GridError {
    /// The shape has fewer than 2 or more than 4 axes.
    #[error("an image must have 2, 3 or 4 axes, this one has {0}")]
    BadRank(usize),
    /// An axis has length zero.
    #[error("axis {axis} has length 0")]
    EmptyAxis {
        /// The offending axis.
        axis: usize,
    },
    /// The voxel count does not fit in memory addressing.
    #[error("shape {shape:?} has too many voxels")]
    TooLarge {
        /// The requested shape.
        shape: Vec<usize>,
    },
    /// The data length does not match the shape.
    #[error("shape {shape:?} needs {expected} voxels, got {found}")]
    LengthMismatch {
        /// The requested shape.
        shape: Vec<usize>,
        /// Voxels the shape needs.
        expected: usize,
        /// Voxels supplied.
        found: usize,
    },
    /// An allocation for the image failed.
    #[error("cannot allocate {bytes} bytes for the image: not enough memory")]
    OutOfMemory {
        /// The bytes asked for.
        bytes: usize,
    },
    /// A voxel value other than 0 or 1.
    #[error("voxel {index} has value {value}; a binary image holds only 0 and 1")]
    NotBinary {
        /// Flat index of the first bad voxel.
        index: usize,
        /// Its value.
        value: u8,
    },
}

/// A binary image in C order, one byte (0 or 1) per voxel.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct BinaryImage {
    dim: Dim,
    shape: [usize; 4],
    strides: [usize; 4],
    data: Vec<u8>,
}

impl fmt::Debug for BinaryImage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BinaryImage")
            .field("shape", &self.shape())
            .field("foreground", &self.count_foreground())
            .finish()
    }
}

/// Steps `row`, the coordinates of a row along the last axis (along the axes before it),
/// to the next row in C order of an image whose sides along those axes are `sides`,
/// counted like an odometer (a division per row cost more than the rest of the row's
/// work); past the last row it wraps to the first.
pub(crate) fn next_row(row: &mut [usize], sides: &[usize]) {
    for axis in (0..row.len()).rev() {
        row[axis] += 1;
        if row[axis] < sides[axis] {
            return;
        }
        row[axis] = 0;
    }
}

/// The C-order strides of `shape` (2 to 4 axes; 0 past the last), products of a length
/// already checked to fit.
pub(crate) fn strides_of(shape: &[usize]) -> [usize; 4] {
    let mut strides = [0usize; 4];
    let mut stride = 1;
    for axis in (0..shape.len()).rev() {
        strides[axis] = stride;
        stride *= shape[axis];
    }
    strides
}

/// Where the row along the last axis whose coordinates along the other axes are `row`
/// starts in the copy padded by `width` layers whose strides are `strides`.
pub(crate) fn padded_row_start(row: &[usize], strides: &[usize], width: usize) -> usize {
    let inside: usize = row
        .iter()
        .zip(strides)
        .map(|(&x, &s)| (x + width) * s)
        .sum();
    inside + width
}

fn checked_len(shape: &[usize]) -> Result<(Dim, usize), GridError> {
    let dim = Dim::new(shape.len()).ok_or(GridError::BadRank(shape.len()))?;
    let mut len: usize = 1;
    for (axis, &n) in shape.iter().enumerate() {
        if n == 0 {
            return Err(GridError::EmptyAxis { axis });
        }
        len = len.checked_mul(n).ok_or_else(|| GridError::TooLarge {
            shape: shape.to_vec(),
        })?;
    }
    // Keep every flat index addressable as i64 offsets too (neighbour arithmetic).
    if len > (isize::MAX as usize) / 2 {
        return Err(GridError::TooLarge {
            shape: shape.to_vec(),
        });
    }
    Ok((dim, len))
}

impl BinaryImage {
    /// An all-background image of the given shape.
    pub fn zeros(shape: &[usize]) -> Result<BinaryImage, GridError> {
        let (dim, len) = checked_len(shape)?;
        // Not through `from_vec`: its scan for values over 1 would read every page of the
        // fresh zeroed buffer, mapping it once to read and once more on the first write.
        Ok(BinaryImage::with_layout(dim, shape, vec![0; len]))
    }

    /// An all-background hypercube of side `side`.
    pub fn cube(dim: Dim, side: usize) -> Result<BinaryImage, GridError> {
        BinaryImage::zeros(&vec![side; dim.get()])
    }

    /// Wraps C-order data; every byte must be 0 or 1.
    pub fn from_vec(shape: &[usize], data: Vec<u8>) -> Result<BinaryImage, GridError> {
        let (dim, len) = checked_len(shape)?;
        if data.len() != len {
            return Err(GridError::LengthMismatch {
                shape: shape.to_vec(),
                expected: len,
                found: data.len(),
            });
        }
        // The OR of a chunk is at most 1 exactly when all its values are: a loop the
        // compiler turns into vector ORs, where a search for the first bad value goes one byte
        // at a time.
        let binary = |chunk: &[u8]| chunk.iter().fold(0u8, |any, &v| any | v) <= 1;
        if !data.chunks(1 << 12).all(binary) {
            let index = data.iter().position(|&v| v > 1).expect("a value over 1");
            return Err(GridError::NotBinary {
                index,
                value: data[index],
            });
        }
        Ok(BinaryImage::with_layout(dim, shape, data))
    }

    /// The image of a checked `shape` (`checked_len`) over `data` of its length, 0s and 1s.
    fn with_layout(dim: Dim, shape: &[usize], data: Vec<u8>) -> BinaryImage {
        debug_assert_eq!(data.len(), shape.iter().product::<usize>());
        let mut full = [1usize; 4];
        full[..shape.len()].copy_from_slice(shape);
        BinaryImage {
            dim,
            shape: full,
            strides: strides_of(shape),
            data,
        }
    }

    /// The number of axes.
    pub fn dim(&self) -> Dim {
        self.dim
    }

    /// The length of each axis.
    pub fn shape(&self) -> &[usize] {
        &self.shape[..self.dim.get()]
    }

    /// The flat-index step of each axis (C order).
    pub fn strides(&self) -> &[usize] {
        &self.strides[..self.dim.get()]
    }

    /// The number of voxels.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Always false: an image has at least one voxel. Present for clippy's sake.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// The voxels in C order.
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// The voxels in C order, writable. Callers must keep every byte 0 or 1.
    pub fn data_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }

    /// Consumes the image and returns its voxels.
    pub fn into_vec(self) -> Vec<u8> {
        self.data
    }

    /// The flat index of a coordinate (no bounds check beyond debug assertions).
    #[inline]
    pub fn index(&self, coords: &[usize]) -> usize {
        debug_assert_eq!(coords.len(), self.dim.get());
        coords
            .iter()
            .zip(self.strides())
            .map(|(&c, &s)| c * s)
            .sum()
    }

    /// The coordinate of a flat index.
    #[inline]
    pub fn coords(&self, mut index: usize) -> [usize; 4] {
        let mut out = [0usize; 4];
        for (coordinate, &stride) in out.iter_mut().zip(self.strides()) {
            *coordinate = index / stride;
            index %= stride;
        }
        out
    }

    /// Whether the voxel at `coords` is foreground.
    #[inline]
    pub fn get(&self, coords: &[usize]) -> bool {
        self.data[self.index(coords)] != 0
    }

    /// Sets the voxel at `coords`.
    #[inline]
    pub fn set(&mut self, coords: &[usize], value: bool) {
        let i = self.index(coords);
        self.data[i] = value as u8;
    }

    /// The number of foreground voxels (the sample's hypervolume).
    pub fn count_foreground(&self) -> u64 {
        // Summed in 16-bit lanes, 257 bytes at a time (at most 65,535 whatever the bytes),
        // which the compiler turns into vector adds (a 64-bit sum per byte does not
        // vectorise as well).
        let run = |run: &[u8]| run.iter().map(|&v| v as u16).sum::<u16>() as u64;
        self.data.chunks(257).map(run).sum()
    }

    /// Whether a coordinate (possibly negative or past the end) lies inside the image.
    pub fn contains(&self, coords: &[i64]) -> bool {
        coords
            .iter()
            .zip(self.shape())
            .all(|(&c, &n)| c >= 0 && (c as usize) < n)
    }

    /// A copy surrounded by `width` layers of background on every side.
    pub fn padded(&self, width: usize) -> BinaryImage {
        let new_shape: Vec<usize> = self.shape().iter().map(|&n| n + 2 * width).collect();
        let mut out = BinaryImage::zeros(&new_shape).expect("padding a valid image stays valid");
        let d = self.dim.get();
        let row = self.shape[d - 1];
        let rows = self.len() / row;
        // The coordinates of the current row along the first d - 1 axes, counted up
        // like an odometer (no divisions per row).
        let mut c = [0usize; 4];
        for r in 0..rows {
            let src = r * row;
            let dst = padded_row_start(&c[..d - 1], &out.strides, width);
            out.data[dst..dst + row].copy_from_slice(&self.data[src..src + row]);
            next_row(&mut c[..d - 1], &self.shape);
        }
        out
    }

    /// [`BinaryImage::padded`] without a second buffer: the data grows in place and every
    /// row moves to its padded position, last row first (a row only moves forward, onto
    /// the old places of rows already moved), then the gaps between rows are cleared. For callers that do not
    /// need the image afterwards: the peak is the padded image alone, where a copy holds
    /// both.
    pub fn into_padded(self, width: usize) -> BinaryImage {
        let d = self.dim.get();
        let new_shape: Vec<usize> = self.shape().iter().map(|&n| n + 2 * width).collect();
        let (dim, new_len) = checked_len(&new_shape).expect("padding a valid image stays valid");
        let old_shape = self.shape;
        let row = old_shape[d - 1];
        let rows = self.len() / row;
        let mut data = self.data;
        data.resize(new_len, 0);
        let strides = strides_of(&new_shape);
        // The padded start of every row, in order (its coordinates along the first d - 1
        // axes are r's digits in the old shape).
        let mut starts = Vec::with_capacity(rows);
        let mut digits = [0usize; 4];
        for _ in 0..rows {
            starts.push(padded_row_start(&digits[..d - 1], &strides, width));
            next_row(&mut digits[..d - 1], &old_shape);
        }
        for (r, &dst) in starts.iter().enumerate().rev() {
            data.copy_within(r * row..(r + 1) * row, dst);
        }
        // Clear what lies between the moved rows (old data or zeros alike).
        let mut cleared_to = 0;
        for &dst in &starts {
            data[cleared_to..dst].fill(0);
            cleared_to = dst + row;
        }
        data[cleared_to..].fill(0);
        BinaryImage::with_layout(dim, &new_shape, data)
    }

    /// [`BinaryImage::into_padded`] for an image whose size comes from input: a failed
    /// allocation of the padded image is an error, not an abort.
    pub fn try_into_padded(mut self, width: usize) -> Result<BinaryImage, GridError> {
        let new_shape: Vec<usize> = self
            .shape()
            .iter()
            .map(|&n| n.saturating_add(width.saturating_mul(2)))
            .collect();
        let (_, new_len) = checked_len(&new_shape)?;
        self.data
            .try_reserve_exact(new_len.saturating_sub(self.data.len()))
            .map_err(|_| GridError::OutOfMemory { bytes: new_len })?;
        Ok(self.into_padded(width))
    }

    /// The inverse of [`BinaryImage::padded`]: drops `width` layers on every side.
    /// Panics if an axis is not longer than `2 * width` (a caller bug).
    pub fn cropped(&self, width: usize) -> BinaryImage {
        let d = self.dim.get();
        let new_shape: Vec<usize> = self
            .shape()
            .iter()
            .map(|&n| {
                assert!(n > 2 * width, "cropping {width} layers from an axis of {n}");
                n - 2 * width
            })
            .collect();
        let mut out = BinaryImage::zeros(&new_shape).expect("cropping a valid image");
        let row = new_shape[d - 1];
        let rows = out.len() / row;
        for r in 0..rows {
            let dst = r * row;
            let c = out.coords(dst);
            let mut src_coords = [0usize; 4];
            for axis in 0..d {
                src_coords[axis] = c[axis] + width;
            }
            let src = self.index(&src_coords[..d]);
            out.data[dst..dst + row].copy_from_slice(&self.data[src..src + row]);
        }
        out
    }

    /// The complement: foreground and background swapped.
    pub fn complement(&self) -> BinaryImage {
        let mut out = self.clone();
        for v in out.data.iter_mut() {
            *v ^= 1;
        }
        out
    }

    /// Whether every voxel of the outermost layer is background. Row by row along the last
    /// axis: a row on the layer must be all background, any other only at its two ends
    /// (the voxels inside are not looked at).
    pub fn border_is_background(&self) -> bool {
        let d = self.dim.get();
        let last = self.shape[d - 1];
        // The row's coordinates along the other axes.
        let mut row = [0usize; 4];
        self.data.chunks_exact(last).all(|line| {
            let on_layer = (0..d - 1).any(|a| row[a] == 0 || row[a] + 1 == self.shape[a]);
            next_row(&mut row[..d - 1], &self.shape);
            if on_layer {
                line.iter().all(|&v| v == 0)
            } else {
                line[0] == 0 && line[last - 1] == 0
            }
        })
    }

    /// The inclusive box of the whole image: `([0; 4], shape - 1)` on the first `d` axes
    /// (0 on the others), the form [`BinaryImage::value_box`] takes.
    pub fn whole_box(&self) -> ([usize; 4], [usize; 4]) {
        let d = self.dim.get();
        let hi = std::array::from_fn(|a| if a < d { self.shape[a] - 1 } else { 0 });
        ([0; 4], hi)
    }

    /// The bounding box (inclusive, on the first `d` axes) of the voxels of `value`, 0 or
    /// 1, within the inclusive box `lo ..= hi`, or `None` when there are none. A row along
    /// the last axis at a time, eight voxels a step.
    pub fn value_box(
        &self,
        value: u8,
        lo: &[usize; 4],
        hi: &[usize; 4],
    ) -> Option<([usize; 4], [usize; 4])> {
        let d = self.dim.get();
        let strides = &self.strides;
        let mut found_lo = [usize::MAX; 4];
        let mut found_hi = [0usize; 4];
        let mut c = *lo;
        loop {
            let start: usize = (0..d - 1).map(|a| c[a] * strides[a]).sum::<usize>() + lo[d - 1];
            let row = &self.data[start..=start + (hi[d - 1] - lo[d - 1])];
            if let Some((first, last)) = row_ends(row, value) {
                for axis in 0..d - 1 {
                    found_lo[axis] = found_lo[axis].min(c[axis]);
                    found_hi[axis] = found_hi[axis].max(c[axis]);
                }
                found_lo[d - 1] = found_lo[d - 1].min(lo[d - 1] + first);
                found_hi[d - 1] = found_hi[d - 1].max(lo[d - 1] + last);
            }
            // The next row: odometer over the first d - 1 axes.
            let mut axis = d - 1;
            loop {
                if axis == 0 {
                    return (found_lo[0] != usize::MAX).then_some((found_lo, found_hi));
                }
                axis -= 1;
                if c[axis] < hi[axis] {
                    c[axis] += 1;
                    break;
                }
                c[axis] = lo[axis];
            }
        }
    }
}

/// The first and last positions of `value` in a row of voxels (0 or 1), or `None`. Eight
/// voxels at a time, one byte each in a u64 (the last eight overlapping the ones before
/// when the length is not a multiple of eight): a byte of `word ^ other` is nonzero
/// exactly where the voxel holds `value`, so a row without it (empty space, solid wall)
/// costs a few instructions a word.
pub fn row_ends(row: &[u8], value: u8) -> Option<(usize, usize)> {
    const LOW_BYTES: u64 = 0x0101_0101_0101_0101;
    let n = row.len();
    if n < 8 {
        let first = row.iter().position(|&v| v == value)?;
        let last = row.iter().rposition(|&v| v == value)?;
        return Some((first, last));
    }
    let other = u64::from(1 - value) * LOW_BYTES;
    let hit = |at: usize| {
        let word: [u8; 8] = row[at..at + 8].try_into().expect("eight bytes");
        u64::from_le_bytes(word) ^ other
    };
    let mut at = 0;
    let first = loop {
        let h = hit(at);
        if h != 0 {
            break at + h.trailing_zeros() as usize / 8;
        }
        if at + 8 >= n {
            return None;
        }
        at = (at + 8).min(n - 8);
    };
    // A word from the end down: the one holding `first` stops it at the latest.
    let mut at = n - 8;
    let last = loop {
        let h = hit(at);
        if h != 0 {
            break at + 7 - h.leading_zeros() as usize / 8;
        }
        at = at.saturating_sub(8);
    };
    Some((first, last))
}

/// Room for `extra` more voxels of an image of at most `total`: doubling as data arrives
/// (a lying header costs only the data sent), never past `total`; failure is an error.
pub(crate) fn reserve(
    voxels: &mut Vec<u8>,
    extra: usize,
    total: usize,
) -> Result<(), npy::NpyError> {
    let needed = voxels.len().saturating_add(extra);
    if needed <= voxels.capacity() {
        return Ok(());
    }
    let target = voxels.capacity().saturating_mul(2).min(total).max(needed);
    voxels
        .try_reserve_exact(target - voxels.len())
        .map_err(|_| out_of_memory(target))
}

pub(crate) fn out_of_memory(bytes: usize) -> npy::NpyError {
    npy::NpyError::Memory(format!(
        "cannot allocate {bytes} bytes for the image: not enough memory"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ends_of_a_row_are_its_first_and_last_voxels_of_the_value() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for len in 1..40 {
            for density in [1u64, 2, 9, 40] {
                let row: Vec<u8> = (0..len)
                    .map(|_| {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        state.is_multiple_of(density) as u8
                    })
                    .collect();
                for value in [0u8, 1] {
                    let want = row
                        .iter()
                        .position(|&v| v == value)
                        .zip(row.iter().rposition(|&v| v == value));
                    assert_eq!(row_ends(&row, value), want, "{row:?} {value}");
                }
            }
        }
    }

    #[test]
    fn the_border_is_background_unless_a_voxel_on_it_is_set() {
        for shape in [&[4, 5][..], &[3, 4, 5], &[3, 4, 3, 5], &[1, 3, 3]] {
            let empty = BinaryImage::zeros(shape).unwrap();
            assert!(empty.border_is_background(), "{shape:?}");
            for index in 0..empty.len() {
                let mut one = empty.clone();
                one.data_mut()[index] = 1;
                let c = one.coords(index);
                let on_border = (0..shape.len()).any(|a| c[a] == 0 || c[a] + 1 == shape[a]);
                assert_eq!(one.border_is_background(), !on_border, "{shape:?} {c:?}");
            }
        }
    }

    /// Full images (every run of 257 bytes sums to its most), empty ones, and one voxel
    /// at each place of lengths around the run's, against a count one voxel at a time.
    #[test]
    fn the_foreground_count_is_the_number_of_ones() {
        for len in [1, 256, 257, 258, 513, 514, 2000] {
            let full = BinaryImage::from_vec(&[len, 1], vec![1; len]).unwrap();
            assert_eq!(full.count_foreground(), len as u64);
            let empty = BinaryImage::zeros(&[1, len]).unwrap();
            assert_eq!(empty.count_foreground(), 0);
            for index in [0, len / 2, len - 1] {
                let mut image = full.clone();
                image.data_mut()[index] = 0;
                assert_eq!(image.count_foreground(), len as u64 - 1, "{len} {index}");
            }
        }
        let mixed: Vec<u8> = (0..5000u32)
            .map(|i| (i.wrapping_mul(2654435761) >> 31) as u8)
            .collect();
        let ones = mixed.iter().filter(|&&v| v == 1).count() as u64;
        assert_eq!(
            BinaryImage::from_vec(&[50, 100], mixed)
                .unwrap()
                .count_foreground(),
            ones
        );
    }

    #[test]
    fn pad_then_crop_round_trips() {
        let mut img = BinaryImage::zeros(&[3, 4, 5]).unwrap();
        img.set(&[0, 0, 0], true);
        img.set(&[2, 3, 4], true);
        img.set(&[1, 2, 0], true);
        let padded = img.padded(2);
        assert_eq!(padded.shape(), &[7, 8, 9]);
        assert!(padded.get(&[2, 2, 2]));
        assert!(padded.get(&[4, 5, 6]));
        assert!(padded.border_is_background());
        assert!(!img.border_is_background());
        assert_eq!(padded.count_foreground(), 3);
        assert_eq!(padded.cropped(2), img);
    }

    /// Every voxel lands `width` further along every axis, in every dimension and for
    /// shapes whose axes all differ.
    #[test]
    fn padding_moves_every_voxel_by_the_width() {
        for shape in [
            &[3usize, 5][..],
            &[2, 3, 4],
            &[2, 3, 4, 5],
            &[1, 1, 1, 6],
            &[4, 1, 3, 1],
        ] {
            let mut img = BinaryImage::zeros(shape).unwrap();
            for index in 0..img.len() {
                img.data_mut()[index] = ((index * 7 + index / 3) % 3 == 0) as u8;
            }
            for width in [1, 2] {
                let padded = img.padded(width);
                assert_eq!(img.clone().into_padded(width), padded, "{shape:?} {width}");
                assert_eq!(padded.count_foreground(), img.count_foreground());
                for index in 0..img.len() {
                    let c = img.coords(index);
                    let moved: Vec<usize> = c[..shape.len()].iter().map(|&x| x + width).collect();
                    assert_eq!(
                        padded.get(&moved),
                        img.data()[index] == 1,
                        "{shape:?} {c:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn shape_errors_are_reported() {
        assert_eq!(BinaryImage::zeros(&[4]), Err(GridError::BadRank(1)));
        assert_eq!(
            BinaryImage::zeros(&[4, 0]),
            Err(GridError::EmptyAxis { axis: 1 })
        );
        assert!(matches!(
            BinaryImage::zeros(&[usize::MAX, 4]),
            Err(GridError::TooLarge { .. })
        ));
        assert!(matches!(
            BinaryImage::from_vec(&[2, 2], vec![0, 1, 2, 0]),
            Err(GridError::NotBinary { index: 2, value: 2 })
        ));
    }

    #[test]
    fn coords_and_index_agree() {
        let img = BinaryImage::zeros(&[3, 4, 5, 6]).unwrap();
        for i in 0..img.len() {
            let c = img.coords(i);
            assert_eq!(img.index(&c[..4]), i);
        }
    }
}
