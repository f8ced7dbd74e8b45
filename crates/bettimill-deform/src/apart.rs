//! Keeping the components of a phase apart while it deforms.
//!
//! Objects are placed with a gap of background voxels between any two of them: at least
//! two (a Chebyshev distance of three), and in scenes a width drawn per sample. A
//! simple-point flip can never merge two components, but
//! nothing in the simple-point rule keeps them from coming within one voxel of each other,
//! and growth presses them there: targeting a hypervolume bin or a few hundred moves leave
//! most two-object samples with their parts one voxel apart. A network trained on such
//! data learns that two components meet across a one-voxel gap and reads two parts
//! farther apart as one. [`Apart`] refuses a flip that brings a voxel of the phase within
//! its gap (at least [`APART`]) of another component, so the placement's gap holds through
//! every deformation, and the distance between parts stays as varied as placement made it.
//!
//! Components are labelled once (a byte a voxel of the image, only for a phase of two or
//! more components) with the phase's own connectivity: the foreground's (3^d - 1)
//! neighbours in embed mode, the background's 2d face neighbours in carve mode. A voxel
//! that joins the phase by a simple flip touches exactly one component and takes its
//! label; one that leaves it loses its label (a simple flip never splits a component, so
//! no other label changes).
//!
//! Most flips happen far from any other component, so the window need not be read there:
//! blocks of `2^BLOCK_SHIFT`^d voxels record which labels have had a voxel within the gap
//! of them (none, one, or several). A voxel whose block has seen no label but its own joins
//! without a look at its window; only near another component is the window read. A block's
//! record only ever gains labels (a voxel leaving the phase does not clear it), which can
//! cost a window read, never a wrong answer: the window read decides. The window is read
//! as rows along the last axis, each a slice of the labels.

use crate::phase::{chebyshev_ball, Layout, Phase};
use bettimill_grid::neighbourhood::{face_offsets, flat_offsets, full_offsets};
use bettimill_grid::BinaryImage;

/// The narrowest gap [`Apart`] keeps: the Chebyshev distance within which a voxel joining
/// the phase may have no voxel of another component is at least two, as the placement's
/// narrowest gap leaves (three apart means two voxels between them).
pub const APART: i64 = 2;

/// log2 of the side of the blocks that record which components are near.
const BLOCK_SHIFT: u32 = 3;

/// A block's record when voxels of two or more components have been near it.
const MIXED: u8 = u8::MAX;

/// The labels of a phase's components and the test that keeps them apart (see the module
/// documentation).
#[derive(Clone, Debug)]
pub struct Apart {
    /// 0 for a voxel outside the phase or its box; `k` for a voxel of component `k`.
    labels: Vec<u8>,
    /// The phase's value.
    value: u8,
    /// Flat offsets of the neighbours whose label a joining voxel takes.
    adjacent: Vec<isize>,
    /// The Chebyshev distance within which a joining voxel may have no voxel of another
    /// component (the gap kept, in background voxels).
    gap: i64,
    /// The rows of the window of radius `gap`: offsets along the leading axes, as
    /// coordinates and flat; each row spans `-gap ..= gap` along the last axis.
    rows: Vec<([i64; 4], isize)>,
    shape: [i64; 4],
    /// The image's flat strides.
    strides: [usize; 4],
    d: usize,
    /// Per block of `2^BLOCK_SHIFT` voxels a side: 0 when no component has had a voxel
    /// within `gap` of it, `k` when only component `k`, [`MIXED`] when several.
    near: Vec<u8>,
    /// Flat strides of the block grid.
    block_strides: [usize; 4],
    /// The block grid's shape.
    blocks: [usize; 4],
}

impl Apart {
    /// Labels the components of `phase` in `image` to keep them [`APART`] apart (see
    /// [`Apart::keeping`]).
    pub fn new(image: &BinaryImage, phase: &Phase) -> Option<Apart> {
        Apart::keeping(image, phase, APART)
    }

