//! Cubical complexes stored densely, 2^d presence bits per voxel of the image grid, and
//! their Z/2 homology by reduction pairs: the fast path of [`crate::topology`] in 4D.
//!
//! Every cell of the grid has exactly one owner voxel: voxel o owns the cells whose
//! Khalimsky coordinate along each axis a is 2 o_a + 1 (odd: the cell spans the voxel along
//! a) or 2 o_a + 2 (even: the cell lies in the plane between o and o + 1). Bit e of
//! `masks[o]` is the owned cell with e_a = 1 exactly on its even axes, so its dimension is
//! d - popcount(e), bit 0 is the voxel itself and bit 2^d - 1 a vertex. A cell's facets
//! and cofacets are then owned by o itself or by the next voxel along one axis:
//! - along an odd axis a (e_a = 0) the facets are (o, e + 2^a) and (o - 1_a, e + 2^a);
//! - along an even axis (e_a = 1) the cofacets are (o, e - 2^a) and (o + 1_a, e - 2^a),
//!   where o ± 1_a is the voxel one step along a.
//!
//! So the complex needs no sorting, no deduplication and no neighbour table, and every step
//! of the reduction is a few loads from one array (two bytes per voxel, in huge pages
//! where the system gives them, and pages no cell touches never backed: [`Masks`]). The
//! array is laid out in bricks of 4^d voxels, so that most steps along any axis stay
//! within the same 512 bytes (in 4D) instead of jumping a whole hyperplane of the image:
//! the reduction wanders through the complex in waves, and with the image's own layout
//! nearly every step along the first axes missed the caches. A voxel's place is
//! `brick << 2d | local`, with two bits of local coordinate per axis. A cell is named by
//! one `u64`, `place << 4 | e`.
//!
//! The reduction removes pairs (a, b), b a facet of a, that are either a free-face collapse
//! (a is the only alive cofacet of b) or a coreduction (b is the only alive facet of a).
//! Over Z/2 both preserve the homology of the remaining set of cells taken with the
//! restricted boundary (an S-complex in the sense of Mrozek and Batko): the reduced chain
//! complex differs from the old one only by the deleted pair. Coreductions need a start, so
//! when no pair is left an alive vertex v is removed (the first time, the one nearest the
//! centre of the grid: started from a corner, the waves stalled on a random 4D image with
//! ten times the cells, issue 18; on a grid large enough, one start per part of the grid,
//! the parts reduced on two threads, see [`DenseComplex::betti_with`]), which turns the
//! homology into that of the pair (X, V) with V the removed vertices. For k >= 2 the long
//! exact sequence of (X, V)
//! gives H_k(X, V) = H_k(X), and in low degrees dim H_0(X, V) = b_0 - c and
//! dim H_1(X, V) = b_1 + m - c, where m = |V| and c is the number of components V meets.
//! b_0 is counted by the caller on its voxels before anything is removed, so b_1 follows
//! (each removed vertex either lowers dim H_0 by one or raises dim H_1 by one). The Euler
//! characteristic (alternating cell count of the whole complex) checks the bookkeeping; a
//! mismatch panics rather than returning a wrong answer. The cells left are ranked
//! explicitly (boundary matrices, top dimension first, with clearing) by elimination with
//! free pivots first ([`crate::eliminate`]). That matters on rough images: the pairs can
//! stall with over a million edges and squares left (a random 48^4 image, issue 18), where
//! a plain column reduction filled in quadratically (over 1000 s at 32^4 when the waves
//! started in a corner).
//!
//! [`crate::reference`] reduces the plain boundary matrices of the whole, unreduced complex
//! (`CellComplex::betti_by_boundaries`), so the two check each other.

#[cfg(test)]
use crate::complex::z2_rank;
use crate::eliminate::{rank_by_elimination, Lists, PoolOverflow};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU16, Ordering::Relaxed};
use zerocopy::FromBytes;

/// How [`DenseComplex::betti_with`] ranks the boundary matrices of the cells that the
/// reduction pairs leave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FinalRank {
    /// Elimination with free pivots first ([`crate::eliminate`]): what [`crate::topology`]
    /// uses.
    Elimination,
    /// Plain left-to-right column reduction ([`crate::complex::z2_rank`], the oracle's),
    /// quadratic on large remnants (issue 18): the route before elimination, kept so that
    /// tests can run both on the same images.
    #[cfg(test)]
    ColumnReduction,
}

/// A closed set of cells of the grid of one image shape, as owner masks (module docs).
///
/// Every cell must lie in the closure of a voxel that is not on the border of the grid
/// (as the cells of a padded image's foreground do): then every facet and cofacet the
/// reduction looks up is owned by a voxel inside the grid.
pub(crate) struct DenseComplex {
    grid: Grid,
    /// The grid's sides (1 for the axes past the last).
    sides: [usize; 4],
    /// The number of places.
    places: usize,
    /// Presence bits of the cells each voxel owns, by place ([`Masks`]).
    masks: Masks,
    /// The voxels that own cells ([`Owners`]).
    owners: Owners,
    /// The Euler characteristic of the cells inserted, counted as they come (a scan of the
    /// owners' masks afterwards took 0.5 ms of a 32^4 blob's 20: they are far apart).
    chi: i64,
}

/// The Euler characteristic of the cells of one owner whose local codes are the bits of a
/// mask, in a grid of an even number of axes: `EULER_OF_BYTE[byte]` for the codes 0-7 of a
/// byte, each counted +1 or -1 by the parity of its number of bits (the axes along which
/// the cell does not extend); the codes 8-15 have the other parity ([`euler_of`]).
const EULER_OF_BYTE: [i8; 256] = {
    let mut table = [0i8; 256];
    let mut byte = 0;
    while byte < 256 {
        let mut code = 0;
        while code < 8 {
            if byte >> code & 1 == 1 {
                table[byte] += if (code as u32).count_ones() % 2 == 0 {
                    1
                } else {
                    -1
                };
            }
            code += 1;
        }
        byte += 1;
    }
    table
};

/// The Euler characteristic of the cells whose local codes are the bits of `cells` in a
/// grid of `d` axes: a cell's dimension is d minus its code's number of bits.
#[inline]
fn euler_of(cells: u16, d: usize) -> i64 {
    let even_d =
        EULER_OF_BYTE[cells as usize & 0xff] as i64 - EULER_OF_BYTE[cells as usize >> 8] as i64;
    if d % 2 == 0 {
        even_d
    } else {
        -even_d
    }
}

/// The places of the voxels that own cells, as the reduction visits them.
#[derive(Debug)]
pub(crate) enum Owners {
    /// Listed: the place of every voxel that has owned a cell, in the order of the first
    /// insertion (of each thread's in turn after [`DenseComplex::insert_split`]; places
    /// fit 32 bits: [`DenseComplex::new`] checks the grid). A smooth image's remnant is a
    /// few owners among many places.
    Listed(Vec<u32>),
    /// Not listed: every place in order, those that own nothing skipped. On a rough
    /// image nearly every voxel owns cells, and the list was four bytes a voxel, the
    /// largest part of the peak (a random 64^4 image: 16.5 million owners, issue 18).
    Scanned,
}

impl Owners {
    /// The owners among the places `inside`, in order: all those listed there, or the
    /// places there whose mask is not 0 as the iterator reaches them. Either way a visit
    /// checks the cells it wants: the reduction may have removed them since.
    fn within<'a>(
        &'a self,
        inside: &std::ops::Range<usize>,
        masks: &'a [AtomicU16],
    ) -> OwnersWithin<'a> {
        match self {
            Owners::Listed(list) => OwnersWithin::Listed(list.iter(), inside.clone()),
            Owners::Scanned => {
                let end = inside.end.min(masks.len());
                OwnersWithin::Scanned(inside.start.min(end)..end, masks)
            }
        }
    }
}

/// The iterator of [`Owners::within`].
enum OwnersWithin<'a> {
    Listed(std::slice::Iter<'a, u32>, std::ops::Range<usize>),
    Scanned(std::ops::Range<usize>, &'a [AtomicU16]),
}

impl Iterator for OwnersWithin<'_> {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        match self {
            OwnersWithin::Listed(list, inside) => list
                .by_ref()
                .map(|&o| o as usize)
                .find(|o| inside.contains(o)),
            OwnersWithin::Scanned(places, masks) => places.find(|&o| masks[o].load(Relaxed) != 0),
        }
    }
}

