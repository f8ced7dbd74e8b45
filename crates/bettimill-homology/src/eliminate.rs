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

/// A pool of [`Lists`] would pass its limit of entries (2^32 - 1: places and lengths are
/// `u32`, 4 bytes per list instead of 8): one boundary matrix of some billion cells left by
/// the reduction pairs, an image of several hundred voxels a side. The rank is not
/// computed rather than computed wrong; [`crate::TopologyError::TooRough`] tells the caller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PoolOverflow {
    /// The entries the pool would have needed.
    pub(crate) needed: u64,
    /// Its limit.
    pub(crate) limit: u64,
}

/// The most entries a pool may hold: every place and length fits a `u32`.
#[cfg(not(test))]
fn pool_limit() -> usize {
    u32::MAX as usize
}

#[cfg(test)]
thread_local! {
    static POOL_LIMIT: std::cell::Cell<usize> = const { std::cell::Cell::new(u32::MAX as usize) };
}

/// The most entries a pool may hold: in tests, as [`with_pool_limit`] sets it on this thread
/// (the elimination runs on the caller's thread).
#[cfg(test)]
fn pool_limit() -> usize {
    POOL_LIMIT.with(|limit| limit.get())
}

/// Runs `f` with the pools' limit lowered to `limit` entries on this thread, so that the
/// overflow path is tested on small images.
#[cfg(test)]
pub(crate) fn with_pool_limit<T>(limit: usize, f: impl FnOnce() -> T) -> T {
    let old = POOL_LIMIT.with(|l| l.replace(limit));
    let out = f();
    POOL_LIMIT.with(|l| l.set(old));
    out
}

/// Checks that a pool of `n` entries is within the limit.
fn check_pool(n: usize) -> Result<(), PoolOverflow> {
    let limit = pool_limit();
    if n > limit {
        Err(PoolOverflow {
            needed: n as u64,
            limit: limit as u64,
        })
    } else {
        Ok(())
    }
}

/// Many short lists of `u32` in one pool: list i is `data[start[i]..start[i] + len[i]]`,
/// with room for `room(cap[i])` entries there (9 bytes of header per list: a place, a
/// length and a one-byte room code). A list that outgrows its room moves to the end of the
/// pool with twice the room (the old place is left unused). A `Vec` per list would cost a
/// 24-byte header and a heap block each, more than the entries of most lists here, and the
/// lists are the peak memory on a random 4D image. When the pool is full and at most half
/// of it holds entries (rooms left behind by moved lists, and lists emptied by the
/// elimination's pivots), it is compacted in place instead of grown, so it stays within
/// about twice the entries the lists hold at once.
#[derive(Debug, Default)]
pub(crate) struct Lists {
    data: Vec<u32>,
    start: Vec<u32>,
    len: Vec<u32>,
    cap: Vec<u8>,
    /// The entries the lists hold, in all.
    live: usize,
}

/// The room a code stands for: 0-127 exactly, 128 + e for 2^e.
#[inline]
fn room(code: u8) -> usize {
    if code < 128 {
        code as usize
    } else {
        1usize << (code - 128)
    }
}

/// The code of the least room of at least `n` entries (exact below 128, else a power of
/// two), and that room.
fn room_code(n: usize) -> (u8, usize) {
    if n < 128 {
        (n as u8, n)
    } else {
        let room = n.next_power_of_two();
        (128 + room.trailing_zeros() as u8, room)
    }
}

impl Lists {
    /// No lists yet, with room for `lists` lists of `entries` entries in all.
    pub(crate) fn with_capacity(lists: usize, entries: usize) -> Lists {
        Lists {
            data: Vec::with_capacity(entries),
            start: Vec::with_capacity(lists),
            len: Vec::with_capacity(lists),
            cap: Vec::with_capacity(lists),
            live: 0,
        }
    }

