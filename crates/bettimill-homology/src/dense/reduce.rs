//! The reduction pairs (free-face collapses and coreductions) on the masks.

use super::grid::Grid;
use super::queue::CellQueue;
use super::split_plan::{Order, Split};
use super::Owners;
use crate::eliminate::{Lists, PoolOverflow};
use std::sync::atomic::{AtomicU16, Ordering::Relaxed};

/// The grid and the masks of a [`DenseComplex`](super::DenseComplex), as a reduction shares them between its
/// threads.
#[derive(Clone, Copy)]
pub(super) struct View<'a> {
    pub(super) grid: Grid,
    pub(super) sides: [usize; 4],
    pub(super) masks: &'a [AtomicU16],
}

impl<'a> View<'a> {
    /// The presence bits of the cells `owner` owns.
    #[inline]
    pub(super) fn mask(&self, owner: usize) -> u16 {
        self.masks[owner].load(Relaxed)
    }

    /// The masks as a reduction works on them (`PART`: see [`Cells`]).
    pub(super) fn cells<const PART: bool>(&self) -> Cells<'a, PART> {
        Cells {
            grid: self.grid,
            masks: self.masks,
        }
    }

    /// Twice the coordinates of the centre of the voxels of the places `places` (a range
    /// of whole bricks, as [`Halves`](super::split_plan::Halves) cuts them), cut at the grid's sides.
    pub(super) fn doubled_centre(&self, places: std::ops::Range<usize>) -> [usize; 4] {
        let (first, last) = (
            self.grid.coords(places.start),
            self.grid.coords(places.end - 1),
        );
        std::array::from_fn(|axis| first[axis] + last[axis].min(self.sides[axis] - 1))
    }

    /// The pairs of one part of a split reduction ([`DenseComplex::betti_with`](super::DenseComplex::betti_with)): those
    /// among the cells owned in `inside`, from its free faces and then from its vertex
    /// nearest its centre. Returns the cells left queued (outside `inside`) and the number
    /// of vertices removed.
    pub(super) fn reduce_part(
        &self,
        owners: &Owners,
        inside: std::ops::Range<usize>,
        queue: CellQueue,
    ) -> (CellQueue, u64) {
        let centre = self.doubled_centre(inside.clone());
        self.cells::<true>()
            .reduce_from_free_faces(owners, &inside, centre, queue)
    }

    /// The parts of a split reduction ([`DenseComplex::betti_with`](super::DenseComplex::betti_with)), each pair of parts
    /// run as `order` says: the lower and upper brick rows, then the two parts of the seam
    /// row if it splits too (each taking the cells left queued in it). Returns the cells
    /// left queued, the last seam (whose cells no part reduced) and the number of vertices
    /// removed.
    pub(super) fn reduce_parts(
        &self,
        owners: &Owners,
        split: Split,
        order: impl Order,
    ) -> (CellQueue, std::ops::Range<usize>, u64) {
        let Split { rows, columns } = split;
        let ((mut left, a), (left_upper, b)) = order.run(
            || self.reduce_part(owners, rows.lower(), CellQueue::default()),
            || self.reduce_part(owners, rows.upper(), CellQueue::default()),
        );
        left.append(left_upper);
        let Some(columns) = columns else {
            return (left, rows.seam(), a + b);
        };
        let (lower, upper) = (columns.lower(), columns.upper());
        let mut queues = [(); 3].map(|_| CellQueue::default());
        while let Some((o, code)) = left.pop() {
            let at = if lower.contains(&o) {
                0
            } else if upper.contains(&o) {
                1
            } else {
                2
            };
            queues[at].push(o, code);
        }
        let [lower_queue, upper_queue, mut rest] = queues;
        let ((left_lower, c), (left_upper, d)) = order.run(
            || self.reduce_part(owners, lower, lower_queue),
            || self.reduce_part(owners, upper, upper_queue),
        );
        rest.append(left_lower);
        rest.append(left_upper);
        (rest, columns.seam(), a + b + c + d)
    }
}

/// The masks, as a reduction sees them. `PART` is whether the reduction is one part of a
/// split one (with a range of owners to reduce): a constant, so that the whole grid's
/// reduction pays no range test in its inner loop.
pub(super) struct Cells<'a, const PART: bool> {
    pub(super) grid: Grid,
    pub(super) masks: &'a [AtomicU16],
}