/// How places are laid out (module docs), and the steps from a cell to its facets and
/// cofacets: small and `Copy`, so that each half of a split reduction holds its own.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Grid {
    d: usize,
    /// Per axis: the shift of its two local bits, and the step from one brick to the next.
    shift: [u32; 4],
    brick_step: [usize; 4],
    /// Per axis, for [`Grid::forward`] and [`Grid::back`]: the two local bits in place, the
    /// step to the next voxel inside a brick (one at the shift) and the step from the last
    /// voxel of a brick to the first of the next (a brick on, three back inside).
    local_bits: [usize; 4],
    inner_step: [usize; 4],
    brick_over: [usize; 4],
    /// Per local code: the codes of its cofacets (facets) held by the same owner.
    up_same: [u16; 16],
    down_same: [u16; 16],
    /// The local codes' bits: 2^d - 1.
    all_codes: u32,
}

impl Grid {
    /// The place of the voxel at `coords`.
    pub(crate) fn place(&self, coords: &[usize]) -> usize {
        (0..self.d)
            .map(|a| (coords[a] / 4) * self.brick_step[a] + ((coords[a] % 4) << self.shift[a]))
            .sum()
    }

    /// The place one voxel further along `axis`.
    #[inline]
    fn forward(&self, place: usize, axis: usize) -> usize {
        let bits = self.local_bits[axis];
        place.wrapping_add(if place & bits == bits {
            self.brick_over[axis]
        } else {
            self.inner_step[axis]
        })
    }