    /// Empty lists with room for `rooms[i]` entries each (rounded up to a room code), side
    /// by side.
    fn with_room(rooms: &[u32]) -> Result<Lists, PoolOverflow> {
        let mut start = Vec::with_capacity(rooms.len());
        let mut cap = Vec::with_capacity(rooms.len());
        let mut at = 0usize;
        for &n in rooms {
            check_pool(at)?;
            start.push(at as u32);
            let (code, room) = room_code(n as usize);
            cap.push(code);
            at += room;
        }
        check_pool(at)?;
        Ok(Lists {
            data: vec![0; at],
            start,
            len: vec![0; rooms.len()],
            cap,
            live: 0,
        })
    }

    /// Appends a list with the given entries (and that much room, rounded up to a room
    /// code).
    pub(crate) fn push_list(&mut self, entries: &[u32]) -> Result<(), PoolOverflow> {
        let at = self.data.len();
        let (code, room) = room_code(entries.len());
        check_pool(at + room)?;
        self.start.push(at as u32);
        self.len.push(entries.len() as u32);
        self.cap.push(code);
        self.data.extend_from_slice(entries);
        self.data.resize(at + room, 0);
        self.live += entries.len();
        Ok(())
    }

    /// Gives back the pool's unused capacity (after the lists are built).
    pub(crate) fn shrink_to_fit(&mut self) {
        self.data.shrink_to_fit();
    }

    /// The number of lists.
    pub(crate) fn count(&self) -> usize {
        self.start.len()
    }

    /// List i.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> &[u32] {
        let start = self.start[i] as usize;
        &self.data[start..start + self.len[i] as usize]
    }

    #[inline]
    fn len_of(&self, i: usize) -> usize {
        self.len[i] as usize
    }

    fn clear(&mut self, i: usize) {
        self.live -= self.len_of(i);
        self.len[i] = 0;
    }

    /// Copies list i into `out` (cleared first) and empties it.
    fn take_into(&mut self, i: usize, out: &mut Vec<u32>) {
        out.clear();
        out.extend_from_slice(self.get(i));
        self.clear(i);
    }

    /// Makes room for `n` entries in list i, moving it (with its entries) to the end of
    /// the pool if its place is too small.
    fn reserve(&mut self, i: usize, n: usize) -> Result<(), PoolOverflow> {
        if n <= room(self.cap[i]) {
            return Ok(());
        }
        let (code, cap) = room_code(n.max(2 * room(self.cap[i])).max(4));
        if self.data.capacity() < self.data.len() + cap && 2 * self.live <= self.data.len() {
            self.compact();
        }
        let (start, len) = (self.start[i] as usize, self.len_of(i));
        let at = self.data.len();
        check_pool(at + cap)?;
        // The pool grows by a quarter at a time, not the doubling of `Vec`: it is most of
        // the memory, and lists move rarely.
        if self.data.capacity() < at + cap {
            self.data
                .reserve_exact(cap.max(at / 4).min(pool_limit() - at).max(cap));
        }
        self.data.extend_from_within(start..start + len);
        self.data.resize(at + cap, 0);
        self.start[i] = at as u32;
        self.cap[i] = code;
        Ok(())
    }

    /// Moves every list to the front of the pool, in the order of their places, each with
    /// the least room that holds it (none for an empty list), and drops the rest: the rooms
    /// left behind by moved lists and those of emptied lists are free again (the
    /// allocation is kept, so the pool need not grow).
    fn compact(&mut self) {
        let mut order: Vec<u32> = (0..self.count() as u32)
            .filter(|&i| self.len[i as usize] > 0)
            .collect();
        order.sort_unstable_by_key(|&i| self.start[i as usize]);
        let mut at = 0usize;
        for &i in &order {
            let i = i as usize;
            let (start, len) = (self.start[i] as usize, self.len_of(i));
            // Places only move down (at <= start), so nothing unread is overwritten.
            self.data.copy_within(start..start + len, at);
            let (code, room) = room_code(len);
            self.start[i] = at as u32;
            self.cap[i] = code;
            at += room;
        }
        for i in 0..self.count() {
            if self.len[i] == 0 {
                self.start[i] = 0;
                self.cap[i] = 0;
            }
        }
        self.data.truncate(at);
    }

    /// Appends `value` to list i.
    #[inline]
    fn push(&mut self, i: usize, value: u32) -> Result<(), PoolOverflow> {
        let len = self.len_of(i);
        if len == room(self.cap[i]) {
            self.reserve(i, len + 1)?;
        }
        self.data[self.start[i] as usize + len] = value;
        self.len[i] += 1;
        self.live += 1;
        Ok(())
    }

    /// Replaces list i by `entries`.
    fn set(&mut self, i: usize, entries: &[u32]) -> Result<(), PoolOverflow> {
        self.clear(i);
        self.reserve(i, entries.len())?;
        let start = self.start[i] as usize;
        self.data[start..start + entries.len()].copy_from_slice(entries);
        self.len[i] = entries.len() as u32;
        self.live += entries.len();
        Ok(())
    }

    /// Removes `value` from the sorted list i, keeping it sorted.
    fn remove_sorted(&mut self, i: usize, value: u32) {
        let at = self
            .get(i)
            .binary_search(&value)
            .expect("row and column lists agree");
        let start = self.start[i] as usize;
        let len = self.len_of(i);
        self.data
            .copy_within(start + at + 1..start + len, start + at);
        self.len[i] -= 1;
        self.live -= 1;
    }

    /// Removes `value` from list i, moving its last entry into its place.
    fn swap_remove_value(&mut self, i: usize, value: u32) {
        let at = self
            .get(i)
            .iter()
            .position(|&x| x == value)
            .expect("row and column lists agree");
        let start = self.start[i] as usize;
        let last = start + self.len_of(i) - 1;
        self.data[start + at] = self.data[last];
        self.len[i] -= 1;
        self.live -= 1;
    }

    /// The lists as vectors (the oracle's column reduction takes those).
    #[cfg(test)]
    pub(crate) fn to_vecs(&self) -> Vec<Vec<u32>> {
        (0..self.count()).map(|i| self.get(i).to_vec()).collect()
    }

    /// Lists from vectors.
    #[cfg(test)]
    pub(crate) fn from_vecs(lists: &[Vec<u32>]) -> Lists {
        let mut out = Lists::default();
        for list in lists {
            out.push_list(list).expect("small lists");
        }
        out
    }
}

