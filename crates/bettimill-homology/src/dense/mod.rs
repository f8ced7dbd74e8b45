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
//! centre of the grid: started from a corner, the waves stall on a random 4D image with
//! many times the cells; on a grid large enough, one start per part of the grid,
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
//! stall with over a million edges and squares left on a random 4D image, where a plain
//! column reduction fills in quadratically.
//!
//! [`crate::reference`] reduces the plain boundary matrices of the whole, unreduced complex
//! (`CellComplex::betti_by_boundaries`), so the two check each other.

mod grid;
mod masks;
mod queue;
mod ranks;
mod reduce;
#[cfg(test)]
pub(crate) mod seams;
mod split_plan;
#[cfg(test)]
mod tests;

#[cfg(doc)]
use crate::eliminate::rank_by_elimination;
use crate::eliminate::{Elimination, Lists, PoolOverflow};
use grid::{cell, split};
pub(crate) use grid::{check_grid, Grid, GridTooLarge};
use masks::Masks;
use queue::CellQueue;
use ranks::Ranks;
use reduce::{Cells, View};
use split_plan::{Parallel, Split};
use std::sync::atomic::{AtomicU16, Ordering::Relaxed};

/// How [`DenseComplex::betti_with`] ranks the boundary matrices of the cells that the
/// reduction pairs leave: from a matrix's columns and number of rows, its rank, pivot rows
/// and general pivots. [`crate::topology`] passes [`rank_by_elimination`] (free pivots
/// first); tests also pass the oracle's plain column reduction
/// (`seams::column_reduction`), to run both on the same images.
pub(crate) type FinalRank = fn(Lists, usize) -> Result<Elimination, PoolOverflow>;

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
    /// owners' masks afterwards would be slow: they are far apart).
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
                table[byte] += if (code as u32).count_ones().is_multiple_of(2) {
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
    if d.is_multiple_of(2) {
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
    /// image nearly every voxel owns cells, and a list would be four bytes a voxel, the
    /// largest part of the peak.
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
        Ok(DenseComplex {
            grid: Grid::new(shape, places),
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
    /// below counts anyway; where the waves of two parts meet, a few more cells stall, a
    /// small price for the second thread.
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
                let (mut left, seam, removed) = view.reduce_parts(&owners, split, Parallel);
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
        // place where a list takes eight bytes a cell. When they are few (a smooth image),
        // they are listed from the owners and sorted: a scan would cost more than the sort
        // (a large blob has millions of places and a few thousand cells left).
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
            let found = final_rank(columns, n_rows)?;
            general += found.general;
            let (r, pivots) = (found.rank, found.pivots);
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
