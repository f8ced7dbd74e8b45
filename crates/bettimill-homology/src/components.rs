//! Connected components of the foreground ((3^d-1)-adjacency) and background (2d-adjacency).
//!
//! b_0 is the number of foreground components, and by duality b_{d-1} is the number of
//! background components of the padded image minus one (the outside). Both are counted by
//! flood fill: of a whole image run by run along its rows, or of a thinned remnant voxel
//! by voxel over flat indices; the visited marks live in a one-byte-per-voxel copy.

use bettimill_grid::neighbourhood::{face_offsets, full_offsets};
use bettimill_grid::BinaryImage;

/// The number of components of voxels with value `value` in `image`. Foreground uses the
/// full neighbourhood, background the face neighbourhood; nothing is joined through the
/// image's edge (the callers pad the image, so the outside is one background component).
///
/// A scanline flood fill: a voxel reached fills its whole run along the last axis, and the
/// neighbouring rows are scanned over the run's span (one voxel wider for the full
/// neighbourhood) for runs to fill next. Every row is read in order, and a voxel's
/// coordinates are worked out once per run, not per voxel, so no neighbour is ever looked
/// up outside the image.
pub(crate) fn count_components(image: &BinaryImage, value: u8) -> u64 {
    let d = image.dim().get();
    let shape = image.shape();
    let row_len = shape[d - 1];
    let leading = &shape[..d - 1];
    // Steps between rows along each leading axis.
    let row_strides: Vec<usize> = image.strides()[..d - 1]
        .iter()
        .map(|&s| s / row_len)
        .collect();
    // The neighbouring rows, as offsets along the leading axes: every other row of the
    // 3^(d-1) block for the full neighbourhood, the 2(d-1) face neighbours for the face one.
    let full = value == 1;
    let row_offsets: Vec<[i8; 4]> = if full {
        full_offsets(image.dim())
            .into_iter()
            .filter(|o| o[d - 1] == 0)
            .map(|o| {
                let mut lead = [0i8; 4];
                lead[..d - 1].copy_from_slice(&o[..d - 1]);
                lead
            })
            .collect()
    } else {
        face_offsets(image.dim())
            .into_iter()
            .filter(|o| o[d - 1] == 0)
            .collect()
    };
    // 0: the other value; 1: this value, not reached yet; 2: reached.
    let mut mark: Vec<u8> = image.data().iter().map(|&v| (v == value) as u8).collect();
    // Fills the run of unreached voxels through flat index `v` and returns its flat span
    // (first, one past the last).
    let fill_run = |mark: &mut [u8], v: usize| -> (usize, usize) {
        let row = v / row_len;
        let base = row * row_len;
        let x = v - base;
        let line = &mut mark[base..base + row_len];
        let lo = last_not_one(&line[..x]).map_or(0, |p| p + 1);
        let hi = first_not_one(&line[x..]).map_or(row_len, |p| x + p);
        line[lo..hi].fill(2);
        (base + lo, base + hi)
    };
    let mut count = 0;
    // Runs filled whose neighbouring rows are still to scan: each run enters once, so the
    // stack never holds more than one entry (16 bytes) per run, 8 bytes per voxel at most.
    let mut stack: Vec<(usize, usize)> = Vec::new();
    let mut start = 0;
    while let Some(skip) = first_one(&mark[start..]) {
        start += skip;
        count += 1;
        stack.push(fill_run(&mut mark, start));
        while let Some((first, end)) = stack.pop() {
            let row = first / row_len;
            let (lo, hi) = (first - row * row_len, end - row * row_len);
            // The span of neighbouring rows that touches the run [lo, hi).
            let (from, to) = if full {
                (lo.saturating_sub(1), (hi + 1).min(row_len))
            } else {
                (lo, hi)
            };
            let mut coords = [0usize; 4];
            let mut rest = row;
            for a in 0..d - 1 {
                coords[a] = rest / row_strides[a];
                rest %= row_strides[a];
            }
            'rows: for off in &row_offsets {
                let mut next = row;
                for a in 0..d - 1 {
                    let c = coords[a] as isize + off[a] as isize;
                    if c < 0 || c as usize >= leading[a] {
                        continue 'rows;
                    }
                    next = (next as isize + off[a] as isize * row_strides[a] as isize) as usize;
                }
                let next_base = next * row_len;
                // Most spans are reached already or the other value: a few words each.
                let mut x = from;
                while let Some(skip) = first_one(&mark[next_base + x..next_base + to]) {
                    let run = fill_run(&mut mark, next_base + x + skip);
                    x = run.1 - next_base;
                    stack.push(run);
                    if x >= to {
                        break;
                    }
                }
            }
        }
        start += 1;
    }
    count
}

