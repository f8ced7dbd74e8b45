//! Z/2 rank of a large sparse matrix by Gaussian elimination with pivots chosen to keep the
//! fill-in small: the final step of the fast path (`crate::dense`), on the cells that
//! reduction pairs could not remove.
//!
//! Plain left-to-right column reduction (`crate::complex::z2_rank`, the oracle's) takes the
//! pivots in a fixed order and on a large remnant (a foam of 2-cycles, as thinning leaves
//! of a random 4D image: over a million edges and squares) its columns fill in
//! quadratically. Here pivots are taken where they cost nothing first, as the reduction
//! pairs do, and only when none is left where they cost least:
//! - a column with one entry (a cell with one facet left: a coreduction) or a row with one
//!   entry (a facet with one cofacet left: a collapse) is a pivot whose row and column can
//!   simply be deleted: rank(M) = 1 + rank(M without them);
//! - otherwise the column with fewest entries is the pivot column and its row with fewest
//!   entries the pivot row (Markowitz's rule, approximately): the other columns through that
//!   row absorb the pivot column, after which the row has one entry.
//!
//! The matrix left after each step is the Schur complement of the pivots taken so far, so the
//! rank is the number of pivots, and the pivot rows and columns index a nonsingular
//! submatrix. That is what clearing needs: if the pivot rows R of the boundary of the
//! (k+1)-cells index such a submatrix, then for each r in R some boundary meets R only in r,
//! so the boundary column of the k-cell r is a sum of the columns outside R and can be
//! skipped.

/// What [`rank_by_elimination`] found.
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct Elimination {
    /// The rank over Z/2.
    pub(crate) rank: u64,
    /// The pivot rows, ascending.
    pub(crate) pivots: Vec<u32>,
    /// How many pivots were not free (a column and a row of two entries or more), so
    /// cost fill-in; tests check that they exercise this case.
    pub(crate) general: u64,
}

/// The rank over Z/2 of the matrix with the given columns (each a sorted list of distinct
/// row indices below `n_rows`), and the pivot rows.
pub(crate) fn rank_by_elimination(mut columns: Vec<Vec<u32>>, n_rows: usize) -> Elimination {
    let mut rows: Vec<Vec<u32>> = vec![Vec::new(); n_rows];
    for (j, column) in columns.iter().enumerate() {
        debug_assert!(column.windows(2).all(|w| w[0] < w[1]), "sorted, distinct");
        for &r in column {
            rows[r as usize].push(j as u32);
        }
    }
    let mut single_columns: Vec<u32> = Vec::new();
    let mut heap = Buckets::default();
    for (j, column) in columns.iter().enumerate() {
        match column.len() {
            0 => {}
            1 => single_columns.push(j as u32),
            n => heap.push(n, j as u32),
        }
    }
    let mut single_rows: Vec<u32> = (0..n_rows as u32)
        .filter(|&r| rows[r as usize].len() == 1)
        .collect();
    let mut is_pivot_row = vec![false; n_rows];
    let mut rank = 0u64;
    let mut merged: Vec<u32> = Vec::new();
    let mut general = 0u64;
    loop {
        if let Some(c) = single_columns.pop() {
            let c = c as usize;
            if columns[c].len() != 1 {
                continue;
            }
            // The column is e_r: it clears row r from every other column.
            let r = columns[c][0] as usize;
            columns[c].clear();
            rank += 1;
            is_pivot_row[r] = true;
            for x in std::mem::take(&mut rows[r]) {
                let x = x as usize;
                if x == c {
                    continue;
                }
                let column = &mut columns[x];
                let at = column
                    .binary_search(&(r as u32))
                    .expect("row and column lists agree");
                column.remove(at);
                note_column(x, column.len(), &mut single_columns, &mut heap);
            }
            continue;
        }
        if let Some(r) = single_rows.pop() {
            let r = r as usize;
            if rows[r].len() != 1 {
                continue;
            }
            // The row is e_c: column c goes, with every entry it had.
            let c = rows[r][0] as usize;
            rank += 1;
            is_pivot_row[r] = true;
            for s in std::mem::take(&mut columns[c]) {
                remove_from_row(&mut rows[s as usize], c as u32);
                if rows[s as usize].len() == 1 {
                    single_rows.push(s);
                }
            }
            continue;
        }
        let Some((degree, c)) = heap.pop() else {
            break;
        };
        let c = c as usize;
        if columns[c].len() != degree as usize {
            // A stale entry: the column changed (and was queued again) or went.
            continue;
        }
        let r = *columns[c]
            .iter()
            .min_by_key(|&&s| (rows[s as usize].len(), s))
            .expect("a column in the heap has entries") as usize;
        let pivot = std::mem::take(&mut columns[c]);
        general += 1;
        let others: Vec<u32> = rows[r]
            .iter()
            .copied()
            .filter(|&x| x as usize != c)
            .collect();
        for x in others {
            // columns[x] += pivot, keeping the row lists in step.
            let column = &columns[x as usize];
            merged.clear();
            let (mut i, mut j) = (0, 0);
            while i < column.len() && j < pivot.len() {
                let (a, b) = (column[i], pivot[j]);
                if a < b {
                    merged.push(a);
                    i += 1;
                } else if b < a {
                    merged.push(b);
                    rows[b as usize].push(x);
                    j += 1;
                } else {
                    remove_from_row(&mut rows[a as usize], x);
                    i += 1;
                    j += 1;
                }
            }
            merged.extend_from_slice(&column[i..]);
            for &b in &pivot[j..] {
                merged.push(b);
                rows[b as usize].push(x);
            }
            std::mem::swap(&mut columns[x as usize], &mut merged);
            note_column(
                x as usize,
                columns[x as usize].len(),
                &mut single_columns,
                &mut heap,
            );
        }
        // Row r now meets only column c: delete both.
        rank += 1;
        is_pivot_row[r] = true;
        for s in pivot {
            remove_from_row(&mut rows[s as usize], c as u32);
            if rows[s as usize].len() == 1 {
                single_rows.push(s);
            }
        }
    }
    let pivots = (0..n_rows as u32)
        .filter(|&r| is_pivot_row[r as usize])
        .collect();
    Elimination {
        rank,
        pivots,
        general,
    }
}

