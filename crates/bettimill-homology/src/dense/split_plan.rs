//! Where a reduction large enough to split is cut: the split planner.

use super::{DenseComplex, Owners};

/// A range of places cut across one axis into two parts and a seam between them:
/// `start..end` is a whole number of units of `unit` places (the grid's brick rows along
/// the first axis, or one brick row's bricks along the second), the unit `half` (counted
/// from `start`) is the seam, the units before it are the lower part and those after it
/// the upper part. See [`DenseComplex::betti_with`](super::DenseComplex::betti_with).
#[derive(Clone, Copy, Debug)]
pub(super) struct Halves {
    pub(super) start: usize,
    pub(super) end: usize,
    pub(super) unit: usize,
    pub(super) half: usize,
}

impl Halves {
    /// `places` cut at the seam unit that makes the split cheapest (`weights`, one per
    /// unit, stand for the work): the larger part's weight, which the two parts take at
    /// once, plus the seam's, taken after them, `seam_share` of it on the critical path
    /// (a half for a seam split again, all of it for the last seam). Kept one unit from
    /// either end; the first of equally cheap seams. None with fewer than three units,
    /// the fewest a cut can have, or no weight.
    ///
    /// The seam was the unit where the weight passed half; when that unit was heavy (the
    /// pile of a 32^4 blob's thinning, a third of its owners) the lower part then held
    /// three times the upper's work.
    pub(super) fn cheapest(
        places: std::ops::Range<usize>,
        unit: usize,
        weights: &[usize],
        seam_share: SeamShare,
    ) -> Option<Halves> {
        let units = weights.len();
        let total: usize = weights.iter().sum();
        if units < 3 || total == 0 {
            return None;
        }
        // Twice the cost, in whole weights.
        let cost = |below: usize, seam: usize| {
            let larger = below.max(total - below - seam);
            2 * larger
                + match seam_share {
                    SeamShare::Half => seam,
                    SeamShare::Whole => 2 * seam,
                }
        };
        let mut below = weights[0];
        let mut best = (cost(below, weights[1]), 1);
        for half in 2..units - 1 {
            below += weights[half - 1];
            best = best.min((cost(below, weights[half]), half));
        }
        Some(Halves {
            start: places.start,
            end: places.end,
            unit,
            half: best.1,
        })
    }

    pub(super) fn lower(&self) -> std::ops::Range<usize> {
        self.start..self.start + self.half * self.unit
    }

    pub(super) fn seam(&self) -> std::ops::Range<usize> {
        self.start + self.half * self.unit..self.start + (self.half + 1) * self.unit
    }

    pub(super) fn upper(&self) -> std::ops::Range<usize> {
        self.start + (self.half + 1) * self.unit..self.end
    }
}

/// How much of a seam's work [`Halves::cheapest`] counts after the parts'.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum SeamShare {
    /// The seam is cut again, its two parts reduced at once: half.
    Half,
    /// The seam is reduced alone: all of it.
    Whole,
}

/// How the two parts of a split reduction run: [`Parallel`] in production; tests also run
/// them one after the other in either order (the test seams): the parts never meet, so
/// every order leaves the same cells.
pub(super) trait Order: Copy {
    fn run<A: Send, B: Send>(
        self,
        lower: impl FnOnce() -> A + Send,
        upper: impl FnOnce() -> B + Send,
    ) -> (A, B);
}

/// The two parts at once, on two threads.
#[derive(Clone, Copy, Debug)]
pub(super) struct Parallel;

impl Order for Parallel {
    fn run<A: Send, B: Send>(
        self,
        lower: impl FnOnce() -> A + Send,
        upper: impl FnOnce() -> B + Send,
    ) -> (A, B) {
        rayon::join(lower, upper)
    }
}

/// How [`DenseComplex::betti_with`](super::DenseComplex::betti_with) splits a reduction: across the first axis, and the
/// seam of that (one brick row) across the second axis when it is long enough.
#[derive(Clone, Copy, Debug)]
pub(super) struct Split {
    pub(super) rows: Halves,
    pub(super) columns: Option<Halves>,
}

impl DenseComplex {
    /// How many owners lie in each unit of `unit` places of `places`.
    pub(super) fn weights(&mut self, places: &std::ops::Range<usize>, unit: usize) -> Vec<usize> {
        let mut weights = vec![0; places.len() / unit];
        let masks = self.masks.shared();
        for o in self.owners.within(places, masks) {
            weights[(o - places.start) / unit] += 1;
        }
        weights
    }

    /// The number of brick rows along the first axis.
    pub(super) fn rows(&self) -> usize {
        self.sides[0].div_ceil(4)
    }

    /// How [`DenseComplex::betti_with`](super::DenseComplex::betti_with) splits the
    /// reduction, if it does: from 8,192 owners and five brick rows, with a seam of one
    /// brick row. Below that the second thread's start-up and the seam cost more than the
    /// halved work saves.
    pub(super) fn split(&mut self) -> Option<Split> {
        let few = match &self.owners {
            Owners::Listed(list) => list.len() < 1 << 13,
            Owners::Scanned => false,
        };
        if few || self.rows() < 5 {
            return None;
        }
        let everywhere = 0..self.places;
        let row = self.grid.brick_step[0];
        let weights = self.weights(&everywhere, row);
        let rows = Halves::cheapest(everywhere.clone(), row, &weights, SeamShare::Half)?;
        let seam = rows.seam();
        let column = self.grid.brick_step[1];
        let columns = (self.grid.d >= 2)
            .then(|| {
                let weights = self.weights(&seam, column);
                Halves::cheapest(seam.clone(), column, &weights, SeamShare::Whole)
            })
            .flatten();
        Some(Split { rows, columns })
    }
}