/// A one in every byte of a word.
const LOW_BYTES: u64 = 0x0101_0101_0101_0101;
/// The top bit of every byte of a word.
const HIGH_BITS: u64 = 0x8080_8080_8080_8080;

/// Eight marks (0, 1 or 2) as a word, byte `i` the mark `i`,
/// xored with ones: a byte is zero exactly where the mark is 1.
#[inline]
fn word_xor_ones(marks: &[u8]) -> u64 {
    u64::from_le_bytes(marks.try_into().expect("eight bytes")) ^ LOW_BYTES
}

/// The position of the first mark 1 in `marks`, eight marks a step. The lowest byte the
/// zero-byte test flags is the first zero byte (its borrows only run upwards).
#[inline]
fn first_one(marks: &[u8]) -> Option<usize> {
    let mut chunks = marks.chunks_exact(8);
    let mut at = 0;
    for chunk in &mut chunks {
        let word = word_xor_ones(chunk);
        let zero = word.wrapping_sub(LOW_BYTES) & !word & HIGH_BITS;
        if zero != 0 {
            return Some(at + zero.trailing_zeros() as usize / 8);
        }
        at += 8;
    }
    chunks
        .remainder()
        .iter()
        .position(|&m| m == 1)
        .map(|p| at + p)
}

/// The position of the first mark other than 1 in `marks`, eight marks a step.
#[inline]
fn first_not_one(marks: &[u8]) -> Option<usize> {
    let mut chunks = marks.chunks_exact(8);
    let mut at = 0;
    for chunk in &mut chunks {
        let word = word_xor_ones(chunk);
        if word != 0 {
            return Some(at + word.trailing_zeros() as usize / 8);
        }
        at += 8;
    }
    chunks
        .remainder()
        .iter()
        .position(|&m| m != 1)
        .map(|p| at + p)
}

/// The position of the last mark other than 1 in `marks`, eight marks a step from the end.
#[inline]
fn last_not_one(marks: &[u8]) -> Option<usize> {
    let mut chunks = marks.rchunks_exact(8);
    let mut end = marks.len();
    for chunk in &mut chunks {
        let word = word_xor_ones(chunk);
        if word != 0 {
            return Some(end - 1 - word.leading_zeros() as usize / 8);
        }
        end -= 8;
    }
    chunks.remainder().iter().rposition(|&m| m != 1)
}

/// The number of components of `voxels` (flat indices into `data` of voxels whose byte is
/// exactly 1, none on the border), two voxels being joined when they are `steps` apart.
/// Cheap next to a flood fill of the whole image when `voxels` is a thin remnant; bit 1 of
/// the bytes marks the voxels reached and is cleared again before returning.
pub(crate) fn count_components_of(data: &mut [u8], voxels: &[u32], steps: &[isize]) -> u64 {
    let mut count = 0;
    // Four bytes a voxel, like `voxels`: on a random image the stack holds a good part of
    // the remnant at once.
    let mut stack: Vec<u32> = Vec::new();
    for &start in voxels {
        if data[start as usize] != 1 {
            continue;
        }
        count += 1;
        data[start as usize] = 3;
        stack.push(start);
        while let Some(v) = stack.pop() {
            for &s in steps {
                let w = (v as isize + s) as usize;
                if data[w] == 1 {
                    data[w] = 3;
                    stack.push(w as u32);
                }
            }
        }
    }
    for &v in voxels {
        data[v as usize] = 1;
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn word_searches_agree_with_plain_ones() {
        let mut state = 7u64;
        for len in 0..40 {
            for _ in 0..50 {
                let marks: Vec<u8> = (0..len)
                    .map(|_| {
                        state = state
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        // Mostly one value, as rows are.
                        [0, 1, 1, 1, 2, 1, 0, 0][(state >> 61) as usize]
                    })
                    .collect();
                assert_eq!(
                    first_one(&marks),
                    marks.iter().position(|&m| m == 1),
                    "{marks:?}"
                );
                assert_eq!(
                    first_not_one(&marks),
                    marks.iter().position(|&m| m != 1),
                    "{marks:?}"
                );
                assert_eq!(
                    last_not_one(&marks),
                    marks.iter().rposition(|&m| m != 1),
                    "{marks:?}"
                );
            }
        }
    }
}
