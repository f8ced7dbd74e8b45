//! Where a picture looks: the part of the image that holds the object, and the 2D slice
//! that shows its topology best.
//!
//! - The **phase of interest** is the foreground in embed mode and, in carve mode, the
//!   cavities: the background components that do not reach the image's border
//!   ([`cavities`]), so neither the margin around the solid nor pits of its outer surface
//!   count, and no view shows the solid's boundary instead of a cavity. A carved solid
//!   without enclosed cavities (a tunnel through it) shows the background inside the
//!   solid's bounding box.
//! - Every view is **cropped** to the bounding box of that phase plus [`MARGIN`] voxels
//!   (clamped to the image), so a small 4D object fills its tiles.
//! - The **chosen view** is, among the 2D slices along every pair of axes, one whose phase
//!   of interest has the most holes (its own b1: background components enclosed in the
//!   plane, [`hole_areas`]) of at least 1% of the plane (and 2 pixels), counted up to the
//!   sample's own number of holes (b1 + ... + b_{d-1}; a ball gets no credit for a pocket
//!   its rough surface leaves in one slice); then the largest hole area; then the fullest (up to three
//!   quarters of the plane, so a slice that is all cavity loses); then the one nearest the middle of the object; then the
//!   first in a fixed order (the last two axes as the plane first). When no slice shows
//!   every hole (a small tilted ring is cut into arcs by every axis-aligned plane), slabs
//!   2, 3, 4, 6, ... slices thick are tried the same way, seen as the union of their
//!   slices, and the thinnest that shows more holes wins (only for crops of at most
//!   2^23 voxels, a bounded cost). The choice depends on the voxels
//!   only, so pictures are deterministic.

use bettimill_grid::{BinaryImage, Mode};
use bettimill_homology::topology;
use std::ops::Range;

/// Voxels of context kept around the phase of interest on every side (fewer at the
/// image's edge).
pub const MARGIN: usize = 2;

/// At most this many positions are tried along each sliced axis (evenly spaced over the
/// object): every slice of the demos and family sheets, a bounded cost at side 128.
const MAX_TRIED_3D: usize = 64;
const MAX_TRIED_4D: usize = 24;

/// The phase of interest of an image and where it lies.
#[derive(Clone, Debug)]
pub struct Focus {
    /// Embed: the foreground is of interest; carve: the cavities.
    pub mode: Mode,
    /// One byte per voxel, 1 where the voxel belongs to the phase of interest.
    pub interest: BinaryImage,
    /// Per axis, the smallest range holding every voxel of interest (the whole axis when
    /// there is none).
    pub object: Vec<Range<usize>>,
    /// Per axis, `object` widened by [`MARGIN`], clamped to the image: what is drawn.
    pub crop: Vec<Range<usize>>,
}

/// Per axis, the smallest range holding every nonzero voxel, or `None` for an empty image.
pub fn bounding_box(image: &BinaryImage) -> Option<Vec<Range<usize>>> {
    let d = image.dim().get();
    let mut lo = vec![usize::MAX; d];
    let mut hi = vec![0usize; d];
    let mut any = false;
    for (i, &v) in image.data().iter().enumerate() {
        if v != 0 {
            any = true;
            let c = image.coords(i);
            for a in 0..d {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a] + 1);
            }
        }
    }
    any.then(|| lo.into_iter().zip(hi).map(|(l, h)| l..h).collect())
}