    /// Labels the components of `phase` in `image` to keep a gap of `gap` background
    /// voxels between them (at least [`APART`]: a narrower gap is [`APART`]). `None` when
    /// there are fewer than two (nothing to keep apart) or more than 254 (a byte cannot
    /// tell them apart beside its marker; such a phase keeps only the simple-point rule).
    pub fn keeping(image: &BinaryImage, phase: &Phase, gap: i64) -> Option<Apart> {
        let gap = gap.max(APART);
        let layout = Layout::new(image, phase);
        if layout.is_empty() {
            return None;
        }
        let dim = image.dim();
        let d = dim.get();
        let adjacent = if phase.value == 1 {
            flat_offsets(image, &full_offsets(dim))
        } else {
            flat_offsets(image, &face_offsets(dim))
        };
        let data = image.data();
        let value = phase.value;
        // Only voxels of the box are labelled: the search tests the box only for a voxel of
        // the phase not yet labelled (each voxel of the box once; a voxel of the phase
        // outside the box, never next to one inside in practice, at each visit). The box
        // keeps off the image's outermost layer, so every neighbour of a voxel in it exists.
        let in_box = |w: usize| {
            let c = layout.coords(w);
            (0..d).all(|a| (layout.lo[a]..=layout.hi[a]).contains(&c[a]))
        };
        let mut labels = vec![0u8; image.len()];
        let mut components = 0usize;
        let mut stack = Vec::new();
        let mut overflow = false;
        layout.for_each_row(|first, last| {
            let mut v = first;
            while !overflow && v <= last {
                // The next voxel of the phase along the row.
                let Some(skip) = data[v..=last].iter().position(|&x| x == value) else {
                    break;
                };
                v += skip;
                if labels[v] != 0 {
                    v += 1;
                    continue;
                }
                components += 1;
                if components >= usize::from(MIXED) {
                    overflow = true;
                    break;
                }
                let label = components as u8;
                labels[v] = label;
                stack.push(v);
                while let Some(u) = stack.pop() {
                    for &o in &adjacent {
                        let w = (u as isize + o) as usize;
                        if labels[w] == 0 && data[w] == value && in_box(w) {
                            labels[w] = label;
                            stack.push(w);
                        }
                    }
                }
                v += 1;
            }
        });
        if overflow || components < 2 {
            return None;
        }
        // The rows of the window: the window's offsets whose last coordinate is its lowest.
        let rows = chebyshev_ball(image, gap)
            .into_iter()
            .filter(|(off, _)| off[d - 1] == -gap)
            .map(|(mut off, flat)| {
                off[d - 1] = 0;
                (off, flat + gap as isize)
            })
            .collect();
        let mut shape = [1i64; 4];
        for (s, &n) in shape.iter_mut().zip(image.shape()) {
            *s = n as i64;
        }
        let mut image_strides = [0usize; 4];
        image_strides[..d].copy_from_slice(image.strides());
        let mut blocks = [1usize; 4];
        for a in 0..d {
            blocks[a] = (shape[a] as usize).div_ceil(1 << BLOCK_SHIFT);
        }
        let mut block_strides = [0usize; 4];
        let mut stride = 1;
        for a in (0..d).rev() {
            block_strides[a] = stride;
            stride *= blocks[a];
        }
        let mut apart = Apart {
            labels,
            value: phase.value,
            adjacent,
            gap,
            rows,
            shape,
            strides: image_strides,
            d,
            near: vec![0u8; stride],
            block_strides,
            blocks,
        };
        // One mark per run of a label along a row of the box (labels lie only there).
        let mut runs = Vec::new();
        layout.for_each_row(|first, last| {
            let labels = &apart.labels;
            let mut v = first;
            while let Some(skip) = labels[v..=last].iter().position(|&l| l != 0) {
                v += skip;
                let label = labels[v];
                let mut end = v;
                while end < last && labels[end + 1] == label {
                    end += 1;
                }
                runs.push((v, end, label));
                if end == last {
                    break;
                }
                v = end + 1;
            }
        });
        for (first, last, label) in runs {
            apart.mark(first, last, label);
        }
        Some(apart)
    }

    /// The gap kept between components, in background voxels.
    pub fn gap(&self) -> i64 {
        self.gap
    }

