//! Unit tests of the simple-point test: the tables, the cache and the unchecked reader
//! against the slow oracle.

use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The unchecked reader and the memo agree with the checked test on every interior
/// voxel of random images in 2D, 3D and 4D, asked twice (computed, then memoised), and
/// with a memo small enough that slots collide.
#[test]
fn the_reader_and_the_memo_agree_with_the_tester() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for shape in [vec![9usize, 11], vec![7, 8, 9], vec![6, 7, 5, 8]] {
        let mut image = BinaryImage::zeros(&shape).unwrap();
        for v in image.data_mut() {
            *v = rng.gen_bool(0.6) as u8;
        }
        let tester = SimpleTester::new(image.dim());
        let mut memo = SimpleCache::new(6);
        for v in (0..image.len()).filter(|&v| is_interior(&image, v, 1)) {
            let config = tester.configuration_in(image.data(), image.strides(), v);
            assert_eq!(
                config,
                tester.configuration(&image, v),
                "{shape:?} voxel {v}"
            );
            for _ in 0..2 {
                assert_eq!(
                    memo.is_simple(&tester, config),
                    tester.is_simple(&image, v),
                    "{shape:?} voxel {v}"
                );
            }
        }
    }
}

/// The unchecked reader gives the configuration as defined (bit k set when the neighbour
/// at `offsets()[k]` is foreground), for every interior voxel, those at the end of the
/// image's bytes included, in 2D, 3D and 4D.
#[test]
fn the_reader_gives_the_defined_configuration() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for shape in [
        vec![5usize, 6],
        vec![4, 5, 6],
        vec![4, 5, 3, 6],
        vec![3, 3, 3, 3],
    ] {
        let mut image = BinaryImage::zeros(&shape).unwrap();
        for v in image.data_mut() {
            *v = rng.gen_bool(0.5) as u8;
        }
        let tester = SimpleTester::new(image.dim());
        let strides = image.strides().to_vec();
        for v in (0..image.len()).filter(|&v| is_interior(&image, v, 1)) {
            let want = tester
                .offsets()
                .iter()
                .enumerate()
                .fold(0u128, |config, (k, offset)| {
                    let at = (0..shape.len()).fold(v as isize, |at, a| {
                        at + isize::from(offset[a]) * strides[a] as isize
                    });
                    config | u128::from(image.data()[at as usize]) << k
                });
            assert_eq!(
                tester.configuration_in(image.data(), &strides, v),
                want,
                "{shape:?} voxel {v}"
            );
        }
    }
}

/// The answer read off the memo key is the answer for the configuration, on random 4D
/// configurations of every density (and in 2D and 3D, where the key is the
/// configuration).
#[test]
fn memo_keys_give_the_same_answers() {
    let mut rng = ChaCha8Rng::seed_from_u64(91);
    for dim in Dim::ALL {
        let tester = SimpleTester::new(dim);
        let n = tester.offsets().len();
        let mut simple = 0;
        for trial in 0..200_000 {
            let density = [0.05, 0.3, 0.5, 0.7, 0.95][trial % 5];
            let config = (0..n).fold(0u128, |acc, k| acc | (rng.gen_bool(density) as u128) << k);
            let answer = tester.is_simple_configuration(config);
            assert_eq!(
                tester.is_simple_key(tester.memo_key(config)),
                answer,
                "{dim:?} {config:#x}"
            );
            simple += answer as u32;
        }
        assert!(simple > 1000, "{dim:?}: {simple}");
    }
}

/// The key of a block in column order is the key of the same block's configuration
/// in raster order, laid out in column order.
#[test]
fn column_order_keys_match_raster_order_keys() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    for dim in Dim::ALL {
        let tester = SimpleTester::new(dim);
        let n = tester.offsets().len();
        let (cells, rows, centre) = (n + 1, (n + 1) / 3, n / 2);
        for trial in 0..20_000 {
            let density = [0.1, 0.5, 0.9][trial % 3];
            let raster: Vec<bool> = (0..cells).map(|_| rng.gen_bool(density)).collect();
            let column = (0..cells).fold(0u128, |block, b| {
                block | (raster[3 * (b % rows) + b / rows] as u128) << b
            });
            let config = (0..cells)
                .filter(|&i| i != centre && raster[i])
                .fold(0u128, |c, i| c | 1 << if i < centre { i } else { i - 1 });
            let key = tester.column_key(column);
            assert_eq!(
                tester.face_key(key),
                tester.memo_key(config),
                "{dim:?} {config:#x}"
            );
            // Only the centre's bit is dropped (and, in 4D, the closure added).
            assert_eq!(key & column, column & !(1 << centre), "{dim:?}");
        }
    }
}

/// The tables are built once a dimension and shared, each dimension its own.
#[test]
fn testers_of_a_dimension_share_their_tables() {
    for dim in [Dim::Two, Dim::Three, Dim::Four] {
        let (a, b) = (SimpleTester::new(dim), SimpleTester::new(dim));
        assert!(Arc::ptr_eq(&a.tables, &b.tables), "{dim:?}");
        assert_eq!(a.dim(), dim);
    }
}

#[test]
fn golden_count_2d() {
    let tester = SimpleTester::new(Dim::Two);
    let simple = (0..256u128)
        .filter(|&c| tester.is_simple_configuration(c))
        .count();
    assert_eq!(simple, 116);
}

#[test]
fn golden_count_3d() {
    let tester = SimpleTester::new(Dim::Three);
    // Every configuration, through the table as callers see it (filling it all).
    let simple = (0..1u128 << 26)
        .filter(|&c| tester.is_simple_configuration(c))
        .count();
    assert_eq!(simple, 25_985_144);
}