/// The mode an unlabelled image most likely has: carve when the foreground's bounding box
/// spans at least half of every axis and at least 90% of its surface is foreground (a
/// solid cube's walls, pierced only where a tunnel leaves), embed otherwise.
pub fn guess_mode(image: &BinaryImage) -> Mode {
    let Some(bbox) = bounding_box(image) else {
        return Mode::Embed;
    };
    let d = image.dim().get();
    let (mut surface, mut solid) = (0u64, 0u64);
    for (i, &v) in image.data().iter().enumerate() {
        let c = image.coords(i);
        let inside = (0..d).all(|a| bbox[a].contains(&c[a]));
        let on_surface = (0..d).any(|a| c[a] == bbox[a].start || c[a] + 1 == bbox[a].end);
        if inside && on_surface {
            surface += 1;
            solid += (v != 0) as u64;
        }
    }
    let spans_image = (0..d).all(|a| 2 * bbox[a].len() >= image.shape()[a]);
    if spans_image && 10 * solid >= 9 * surface {
        Mode::Carve
    } else {
        Mode::Embed
    }
}

/// The enclosed background: background voxels whose component (through shared faces, the
/// background's adjacency in the voxel model) does not reach the image's border. These are
/// the cavities of a carved solid; pits and tunnels of its outer surface, however rough
/// a deformation leaves it, are not. `None` when there is none (a solid whose only
/// feature is a tunnel through it).
pub fn cavities(image: &BinaryImage) -> Option<BinaryImage> {
    let shape = image.shape();
    let strides = image.strides();
    let d = shape.len();
    // Start from every background voxel and clear those the border reaches.
    let mut mask = image.complement();
    let mut stack = Vec::new();
    for i in 0..mask.len() {
        let c = image.coords(i);
        if mask.data()[i] != 0 && (0..d).any(|a| c[a] == 0 || c[a] + 1 == shape[a]) {
            mask.data_mut()[i] = 0;
            stack.push(i);
        }
    }
    while let Some(i) = stack.pop() {
        let c = image.coords(i);
        for a in 0..d {
            let mut visit = |j: usize| {
                if mask.data()[j] != 0 {
                    mask.data_mut()[j] = 0;
                    stack.push(j);
                }
            };
            if c[a] > 0 {
                visit(i - strides[a]);
            }
            if c[a] + 1 < shape[a] {
                visit(i + strides[a]);
            }
        }
    }
    mask.data().iter().any(|&v| v != 0).then_some(mask)
}

/// The background inside the solid's bounding box: what a carved sample without enclosed
/// cavities (a tunnel through its solid) draws.
fn inside_the_solid(image: &BinaryImage) -> BinaryImage {
    let shape = image.shape();
    let mut mask = BinaryImage::zeros(shape).expect("same shape as a valid image");
    if let Some(cube) = bounding_box(image) {
        let d = shape.len();
        for (i, (m, &v)) in mask.data_mut().iter_mut().zip(image.data()).enumerate() {
            if v == 0 {
                let c = image.coords(i);
                *m = (0..d).all(|a| cube[a].contains(&c[a])) as u8;
            }
        }
    }
    mask
}

impl Focus {
    /// The phase of interest of `image` drawn in `mode`.
    pub fn new(image: &BinaryImage, mode: Mode) -> Focus {
        let shape = image.shape();
        let interest = match mode {
            Mode::Embed => image.clone(),
            Mode::Carve => cavities(image).unwrap_or_else(|| inside_the_solid(image)),
        };
        let object =
            bounding_box(&interest).unwrap_or_else(|| shape.iter().map(|&n| 0..n).collect());
        let crop = object
            .iter()
            .zip(shape)
            .map(|(r, &n)| r.start.saturating_sub(MARGIN)..(r.end + MARGIN).min(n))
            .collect();
        Focus {
            mode,
            interest,
            object,
            crop,
        }
    }
}

