//! Property tests: on random small images in 2D, 3D and 4D, every deformation keeps the
//! exact Betti numbers, moves keep the foreground count, and the outer layer is untouched.

use bettimill_deform::{
    deform, deform_phase, target_hypervolume, target_hypervolume_phase, Apart, DeformSettings,
    Method, Phase,
};
use bettimill_grid::neighbourhood::is_interior;
use bettimill_grid::BinaryImage;
use bettimill_homology::topology;
use proptest::prelude::*;

/// A random image whose outer layer is background (the dataset's convention) or, when
/// `touch_border` is set, may hold foreground anywhere.
fn image(shape: Vec<usize>, bits: Vec<bool>, touch_border: bool) -> BinaryImage {
    let mut img = BinaryImage::zeros(&shape).unwrap();
    for (v, &b) in bits.iter().enumerate().take(img.len()) {
        if b && (touch_border || is_interior(&img, v, 1)) {
            img.data_mut()[v] = 1;
        }
    }
    img
}

fn method() -> impl Strategy<Value = Method> {
    prop_oneof![
        Just(Method::Moves),
        Just(Method::Dilate),
        Just(Method::Erode),
        Just(Method::Tentacles),
        Just(Method::Walk),
        Just(Method::Pinch)
    ]
}

fn check(img: BinaryImage, method: Method, steps: u32, max_distance: u32, p: f64, seed: u64) {
    let before = topology(&img);
    let mut out = img.clone();
    let settings = DeformSettings {
        method,
        steps,
        max_distance,
        growth_probability: p,
        noise_frequency: 0.19,
        octaves: 2,
        count: 1 + (seed % 3) as u32,
    };
    let report = deform(&mut out, &settings, seed).unwrap();
    assert_eq!(topology(&out), before, "{method:?} {report:?}");
    if method == Method::Moves {
        assert_eq!(out.count_foreground(), img.count_foreground());
    }
    for v in 0..img.len() {
        if !is_interior(&img, v, 1) {
            assert_eq!(out.data()[v], img.data()[v], "outer voxel {v} edited");
        }
    }
}

/// The cavity phase of `img` in the box two voxels in from every face: the deformation
/// keeps the topology and edits nothing outside the box.
fn check_cavities(img: BinaryImage, method: Method, steps: u32, p: f64, seed: u64) {
    let before = topology(&img);
    let d = img.shape().len();
    let lo = vec![2usize; d];
    let hi: Vec<usize> = img.shape().iter().map(|&n| n - 3).collect();
    let phase = Phase::cavities(&img, &lo, &hi);
    let settings = DeformSettings {
        method,
        steps,
        growth_probability: p,
        noise_frequency: 0.19,
        octaves: 2,
        count: 1 + (seed % 3) as u32,
        ..DeformSettings::default()
    };
    let mut out = img.clone();
    // Random images hold many cavities: the separation's labels are exercised too.
    let mut apart = Apart::new(&img, &phase);
    // Each run from `img` starts from the phase made from it.
    let mut deformed = phase;
    let report = deform_phase(&mut out, &settings, &mut deformed, apart.as_mut(), seed).unwrap();
    assert_eq!(topology(&out), before, "{method:?} {report:?}");
    let in_box = |v: usize| {
        let c = img.coords(v);
        (0..d).all(|a| c[a] >= lo[a] && c[a] <= hi[a])
    };
    for v in 0..img.len() {
        if !in_box(v) {
            assert_eq!(
                out.data()[v],
                img.data()[v],
                "voxel {v} outside the box edited"
            );
        }
    }
    let goal = img.count_foreground() + 5;
    let mut targeted = img.clone();
    let mut apart = Apart::new(&img, &phase);
    let mut targeted_phase = phase;
    match target_hypervolume_phase(
        &mut targeted,
        goal,
        goal,
        goal,
        &mut targeted_phase,
        apart.as_mut(),
        seed,
    ) {
        Ok(_) => {
            assert_eq!(targeted.count_foreground(), goal);
            assert_eq!(topology(&targeted), before);
        }
        Err(_) => assert_eq!(targeted, img),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn cavity_deformations_keep_topology_and_their_box_3d(
        bits in proptest::collection::vec(proptest::bool::weighted(0.7), 9 * 8 * 9),
        method in method(),
        steps in 1u32..20,
        p in 0.1f64..=1.0,
        seed in any::<u64>(),
    ) {
        check_cavities(image(vec![9, 8, 9], bits, false), method, steps, p, seed);
    }

    #[test]
    fn cavity_deformations_keep_topology_and_their_box_4d(
        bits in proptest::collection::vec(proptest::bool::weighted(0.7), 7 * 6 * 7 * 6),
        method in method(),
        steps in 1u32..12,
        p in 0.1f64..=1.0,
        seed in any::<u64>(),
    ) {
        check_cavities(image(vec![7, 6, 7, 6], bits, false), method, steps, p, seed);
    }

    #[test]
    fn deformations_keep_topology_2d(
        bits in proptest::collection::vec(proptest::bool::weighted(0.45), 14 * 13),
        touch in any::<bool>(),
        method in method(),
        steps in 1u32..60,
        max_distance in 1u32..4,
        p in 0.1f64..=1.0,
        seed in any::<u64>(),
    ) {
        check(image(vec![14, 13], bits, touch), method, steps, max_distance, p, seed);
    }

    #[test]
    fn deformations_keep_topology_3d(
        bits in proptest::collection::vec(proptest::bool::weighted(0.4), 8 * 7 * 8),
        touch in any::<bool>(),
        method in method(),
        steps in 1u32..60,
        max_distance in 1u32..3,
        p in 0.1f64..=1.0,
        seed in any::<u64>(),
    ) {
        check(image(vec![8, 7, 8], bits, touch), method, steps, max_distance, p, seed);
    }

    #[test]
    fn deformations_keep_topology_4d(
        bits in proptest::collection::vec(proptest::bool::weighted(0.35), 6 * 5 * 6 * 5),
        method in method(),
        steps in 1u32..30,
        p in 0.1f64..=1.0,
        seed in any::<u64>(),
    ) {
        check(image(vec![6, 5, 6, 5], bits, false), method, steps, 1, p, seed);
    }

    #[test]
    fn targeting_lands_in_range_or_leaves_the_image_alone(
        bits in proptest::collection::vec(proptest::bool::weighted(0.3), 12 * 12),
        lo in 0u64..100,
        width in 0u64..10,
        seed in any::<u64>(),
    ) {
        let img = image(vec![12, 12], bits, false);
        let before = topology(&img);
        let mut out = img.clone();
        match target_hypervolume(&mut out, lo, lo + width, seed) {
            Ok(_) => {
                prop_assert!((lo..=lo + width).contains(&out.count_foreground()));
                prop_assert_eq!(topology(&out), before);
            }
            Err(_) => prop_assert_eq!(out, img),
        }
    }
}