/// Queues column `x`, now with `len` entries, where it belongs.
fn note_column(x: usize, len: usize, single_columns: &mut Vec<u32>, heap: &mut Buckets) {
    match len {
        0 => {}
        1 => single_columns.push(x as u32),
        n => heap.push(n, x as u32),
    }
}

/// Columns by their number of entries when queued (a bucket queue: entries go stale when
/// the column changes, and are checked when taken). First in, first out within a bucket.
#[derive(Default)]
struct Buckets {
    buckets: Vec<std::collections::VecDeque<u32>>,
    /// No bucket below this one holds anything.
    lowest: usize,
}

impl Buckets {
    fn push(&mut self, degree: usize, column: u32) {
        if self.buckets.len() <= degree {
            self.buckets.resize_with(degree + 1, Default::default);
        }
        self.buckets[degree].push_back(column);
        self.lowest = self.lowest.min(degree);
    }

    fn pop(&mut self) -> Option<(u32, u32)> {
        while self.lowest < self.buckets.len() {
            if let Some(column) = self.buckets[self.lowest].pop_front() {
                return Some((self.lowest as u32, column));
            }
            self.lowest += 1;
        }
        None
    }
}

fn remove_from_row(row: &mut Vec<u32>, column: u32) {
    let at = row
        .iter()
        .position(|&x| x == column)
        .expect("row and column lists agree");
    row.swap_remove(at);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::complex::z2_rank;
    use rand::{Rng, SeedableRng};

    #[test]
    fn small_matrices() {
        let rank = |columns: Vec<Vec<u32>>, n_rows| rank_by_elimination(columns, n_rows).rank;
        // Columns {0,1}, {1,2}, {0,2}: a cycle, no free pivot (two general ones: the first
        // leaves two equal columns), and dependent over Z/2.
        let cycle = rank_by_elimination(vec![vec![0, 1], vec![1, 2], vec![0, 2]], 3);
        assert_eq!((cycle.rank, cycle.general), (2, 2));
        assert_eq!(rank(vec![vec![0], vec![1], vec![2]], 3), 3);
        assert_eq!(rank(vec![vec![0, 1, 2], vec![0, 1, 2]], 3), 1);
        assert_eq!(
            rank_by_elimination(vec![vec![], vec![1]], 3),
            Elimination {
                rank: 1,
                pivots: vec![1],
                general: 0
            }
        );
        assert_eq!(rank(Vec::new(), 0), 0);
    }

    /// Against plain column reduction on random matrices from sparse (mostly peeling) to
    /// dense (mostly general pivots), square and not, with duplicate and zero columns; the
    /// pivot rows must index a nonsingular submatrix (the rows alone have full rank).
    #[test]
    fn agrees_with_column_reduction_on_random_matrices() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut general = 0;
        for trial in 0..3000 {
            let n_rows = rng.gen_range(0..40);
            let n_cols = rng.gen_range(0..40);
            let p: f64 = rng.gen_range(0.02..0.6);
            let mut columns: Vec<Vec<u32>> = (0..n_cols)
                .map(|_| {
                    (0..n_rows as u32)
                        .filter(|_| rng.gen_bool(p))
                        .collect::<Vec<u32>>()
                })
                .collect();
            if n_cols > 2 && trial % 3 == 0 {
                columns[1] = columns[0].clone();
            }
            let (expected, _) = z2_rank(columns.clone(), n_rows);
            let found = rank_by_elimination(columns.clone(), n_rows);
            general += found.general;
            let (rank, pivots) = (found.rank, found.pivots);
            assert_eq!(rank, expected, "trial {trial}");
            assert_eq!(pivots.len() as u64, rank, "trial {trial}");
            // The pivot rows of the matrix keep its rank: the transpose restricted to
            // them has full row rank, i.e. rank(M[R, :]) = |R|.
            let restricted: Vec<Vec<u32>> = columns
                .iter()
                .map(|column| {
                    column
                        .iter()
                        .filter_map(|r| pivots.binary_search(r).ok().map(|i| i as u32))
                        .collect()
                })
                .collect();
            assert_eq!(z2_rank(restricted, pivots.len()).0, rank, "trial {trial}");
        }
        assert!(general > 10_000, "only {general} general pivots");
    }
}
