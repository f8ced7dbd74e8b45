use super::grid::check_grid;
use super::queue::{CellQueue, Kind};
use super::ranks::Ranks;
use super::seams::{column_reduction, LowerFirst, UpperFirst};
use super::split_plan::{Halves, Order, SeamShare, Split};
use super::*;
use crate::complex::CellComplex;
use crate::eliminate::rank_by_elimination;
use bettimill_grid::BinaryImage;
use std::collections::VecDeque;

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
            .betti_with(1, rank_by_elimination)
            .unwrap()
            .0,
        vec![1, 1, 0, 0]
    );
    let empty = BinaryImage::zeros(&[4, 4, 4, 4]).unwrap();
    assert_eq!(
        DenseComplex::of_image(&empty)
            .betti_with(0, rank_by_elimination)
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
            whole.betti_split(b0, rank_by_elimination, None).unwrap().0,
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
                .betti_split(b0, rank_by_elimination, Some(split))
                .unwrap()
                .0;
            let case = format!("trial {trial} split at {half}, {column:?}, listed {listed}");
            assert_eq!(found, expected, "{case}");
            // The parts never meet: in either order they leave the same cells, and
            // the same cells queued.
            let lower_first = reduce_parts_in(image, listed, split, LowerFirst);
            let upper_first = reduce_parts_in(image, listed, split, UpperFirst);
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
            let ranks: [(&str, FinalRank); 2] = [
                ("elimination", rank_by_elimination),
                ("column reduction", column_reduction),
            ];
            let routes = ranks
                .into_iter()
                .flat_map(|rank| [(rank, true), (rank, false)]);
            for ((route, final_rank), listed) in routes {
                assert_eq!(
                    DenseComplex::of_image_with(&image, listed)
                        .betti_with(b0, final_rank)
                        .unwrap()
                        .0,
                    expected,
                    "{d}D trial {trial}, density {density:.2}, {route}, \
                     listed {listed}"
                );
            }
        }
    }
}

/// What the parts of a split reduction leave: the masks, the cells left queued, the last
/// seam and the vertices removed.
type PartsLeft = (Vec<u16>, Vec<(usize, u32)>, std::ops::Range<usize>, u64);

/// What the parts of `split` leave of `image`'s complex, run in `order`.
fn reduce_parts_in(
    image: &BinaryImage,
    listed: bool,
    split: Split,
    order: impl Order,
) -> PartsLeft {
    let mut complex = DenseComplex::of_image_with(image, listed);
    let owners = std::mem::replace(&mut complex.owners, Owners::Scanned);
    let (mut left, seam, removed) = complex.view().reduce_parts(&owners, split, order);
    let mut queued = Vec::new();
    while let Some(cell) = left.pop() {
        queued.push(cell);
    }
    let masks: Vec<u16> = complex.masks.get_mut().to_vec();
    (masks, queued, seam, removed)
}
