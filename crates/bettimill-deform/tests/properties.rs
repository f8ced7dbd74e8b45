//! Property tests: on random small images in 2D, 3D and 4D, every deformation keeps the
//! exact Betti numbers, moves keep the foreground count, and the outer layer is untouched.

use bettimill_deform::{deform, target_hypervolume, DeformSettings, Method};
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
        Just(Method::Erode)
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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

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