/// A copy of the box `ranges` (one range per axis of `image`) with its axes reordered: axis
/// `k` of the result is axis `order[k]` of `image`. Returns the shape and the C-order data.
pub fn arrange(
    image: &BinaryImage,
    order: &[usize],
    ranges: &[Range<usize>],
) -> (Vec<usize>, Vec<u8>) {
    let d = order.len();
    let shape: Vec<usize> = order.iter().map(|&a| ranges[a].len()).collect();
    let strides: Vec<usize> = order.iter().map(|&a| image.strides()[a]).collect();
    let start: usize = ranges
        .iter()
        .enumerate()
        .map(|(a, r)| r.start * image.strides()[a])
        .sum();
    let len: usize = shape.iter().product();
    let mut out = Vec::with_capacity(len);
    if len == 0 {
        return (shape, out);
    }
    let src = image.data();
    let (inner, inner_stride) = (shape[d - 1], strides[d - 1]);
    let mut c = vec![0usize; d];
    loop {
        let base = start + (0..d - 1).map(|k| c[k] * strides[k]).sum::<usize>();
        out.extend((0..inner).map(|x| src[base + x * inner_stride]));
        let mut k = d - 1;
        loop {
            if k == 0 {
                return (shape, out);
            }
            k -= 1;
            c[k] += 1;
            if c[k] < shape[k] {
                break;
            }
            c[k] = 0;
        }
    }
}

/// The image of `data` with its length-1 axes dropped (a slice of a bigger image).
fn squeeze(shape: &[usize], data: Vec<u8>) -> BinaryImage {
    let kept: Vec<usize> = shape.iter().copied().filter(|&n| n != 1).collect();
    let kept = if kept.len() < 2 {
        // A slice one voxel wide in-plane: keep two axes so it is still an image.
        let mut two = vec![1; 2 - kept.len()];
        two.extend(kept);
        two
    } else {
        kept
    };
    BinaryImage::from_vec(&kept, data).expect("a slice of a valid image")
}

/// How a 3D or 4D image is cut for its picture: a slab `width` voxels thick along every
/// sliced axis (a plain slice when `width` is 1), seen as the union of its slices (carve:
/// of their cavities).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Choice {
    /// The axes in drawing order: the sliced (fixed) axes first, then the plane's row axis
    /// and column axis.
    pub order: Vec<usize>,
    /// Where the slab starts along each sliced axis, in `order`.
    pub at: Vec<usize>,
    /// Its thickness along each sliced axis.
    pub width: usize,
}

impl Choice {
    /// The sliced axes with the slab's ranges, as (axis, range) pairs.
    pub fn fixed(&self) -> Vec<(usize, Range<usize>)> {
        self.order
            .iter()
            .zip(&self.at)
            .map(|(&axis, &at)| (axis, at..at + self.width))
            .collect()
    }
}

/// The 2D view of `image` through the slab `fixed` ((axis, range) pairs for all but two
/// axes), over the whole plane: embed, voxels of any slice of the slab; carve, voxels of
/// every slice (so a cavity in any of them shows). Rows and columns are the two remaining
/// axes in ascending order.
pub fn slab_view(image: &BinaryImage, mode: Mode, fixed: &[(usize, Range<usize>)]) -> BinaryImage {
    let d = image.dim().get();
    let mut ranges: Vec<Range<usize>> = image.shape().iter().map(|&n| 0..n).collect();
    for (axis, r) in fixed {
        ranges[*axis] = r.clone();
    }
    let mut order: Vec<usize> = fixed.iter().map(|(a, _)| *a).collect();
    let plane: Vec<usize> = (0..d).filter(|a| !order.contains(a)).collect();
    order.extend(plane);
    let (shape, data) = arrange(image, &order, &ranges);
    let plane = shape[d - 2] * shape[d - 1];
    let mut out = match mode {
        Mode::Embed => vec![0u8; plane],
        Mode::Carve => vec![1u8; plane],
    };
    for layer in data.chunks(plane) {
        for (o, &v) in out.iter_mut().zip(layer) {
            *o = match mode {
                Mode::Embed => *o | (v != 0) as u8,
                Mode::Carve => *o & (v != 0) as u8,
            };
        }
    }
    BinaryImage::from_vec(&shape[d - 2..], out).expect("a plane of a valid image")
}