    /// The place one voxel back along `axis`.
    #[inline]
    fn back(&self, place: usize, axis: usize) -> usize {
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
    fn coords(&self, place: usize) -> [usize; 4] {
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

/// A range of places cut across one axis into two parts and a seam between them:
/// `start..end` is a whole number of units of `unit` places (the grid's brick rows along
/// the first axis, or one brick row's bricks along the second), the unit `half` (counted
/// from `start`) is the seam, the units before it are the lower part and those after it
/// the upper part. See [`DenseComplex::betti_with`].
#[derive(Clone, Copy, Debug)]
struct Halves {
    start: usize,
    end: usize,
    unit: usize,
    half: usize,
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
    fn cheapest(
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

    fn lower(&self) -> std::ops::Range<usize> {
        self.start..self.start + self.half * self.unit
    }

    fn seam(&self) -> std::ops::Range<usize> {
        self.start + self.half * self.unit..self.start + (self.half + 1) * self.unit
    }

    fn upper(&self) -> std::ops::Range<usize> {
        self.start + (self.half + 1) * self.unit..self.end
    }
}

/// How much of a seam's work [`Halves::cheapest`] counts after the parts'.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SeamShare {
    /// The seam is cut again, its two parts reduced at once: half.
    Half,
    /// The seam is reduced alone: all of it.
    Whole,
}

/// How the two parts of a split reduction run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Order {
    /// At once, on two threads.
    Parallel,
    /// One after the other, lower part first (tests: the parts never meet, so every order
    /// leaves the same cells).
    #[cfg(test)]
    LowerFirst,
    /// One after the other, upper part first.
    #[cfg(test)]
    UpperFirst,
}

impl Order {
    fn run<A: Send, B: Send>(
        self,
        lower: impl FnOnce() -> A + Send,
        upper: impl FnOnce() -> B + Send,
    ) -> (A, B) {
        match self {
            Order::Parallel => rayon::join(lower, upper),
            #[cfg(test)]
            Order::LowerFirst => {
                let a = lower();
                (a, upper())
            }
            #[cfg(test)]
            Order::UpperFirst => {
                let b = upper();
                (lower(), b)
            }
        }
    }
}

/// How [`DenseComplex::betti_with`] splits a reduction: across the first axis, and the
/// seam of that (one brick row) across the second axis when it is long enough.
#[derive(Clone, Copy, Debug)]
struct Split {
    rows: Halves,
    columns: Option<Halves>,
}

impl DenseComplex {
    /// An empty complex in the grid of an image of `shape` (1 to 4 axes, C order), or an
    /// error when the grid has more than 2^32 places ([`check_grid`]): places are held in
    /// 32 bits, 4 bytes per owner and 5 per queued cell instead of 8 and 8.
    pub(crate) fn new(shape: &[usize]) -> Result<DenseComplex, GridTooLarge> {
        let d = shape.len();
        assert!(
            (1..=4).contains(&d),
            "{d} axes: dense complexes have 1 to 4"
        );
        // Checked first: the brick counts below cannot overflow once the places fit.
        let places = check_grid(shape)?;
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
        Ok(DenseComplex {
            grid: Grid {
                d,
                shift,
                brick_step,
                local_bits: shift.map(|shift| 3 << shift),
                inner_step: shift.map(|shift| 1 << shift),
                brick_over: std::array::from_fn(|axis| {
                    brick_step[axis].wrapping_sub(3 << shift[axis])
                }),
                up_same,
                down_same,
                all_codes,
            },
            sides: std::array::from_fn(|axis| shape.get(axis).copied().unwrap_or(1)),
            places,
            masks: Masks::zeroed(places),
            owners: Owners::Listed(Vec::new()),
            chi: 0,
        })
    }

    /// Leaves the owners unlisted ([`Owners::Scanned`]), before any cell is inserted: for
    /// a complex where most places will own cells.
    pub(crate) fn unlisted(mut self) -> DenseComplex {
        debug_assert!(matches!(&self.owners, Owners::Listed(list) if list.is_empty()));
        self.owners = Owners::Scanned;
        self
    }

    /// Whether the owners are listed ([`Owners`]).
    pub(crate) fn lists_owners(&self) -> bool {
        matches!(self.owners, Owners::Listed(_))
    }

    /// The number of places of the grid.
    pub(crate) fn places(&self) -> usize {
        self.places
    }

    /// The layout of the complex's places.
    pub(crate) fn grid(&self) -> &Grid {
        &self.grid
    }

    /// How many owners lie in each unit of `unit` places of `places`.
    fn weights(&mut self, places: &std::ops::Range<usize>, unit: usize) -> Vec<usize> {
        let mut weights = vec![0; places.len() / unit];
        let masks = self.masks.shared();
        for o in self.owners.within(places, masks) {
            weights[(o - places.start) / unit] += 1;
        }
        weights
    }

    /// The split at brick row `row`, its seam split at brick `column` along the second
    /// axis if given (both counted from 0).
    #[cfg(test)]
    fn split_at(&self, row: usize, column: Option<usize>) -> Split {
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

    /// The number of brick rows along the first axis.
    fn rows(&self) -> usize {
        self.sides[0].div_ceil(4)
    }

    /// Adds the cell with local code `code` owned by the voxel at `owner` (a place).
    #[inline]
    pub(crate) fn insert(&mut self, owner: usize, code: u32) {
        self.insert_mask(owner, 1 << code);
    }

    /// Adds the cells whose local codes are the bits of `cells` (not 0), owned by the voxel
    /// at `owner` (a place).
    #[inline]
    pub(crate) fn insert_mask(&mut self, owner: usize, cells: u16) {
        let mask = &mut self.masks.get_mut()[owner];
        let list = match &mut self.owners {
            Owners::Listed(list) => Some(list),
            Owners::Scanned => None,
        };
        *mask = add_cells(*mask, cells, owner, list, self.grid.d, &mut self.chi);
    }

    /// Inserts cells on two threads at once: `lower` and `upper` each get an [`Inserter`],
    /// `lower`'s for the places below `boundary`, `upper`'s for the rest. Cells an inserter
    /// is given outside its places are held back and inserted after both are done, in its
    /// order. The owners are listed as `lower` first inserted them, then as `upper` did,
    /// then the held-back ones: the same whatever the threads' timing. Returns how many
    /// masks were held back.
    pub(crate) fn insert_split(
        &mut self,
        boundary: usize,
        lower: impl FnOnce(&mut Inserter) + Send,
        upper: impl FnOnce(&mut Inserter) + Send,
    ) -> usize {
        let places = self.places;
        let listed = matches!(self.owners, Owners::Listed(_));
        let masks = self.masks.shared();
        let d = self.grid.d;
        let mut parts = [0..boundary, boundary..places].map(|own| Inserter {
            masks,
            own,
            owners: listed.then(Vec::new),
            held: Vec::new(),
            d,
            chi: 0,
        });
        let [a, b] = &mut parts;
        rayon::join(|| lower(a), || upper(b));
        self.chi += parts[0].chi + parts[1].chi;
        let [(owners_a, held_a), (owners_b, held_b)] = parts.map(|part| (part.owners, part.held));
        if let (Owners::Listed(list), Some(a), Some(b)) = (&mut self.owners, owners_a, owners_b) {
            // Lower's list grows in place to take upper's: no third copy at the peak.
            if list.is_empty() {
                *list = a;
            } else {
                list.extend_from_slice(&a);
            }
            list.reserve_exact(b.len());
            list.extend_from_slice(&b);
        }
        let mut count = 0;
        for held in [held_a, held_b] {
            count += held.len();
            for (owner, cells) in held {
                self.insert_mask(owner as usize, cells);
            }
        }
        count
    }

    /// Every place's presence bits.
    #[cfg(test)]
    pub(crate) fn cells_by_place(&mut self) -> Vec<u16> {
        self.masks.get_mut().to_vec()
    }

    /// The closed cubical complex of the foreground voxels of `image`, whose border must
    /// be background.
    #[cfg(test)]
    pub(crate) fn of_image(image: &bettimill_grid::BinaryImage) -> DenseComplex {
        DenseComplex::of_image_with(image, true)
    }

    /// [`DenseComplex::of_image`], its owners listed or not ([`Owners`]).
    #[cfg(test)]
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

    /// The grid and the masks, as a reduction shares them between its threads.
    fn view(&mut self) -> View<'_> {
        View {
            grid: self.grid,
            sides: self.sides,
            masks: self.masks.shared(),
        }
    }

    /// Betti numbers b_0..b_d over Z/2 (module docs for the method), given b_0, the
    /// number of connected components, which the caller counts on its voxels (far fewer
    /// than the complex's vertices). Consumes the complex: the reduction deletes cells as it
    /// goes.
    ///
    /// When the complex is large enough ([`DenseComplex::split`]), the pairs run on two
    /// threads first. The grid is cut across its first axis at the brick row that halves
    /// the owners: that row is the seam, and the rows before and after it are the two
    /// parts. Each part removes the pairs it reaches among the cells it owns (its free
    /// faces, then coreductions from its own vertex nearest its centre, and from one more
    /// vertex for each piece of it those waves miss) and leaves the rest queued. A step
    /// from a cell writes at most one voxel away (the cell and its partner) and reads at
    /// most three (the counts of their neighbours' neighbours), so across a seam of four
    /// planes neither part reads a place the other writes: the two never meet, and the
    /// cells left do not depend on the threads' timing (the masks are atomics only so that
    /// both threads may hold them). Then the seam row is cut the same way across the
    /// second axis, its two parts taking the cells left queued in them, and only the last
    /// seam, one brick along each of the first two axes, and whatever is still queued go
    /// on one thread. The extra vertices are more vertices in V, which the bookkeeping
    /// below counts anyway; where the waves of two parts meet, a few more cells stall
    /// (issue 18 measured the trade: BENCHMARKS.md).
    ///
    /// The final rank is computed as `final_rank` says; also returns how many general
    /// (fill-in) pivots the elimination took. An error when the elimination's lists would
    /// pass their limit ([`PoolOverflow`]).
    pub(crate) fn betti_with(
        mut self,
        b0: u64,
        final_rank: FinalRank,
    ) -> Result<(Vec<u64>, u64), PoolOverflow> {
        let split = self.split();
        self.betti_split(b0, final_rank, split)
    }

    /// How [`DenseComplex::betti_with`] splits the reduction, if it does: from 8,192
    /// owners and five brick rows. With a seam of one brick row, a 32^4 blob (35,183
    /// owners, nine rows) reduced in 6.3 ms instead of 10.3, a random 24^4 image (seven
    /// rows) in 104 ms instead of 186; a 16^4 blob (1,205 owners) took longer split
    /// (BENCHMARKS.md).
    fn split(&mut self) -> Option<Split> {
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

    /// Whether [`DenseComplex::betti_with`] splits this complex's reduction, and its
    /// seam row too.
    #[cfg(test)]
    pub(crate) fn splits(&mut self) -> bool {
        self.split().is_some_and(|split| split.columns.is_some())
    }

    /// [`DenseComplex::betti_with`] without the split (both routes agree: tests).
    #[cfg(test)]
    pub(crate) fn betti_unsplit(self, b0: u64) -> Result<(Vec<u64>, u64), PoolOverflow> {
        self.betti_split(b0, FinalRank::Elimination, None)
    }

    /// [`DenseComplex::betti_with`], split as `parts` says (or not at all).
    fn betti_split(
        mut self,
        b0: u64,
        final_rank: FinalRank,
        parts: Option<Split>,
    ) -> Result<(Vec<u64>, u64), PoolOverflow> {
        let d = self.grid.d;
        // The vertex code: every axis even.
        let top = self.grid.all_codes;
        // The local codes of the k-cells: dimension d - popcount(code).
        let codes_of = |k: usize| {
            (0..=top)
                .filter(|&code| d - code.count_ones() as usize == k)
                .fold(0u16, |mask, code| mask | 1 << code)
        };
        let owners = std::mem::replace(&mut self.owners, Owners::Scanned);
        let places = self.places;
        // Counted as the cells came, before any pair went.
        let chi = self.chi;
        let view = self.view();
        let everywhere = 0..usize::MAX;
        if owners.within(&everywhere, view.masks).next().is_none() {
            return Ok((vec![0; d + 1], 0));
        }
        let mut removed_vertices = 0u64;
        match parts {
            None => {
                let centre = view.doubled_centre(0..places);
                let (_, removed) = view.cells::<false>().reduce_from_free_faces(
                    &owners,
                    &everywhere,
                    centre,
                    CellQueue::default(),
                );
                removed_vertices += removed;
            }
            Some(split) => {
                let (mut left, seam, removed) = view.reduce_parts(&owners, split, Order::Parallel);
                removed_vertices += removed;
                // What is left queued, then the last seam's own candidates. The parts
                // removed every vertex they own: only the last seam's are left.
                let mut cells = view.cells::<false>();
                cells.queue_free_faces(&owners, &seam, &mut left);
                removed_vertices += cells.reduce(&mut left, &everywhere, &seam, &owners, None);
            }
        }
        // Every pair was taken: the tags of the queue (`COREDUCIBLE`) skip no pair.
        debug_assert_eq!(view.cells::<false>().reducible(&owners), 0);
        // Explicit reduction of what is left, top dimension first; a k-cell that is the
        // lowest row of a reduced (k+1)-column has a boundary column reducing to zero. (The
        // queues went with the match above.)
        // Counted first, so that each list is allocated once at its size.
        let mut counts = vec![0usize; d + 1];
        for o in owners.within(&everywhere, view.masks) {
            let mut rest = view.mask(o);
            while rest != 0 {
                let code = rest.trailing_zeros();
                rest &= rest - 1;
                counts[d - code.count_ones() as usize] += 1;
            }
        }
        // The cells of each dimension in increasing order of place and code, i.e. of
        // cell: the columns are built in that order, and a facet's row is its rank in it.
        // When the cells left are many (a rough image), the masks are in that order
        // already: a scan gives the columns, and [`Ranks`] the rows, a quarter of a byte a
        // place where a list took eight bytes a cell (190 MB of a random 96^4 image's
        // peak). When they are few (a smooth image), they are listed from the owners and
        // sorted: a scan would cost more than the sort (a 64^4 blob has 21 million places
        // and a few thousand cells left).
        let few = counts.iter().sum::<usize>() < places / 64;
        // The ranks only look cells up in the masks: the owners go before the lists grow
        // (unless the lists come from them).
        let owners = match owners {
            Owners::Listed(list) if few => list,
            _ => Vec::new(),
        };
        let mut listed = (few && !owners.is_empty()).then(|| {
            let mut by_dim: Vec<Vec<u64>> = counts.iter().map(|&n| Vec::with_capacity(n)).collect();
            for o in owners {
                let mut rest = view.mask(o as usize);
                while rest != 0 {
                    let code = rest.trailing_zeros();
                    rest &= rest - 1;
                    by_dim[d - code.count_ones() as usize].push(cell(o as usize, code));
                }
            }
            for cells in &mut by_dim {
                cells.sort_unstable();
            }
            by_dim
        });
        // The masks go as soon as no column is left to look facets up in (before the
        // squares' elimination on a random 4D image, whose peak it is: two bytes a place).
        let grid = self.grid;
        let mut masks = Some(self.masks);
        let looks_up = |k: usize| counts[k] > 0 && counts[k - 1] > 0;
        let mut rank = vec![0u64; d + 2];
        let mut general = 0u64;
        let mut cleared = vec![false; counts[d]];
        for k in (1..=d).rev() {
            // Without (k-1)-cells, or k-cells, the boundary matrix is zero.
            let columns = if looks_up(k) {
                let cells = Cells::<false> {
                    grid,
                    masks: masks
                        .as_mut()
                        .expect("kept while columns look facets up")
                        .shared(),
                };
                match &listed {
                    Some(by_dim) => {
                        let rows = &by_dim[k - 1];
                        let row = |o, code| {
                            let row = rows.binary_search(&cell(o, code));
                            row.expect("an alive facet is a listed cell") as u32
                        };
                        let of_k = by_dim[k].iter().map(|&c| split(c));
                        cells.boundary_columns(k, counts[k], of_k, &cleared, row)?
                    }
                    None => {
                        let ranks = Ranks::new(cells.masks, codes_of(k - 1));
                        let row = |o, code| ranks.rank(cells.masks, o, code);
                        let of_k = cells.all_of(codes_of(k));
                        cells.boundary_columns(k, counts[k], of_k, &cleared, row)?
                    }
                }
            } else {
                Lists::default()
            };
            if !(1..k).any(looks_up) {
                masks = None;
            }
            // The k-cells are not needed again (only their number).
            if let Some(by_dim) = &mut listed {
                by_dim[k] = Vec::new();
            }
            let n_rows = counts[k - 1];
            let (r, pivots) = match final_rank {
                FinalRank::Elimination => {
                    let found = rank_by_elimination(columns, n_rows)?;
                    general += found.general;
                    (found.rank, found.pivots)
                }
                #[cfg(test)]
                FinalRank::ColumnReduction => z2_rank(columns.to_vecs(), n_rows),
            };
            rank[k] = r;
            cleared = vec![false; n_rows];
            for row in pivots {
                cleared[row as usize] = true;
            }
        }
        let relative: Vec<u64> = (0..=d)
            .map(|k| counts[k] as u64 - rank[k] - rank[k + 1])
            .collect();
        // c = b_0 - dim H_0(X, V); b_1 = dim H_1(X, V) - m + c.
        let met = b0
            .checked_sub(relative[0])
            .expect("H_0(X, V) cannot exceed H_0(X)");
        let b1 = (relative[1] + met)
            .checked_sub(removed_vertices)
            .expect("H_1(X, V) has dimension b_1 + m - c");
        let mut betti = relative;
        betti[0] = b0;
        betti[1] = b1;
        let euler: i64 = betti
            .iter()
            .enumerate()
            .map(|(k, &b)| if k % 2 == 0 { b as i64 } else { -(b as i64) })
            .sum();
        assert_eq!(
            euler, chi,
            "reduction pairs lost homology: Betti numbers {betti:?} disagree with the Euler \
             characteristic {chi}"
        );
        Ok((betti, general))
    }
}

/// Inserts cells into a [`DenseComplex`] from one of two threads
/// ([`DenseComplex::insert_split`]): the places `own` are its alone.
pub(crate) struct Inserter<'a> {
    masks: &'a [AtomicU16],
    own: std::ops::Range<usize>,
    /// The owners it made, in the order of their first cell, if the complex lists them.
    owners: Option<Vec<u32>>,
    /// Cells given outside `own`, inserted later.
    held: Vec<(u32, u16)>,
    /// The grid's axes, and the Euler characteristic of the cells it added.
    d: usize,
    chi: i64,
}

impl Inserter<'_> {
    /// Adds the cells whose local codes are the bits of `cells` (not 0), owned by the voxel
    /// at `owner` (a place).
    #[inline]
    pub(crate) fn insert_mask(&mut self, owner: usize, cells: u16) {
        if !self.own.contains(&owner) {
            self.held.push((owner as u32, cells));
            return;
        }
        // A load and a store: no other thread touches these places.
        let mask = &self.masks[owner];
        let list = self.owners.as_mut();
        let new = add_cells(
            mask.load(Relaxed),
            cells,
            owner,
            list,
            self.d,
            &mut self.chi,
        );
        mask.store(new, Relaxed);
    }
}

/// The mask of `owner` once `cells` join its mask `old`, for both ways of inserting: the
/// owner is listed in `owners` (if they are listed) when it had no cell, and the new
/// cells' Euler characteristic (in a grid of `d` axes) is added to `chi`.
#[inline]
fn add_cells(
    old: u16,
    cells: u16,
    owner: usize,
    owners: Option<&mut Vec<u32>>,
    d: usize,
    chi: &mut i64,
) -> u16 {
    if old == 0 {
        if let Some(list) = owners {
            list.push(owner as u32);
        }
    }
    *chi += euler_of(cells & !old, d);
    old | cells
}

/// The grid and the masks of a [`DenseComplex`], as a reduction shares them between its
/// threads.
#[derive(Clone, Copy)]
struct View<'a> {
    grid: Grid,
    sides: [usize; 4],
    masks: &'a [AtomicU16],
}

