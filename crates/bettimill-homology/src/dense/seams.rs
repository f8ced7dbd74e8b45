//! Test seams of the dense complex: constructors from images, the split's plumbing
//! exposed, and the other final rank and part orders that tests run beside production's.

use super::split_plan::{Halves, Order, Split};
use super::DenseComplex;
use crate::complex::z2_rank;
use crate::eliminate::{rank_by_elimination, Elimination, Lists, PoolOverflow};

impl DenseComplex {
    /// The split at brick row `row`, its seam split at brick `column` along the second
    /// axis if given (both counted from 0).
    pub(super) fn split_at(&self, row: usize, column: Option<usize>) -> Split {
        let (unit, places) = (self.grid.brick_step[0], self.places);
        let rows = Halves {
            start: 0,
            end: places,
            unit,
            half: row,
        };
        let seam = rows.seam();
        let columns = column.map(|half| Halves {
            start: seam.start,
            end: seam.end,
            unit: self.grid.brick_step[1],
            half,
        });
        Split { rows, columns }
    }

    /// Every place's presence bits.
    pub(crate) fn cells_by_place(&mut self) -> Vec<u16> {
        self.masks.get_mut().to_vec()
    }

    /// The closed cubical complex of the foreground voxels of `image`, whose border must
    /// be background.
    pub(crate) fn of_image(image: &bettimill_grid::BinaryImage) -> DenseComplex {
        DenseComplex::of_image_with(image, true)
    }

    /// [`DenseComplex::of_image`], its owners listed or not ([`super::Owners`]).
    pub(crate) fn of_image_with(image: &bettimill_grid::BinaryImage, listed: bool) -> DenseComplex {
        let mut complex = DenseComplex::new(image.shape()).expect("a small test grid");
        if !listed {
            complex = complex.unlisted();
        }
        let offsets = bettimill_grid::neighbourhood::full_offsets(image.dim());
        let grid = *complex.grid();
        let places = grid.face_places(&offsets);
        for (index, &v) in image.data().iter().enumerate() {
            if v != 0 {
                let around = grid.owners_around(grid.place(&image.coords(index)));
                complex.insert(around[0], 0);
                for &(back, code) in &places {
                    complex.insert(around[back], code);
                }
            }
        }
        complex
    }

    /// Whether [`DenseComplex::betti_with`] splits this complex's reduction, and its
    /// seam row too.
    pub(crate) fn splits(&mut self) -> bool {
        self.split().is_some_and(|split| split.columns.is_some())
    }

    /// [`DenseComplex::betti_with`] without the split (both routes agree: tests).
    pub(crate) fn betti_unsplit(self, b0: u64) -> Result<(Vec<u64>, u64), PoolOverflow> {
        self.betti_split(b0, rank_by_elimination, None)
    }
}

/// The oracle's plain left-to-right column reduction ([`crate::complex::z2_rank`]) as a
/// [`super::FinalRank`]: quadratic on large remnants, so tests run it beside elimination on
/// the same images. It takes no general pivots.
pub(crate) fn column_reduction(columns: Lists, n_rows: usize) -> Result<Elimination, PoolOverflow> {
    let (rank, pivots) = z2_rank(columns.to_vecs(), n_rows);
    Ok(Elimination {
        rank,
        pivots,
        general: 0,
    })
}

/// The parts of a split reduction one after the other, lower part first.
#[derive(Clone, Copy, Debug)]
pub(super) struct LowerFirst;

impl Order for LowerFirst {
    fn run<A: Send, B: Send>(
        self,
        lower: impl FnOnce() -> A + Send,
        upper: impl FnOnce() -> B + Send,
    ) -> (A, B) {
        let a = lower();
        (a, upper())
    }
}

/// The parts of a split reduction one after the other, upper part first.
#[derive(Clone, Copy, Debug)]
pub(super) struct UpperFirst;

impl Order for UpperFirst {
    fn run<A: Send, B: Send>(
        self,
        lower: impl FnOnce() -> A + Send,
        upper: impl FnOnce() -> B + Send,
    ) -> (A, B) {
        let b = upper();
        (lower(), b)
    }
}