impl<const PART: bool> Cells<'_, PART> {
    /// The presence bits of the cells `owner` owns.
    #[inline]
    pub(super) fn mask(&self, owner: usize) -> u16 {
        self.masks[owner].load(Relaxed)
    }

    #[inline]
    pub(super) fn has(&self, owner: usize, code: u32) -> bool {
        self.mask(owner) >> code & 1 == 1
    }

    /// Removes a cell. A load and a store, not one atomic update: no other thread writes
    /// or reads this place meanwhile (the parts of a split are apart).
    #[inline]
    pub(super) fn remove(&mut self, owner: usize, code: u32) {
        let mask = &self.masks[owner];
        mask.store(mask.load(Relaxed) & !(1 << code), Relaxed);
    }

    /// The only alive cofacet (`UP`) or facet of (owner, code), if it has exactly one.
    /// Those the owner holds are one mask test; the others are one bit each from the next
    /// voxel along an even axis (cofacets) or the previous one along an odd axis (facets),
    /// looked at only while fewer than two are found (most cells have two among the owner's
    /// own).
    #[inline]
    pub(super) fn sole<const UP: bool>(&self, owner: usize, code: u32) -> Option<(usize, u32)> {
        let same = self.mask(owner)
            & if UP {
                self.grid.up_same[code as usize]
            } else {
                self.grid.down_same[code as usize]
            };
        // Zero, one or two (meaning two or more): without a popcount instruction in the
        // baseline x86-64 target, `count_ones` is a dozen instructions.
        let mut count = (same != 0) as u32 + (same & same.wrapping_sub(1) != 0) as u32;
        let mut found = (owner, same.trailing_zeros());
        let mut axes = if UP {
            code
        } else {
            !code & self.grid.all_codes
        };
        while axes != 0 && count < 2 {
            let axis = axes.trailing_zeros() as usize;
            axes &= axes - 1;
            let (o, c) = if UP {
                (self.grid.forward(owner, axis), code ^ 1 << axis)
            } else {
                (self.grid.back(owner, axis), code | 1 << axis)
            };
            if self.has(o, c) {
                count += 1;
                found = (o, c);
            }
        }
        (count == 1).then_some(found)
    }

    /// Whether (owner, code) has exactly one alive cofacet ([`Cells::sole`]).
    #[inline]
    pub(super) fn one_cofacet(&self, owner: usize, code: u32) -> bool {
        self.sole::<true>(owner, code).is_some()
    }

    /// Whether (owner, code) has exactly one alive facet ([`Cells::sole`]).
    #[inline]
    pub(super) fn one_facet(&self, owner: usize, code: u32) -> bool {
        self.sole::<false>(owner, code).is_some()
    }

    /// How many alive cells of `owners` still have one alive cofacet or one alive facet
    /// (for the checks of debug builds: none after the pairs).
    pub(super) fn reducible(&self, owners: &Owners) -> usize {
        let mut reducible = 0;
        for o in owners.within(&(0..usize::MAX), self.masks) {
            let mut rest = self.mask(o);
            while rest != 0 {
                let code = rest.trailing_zeros();
                rest &= rest - 1;
                reducible += (self.one_cofacet(o, code) || self.one_facet(o, code)) as usize;
            }
        }
        reducible
    }

    /// The alive cells whose codes are in `codes`, in increasing order of place and code.
    pub(super) fn all_of(&self, codes: u16) -> impl Iterator<Item = (usize, u32)> + '_ {
        self.masks.iter().enumerate().flat_map(move |(o, mask)| {
            let mut rest = mask.load(Relaxed) & codes;
            std::iter::from_fn(move || {
                (rest != 0).then(|| {
                    let code = rest.trailing_zeros();
                    rest &= rest - 1;
                    (o, code)
                })
            })
        })
    }

    /// The boundary columns of the `n` k-cells `of_k` (a column of `cleared` is left
    /// empty): the rows of their alive facets, `row` giving a facet's, in increasing order.
    pub(super) fn boundary_columns(
        &self,
        k: usize,
        n: usize,
        of_k: impl Iterator<Item = (usize, u32)>,
        cleared: &[bool],
        row: impl Fn(usize, u32) -> u32,
    ) -> Result<Lists, PoolOverflow> {
        debug_assert_eq!(cleared.len(), n);
        let d = self.grid.d;
        // A k-cell has at most 2k facets.
        let mut columns = Lists::with_capacity(n, 2 * k * n);
        let mut column = Vec::with_capacity(2 * d);
        for ((o, code), &skip) in of_k.zip(cleared) {
            column.clear();
            if !skip {
                for axis in 0..d {
                    if code >> axis & 1 == 0 {
                        let f = code | 1 << axis;
                        for fo in [o, self.grid.back(o, axis)] {
                            if self.has(fo, f) {
                                column.push(row(fo, f));
                            }
                        }
                    }
                }
                column.sort_unstable();
            }
            columns.push_list(&column)?;
        }
        columns.shrink_to_fit();
        Ok(columns)
    }

    /// Queues the cells of the owners in `inside` that are free faces (one alive
    /// cofacet). Coreducible cells (one alive facet) only appear when a cell goes, and are
    /// queued then.
    pub(super) fn queue_free_faces(
        &self,
        owners: &Owners,
        inside: &std::ops::Range<usize>,
        queue: &mut CellQueue,
    ) {
        for o in owners.within(inside, self.masks) {
            let mut rest = self.mask(o);
            while rest != 0 {
                let code = rest.trailing_zeros();
                rest &= rest - 1;
                if self.one_cofacet(o, code) {
                    queue.push_scanned(o, code);
                }
            }
        }
    }

    /// After (owner, code) was removed: queues its alive facets that are left with one
    /// cofacet (free faces now) and its alive cofacets that are left with one facet
    /// (coreducible now). A cell's counts only drop when a neighbour goes, so every cell
    /// that becomes a candidate is queued at that moment.
    pub(super) fn queue_new_candidates(&self, owner: usize, code: u32, queue: &mut CellQueue) {
        for axis in 0..self.grid.d {
            let c = code ^ 1 << axis;
            let upward = code >> axis & 1 == 1;
            let other = if upward {
                self.grid.forward(owner, axis)
            } else {
                self.grid.back(owner, axis)
            };
            for o in [owner, other] {
                if self.has(o, c) {
                    let one = if upward {
                        self.one_facet(o, c)
                    } else {
                        self.one_cofacet(o, c)
                    };
                    if one {
                        queue.push(o, if upward { c | COREDUCIBLE } else { c });
                    }
                }
            }
        }
    }

    /// Queues the free faces of the owners in `inside`, then [`Cells::reduce`]s from them
    /// with the first wave at `centre`, removing vertices in `inside` only: the cells left
    /// queued (those outside `inside`) and the number of vertices removed.
    pub(super) fn reduce_from_free_faces(
        &mut self,
        owners: &Owners,
        inside: &std::ops::Range<usize>,
        centre: [usize; 4],
        mut queue: CellQueue,
    ) -> (CellQueue, u64) {
        self.queue_free_faces(owners, inside, &mut queue);
        let removed = self.reduce(&mut queue, inside, inside, owners, Some(centre));
        (queue, removed)
    }

    /// Removes reduction pairs from `queue` (free faces and coreductions) and, whenever it
    /// runs empty, an alive vertex of the owners in `inside`: first the one nearest the
    /// centre `centre` (twice its coordinates) when given, then the first in owner order.
    /// Only cells owned in `inside` are reduced; queued cells outside stay in `queue`,
    /// which holds just them at the end. Returns the number of vertices removed.
    ///
    /// The first wave starts at the centre: from a corner (the first owner) the waves of
    /// a rough image's coreductions stall with many times the cells.
    pub(super) fn reduce(
        &mut self,
        queue: &mut CellQueue,
        inside: &std::ops::Range<usize>,
        vertices: &std::ops::Range<usize>,
        owners: &Owners,
        centre: Option<[usize; 4]>,
    ) -> u64 {
        let top = self.grid.all_codes;
        let mut left = CellQueue::default();
        let mut removed_vertices = 0u64;
        let mut rest = owners.within(vertices, self.masks);
        let mut centre = centre;
        loop {
            while let Some((o, queued)) = queue.pop() {
                if PART && !inside.contains(&o) {
                    left.push(o, queued);
                    continue;
                }
                let code = queued & !COREDUCIBLE;
                if !self.has(o, code) {
                    continue;
                }
                // Free face: c is the facet and its only cofacet goes with it; coreduction:
                // c is the cell and its only facet goes with it. Only the count the cell
                // was queued for is checked: when the other one is 1 too, the cell was
                // queued for it as well, at the removal that made it 1 (a count only falls,
                // and a closed complex starts with no cell of one facet), and that entry
                // is still to come, or the cell would be gone.
                let free = queued & COREDUCIBLE == 0;
                let partner = if free {
                    self.sole::<true>(o, code)
                } else {
                    self.sole::<false>(o, code)
                };
                let Some((po, pcode)) = partner else {
                    continue;
                };
                self.remove(o, code);
                self.remove(po, pcode);
                self.queue_new_candidates(o, code, queue);
                self.queue_new_candidates(po, pcode, queue);
            }
            let central = centre
                .take()
                .and_then(|c| self.central_vertex(owners, vertices, c));
            let o = match central {
                Some(o) => o,
                // The next in owner order: those before it have no vertex left (a vertex
                // only goes, it never comes back).
                None => match rest.find(|&o| self.has(o, top)) {
                    Some(o) => o,
                    None => break,
                },
            };
            removed_vertices += 1;
            self.remove(o, top);
            self.queue_new_candidates(o, top, queue);
        }
        *queue = left;
        removed_vertices
    }

    /// The owner in `inside` of an alive vertex whose owner voxel is nearest the point
    /// with doubled coordinates `centre` (the first in owner order among the nearest; the
    /// vertex itself is half a voxel further along every axis), if any vertex is alive.
    pub(super) fn central_vertex(
        &self,
        owners: &Owners,
        inside: &std::ops::Range<usize>,
        centre: [usize; 4],
    ) -> Option<usize> {
        let top = self.grid.all_codes;
        owners
            .within(inside, self.masks)
            .filter(|&o| self.has(o, top))
            .min_by_key(|&o| {
                let c = self.grid.coords(o);
                (0..self.grid.d)
                    .map(|axis| (2 * c[axis]).abs_diff(centre[axis]).pow(2))
                    .sum::<usize>()
            })
    }
}

/// Marks a queued cell as queued for a coreduction (one alive facet); a cell without it
/// was queued as a free face (one alive cofacet). Above the four bits of a code.
pub(super) const COREDUCIBLE: u32 = 16;