    /// Records `label` in every block within `gap` of the voxels `first ..= last` of one
    /// row along the last axis.
    fn mark(&mut self, first: usize, last: usize, label: u8) {
        let mut lo = [0usize; 4];
        let mut hi = [0usize; 4];
        for a in 0..self.d {
            let x = (first / self.strides[a]) as i64 % self.shape[a];
            let y = (last / self.strides[a]) as i64 % self.shape[a];
            lo[a] = ((x - self.gap).max(0) as usize) >> BLOCK_SHIFT;
            hi[a] = (((y + self.gap) as usize) >> BLOCK_SHIFT).min(self.blocks[a] - 1);
        }
        let mut at = lo;
        loop {
            let b: usize = (0..self.d).map(|a| at[a] * self.block_strides[a]).sum();
            let seen = &mut self.near[b];
            if *seen == 0 {
                *seen = label;
            } else if *seen != label {
                *seen = MIXED;
            }
            // Odometer over the blocks' box.
            let mut a = self.d;
            loop {
                if a == 0 {
                    return;
                }
                a -= 1;
                if at[a] < hi[a] {
                    at[a] += 1;
                    break;
                }
                at[a] = lo[a];
            }
        }
    }

    /// Whether `v`, not in the phase, may join it: `Some(label)` of the component it would
    /// join (0 if it touches none: a flip that the simple-point test refuses anyway), or
    /// `None` when a voxel of another component lies within the gap of it. Reads the
    /// image as it is; changes nothing.
    pub(crate) fn joins(&self, image: &BinaryImage, v: usize) -> Option<u8> {
        let data = image.data();
        let own = self.own(image, v);
        let c = image.coords(v);
        let block: usize = (0..self.d)
            .map(|a| (c[a] >> BLOCK_SHIFT) * self.block_strides[a])
            .sum();
        let seen = self.near[block];
        if seen == 0 || seen == own {
            return Some(own);
        }
        let last = self.d - 1;
        let x = c[last] as i64;
        // The row's span along the last axis, clipped to the image, relative to its centre.
        let from = (x - self.gap).max(0) - x;
        let to = (x + self.gap).min(self.shape[last] - 1) - x;
        let deep = (0..last).all(|a| {
            let y = c[a] as i64;
            y >= self.gap && y + self.gap < self.shape[a]
        });
        for &(off, flat) in &self.rows {
            if !deep
                && !(0..last).all(|a| {
                    let y = c[a] as i64 + off[a];
                    y >= 0 && y < self.shape[a]
                })
            {
                continue;
            }
            let centre = v as isize + flat;
            let span = (centre + from as isize) as usize..=(centre + to as isize) as usize;
            let labels = &self.labels[span.clone()];
            if has_other(labels, own)
                && labels
                    .iter()
                    .zip(&data[span])
                    .any(|(&label, &value)| label != 0 && label != own && value == self.value)
            {
                return None;
            }
        }
        Some(own)
    }

    /// The label of the first component beside `v` (in the phase's adjacency), 0 when
    /// none is.
    pub(crate) fn own(&self, image: &BinaryImage, v: usize) -> u8 {
        let data = image.data();
        self.adjacent
            .iter()
            .map(|&o| (v as isize + o) as usize)
            .find(|&w| data[w] == self.value && self.labels[w] != 0)
            .map_or(0, |w| self.labels[w])
    }

    /// Records that `v` joined the phase as part of component `label`.
    pub(crate) fn join(&mut self, v: usize, label: u8) {
        self.labels[v] = label;
        if label != 0 {
            self.mark(v, v, label);
        }
    }

    /// Records that `v` left the phase; returns the label it had (to restore it if the
    /// flip is undone).
    pub(crate) fn leave(&mut self, v: usize) -> u8 {
        std::mem::take(&mut self.labels[v])
    }
}

/// Every byte's lowest and highest bit.
const LOW: u64 = 0x0101_0101_0101_0101;
const HIGH: u64 = 0x8080_8080_8080_8080;

/// The high bit of every byte of `x` that is not zero (exact: no carry crosses a byte).
#[inline]
fn nonzero_bytes(x: u64) -> u64 {
    (((x & !HIGH) + !HIGH) | x) & HIGH
}

/// Whether `labels` holds a label other than 0 and `own`: eight bytes a step, as the
/// window's rows are read for nearly every voxel that joins near another component.
#[inline]
fn has_other(labels: &[u8], own: u8) -> bool {
    let word = |bytes: &[u8]| u64::from_le_bytes(bytes.try_into().expect("eight bytes"));
    let other = |x: u64| nonzero_bytes(x) & nonzero_bytes(x ^ (LOW * u64::from(own))) != 0;
    if labels.len() < 8 {
        return labels.iter().any(|&label| label != 0 && label != own);
    }
    // Overlapping words cover the row: a byte read twice answers the same.
    labels.chunks(8).any(|chunk| {
        other(word(if chunk.len() == 8 {
            chunk
        } else {
            &labels[labels.len() - 8..]
        }))
    })
}