#[test]
fn three_conditions_agree_with_collapse_in_2d() {
    let tester = SimpleTester::new(Dim::Two);
    for config in 0..256u128 {
        assert_eq!(
            tester.is_simple_configuration(config),
            tester.is_simple_by_collapse(config),
            "2D configuration {config:#010b}"
        );
    }
}

#[test]
fn three_conditions_agree_with_collapse_on_sampled_3d() {
    let tester = SimpleTester::new(Dim::Three);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200_000 {
        // Mix densities so that both simple and non-simple cases are common.
        let density: f64 = rng.gen_range(0.05..0.95);
        let mut config = 0u128;
        for k in 0..26 {
            if rng.gen_bool(density) {
                config |= 1 << k;
            }
        }
        assert_eq!(
            tester.is_simple_configuration(config),
            tester.is_simple_by_collapse(config),
            "3D configuration {config:#x}"
        );
    }
}

#[test]
fn three_conditions_agree_with_collapse_on_sampled_4d() {
    let tester = SimpleTester::new(Dim::Four);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut n_simple = 0;
    let mut n_euler_decided = 0;
    for _ in 0..200_000 {
        let density: f64 = rng.gen_range(0.05..0.95);
        let mut config = 0u128;
        for k in 0..80 {
            if rng.gen_bool(density) {
                config |= 1 << k;
            }
        }
        let fast = tester.is_simple_configuration(config);
        assert_eq!(
            fast,
            tester.is_simple_by_collapse(config),
            "4D configuration {config:#x}"
        );
        n_simple += fast as u32;
        let tables = &tester.tables;
        if !fast && tables.background_faces_connected(config) && tables.foreground_connected(config)
        {
            n_euler_decided += 1;
        }
    }
    // The sample must exercise both answers and the Euler condition, or it proves little.
    assert!(n_simple > 1000, "only {n_simple} simple samples");
    assert!(
        n_euler_decided > 100,
        "Euler test decided only {n_euler_decided}"
    );
}

#[test]
fn byte_tables_give_the_attachment_set() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for dim in Dim::ALL {
        let tables = &SimpleTester::new(dim).tables;
        let all = (1u128 << tables.n_neighbours) - 1;
        for _ in 0..20_000 {
            let config = rng.gen::<u128>() & all & if rng.gen_bool(0.5) { rng.gen() } else { all };
            assert_eq!(
                tables.attachment(config),
                tables.attachment_by_neighbours(config),
                "{dim}D configuration {config:#x}"
            );
        }
        for k in 0..tables.n_neighbours {
            assert_eq!(tables.attachment(1 << k), tables.closure[k]);
        }
        assert_eq!(tables.attachment(all), tables.attachment_by_neighbours(all));
    }
}

#[test]
fn both_ways_of_counting_t_agree() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for dim in Dim::ALL {
        let tables = &SimpleTester::new(dim).tables;
        for _ in 0..50_000 {
            let density: f64 = rng.gen_range(0.02..0.6);
            let mut config = 0u128;
            for k in 0..tables.n_neighbours {
                if rng.gen_bool(density) {
                    config |= 1 << k;
                }
            }
            assert_eq!(
                tables.foreground_connected(config),
                tables.attachment_connected(tables.attachment(config)),
                "{dim}D configuration {config:#x}"
            );
        }
    }
}

#[test]
fn configuration_reads_neighbours_in_canonical_order() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for dim in Dim::ALL {
        let tester = SimpleTester::new(dim);
        let shape: Vec<usize> = (0..dim.get()).map(|a| 4 + a).collect();
        let mut image = BinaryImage::zeros(&shape).unwrap();
        for v in image.data_mut() {
            *v = rng.gen_range(0..2);
        }
        for index in 0..image.len() {
            if !is_interior(&image, index, 1) {
                continue;
            }
            let c = image.coords(index);
            let mut expected = 0u128;
            for (k, off) in tester.offsets().iter().enumerate() {
                let n: Vec<usize> = (0..dim.get())
                    .map(|a| (c[a] as i64 + off[a] as i64) as usize)
                    .collect();
                if image.get(&n) {
                    expected |= 1 << k;
                }
            }
            assert_eq!(tester.configuration(&image, index), expected);
        }
    }
}

#[test]
#[should_panic(expected = "on or outside the border")]
fn configuration_refuses_border_voxels() {
    let image = BinaryImage::zeros(&[4, 4]).unwrap();
    SimpleTester::new(Dim::Two).configuration(&image, 1);
}

#[test]
fn tables_agree_with_direct_evaluation() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let tester = SimpleTester::new(Dim::Three);
    for _ in 0..100_000 {
        let config = rng.gen::<u128>() & ((1 << 26) - 1);
        assert_eq!(
            tester.is_simple_configuration(config),
            tester.evaluate(config)
        );
    }
}

#[test]
fn centre_value_and_extra_bits_are_ignored() {
    // An isolated voxel is never simple; a voxel with one face neighbour always is.
    for dim in Dim::ALL {
        let tester = SimpleTester::new(dim);
        let shape = vec![3; dim.get()];
        let mut image = BinaryImage::zeros(&shape).unwrap();
        let centre = image.len() / 2;
        image.data_mut()[centre] = 1;
        assert!(!tester.is_simple(&image, centre));
        let mut one = vec![1; dim.get()];
        one[0] = 0;
        image.set(&one, true);
        assert!(tester.is_simple(&image, centre));
        image.data_mut()[centre] = 0;
        assert!(tester.is_simple(&image, centre));
        let config = tester.configuration(&image, centre);
        assert!(tester.is_simple_configuration(config | (1u128 << 127)));
    }
}