/// The Betti numbers of the whole slice of `image` that fixes `fixed` (axis, position) and
/// spans every other axis (2D or 3D): the slice's own topology, not that of a crop.
pub fn slice_betti(image: &BinaryImage, fixed: &[(usize, usize)]) -> Vec<u64> {
    let d = image.dim().get();
    let mut ranges: Vec<Range<usize>> = image.shape().iter().map(|&n| 0..n).collect();
    for &(axis, at) in fixed {
        ranges[axis] = at..at + 1;
    }
    let order: Vec<usize> = (0..d).collect();
    let (shape, data) = arrange(image, &order, &ranges);
    topology(&squeeze(&shape, data)).betti
}

/// The axis orders tried, default first: for each plane (a pair of axes, rows before
/// columns; the last two axes first), the other axes ascending, then the plane.
fn orders(d: usize) -> Vec<Vec<usize>> {
    let mut planes = Vec::new();
    for q in (1..d).rev() {
        for p in (0..q).rev() {
            planes.push((p, q));
        }
    }
    planes
        .into_iter()
        .map(|(p, q)| {
            let mut order: Vec<usize> = (0..d).filter(|&a| a != p && a != q).collect();
            order.extend([p, q]);
            order
        })
        .collect()
}

/// `max` evenly spaced values of `range` (all of them when it is short), ends included.
pub fn spread(range: Range<usize>, max: usize) -> Vec<usize> {
    let n = range.len();
    if n <= max || max < 2 {
        range.take(max.max(1)).collect()
    } else {
        (0..max)
            .map(|k| range.start + k * (n - 1) / (max - 1))
            .collect()
    }
}