/// Whether `v` may join `phase`, and the label it takes: refused where it would narrow a
/// gap below the phase's clearance, or bring two components within the gap [`Apart`]
/// keeps; always
/// otherwise.
pub(crate) fn joins(
    apart: Option<&Apart>,
    phase: &Phase,
    image: &BinaryImage,
    v: usize,
) -> Option<u8> {
    if !crate::clearance::leaves_room(image, v, phase.value, phase.clearance()) {
        return None;
    }
    match apart {
        Some(apart) => apart.joins(image, v),
        None => Some(0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The answer [`Apart::joins`] gives, from every voxel of the window one by one.
    fn joins_by_every_voxel(apart: &Apart, image: &BinaryImage, v: usize) -> Option<u8> {
        let data = image.data();
        let own = apart
            .adjacent
            .iter()
            .map(|&o| (v as isize + o) as usize)
            .find(|&w| data[w] == apart.value && apart.labels[w] != 0)
            .map_or(0, |w| apart.labels[w]);
        let c = image.coords(v);
        for (off, flat) in chebyshev_ball(image, apart.gap) {
            if (0..apart.d).all(|a| (0..apart.shape[a]).contains(&(c[a] as i64 + off[a]))) {
                let w = (v as isize + flat) as usize;
                let label = apart.labels[w];
                if label != 0 && label != own && data[w] == apart.value {
                    return None;
                }
            }
        }
        Some(own)
    }

    /// Eight bytes a step find another label wherever it sits in a row, and nothing else.
    #[test]
    fn rows_find_another_label_anywhere() {
        for len in 1..=20 {
            for own in [0u8, 1, 2, 0x80, 0xFE] {
                let mut row = vec![0u8; len];
                assert!(!has_other(&row, own));
                row.iter_mut().for_each(|b| *b = own);
                assert!(!has_other(&row, own));
                for at in 0..len {
                    for label in [1u8, 2, 0x7F, 0x80, 0x81, 0xFE] {
                        let mut row = vec![own; len];
                        row[at] = label;
                        assert_eq!(
                            has_other(&row, own),
                            label != own,
                            "{len} {own} {at} {label}"
                        );
                    }
                }
            }
        }
    }

    /// Reading the window as rows, after the blocks' shortcut, answers as reading every
    /// voxel of it, at every gap, near the faces and far from them.
    #[test]
    fn rows_and_blocks_answer_as_every_voxel_of_the_window() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for shape in [vec![40usize, 37], vec![19, 17, 21], vec![13, 11, 12, 14]] {
            for gap in [APART, 3, 5] {
                // About one voxel of the phase a window, so that some joins are refused
                // and some allowed.
                let mut image = BinaryImage::zeros(&shape).unwrap();
                let window = (2 * gap as usize + 1).pow(shape.len() as u32);
                for _ in 0..(image.len() / window).max(4) {
                    let v = rng.gen_range(0..image.len());
                    image.data_mut()[v] = 1;
                }
                let phase = Phase::foreground(&image);
                let apart = Apart::keeping(&image, &phase, gap).expect("many components");
                let (mut refused, mut allowed) = (0, 0);
                for v in 0..image.len() {
                    let c = image.coords(v);
                    let inner = (0..shape.len()).all(|a| c[a] >= 1 && c[a] + 1 < shape[a]);
                    if !inner || image.data()[v] == 1 {
                        continue;
                    }
                    let expected = joins_by_every_voxel(&apart, &image, v);
                    assert_eq!(
                        apart.joins(&image, v),
                        expected,
                        "{shape:?} gap {gap} at {c:?}"
                    );
                    if expected.is_some() {
                        allowed += 1;
                    } else {
                        refused += 1;
                    }
                }
                assert!(
                    refused > 0 && allowed > 0,
                    "{shape:?} gap {gap}: {refused} {allowed}"
                );
            }
        }
    }
}