impl<'a> View<'a> {
    /// The presence bits of the cells `owner` owns.
    #[inline]
    fn mask(&self, owner: usize) -> u16 {
        self.masks[owner].load(Relaxed)
    }

    /// The masks as a reduction works on them (`PART`: see [`Cells`]).
    fn cells<const PART: bool>(&self) -> Cells<'a, PART> {
        Cells {
            grid: self.grid,
            masks: self.masks,
        }
    }

    /// Twice the coordinates of the centre of the voxels of the places `places` (a range
    /// of whole bricks, as [`Halves`] cuts them), cut at the grid's sides.
    fn doubled_centre(&self, places: std::ops::Range<usize>) -> [usize; 4] {
        let (first, last) = (
            self.grid.coords(places.start),
            self.grid.coords(places.end - 1),
        );
        std::array::from_fn(|axis| first[axis] + last[axis].min(self.sides[axis] - 1))
    }

    /// The pairs of one part of a split reduction ([`DenseComplex::betti_with`]): those
    /// among the cells owned in `inside`, from its free faces and then from its vertex
    /// nearest its centre. Returns the cells left queued (outside `inside`) and the number
    /// of vertices removed.
    fn reduce_part(
        &self,
        owners: &Owners,
        inside: std::ops::Range<usize>,
        queue: CellQueue,
    ) -> (CellQueue, u64) {
        let centre = self.doubled_centre(inside.clone());
        self.cells::<true>()
            .reduce_from_free_faces(owners, &inside, centre, queue)
    }

    /// The parts of a split reduction ([`DenseComplex::betti_with`]), each pair of parts
    /// run as `order` says: the lower and upper brick rows, then the two parts of the seam
    /// row if it splits too (each taking the cells left queued in it). Returns the cells
    /// left queued, the last seam (whose cells no part reduced) and the number of vertices
    /// removed.
    fn reduce_parts(
        &self,
        owners: &Owners,
        split: Split,
        order: Order,
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

/// The masks' memory: an anonymous mapping of two bytes per place, rounded up to whole
/// 2 MiB pages and one more for the alignment, zeroed by the kernel (pages no cell touches
/// are never written) and asked for as transparent huge pages on Linux. On the test
/// machine a fault on a fresh 4 KiB page cost about 2.3 us, so the 14.6 MB of a 48^4
/// image's masks took 8 ms of faults, most of the inserts' time; a huge page costs one
/// fault per 2 MiB (issue 18, BENCHMARKS.md).
struct Masks {
    map: memmap2::MmapMut,
    /// Where the masks start in `map`: its first 2 MiB boundary, so that they lie in whole
    /// huge pages of the mapping.
    start: usize,
    /// Their bytes: two per place.
    len: usize,
}

impl Masks {
    /// A huge page.
    const HUGE: usize = 2 << 20;

    fn zeroed(places: usize) -> Masks {
        let len = 2 * places.max(1);
        // Room for whole huge pages after the first boundary: with only `len` there, the
        // huge page holding the masks' end could stick out of the mapping and be faulted
        // in 4 KiB pages (about 540 more faults on a 32^4 image, in about half the runs).
        let map = memmap2::MmapMut::map_anon(len.next_multiple_of(Masks::HUGE) + Masks::HUGE)
            .unwrap_or_else(|error| panic!("no memory for the complex's masks: {error}"));
        // Only a hint: without huge pages the mapping works the same.
        #[cfg(target_os = "linux")]
        let _ = map.advise(memmap2::Advice::HugePage);
        let at = map.as_ptr() as usize;
        let start = at.next_multiple_of(Masks::HUGE) - at;
        Masks { map, start, len }
    }

    fn bytes(&mut self) -> &mut [u8] {
        &mut self.map[self.start..self.start + self.len]
    }

    /// The masks, for threads to share: relaxed loads and stores of atomics are plain
    /// moves, and the parts of a split reduction never touch the same place (see
    /// [`DenseComplex::betti_with`]).
    fn shared(&mut self) -> &[AtomicU16] {
        <[AtomicU16]>::mut_from_bytes(self.bytes()).expect("an aligned, even length")
    }

    /// The masks, for one writer.
    #[inline]
    fn get_mut(&mut self) -> &mut [u16] {
        <[u16]>::mut_from_bytes(self.bytes()).expect("an aligned, even length")
    }
}

/// The masks, as a reduction sees them. `PART` is whether the reduction is one part of a
/// split one (with a range of owners to reduce): a constant, so that the whole grid's
/// reduction pays no range test in its inner loop.
struct Cells<'a, const PART: bool> {
    grid: Grid,
    masks: &'a [AtomicU16],
}