/// The areas of the holes of a `rows x cols` plane: its background components (through
/// shared edges, as in the voxel model) that do not reach the plane's edge. There are b1 of
/// them.
pub fn hole_areas(plane: &[u8], rows: usize, cols: usize) -> Vec<usize> {
    let mut seen: Vec<bool> = plane.iter().map(|&v| v != 0).collect();
    let mut areas = Vec::new();
    let mut stack = Vec::new();
    for start in 0..plane.len() {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let (mut area, mut open) = (0usize, false);
        while let Some(i) = stack.pop() {
            area += 1;
            let (r, c) = (i / cols, i % cols);
            open |= r == 0 || c == 0 || r + 1 == rows || c + 1 == cols;
            let mut visit = |j: usize| {
                if !seen[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            };
            if r > 0 {
                visit(i - cols);
            }
            if r + 1 < rows {
                visit(i + cols);
            }
            if c > 0 {
                visit(i - 1);
            }
            if c + 1 < cols {
                visit(i + 1);
            }
        }
        if !open {
            areas.push(area);
        }
    }
    areas
}

/// Slabs are tried only when the crop holds at most this many voxels (every demo and
/// family sheet, up to 48^4): trying them costs about a second per 4D sample at side 48,
/// and a large object is big enough for plain slices to show its holes.
const MAX_SLAB_VOLUME: usize = 1 << 23;

/// Slab thicknesses tried, thinnest first.
const WIDTHS: [usize; 12] = [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64];

/// `data` (the leading `fixed` axes of `shape` sliced, the rest a plane) with every
/// window of `width` consecutive positions along each sliced axis merged into one (any
/// voxel set), so axis `k` becomes `shape[k] - width + 1` long.
fn windows(shape: &[usize], data: &[u8], fixed: usize, width: usize) -> (Vec<usize>, Vec<u8>) {
    let mut shape = shape.to_vec();
    let mut data = data.to_vec();
    if width == 1 {
        return (shape, data);
    }
    for k in 0..fixed {
        let n = shape[k];
        let outer: usize = shape[..k].iter().product();
        let inner: usize = shape[k + 1..].iter().product();
        let m = n + 1 - width;
        let mut out = vec![0u8; outer * m * inner];
        let mut counts = vec![0u32; inner];
        for o in 0..outer {
            counts.iter_mut().for_each(|c| *c = 0);
            let at = |x: usize| (o * n + x) * inner;
            for x in 0..n {
                for (c, &v) in counts.iter_mut().zip(&data[at(x)..at(x) + inner]) {
                    *c += (v != 0) as u32;
                }
                if x >= width {
                    for (c, &v) in counts
                        .iter_mut()
                        .zip(&data[at(x - width)..at(x - width) + inner])
                    {
                        *c -= (v != 0) as u32;
                    }
                }
                if x + 1 >= width {
                    let dst = (o * m + x + 1 - width) * inner;
                    for (d, &c) in out[dst..dst + inner].iter_mut().zip(&counts) {
                        *d = (c > 0) as u8;
                    }
                }
            }
        }
        shape[k] = m;
        data = out;
    }
    (shape, data)
}

/// The view that shows the topology best (see the module documentation), thinnest slab
/// first: slices, then slabs of the widths in `WIDTHS`, stopping at the first width at
/// which some view shows all `holes` (the sample's b1 + ... + b_{d-1}). `None` for a 2D
/// image, which is drawn whole.
pub fn choose_slice(focus: &Focus, holes: u64) -> Option<Choice> {
    let d = focus.interest.dim().get();
    if d == 2 {
        return None;
    }
    let tried = if d == 3 { MAX_TRIED_3D } else { MAX_TRIED_4D };
    let deepest = focus.crop.iter().map(|r| r.len()).max().unwrap_or(1);
    // (holes shown, -width, their area, fill, -distance from the middle), larger is
    // better.
    type Score = (u64, i64, usize, usize, i64);
    let mut best: Option<(Score, Choice)> = None;
    let volume: usize = focus.crop.iter().map(|r| r.len()).product();
    let slabs = volume <= MAX_SLAB_VOLUME;
    for width in WIDTHS
        .into_iter()
        .filter(|&w| w == 1 || (slabs && w < deepest))
    {
        for order in orders(d) {
            let fixed = &order[..d - 2];
            if fixed.iter().any(|&a| focus.crop[a].len() < width) {
                continue;
            }
            let (shape, data) = arrange(&focus.interest, &order, &focus.crop);
            let (shape, data) = windows(&shape, &data, d - 2, width);
            let (rows, cols) = (shape[d - 2], shape[d - 1]);
            let area = rows * cols;
            // Slab starts whose slab meets the object and fits in the crop.
            let axes: Vec<Vec<usize>> = fixed
                .iter()
                .map(|&a| {
                    let (crop, object) = (&focus.crop[a], &focus.object[a]);
                    let lo = object.start.saturating_sub(width - 1).max(crop.start);
                    let hi = (object.end).min(crop.end + 1 - width);
                    spread(lo..hi, tried)
                })
                .collect();
            let mut positions: Vec<Vec<usize>> = vec![Vec::new()];
            for along in &axes {
                positions = positions
                    .into_iter()
                    .flat_map(|p| {
                        along.iter().map(move |&x| {
                            let mut q = p.clone();
                            q.push(x);
                            q
                        })
                    })
                    .collect();
            }
            for at in positions {
                let mut index = 0;
                for (k, (&axis, &x)) in fixed.iter().zip(&at).enumerate() {
                    index = index * shape[k] + (x - focus.crop[axis].start);
                }
                let plane = &data[index * area..(index + 1) * area];
                let voxels = plane.iter().filter(|&&v| v != 0).count();
                if voxels == 0 {
                    continue;
                }
                let min_area = (area / 100).max(2);
                let significant: Vec<usize> = hole_areas(plane, rows, cols)
                    .into_iter()
                    .filter(|&a| a >= min_area)
                    .collect();
                let shown = (significant.len() as u64).min(holes);
                let hole_area = significant.iter().sum::<usize>();
                let off_centre: i64 = fixed
                    .iter()
                    .zip(&at)
                    .map(|(&axis, &x)| {
                        let r = &focus.object[axis];
                        (2 * x as i64 + width as i64 - 1 - (r.start + r.end - 1) as i64).abs()
                    })
                    .sum();
                // Fullest, up to three quarters of the plane: a slice all cavity (a tunnel's)
                // shows nothing.
                let fill = voxels.min(3 * (area - voxels));
                let score = (shown, -(width as i64), hole_area, fill, -off_centre);
                if best.as_ref().is_none_or(|(s, _)| score > *s) {
                    best = Some((
                        score,
                        Choice {
                            order: order.clone(),
                            at,
                            width,
                        },
                    ));
                }
            }
        }
        if best
            .as_ref()
            .is_some_and(|((shown, ..), _)| *shown >= holes)
        {
            break;
        }
    }
    Some(best.map_or_else(
        || {
            // Nothing of interest anywhere: the middle slice of the default order.
            let order = orders(d).swap_remove(0);
            let at = order[..d - 2]
                .iter()
                .map(|&a| focus.interest.shape()[a] / 2)
                .collect();
            Choice {
                order,
                at,
                width: 1,
            }
        },
        |(_, choice)| choice,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random bytes (a 64-bit LCG), each 1 with probability `p`/256.
    fn noise(shape: &[usize], seed: u64, p: u64) -> BinaryImage {
        let mut image = BinaryImage::zeros(shape).unwrap();
        let mut x = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        for v in image.data_mut() {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *v = ((x >> 33) % 256 < p) as u8;
        }
        image
    }

    /// Face-connected components of the voxels set in `image`.
    fn face_components(image: &BinaryImage) -> u64 {
        let mut seen = image.complement();
        let (shape, strides, d) = (image.shape(), image.strides(), image.dim().get());
        let mut count = 0;
        for start in 0..image.len() {
            if seen.data()[start] != 0 {
                continue;
            }
            count += 1;
            seen.data_mut()[start] = 1;
            let mut stack = vec![start];
            while let Some(i) = stack.pop() {
                let c = image.coords(i);
                for a in 0..d {
                    let mut near = Vec::new();
                    if c[a] > 0 {
                        near.push(i - strides[a]);
                    }
                    if c[a] + 1 < shape[a] {
                        near.push(i + strides[a]);
                    }
                    for j in near {
                        if seen.data()[j] == 0 {
                            seen.data_mut()[j] = 1;
                            stack.push(j);
                        }
                    }
                }
            }
        }
        count
    }

    /// Clears everything outside the box `lo..hi` on every axis.
    fn keep_box(image: &mut BinaryImage, lo: usize, hi: usize) {
        for i in 0..image.len() {
            let c = image.coords(i);
            if (0..image.dim().get()).any(|a| c[a] < lo || c[a] >= hi) {
                image.data_mut()[i] = 0;
            }
        }
    }

    #[test]
    fn the_crop_holds_every_voxel_of_interest() {
        for (n, shape) in [vec![30, 20], vec![12, 17, 9], vec![8, 9, 7, 10]]
            .iter()
            .enumerate()
        {
            for seed in 0..4 {
                let mut image = noise(shape, seed + 10 * n as u64, 6);
                keep_box(&mut image, 2, 7);
                // Embed: every foreground voxel lies in the crop, with MARGIN around the
                // object where the image allows.
                let focus = Focus::new(&image, Mode::Embed);
                for i in 0..image.len() {
                    let c = image.coords(i);
                    if image.data()[i] != 0 {
                        assert!((0..shape.len()).all(|a| focus.crop[a].contains(&c[a])));
                    }
                }
                for (a, (crop, object)) in focus.crop.iter().zip(&focus.object).enumerate() {
                    assert_eq!(crop.start, object.start.saturating_sub(MARGIN), "axis {a}");
                    assert_eq!(crop.end, (object.end + MARGIN).min(shape[a]), "axis {a}");
                }
                // Carve: a solid cube (one-voxel margin) with the noise removed. The
                // cavities are the enclosed background: as many face-connected pieces as
                // the sample's b_{d-1}, all inside the solid and the crop; without any,
                // the background inside the solid is drawn.
                let inner =
                    |c: &[usize; 4]| (0..shape.len()).all(|a| c[a] >= 1 && c[a] + 1 < shape[a]);
                let mut carved = image.complement();
                for i in 0..carved.len() {
                    if !inner(&carved.coords(i)) {
                        carved.data_mut()[i] = 0;
                    }
                }
                let focus = Focus::new(&carved, Mode::Carve);
                let d = shape.len();
                let enclosed = cavities(&carved).is_some();
                if enclosed {
                    assert_eq!(
                        face_components(&focus.interest),
                        topology(&carved).betti[d - 1]
                    );
                }
                for i in 0..carved.len() {
                    let c = carved.coords(i);
                    let inside = inner(&c) && carved.data()[i] == 0;
                    if focus.interest.data()[i] != 0 {
                        assert!(inside);
                        assert!((0..d).all(|a| focus.crop[a].contains(&c[a])));
                    } else {
                        assert!(enclosed || !inside);
                    }
                }
                assert_eq!(guess_mode(&carved), Mode::Carve);
                assert_eq!(guess_mode(&image), Mode::Embed);
            }
        }
    }

    #[test]
    fn holes_are_counted_like_the_homology_counts_b1() {
        for seed in 0..40 {
            let image = noise(&[11, 13], seed, 40 + 4 * seed);
            let b1 = topology(&image).betti[1];
            assert_eq!(
                hole_areas(image.data(), 11, 13).len() as u64,
                b1,
                "seed {seed}"
            );
        }
        // A 3x3 ring has one hole of one pixel.
        assert_eq!(hole_areas(&[1, 1, 1, 1, 0, 1, 1, 1, 1], 3, 3), vec![1]);
    }

    #[test]
    fn arranging_permutes_axes_and_slabs_merge_windows() {
        let image = noise(&[4, 5, 6], 7, 128);
        let ranges = [1..3, 0..5, 2..6];
        let (shape, data) = arrange(&image, &[2, 0, 1], &ranges);
        assert_eq!(shape, vec![4, 2, 5]);
        for z in 0..4 {
            for x in 0..2 {
                for y in 0..5 {
                    let v = data[(z * 2 + x) * 5 + y] != 0;
                    assert_eq!(v, image.get(&[x + 1, y, z + 2]));
                }
            }
        }
        // Windows of 3 along the first axis: any voxel of the three.
        let (wshape, wdata) = windows(&shape, &data, 1, 3);
        assert_eq!(wshape, vec![2, 2, 5]);
        for s in 0..2 {
            for p in 0..10 {
                let any = (s..s + 3).any(|z| data[z * 10 + p] != 0);
                assert_eq!(wdata[s * 10 + p] != 0, any);
            }
        }
        // A slab view of width 1 is the slice; its Betti numbers are the slice's.
        let fixed = [(1usize, 2..3)];
        let view = slab_view(&image, Mode::Embed, &fixed);
        assert_eq!(view.shape(), &[4, 6]);
        assert_eq!(topology(&view).betti, slice_betti(&image, &[(1, 2)]));
        for x in 0..4 {
            for z in 0..6 {
                assert_eq!(view.get(&[x, z]), image.get(&[x, 2, z]));
            }
        }
    }

    #[test]
    fn a_ball_is_cut_through_its_middle() {
        // No holes to show: the fullest slice wins, the middle one of a ball.
        let mut image = BinaryImage::zeros(&[15, 15, 15]).unwrap();
        for i in 0..image.len() {
            let c = image.coords(i);
            let r2: i64 = (0..3).map(|a| (c[a] as i64 - 7).pow(2)).sum();
            image.data_mut()[i] = (r2 <= 20) as u8;
        }
        let choice = choose_slice(&Focus::new(&image, Mode::Embed), 0).unwrap();
        assert_eq!(
            choice,
            Choice {
                order: vec![0, 1, 2],
                at: vec![7],
                width: 1
            }
        );
    }
}
