//! Keeping the components of a phase apart while it deforms.
//!
//! Objects are placed with at least two background voxels between any two of them (a
//! Chebyshev distance of three). A simple-point flip can never merge two components, but
//! nothing in the simple-point rule keeps them from coming within one voxel of each other,
//! and growth presses them there: targeting a hypervolume bin or a few hundred moves leave
//! most two-object samples with their parts one voxel apart. A network trained on such
//! data learns that two components meet across a one-voxel gap and reads two parts
//! farther apart as one. [`Apart`] refuses a flip that brings a voxel of the phase within
//! [`APART`] of another component, so the placement's gap holds through every
//! deformation, and the distance between parts stays as varied as placement made it.
//!
//! Components are labelled once (a byte a voxel of the image, only for a phase of two or
//! more components) with the phase's own connectivity: the foreground's (3^d - 1)
//! neighbours in embed mode, the background's 2d face neighbours in carve mode. A voxel
//! that joins the phase by a simple flip touches exactly one component and takes its
//! label; one that leaves it loses its label (a simple flip never splits a component, so
//! no other label changes).

use crate::phase::{Layout, Phase};
use bettimill_grid::neighbourhood::{face_offsets, flat_offsets, full_offsets};
use bettimill_grid::BinaryImage;

/// The Chebyshev distance within which a voxel joining the phase may have no voxel of
/// another component: two, as the placement's gap leaves (three apart means two voxels
/// between them).
pub const APART: i64 = 2;

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
    /// The window of radius [`APART`] without its centre, as coordinate and flat offsets.
    window: Vec<([i64; 4], isize)>,
    shape: [i64; 4],
    d: usize,
}

impl Apart {
    /// Labels the components of `phase` in `image`. `None` when there are fewer than two
    /// (nothing to keep apart) or more than 255 (a byte cannot tell them apart; such a
    /// phase keeps only the simple-point rule).
    pub fn new(image: &BinaryImage, phase: &Phase) -> Option<Apart> {
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
        let mut labels = vec![0u8; image.len()];
        let mut components = 0usize;
        let mut stack = Vec::new();
        let mut overflow = false;
        layout.for_each_row(|first, last| {
            if overflow {
                return;
            }
            for v in first..=last {
                if data[v] != phase.value || labels[v] != 0 {
                    continue;
                }
                components += 1;
                if components > usize::from(u8::MAX) {
                    overflow = true;
                    return;
                }
                let label = components as u8;
                labels[v] = label;
                stack.push(v);
                while let Some(u) = stack.pop() {
                    // The box keeps off the image's outermost layer, so every neighbour
                    // of a voxel in it exists.
                    for &o in &adjacent {
                        let w = (u as isize + o) as usize;
                        if data[w] == phase.value && labels[w] == 0 && layout.in_box(w) {
                            labels[w] = label;
                            stack.push(w);
                        }
                    }
                }
            }
        });
        if overflow || components < 2 {
            return None;
        }
        let side = 2 * APART + 1;
        let strides = image.strides();
        let mut window = Vec::new();
        for k in 0..side.pow(d as u32) {
            let mut off = [0i64; 4];
            let mut rest = k;
            for axis in (0..d).rev() {
                off[axis] = rest % side - APART;
                rest /= side;
            }
            if off.iter().all(|&o| o == 0) {
                continue;
            }
            let flat = (0..d).map(|a| off[a] as isize * strides[a] as isize).sum();
            window.push((off, flat));
        }
        let mut shape = [1i64; 4];
        for (s, &n) in shape.iter_mut().zip(image.shape()) {
            *s = n as i64;
        }
        Some(Apart {
            labels,
            value: phase.value,
            adjacent,
            window,
            shape,
            d,
        })
    }

    /// Whether `v`, not in the phase, may join it: `Some(label)` of the component it would
    /// join (0 if it touches none: a flip that the simple-point test refuses anyway), or
    /// `None` when a voxel of another component lies within [`APART`] of it. Reads the
    /// image as it is; changes nothing.
    pub(crate) fn joins(&self, image: &BinaryImage, v: usize) -> Option<u8> {
        let data = image.data();
        let own = self
            .adjacent
            .iter()
            .map(|&o| (v as isize + o) as usize)
            .find(|&w| data[w] == self.value && self.labels[w] != 0)
            .map_or(0, |w| self.labels[w]);
        let c = image.coords(v);
        let deep = (0..self.d).all(|a| {
            let x = c[a] as i64;
            x >= APART && x + APART < self.shape[a]
        });
        for &(off, flat) in &self.window {
            if !deep
                && !(0..self.d).all(|a| {
                    let x = c[a] as i64 + off[a];
                    x >= 0 && x < self.shape[a]
                })
            {
                continue;
            }
            let w = (v as isize + flat) as usize;
            let label = self.labels[w];
            if label != 0 && label != own && data[w] == self.value {
                return None;
            }
        }
        Some(own)
    }

    /// Records that `v` joined the phase as part of component `label`.
    pub(crate) fn join(&mut self, v: usize, label: u8) {
        self.labels[v] = label;
    }

    /// Records that `v` left the phase; returns the label it had (to restore it if the
    /// flip is undone).
    pub(crate) fn leave(&mut self, v: usize) -> u8 {
        std::mem::take(&mut self.labels[v])
    }
}

/// Whether `v` may join the phase: always without a separation to keep.
pub(crate) fn joins(apart: Option<&Apart>, image: &BinaryImage, v: usize) -> Option<u8> {
    match apart {
        Some(apart) => apart.joins(image, v),
        None => Some(0),
    }
}