impl<const PART: bool> Cells<'_, PART> {
    /// The presence bits of the cells `owner` owns.
    #[inline]
    fn mask(&self, owner: usize) -> u16 {
        self.masks[owner].load(Relaxed)
    }

    #[inline]
    fn has(&self, owner: usize, code: u32) -> bool {
        self.mask(owner) >> code & 1 == 1
    }

    /// Removes a cell. A load and a store, not one atomic update: no other thread writes
    /// or reads this place meanwhile (the parts of a split are apart).
    #[inline]
    fn remove(&mut self, owner: usize, code: u32) {
        let mask = &self.masks[owner];
        mask.store(mask.load(Relaxed) & !(1 << code), Relaxed);
    }

    /// The only alive cofacet (`UP`) or facet of (owner, code), if it has exactly one.
    /// Those the owner holds are one mask test; the others are one bit each from the next
    /// voxel along an even axis (cofacets) or the previous one along an odd axis (facets),
    /// looked at only while fewer than two are found (most cells have two among the owner's
    /// own).
    #[inline]
    fn sole<const UP: bool>(&self, owner: usize, code: u32) -> Option<(usize, u32)> {
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
    fn one_cofacet(&self, owner: usize, code: u32) -> bool {
        self.sole::<true>(owner, code).is_some()
    }

    /// Whether (owner, code) has exactly one alive facet ([`Cells::sole`]).
    #[inline]
    fn one_facet(&self, owner: usize, code: u32) -> bool {
        self.sole::<false>(owner, code).is_some()
    }

    /// How many alive cells of `owners` still have one alive cofacet or one alive facet
    /// (for the checks of debug builds: none after the pairs).
    fn reducible(&self, owners: &Owners) -> usize {
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
    fn all_of(&self, codes: u16) -> impl Iterator<Item = (usize, u32)> + '_ {
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
    fn boundary_columns(
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
    fn queue_free_faces(
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
    fn queue_new_candidates(&self, owner: usize, code: u32, queue: &mut CellQueue) {
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
    fn reduce_from_free_faces(
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
    /// a rough image's coreductions stalled with ten times the cells (issue 18).
    fn reduce(
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
    fn central_vertex(
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

/// The rank of a cell among the alive cells of some codes (one dimension's), in increasing
/// order of place and code, read off the masks: the count before every
/// [`Ranks::STRIDE`]-th place is kept (a quarter of a byte a place), the places since are
/// counted when asked.
struct Ranks {
    codes: u16,
    before: Vec<u32>,
}

impl Ranks {
    const STRIDE: usize = 16;

    fn new(masks: &[AtomicU16], codes: u16) -> Ranks {
        let mut before = Vec::with_capacity(masks.len().div_ceil(Ranks::STRIDE));
        let mut n = 0u32;
        for stride in masks.chunks(Ranks::STRIDE) {
            before.push(n);
            n += Ranks::count(stride, codes);
        }
        Ranks { codes, before }
    }

    /// The cells of `masks` whose codes are in `codes`. Four masks a word: one count of
    /// its ones for four places (x86-64 without `popcnt` counts a word's ones in a dozen
    /// instructions).
    #[inline]
    fn count(masks: &[AtomicU16], codes: u16) -> u32 {
        let codes = codes as u64 * 0x0001_0001_0001_0001;
        masks
            .chunks(4)
            .map(|four| {
                let word = four
                    .iter()
                    .rev()
                    .fold(0u64, |word, mask| word << 16 | mask.load(Relaxed) as u64);
                (word & codes).count_ones()
            })
            .sum()
    }

    /// The rank of the alive cell (owner, code), whose code is one of the codes.
    #[inline]
    fn rank(&self, masks: &[AtomicU16], owner: usize, code: u32) -> u32 {
        let start = owner - owner % Ranks::STRIDE;
        let earlier = Ranks::count(&masks[start..owner], self.codes);
        let below = masks[owner].load(Relaxed) & self.codes & ((1u16 << code) - 1);
        self.before[owner / Ranks::STRIDE] + earlier + below.count_ones()
    }
}

/// [`DenseComplex::new`] refused a grid: its places would not fit 32 bits.
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

/// Cells in first-in, first-out order, in blocks recycled as they empty: the queue's
/// memory follows its length. A cell pushed with [`CellQueue::push`] takes 5 bytes (a
/// 32-bit place and a code); a run of cells pushed with [`CellQueue::push_scanned`] in
/// increasing order of place, as a scan of the owners finds the free faces, takes one byte
/// a cell (the step from the one before and the code), five where the step is 15 or more.
/// On a random 4D image the free faces are about one cell per voxel, and they were the
/// pairs' peak (85 MB of a random 64^4 image's 150, issue 18). Past
/// [`CellQueue::NEAR_FROM`] full blocks, the cells of `push` (the candidates a removal
/// makes) are kept as runs too, their steps either way in 0 to 4 bytes ([`Kind::Near`]):
/// the steps from one candidate to the next are spread (a quarter under 8 places, a
/// quarter under 128, a quarter under 32,768), about 2.7 bytes a cell against 5. A
/// `VecDeque<u64>` took 16 bytes per cell (8 bytes, doubled capacity, and every page
/// touched as the ring turns).
struct CellQueue {
    /// Full blocks, oldest first.
    full: VecDeque<Block>,
    /// The block being filled.
    tail: Block,
    /// The next cell to pop (a byte offset in a run): in the front full block, or in
    /// `tail` when there is none.
    head: usize,
    /// In a run at the front: the place of the cell popped last (0 at its start).
    read_place: u32,
    /// In a run at the tail: the place of the cell pushed last (0 at its start).
    write_place: u32,
    /// The cells a plain tail holds, 0 for a run (so that [`CellQueue::push`] tests one
    /// length for both a full tail and a run).
    plain_room: usize,
    /// An emptied block, kept for the next one needed.
    spare: Option<Block>,
}

/// A block of [`CellQueue`], in an anonymous mapping of its own, so that an emptied block
/// goes back to the system (as small heap blocks they stayed with the allocator after the
/// pairs, and the lists of the cells left were allocated beside them: a random 64^4 image
/// peaked at 163-204 MB from run to run, 154 MB with blocks of their own, issue 18).
/// Plain: `len` cells, their places (four bytes each) from the start, their codes (a byte
/// each) after [`CellQueue::BLOCK`] places. A run: `len` bytes of steps and codes
/// ([`Block::push_run`] for a scan's, [`Block::push_near`] for candidates).
struct Block {
    map: memmap2::MmapMut,
    len: usize,
    kind: Kind,
}

/// How a [`Block`] holds its cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// Four bytes of place and one of code a cell.
    Plain,
    /// A run of a scan ([`Block::push_run`]).
    Scan,
    /// A run of candidates ([`Block::push_near`]).
    Near,
}

impl Block {
    /// Bytes a block holds.
    const BYTES: usize = 5 * CellQueue::BLOCK;
    /// The step that stands for a step of four bytes after it.
    const FAR: u8 = 15;

    fn new() -> Block {
        let map = memmap2::MmapMut::map_anon(Block::BYTES)
            .unwrap_or_else(|error| panic!("no memory for the reduction's queue: {error}"));
        Block {
            map,
            len: 0,
            kind: Kind::Plain,
        }
    }

    #[inline(always)]
    fn push(&mut self, place: u32, code: u8) {
        let at = self.len;
        self.map[4 * at..4 * at + 4].copy_from_slice(&place.to_ne_bytes());
        self.map[4 * CellQueue::BLOCK + at] = code;
        self.len += 1;
    }

    #[inline(always)]
    fn get(&self, at: usize) -> (u32, u8) {
        let place = self.map[4 * at..4 * at + 4]
            .try_into()
            .map(u32::from_ne_bytes)
            .expect("four bytes");
        (place, self.map[4 * CellQueue::BLOCK + at])
    }

    /// Appends to a run a cell `step` places after the one before (wrapping), with code
    /// `code` (below 16): one byte, the step times 16 plus the code, when the step is
    /// below [`Block::FAR`]; else [`Block::FAR`] times 16 plus the code, then the step's
    /// four bytes. The caller leaves room for five bytes.
    #[inline]
    fn push_run(&mut self, step: u32, code: u8) {
        let at = self.len;
        if step < Block::FAR as u32 {
            self.map[at] = (step as u8) << 4 | code;
            self.len += 1;
        } else {
            self.map[at] = Block::FAR << 4 | code;
            self.map[at + 1..at + 5].copy_from_slice(&step.to_ne_bytes());
            self.len += 5;
        }
    }

    /// Appends to a run of candidates a cell `step` places after the one before (wrapping,
    /// as a signed step), with code `code` (below 32): a byte of the code and of how many
    /// bytes the step takes, zigzag-coded (0 to 4, least significant first), then those
    /// bytes. The caller leaves room for five bytes.
    #[inline]
    fn push_near(&mut self, step: u32, code: u8) {
        let at = self.len;
        let step = step as i32;
        let zigzag = (step << 1 ^ step >> 31) as u32;
        let bytes = (32 - zigzag.leading_zeros()).div_ceil(8) as usize;
        self.map[at] = code | (bytes as u8) << 5;
        self.map[at + 1..at + 5].copy_from_slice(&zigzag.to_le_bytes());
        self.len += 1 + bytes;
    }

    /// The step, the code and the bytes of the candidates' cell at byte `at`.
    #[inline(always)]
    fn get_near(&self, at: usize) -> (u32, u8, usize) {
        let byte = self.map[at];
        let bytes = (byte >> 5) as usize;
        let word = self.map[at + 1..at + 5]
            .try_into()
            .map(u32::from_le_bytes)
            .expect("four bytes");
        let zigzag = (word as u64 & ((1u64 << (8 * bytes)) - 1)) as u32;
        let step = (zigzag >> 1) as i32 ^ -((zigzag & 1) as i32);
        (step as u32, byte & 31, 1 + bytes)
    }

    /// The step, the code and the bytes of the run's cell at byte `at`.
    #[inline(always)]
    fn get_run(&self, at: usize) -> (u32, u8, usize) {
        let byte = self.map[at];
        let code = byte & 15;
        if byte >> 4 != Block::FAR {
            return ((byte >> 4) as u32, code, 1);
        }
        let step = self.map[at + 1..at + 5]
            .try_into()
            .map(u32::from_ne_bytes)
            .expect("four bytes");
        (step, code, 5)
    }
}

impl Default for CellQueue {
    fn default() -> CellQueue {
        CellQueue {
            full: VecDeque::new(),
            tail: Block::new(),
            head: 0,
            read_place: 0,
            write_place: 0,
            plain_room: CellQueue::BLOCK,
            spare: None,
        }
    }
}

impl CellQueue {
    const BLOCK: usize = 1 << 16;

    /// Full blocks from which a queue keeps its candidates as runs ([`Kind::Near`]),
    /// until it runs empty: a smooth image's queue never holds that many.
    const NEAR_FROM: usize = 8;

    #[inline]
    fn push(&mut self, owner: usize, code: u32) {
        if self.tail.len < self.plain_room {
            self.tail.push(owner as u32, code as u8);
        } else {
            self.push_other(owner, code);
        }
    }

    /// [`CellQueue::push`] when the tail is full or not plain.
    #[cold]
    #[inline(never)]
    fn push_other(&mut self, owner: usize, code: u32) {
        let place = owner as u32;
        if self.tail.kind == Kind::Near && self.tail.len + 5 <= Block::BYTES {
            self.tail
                .push_near(place.wrapping_sub(self.write_place), code as u8);
            self.write_place = place;
            return;
        }
        let kind = if self.tail.kind == Kind::Near || self.full.len() >= Self::NEAR_FROM {
            Kind::Near
        } else {
            Kind::Plain
        };
        self.start_block(kind);
        self.push(owner, code);
    }

    /// [`CellQueue::push`] for cells found in increasing order of place (any order is
    /// right, that one is compact): `code` is below 16 (not [`COREDUCIBLE`]).
    #[inline]
    fn push_scanned(&mut self, owner: usize, code: u32) {
        debug_assert!(code < 16);
        if self.tail.kind != Kind::Scan || self.tail.len + 5 > Block::BYTES {
            self.start_block(Kind::Scan);
        }
        let place = owner as u32;
        self.tail
            .push_run(place.wrapping_sub(self.write_place), code as u8);
        self.write_place = place;
    }

    /// Pushes the cells of `other`, in its order.
    fn append(&mut self, mut other: CellQueue) {
        while let Some((owner, code)) = other.pop() {
            self.push(owner, code);
        }
    }

    /// Files the tail block, unless it is empty, and starts another of kind `kind`.
    #[cold]
    fn start_block(&mut self, kind: Kind) {
        if self.tail.len > 0 {
            let block = self.spare.take().unwrap_or_else(Block::new);
            let full = std::mem::replace(&mut self.tail, block);
            self.full.push_back(full);
        }
        self.tail.kind = kind;
        self.plain_room = match kind {
            Kind::Plain => Self::BLOCK,
            Kind::Scan | Kind::Near => 0,
        };
        self.write_place = 0;
    }

    /// [`CellQueue::pop`] from a run of candidates at the front (not empty there). Out of
    /// line, as is [`CellQueue::push_other`]: a smooth image's queue never holds such a
    /// run, and with both in the reduction's loop it took 1.7% more instructions.
    #[inline(never)]
    fn pop_near(&mut self) -> (usize, u32) {
        let block = self.full.front().unwrap_or(&self.tail);
        let (step, code, bytes) = block.get_near(self.head);
        self.head += bytes;
        self.read_place = self.read_place.wrapping_add(step);
        (self.read_place as usize, code as u32)
    }

    // Always inlined: the reduction's loop is large enough that it was not, which cost
    // 3% of a random 24^4 image's instructions.
    #[inline(always)]
    fn pop(&mut self) -> Option<(usize, u32)> {
        loop {
            let block = self.full.front().unwrap_or(&self.tail);
            if self.head < block.len {
                let (step, code, bytes) = match block.kind {
                    Kind::Plain => {
                        let (place, code) = block.get(self.head);
                        self.head += 1;
                        return Some((place as usize, code as u32));
                    }
                    Kind::Scan => block.get_run(self.head),
                    Kind::Near => return Some(self.pop_near()),
                };
                self.head += bytes;
                self.read_place = self.read_place.wrapping_add(step);
                return Some((self.read_place as usize, code as u32));
            }
            self.head = 0;
            self.read_place = 0;
            match self.full.pop_front() {
                // A used-up full block is kept for reuse; the tail comes next.
                Some(mut block) => {
                    block.len = 0;
                    self.spare = Some(block);
                }
                // The tail is used up too: the queue is empty, and the tail fills again
                // from its start.
                None => {
                    self.tail.len = 0;
                    self.write_place = 0;
                    if self.tail.kind == Kind::Near {
                        self.start_block(Kind::Plain);
                    }
                    return None;
                }
            }
        }
    }
}

/// Marks a queued cell as queued for a coreduction (one alive facet); a cell without it
/// was queued as a free face (one alive cofacet). Above the four bits of a code.
const COREDUCIBLE: u32 = 16;

#[inline]
fn cell(owner: usize, code: u32) -> u64 {
    (owner as u64) << 4 | code as u64
}

#[inline]
fn split(cell: u64) -> (usize, u32) {
    ((cell >> 4) as usize, (cell & 15) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::complex::CellComplex;
    use bettimill_grid::BinaryImage;

    /// A square ring of voxels in a plane of a 3D image: one loop.
    fn ring() -> BinaryImage {
        let mut image = BinaryImage::zeros(&[7, 7, 7]).unwrap();
        for i in 1..6 {
            image.set(&[3, 1, i], true);
            image.set(&[3, 5, i], true);
            image.set(&[3, i, 1], true);
            image.set(&[3, i, 5], true);
        }
        image
    }

    #[test]
    fn reduction_pairs_keep_homology() {
        let image = ring();
        assert_eq!(
            CellComplex::of_image(&image).betti_by_boundaries(),
            vec![1, 1, 0, 0]
        );
        assert_eq!(
            DenseComplex::of_image(&image)
                .betti_with(1, FinalRank::Elimination)
                .unwrap()
                .0,
            vec![1, 1, 0, 0]
        );
        let empty = BinaryImage::zeros(&[4, 4, 4, 4]).unwrap();
        assert_eq!(
            DenseComplex::of_image(&empty)
                .betti_with(0, FinalRank::Elimination)
                .unwrap()
                .0,
            vec![0; 5]
        );
    }

    /// `coords` inverts `place` on a grid whose sides are not multiples of the brick, and
    /// the first coreduction wave's vertex is the one nearest the centre, not the first
    /// owner.
    #[test]
    fn places_invert_and_the_first_wave_starts_at_the_centre() {
        let shape = [9, 6, 7, 5];
        let grid = *DenseComplex::new(&shape).unwrap().grid();
        let mut seen = std::collections::BTreeSet::new();
        for index in 0..shape.iter().product::<usize>() {
            let mut rest = index;
            let mut coords = [0usize; 4];
            for axis in (0..4).rev() {
                coords[axis] = rest % shape[axis];
                rest /= shape[axis];
            }
            let place = grid.place(&coords);
            assert!(seen.insert(place), "{coords:?}");
            assert_eq!(grid.coords(place), coords);
        }
        // Three voxels: two at the ends of the first axis, one in the middle. A voxel's
        // own vertex (every code axis even) is its far corner.
        let mut image = BinaryImage::zeros(&[11, 5, 5, 5]).unwrap();
        for x in [1, 5, 9] {
            image.set(&[x, 2, 2, 2], true);
        }
        let mut complex = DenseComplex::of_image(&image);
        let Owners::Listed(list) = &complex.owners else {
            panic!("of_image lists the owners");
        };
        let first = list[0];
        let owners = Owners::Listed(list.clone());
        let places = complex.places;
        let view = complex.view();
        let centre = view.doubled_centre(0..places);
        let grid = view.grid;
        let centre = view
            .cells::<false>()
            .central_vertex(&owners, &(0..usize::MAX), centre)
            .expect("vertices are alive");
        let c = grid.coords(centre);
        // The middle voxel's corners are owned by it or by its neighbours one step back.
        assert!((4..=5).contains(&c[0]), "{c:?}");
        assert_eq!(first as usize, grid.place(&[1, 2, 2, 2]));
    }

    /// Grids whose places fit 32 bits are accepted, larger ones (and shapes whose product
    /// overflows) are an error, not a wrong place.
    #[test]
    fn grids_over_32_bit_places_are_refused() {
        assert_eq!(check_grid(&[256; 4]), Ok(1 << 32));
        assert_eq!(check_grid(&[253, 254, 255, 256]), Ok(1 << 32));
        assert_eq!(
            check_grid(&[257, 256, 256, 256]),
            Err(GridTooLarge {
                places: 260 * 256 * 256 * 256
            })
        );
        assert_eq!(
            check_grid(&[usize::MAX / 2; 4]),
            Err(GridTooLarge { places: u64::MAX })
        );
        // The largest 4D cube manifests accept fits with its border; one more does not.
        let side = crate::MAX_4D_SIDE;
        assert!(check_grid(&[side + 2; 4]).is_ok());
        assert!(check_grid(&[side + 3; 4]).is_err());
        assert!(DenseComplex::new(&[300; 4]).is_err());
    }

    /// The reduction's cut: the middle of even weights, never an end unit, and off a heavy
    /// unit that would leave one part most of the work, by the seam's share.
    #[test]
    fn the_cheapest_seam_spares_the_parts_a_heavy_unit() {
        let half = |weights: &[usize], share| {
            Halves::cheapest(0..10 * weights.len(), 10, weights, share).map(|h| h.half)
        };
        for share in [SeamShare::Half, SeamShare::Whole] {
            // Even weights: the middle; too few units or no weight: no cut.
            assert_eq!(half(&[5; 7], share), Some(3));
            assert_eq!(half(&[5; 8], share), Some(3));
            assert_eq!(half(&[5, 5], share), None);
            assert_eq!(half(&[0; 5], share), None);
            // Never an end unit, however the weight lies.
            assert_eq!(half(&[100, 1, 1, 1], share), Some(1));
            assert_eq!(half(&[1, 1, 1, 100], share), Some(2));
        }
        // A 32^4 blob's owners by brick row: the weight passes half in the heavy unit 4,
        // which would leave the parts 12,671 and 3,858; seam 3 leaves them 6,797 and
        // 13,229 and the seam 5,874, half of it after them.
        let blob = [816, 2018, 3963, 5874, 9371, 1712, 1575, 550, 21];
        assert_eq!(half(&blob, SeamShare::Half), Some(3));
        // A heavy unit in the middle with light parts around it is still the seam when
        // its share is a half, not when it is reduced alone.
        let heavy = [1, 7, 30, 7, 12, 1];
        assert_eq!(half(&heavy, SeamShare::Half), Some(2));
        assert_eq!(half(&heavy, SeamShare::Whole), Some(3));
    }

    /// A queue of cells gives them back in the order they came, across blocks, plain and
    /// runs of both kinds, with pops between the pushes and after it ran empty.
    #[test]
    fn the_cell_queue_is_first_in_first_out() {
        let mut queue = CellQueue::default();
        let mut expected = VecDeque::new();
        let (mut next, mut place) = (0usize, 0usize);
        for round in 0..9 {
            for _ in 0..(round * 7919) % (3 * CellQueue::BLOCK) + 1 {
                if round % 3 == 0 {
                    queue.push(next, (next % 32) as u32);
                    expected.push_back((next, (next % 32) as u32));
                } else {
                    // Runs: steps of 0 to 36 places (15 and more are far), and now and
                    // then back.
                    place = match next % 97 {
                        0 => place / 2,
                        _ => place + next % 37,
                    };
                    queue.push_scanned(place, (next % 16) as u32);
                    expected.push_back((place, (next % 16) as u32));
                }
                next += 1;
            }
            for _ in 0..(round * 5003) % (2 * CellQueue::BLOCK) {
                assert_eq!(queue.pop(), expected.pop_front());
            }
        }
        while let Some(cell) = expected.pop_front() {
            assert_eq!(queue.pop(), Some(cell));
        }
        assert_eq!(queue.pop(), None);
        // A queue of more than `NEAR_FROM` full blocks keeps its later cells as runs of
        // candidates: steps of every length both ways, every code with the coreduction
        // bit, places up to the last 32-bit one.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut place = 1usize << 31;
        for round in 0..4 {
            for _ in 0..(CellQueue::NEAR_FROM + 3) * CellQueue::BLOCK / (round + 1) {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let step = match state % 5 {
                    0 => 0,
                    1 => state >> 40 & 0xff,
                    2 => state >> 40 & 0xffff,
                    3 => state >> 40 & 0xff_ffff,
                    _ => state >> 32,
                } as usize;
                place = match state >> 3 & 1 {
                    0 => place.wrapping_add(step),
                    _ => place.wrapping_sub(step),
                } & 0xffff_ffff;
                let code = (state >> 8 & 31) as u32;
                queue.push(place, code);
                expected.push_back((place, code));
            }
            for _ in 0..expected.len() / 2 {
                assert_eq!(queue.pop(), expected.pop_front());
            }
        }
        assert!(queue.full.iter().any(|block| block.kind == Kind::Near));
        while let Some(cell) = expected.pop_front() {
            assert_eq!(queue.pop(), Some(cell));
        }
        assert_eq!(queue.pop(), None);
        // A run again in the emptied tail (a run too).
        queue.push_scanned(5, 1);
        queue.push_scanned(6, 2);
        assert_eq!(queue.pop(), Some((5, 1)));
        assert_eq!(queue.pop(), Some((6, 2)));
        assert_eq!(queue.pop(), None);
        queue.push(7, 3);
        assert_eq!(queue.pop(), Some((7, 3)));
        assert_eq!(queue.pop(), None);
    }

    /// A cell's rank from [`Ranks`] is its place in the list of the cells of its codes, in
    /// order of place and code, on masks of every density and length.
    #[test]
    fn ranks_count_the_cells_before() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for (len, density) in [(1, 8), (15, 2), (16, 8), (17, 16), (100, 1), (1000, 4)] {
            let masks: Vec<AtomicU16> = (0..len)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    AtomicU16::new((state as u16) & (state >> 16) as u16 | (density << 3))
                })
                .collect();
            for codes in [0x0001u16, 0x0116, 0x6a80, 0xffff] {
                let ranks = Ranks::new(&masks, codes);
                let mut n = 0;
                for (o, mask) in masks.iter().enumerate() {
                    let mask = mask.load(Relaxed) & codes;
                    for code in (0..16).filter(|&c| mask >> c & 1 == 1) {
                        assert_eq!(ranks.rank(&masks, o, code), n, "{len} {codes:#x} {o}");
                        n += 1;
                    }
                }
            }
        }
    }

    /// Every cell has one owner: a voxel's closure is 3^d distinct cells, and the closures
    /// of two face-adjacent voxels share exactly 3^(d-1).
    #[test]
    fn owners_name_each_cell_once() {
        for d in 2..=4 {
            let mut image = BinaryImage::zeros(&vec![5; d]).unwrap();
            let mut centre = vec![2; d];
            image.set(&centre, true);
            let count = |image: &BinaryImage| -> u32 {
                let mut complex = DenseComplex::of_image(image);
                complex.masks.get_mut().iter().map(|m| m.count_ones()).sum()
            };
            assert_eq!(count(&image), 3u32.pow(d as u32), "{d}D");
            centre[d - 1] = 3;
            image.set(&centre, true);
            assert_eq!(
                count(&image),
                2 * 3u32.pow(d as u32) - 3u32.pow(d as u32 - 1)
            );
        }
    }

    /// The reduction split (two parts on two threads, then the seam row's two parts, then
    /// the last seam) against the same reduction unsplit and against plain boundary ranks,
    /// on random 4D images long enough to split, sparse to dense, and on a loop that
    /// crosses the seams; every split row from the first possible to the last, with and
    /// without the seam row's own split. And the parts never meet: run one after the other
    /// in either order, they leave the same cells.
    #[test]
    fn split_reductions_agree_with_boundary_ranks() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(44);
        // Seven brick rows along the first axis, three brick columns along the second.
        let shape = [28, 10, 5, 5];
        let mut images = Vec::new();
        for trial in 0..24 {
            let density = 0.15 + 0.7 * trial as f64 / 23.0;
            let mut image = BinaryImage::zeros(&shape).unwrap();
            for index in 0..image.len() {
                let c = image.coords(index);
                if (0..4).all(|a| c[a] > 0 && c[a] + 1 < shape[a]) {
                    image.data_mut()[index] = rng.gen_bool(density) as u8;
                }
            }
            images.push(image);
        }
        // A rectangle loop in the plane of the first two axes, across every split point.
        let mut ring = BinaryImage::zeros(&shape).unwrap();
        for x in 2..26 {
            ring.set(&[x, 1, 2, 2], true);
            ring.set(&[x, 8, 2, 2], true);
        }
        for y in 1..9 {
            ring.set(&[2, y, 2, 2], true);
            ring.set(&[25, y, 2, 2], true);
        }
        images.push(ring);
        let mut checked = 0;
        for (trial, image) in images.iter().enumerate() {
            let b0 = crate::components::count_components(image, 1);
            let expected = CellComplex::of_image(image).betti_by_boundaries();
            let mut whole = DenseComplex::of_image(image);
            let row = whole.grid.brick_step[0];
            let everywhere = 0..whole.places;
            let weights = whole.weights(&everywhere, row);
            let balanced = Halves::cheapest(everywhere.clone(), row, &weights, SeamShare::Half)
                .expect("seven brick rows split");
            assert!(balanced.half >= 1 && balanced.half <= 5);
            let splits: Vec<Split> = (1..=5)
                .flat_map(|half| [None, Some(1)].map(|column| whole.split_at(half, column)))
                .collect();
            assert_eq!(
                whole
                    .betti_split(b0, FinalRank::Elimination, None)
                    .unwrap()
                    .0,
                expected,
                "trial {trial} unsplit"
            );
            // Owners listed and scanned (the order of the vertices and free faces
            // differs, the Betti numbers do not).
            let both = splits
                .iter()
                .flat_map(|&split| [(split, true), (split, false)]);
            for (split, listed) in both {
                let (half, column) = (split.rows.half, split.columns.map(|c| c.half));
                let found = DenseComplex::of_image_with(image, listed)
                    .betti_split(b0, FinalRank::Elimination, Some(split))
                    .unwrap()
                    .0;
                let case = format!("trial {trial} split at {half}, {column:?}, listed {listed}");
                assert_eq!(found, expected, "{case}");
                // The parts never meet: in either order they leave the same cells, and
                // the same cells queued.
                let [lower_first, upper_first] =
                    [Order::LowerFirst, Order::UpperFirst].map(|order| {
                        let mut complex = DenseComplex::of_image_with(image, listed);
                        let owners = std::mem::replace(&mut complex.owners, Owners::Scanned);
                        let (mut left, seam, removed) =
                            complex.view().reduce_parts(&owners, split, order);
                        let mut queued = Vec::new();
                        while let Some(cell) = left.pop() {
                            queued.push(cell);
                        }
                        let masks: Vec<u16> = complex.masks.get_mut().to_vec();
                        (masks, queued, seam, removed)
                    });
                assert!(lower_first == upper_first, "{case}");
                checked += 1;
            }
        }
        assert_eq!(checked, 2 * 10 * 25);
        // Both parts start a wave of their own on the ring, and the seam joins them.
        assert_eq!(
            CellComplex::of_image(&images[24]).betti_by_boundaries(),
            vec![1, 1, 0, 0, 0]
        );
    }

    /// Reduction pairs against plain boundary ranks on random complexes of every dimension,
    /// sparse to dense, including several components (so several vertices are removed) and
    /// checkerboards (only corner contacts).
    #[test]
    fn reduction_agrees_with_boundary_ranks_on_random_complexes() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
        for (d, side, n) in [(2, 9, 400), (3, 6, 400), (4, 4, 300), (4, 5, 60)] {
            for trial in 0..n {
                let shape = vec![side + 2; d];
                let mut image = BinaryImage::zeros(&shape).unwrap();
                let density: f64 = rng.gen_range(0.05..0.95);
                let checker = trial % 10 == 0;
                for index in 0..image.len() {
                    let c = image.coords(index);
                    if c[..d].iter().any(|&x| x == 0 || x == side + 1) {
                        continue;
                    }
                    let on = if checker {
                        c[..d].iter().sum::<usize>() % 2 == 0 || rng.gen_bool(0.1)
                    } else {
                        rng.gen_bool(density)
                    };
                    image.data_mut()[index] = on as u8;
                }
                let b0 = crate::components::count_components(&image, 1);
                let expected = CellComplex::of_image(&image).betti_by_boundaries();
                let routes = [FinalRank::Elimination, FinalRank::ColumnReduction]
                    .into_iter()
                    .flat_map(|rank| [(rank, true), (rank, false)]);
                for (final_rank, listed) in routes {
                    assert_eq!(
                        DenseComplex::of_image_with(&image, listed)
                            .betti_with(b0, final_rank)
                            .unwrap()
                            .0,
                        expected,
                        "{d}D trial {trial}, density {density:.2}, {final_rank:?}, \
                         listed {listed}"
                    );
                }
            }
        }
    }
}