/// The rank over Z/2 of the matrix with the given columns (each a sorted list of distinct
/// row indices below `n_rows`), and the pivot rows; an error when a pool would pass its
/// limit ([`PoolOverflow`]).
pub(crate) fn rank_by_elimination(
    mut columns: Lists,
    n_rows: usize,
) -> Result<Elimination, PoolOverflow> {
    let n_columns = columns.count();
    // The rows: counted first, so that they are filled in place with exact room.
    let mut counts = vec![0u32; n_rows];
    for j in 0..n_columns {
        let column = columns.get(j);
        debug_assert!(column.windows(2).all(|w| w[0] < w[1]), "sorted, distinct");
        for &r in column {
            counts[r as usize] += 1;
        }
    }
    let mut rows = Lists::with_room(&counts)?;
    drop(counts);
    for j in 0..n_columns {
        for &r in columns.get(j) {
            rows.push(r as usize, j as u32)?;
        }
    }
    let mut single_columns: Vec<u32> = (0..n_columns as u32)
        .filter(|&j| columns.len_of(j as usize) == 1)
        .collect();
    // Every column of two entries or more starts in the bucket of its length (held as the
    // lengths themselves, not as queue entries).
    let mut heap = Buckets::new(&columns);
    let mut single_rows: Vec<u32> = (0..n_rows as u32)
        .filter(|&r| rows.len_of(r as usize) == 1)
        .collect();
    let mut is_pivot_row = vec![false; n_rows];
    let mut rank = 0u64;
    let mut merged: Vec<u32> = Vec::new();
    let mut line: Vec<u32> = Vec::new();
    let mut pivot: Vec<u32> = Vec::new();
    let mut general = 0u64;
    loop {
        if let Some(c) = single_columns.pop() {
            let c = c as usize;
            if columns.len_of(c) != 1 {
                continue;
            }
            // The column is e_r: it clears row r from every other column.
            let r = columns.get(c)[0] as usize;
            columns.clear(c);
            rank += 1;
            is_pivot_row[r] = true;
            rows.take_into(r, &mut line);
            for &x in &line {
                let x = x as usize;
                if x == c {
                    continue;
                }
                columns.remove_sorted(x, r as u32);
                note_column(x, columns.len_of(x), &mut single_columns, &mut heap);
            }
            continue;
        }
        if let Some(r) = single_rows.pop() {
            let r = r as usize;
            if rows.len_of(r) != 1 {
                continue;
            }
            // The row is e_c: column c goes, with every entry it had.
            let c = rows.get(r)[0] as usize;
            rank += 1;
            is_pivot_row[r] = true;
            columns.take_into(c, &mut line);
            for &s in &line {
                rows.swap_remove_value(s as usize, c as u32);
                if rows.len_of(s as usize) == 1 {
                    single_rows.push(s);
                }
            }
            continue;
        }
        let Some((degree, c)) = heap.pop() else {
            break;
        };
        let c = c as usize;
        if columns.len_of(c) != degree as usize {
            // A stale entry: the column changed (and was queued again) or went.
            continue;
        }
        let r = *columns
            .get(c)
            .iter()
            .min_by_key(|&&s| (rows.len_of(s as usize), s))
            .expect("a column in the heap has entries") as usize;
        columns.take_into(c, &mut pivot);
        general += 1;
        line.clear();
        line.extend(rows.get(r).iter().copied().filter(|&x| x as usize != c));
        for &x in &line {
            // columns[x] += pivot, keeping the row lists in step.
            let column = columns.get(x as usize);
            merged.clear();
            let (mut i, mut j) = (0, 0);
            while i < column.len() && j < pivot.len() {
                let (a, b) = (column[i], pivot[j]);
                if a < b {
                    merged.push(a);
                    i += 1;
                } else if b < a {
                    merged.push(b);
                    rows.push(b as usize, x)?;
                    j += 1;
                } else {
                    rows.swap_remove_value(a as usize, x);
                    i += 1;
                    j += 1;
                }
            }
            merged.extend_from_slice(&column[i..]);
            for &b in &pivot[j..] {
                merged.push(b);
                rows.push(b as usize, x)?;
            }
            columns.set(x as usize, &merged)?;
            note_column(
                x as usize,
                columns.len_of(x as usize),
                &mut single_columns,
                &mut heap,
            );
        }
        // Row r now meets only column c: delete both.
        rank += 1;
        is_pivot_row[r] = true;
        for &s in &pivot {
            rows.swap_remove_value(s as usize, c as u32);
            if rows.len_of(s as usize) == 1 {
                single_rows.push(s);
            }
        }
    }
    let pivots = (0..n_rows as u32)
        .filter(|&r| is_pivot_row[r as usize])
        .collect();
    Ok(Elimination {
        rank,
        pivots,
        general,
    })
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
///
/// The first entries of each bucket are every column whose length at the start was that
/// bucket's, in column order: those are not stored as entries but as the start lengths
/// (one byte per column, `initial`) with a cursor per bucket, which is the same order as
/// pushing them all first (about 4 bytes per column less, and no queue doubling).
struct Buckets {
    /// Per column, its length when the elimination started (0 for those of no bucket:
    /// under two entries, or over 255, which are queued as entries instead).
    initial: Vec<u8>,
    /// Per bucket, the next column to look at in `initial`.
    cursor: Vec<u32>,
    buckets: Vec<std::collections::VecDeque<u32>>,
    /// No bucket below this one holds anything.
    lowest: usize,
}

impl Buckets {
    /// Every column of `columns` with two entries or more, in the bucket of its length.
    fn new(columns: &Lists) -> Buckets {
        let mut queue = Buckets {
            initial: Vec::with_capacity(columns.count()),
            cursor: Vec::new(),
            buckets: Vec::new(),
            lowest: 0,
        };
        for j in 0..columns.count() {
            let n = columns.len_of(j);
            queue.initial.push(match n {
                2..=255 => n as u8,
                _ => 0,
            });
            if n > 255 {
                queue.push(n, j as u32);
            }
        }
        let widest = queue.initial.iter().copied().max().unwrap_or(0) as usize;
        if queue.buckets.len() <= widest {
            queue.buckets.resize_with(widest + 1, Default::default);
        }
        queue.cursor = vec![0; queue.buckets.len()];
        queue
    }

    fn push(&mut self, degree: usize, column: u32) {
        if self.buckets.len() <= degree {
            self.buckets.resize_with(degree + 1, Default::default);
            self.cursor.resize(degree + 1, 0);
        }
        self.buckets[degree].push_back(column);
        self.lowest = self.lowest.min(degree);
    }

    /// The next entry of the lowest bucket (bucket, column): maybe stale, so the caller
    /// checks the column's length.
    fn pop(&mut self) -> Option<(u32, u32)> {
        while self.lowest < self.buckets.len() {
            let degree = self.lowest;
            if (2..256).contains(&degree) {
                let cursor = &mut self.cursor[degree];
                while (*cursor as usize) < self.initial.len() {
                    let j = *cursor;
                    *cursor += 1;
                    if self.initial[j as usize] as usize == degree {
                        return Some((degree as u32, j));
                    }
                }
            }
            if let Some(column) = self.buckets[degree].pop_front() {
                return Some((degree as u32, column));
            }
            self.lowest += 1;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::complex::z2_rank;
    use rand::{Rng, SeedableRng};

    #[test]
    fn small_matrices() {
        let rank = |columns: Vec<Vec<u32>>, n_rows| {
            rank_by_elimination(Lists::from_vecs(&columns), n_rows)
                .unwrap()
                .rank
        };
        // Columns {0,1}, {1,2}, {0,2}: a cycle, no free pivot (two general ones: the first
        // leaves two equal columns), and dependent over Z/2.
        let cycle = rank_by_elimination(Lists::from_vecs(&[vec![0, 1], vec![1, 2], vec![0, 2]]), 3)
            .unwrap();
        assert_eq!((cycle.rank, cycle.general), (2, 2));
        assert_eq!(rank(vec![vec![0], vec![1], vec![2]], 3), 3);
        assert_eq!(rank(vec![vec![0, 1, 2], vec![0, 1, 2]], 3), 1);
        assert_eq!(
            rank_by_elimination(Lists::from_vecs(&[vec![], vec![1]]), 3).unwrap(),
            Elimination {
                rank: 1,
                pivots: vec![1],
                general: 0
            }
        );
        assert_eq!(rank(Vec::new(), 0), 0);
    }

    /// The pool against a `Vec` per list under random pushes, sets, removals and takes,
    /// so lists move (outgrow their room) many times.
    #[test]
    fn pooled_lists_match_vectors() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut model: Vec<Vec<u32>> = (0..20)
            .map(|_| (0..rng.gen_range(0..5)).collect())
            .collect();
        let mut lists = Lists::from_vecs(&model);
        let mut out = Vec::new();
        for step in 0..20_000 {
            let i = rng.gen_range(0..model.len());
            match rng.gen_range(0..5) {
                0 | 1 => {
                    let v = rng.gen_range(0..1000);
                    model[i].push(v);
                    lists.push(i, v).unwrap();
                }
                2 => {
                    let n = rng.gen_range(0..12);
                    let new: Vec<u32> = (0..n).map(|_| rng.gen_range(0..1000)).collect();
                    lists.set(i, &new).unwrap();
                    model[i] = new;
                }
                3 if !model[i].is_empty() => {
                    let at = rng.gen_range(0..model[i].len());
                    // The first entry of that value (values may repeat here).
                    let v = model[i][at];
                    let first = model[i].iter().position(|&x| x == v).unwrap();
                    model[i].swap_remove(first);
                    lists.swap_remove_value(i, v);
                }
                3 => {}
                _ => {
                    lists.take_into(i, &mut out);
                    assert_eq!(out, std::mem::take(&mut model[i]), "step {step}");
                }
            }
            assert_eq!(lists.get(i), &model[i][..], "step {step}");
        }
        assert_eq!(lists.to_vecs(), model);
        let mut sorted = Lists::from_vecs(&[vec![1, 4, 9, 12]]);
        sorted.remove_sorted(0, 9);
        assert_eq!(sorted.get(0), &[1, 4, 12]);
    }

    /// Compaction keeps every list and frees the rooms of moved and emptied lists; a
    /// pool's limit turns growth past it into an error, and a list of 128 entries or more
    /// gets a power-of-two room.
    #[test]
    fn compaction_keeps_the_lists_and_the_limit_is_an_error() {
        let mut model: Vec<Vec<u32>> = (0..50).map(|i| (0..i % 7).collect()).collect();
        let mut lists = Lists::from_vecs(&model);
        for (i, list) in model.iter_mut().enumerate() {
            if i % 3 == 0 {
                for v in 0..10 {
                    list.push(100 + v);
                    lists.push(i, 100 + v).unwrap();
                }
            }
        }
        let mut out = Vec::new();
        for i in (0..50).step_by(2) {
            lists.take_into(i, &mut out);
            model[i].clear();
        }
        let before = lists.data.len();
        lists.compact();
        assert_eq!(lists.to_vecs(), model);
        let held: usize = model.iter().map(Vec::len).sum();
        assert_eq!(lists.live, held);
        assert_eq!(lists.data.len(), held, "exact rooms after compaction");
        assert!(before > 2 * held, "{before} entries before, {held} held");
        lists.push(0, 7).unwrap();
        model[0].push(7);
        assert_eq!(lists.to_vecs(), model);
        assert_eq!(room_code(127), (127, 127));
        assert_eq!(room_code(128), (135, 128));
        assert_eq!(room(room_code(129).0), 256);
        // The limit: a pool of more entries is refused, whichever way it would grow.
        with_pool_limit(10, || {
            let mut small = Lists::default();
            small.push_list(&[1, 2, 3, 4, 5, 6]).unwrap();
            assert_eq!(
                small.push_list(&[1, 2, 3, 4, 5]),
                Err(PoolOverflow {
                    needed: 11,
                    limit: 10
                })
            );
            small.push_list(&[1]).unwrap();
            assert!(small.push(1, 2).is_err());
            assert!(small.set(0, &[0; 11]).is_err());
            assert!(Lists::with_room(&[4, 7]).is_err());
        });
    }

    /// Fill-in past the limit is an error of the elimination, the same matrices within it
    /// the rank.
    #[test]
    fn elimination_over_the_pool_limit_is_an_error() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let columns: Vec<Vec<u32>> = (0..30)
            .map(|_| (0..30u32).filter(|_| rng.gen_bool(0.5)).collect())
            .collect();
        let entries: usize = columns.iter().map(Vec::len).sum();
        let (expected, _) = z2_rank(columns.clone(), 30);
        let found = rank_by_elimination(Lists::from_vecs(&columns), 30).unwrap();
        assert!(found.general > 5, "{} general pivots", found.general);
        assert_eq!(found.rank, expected);
        let lists = Lists::from_vecs(&columns);
        let refused = with_pool_limit(entries + 2, || rank_by_elimination(lists, 30));
        assert!(
            matches!(refused, Err(PoolOverflow { limit, .. }) if limit == entries as u64 + 2),
            "{refused:?}"
        );
        let lists = Lists::from_vecs(&columns);
        assert_eq!(
            with_pool_limit(1 << 20, || rank_by_elimination(lists, 30)),
            Ok(found)
        );
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
            let found = rank_by_elimination(Lists::from_vecs(&columns), n_rows).unwrap();
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
