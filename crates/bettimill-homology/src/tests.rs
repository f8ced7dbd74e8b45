//! Tests of [`crate::topology`]: constructed shapes with known labels (labels.md), the
//! object/cavity duality, invariance under simple-point flips, and agreement with the
//! slow oracles on thousands of random and adversarial small images.

use super::*;
use crate::dense::seams::column_reduction;
use crate::simple::SimpleTester;
use bettimill_grid::neighbourhood::is_interior;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// An image of side `side` whose voxel centres satisfy `inside` (coordinates relative to
/// the image centre).
fn shape(d: usize, side: usize, inside: impl Fn(&[f64]) -> bool) -> BinaryImage {
    let mut image = BinaryImage::cube(Dim::new(d).unwrap(), side).unwrap();
    let centre = (side as f64 - 1.0) / 2.0;
    for index in 0..image.len() {
        let c = image.coords(index);
        let p: Vec<f64> = (0..d).map(|a| c[a] as f64 - centre).collect();
        if inside(&p) {
            image.data_mut()[index] = 1;
        }
    }
    image
}

/// The cube with the object carved out: every voxel but the outer layer and the object.
fn cavity(object: &BinaryImage) -> BinaryImage {
    let mut out = object.complement();
    for index in 0..out.len() {
        if !is_interior(&out, index, 1) {
            out.data_mut()[index] = 0;
        }
    }
    out
}

fn norm(p: &[f64]) -> f64 {
    p.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Distance from (p0, p1) to the circle of radius r in that plane, with the rest of p.
fn circle_distance(r: f64, p: &[f64]) -> f64 {
    let radial = (p[0] * p[0] + p[1] * p[1]).sqrt() - r;
    let rest: f64 = p[2..].iter().map(|x| x * x).sum();
    (radial * radial + rest).sqrt()
}

fn check(name: &str, image: &BinaryImage, object: &[u64], carved: &[u64]) {
    // labels.md: objects need two voxels of clearance from the border, or the cavity
    // leaks into the outside.
    assert!(
        (0..image.len()).all(|i| image.data()[i] == 0 || is_interior(image, i, 2)),
        "{name} comes closer than two voxels to the border"
    );
    let found = topology(image);
    assert_eq!(found.betti, object, "{name} as an object");
    assert_eq!(
        found,
        topology_by_thinning(image.padded(1)).unwrap(),
        "{name} by thinning"
    );
    let found = topology(&cavity(image));
    assert_eq!(found.betti, carved, "{name} as a cavity");
    // Padded in place (a carved 4D cube takes the background route).
    assert_eq!(
        try_topology_owned(cavity(image)).as_ref(),
        Ok(&found),
        "{name} as a cavity, owned"
    );
    // labels.md duality, checked on the computed numbers too.
    let d = object.len();
    let b = &topology(image).betti;
    let mut dual = vec![1 + b[d - 1]];
    dual.extend((1..d - 1).map(|k| b[d - 1 - k]));
    dual.push(b[0]);
    assert_eq!(found.betti, dual, "{name} duality");
}

#[test]
fn labels_2d() {
    check("disk", &shape(2, 18, |p| norm(p) <= 5.0), &[1, 0], &[1, 1]);
    check(
        "annulus",
        &shape(2, 22, |p| (3.0..=7.0).contains(&norm(p))),
        &[1, 1],
        &[2, 1],
    );
}

#[test]
fn labels_3d() {
    check(
        "ball",
        &shape(3, 16, |p| norm(p) <= 4.5),
        &[1, 0, 0],
        &[1, 0, 1],
    );
    check(
        "solid torus",
        &shape(3, 22, |p| circle_distance(5.5, p) <= 2.2),
        &[1, 1, 0],
        &[1, 1, 1],
    );
    let genus_two = shape(3, 32, |p| {
        let left = [p[0] + 5.0, p[1], p[2]];
        let right = [p[0] - 5.0, p[1], p[2]];
        circle_distance(5.0, &left) <= 2.0 || circle_distance(5.0, &right) <= 2.0
    });
    check("genus-2 handlebody", &genus_two, &[1, 2, 0], &[1, 2, 1]);
    check(
        "spherical shell",
        &shape(3, 20, |p| (4.0..=6.5).contains(&norm(p))),
        &[1, 0, 1],
        &[2, 0, 1],
    );
    check(
        "torus shell",
        &shape(3, 28, |p| (1.6..=3.6).contains(&circle_distance(7.0, p))),
        &[1, 2, 1],
        &[2, 2, 1],
    );
    let hopf = shape(3, 28, |p| {
        let first = [p[0] + 3.0, p[1], p[2]];
        let second = [p[0] - 3.0, p[2], p[1]];
        circle_distance(6.0, &first) <= 1.8 || circle_distance(6.0, &second) <= 1.8
    });
    check("Hopf link", &hopf, &[2, 2, 0], &[1, 2, 2]);
}

#[test]
fn labels_4d() {
    check(
        "B4",
        &shape(4, 14, |p| norm(p) <= 3.5),
        &[1, 0, 0, 0],
        &[1, 0, 0, 1],
    );
    check(
        "S1xB3",
        &shape(4, 18, |p| circle_distance(4.0, p) <= 1.8),
        &[1, 1, 0, 0],
        &[1, 0, 1, 1],
    );
    check(
        "S2xB2",
        &shape(4, 18, |p| {
            let radial = norm(&p[..3]) - 4.0;
            (radial * radial + p[3] * p[3]).sqrt() <= 1.8
        }),
        &[1, 0, 1, 0],
        &[1, 1, 0, 1],
    );
    check(
        "T2xB2",
        &shape(4, 24, |p| {
            // Distance to the torus surface in the first three axes, thickened in 4D.
            let tube = circle_distance(5.0, &p[..3]) - 2.6;
            (tube * tube + p[3] * p[3]).sqrt() <= 1.4
        }),
        &[1, 2, 1, 0],
        &[1, 1, 2, 1],
    );
    check(
        "S3 shell",
        &shape(4, 18, |p| (3.5..=5.5).contains(&norm(p))),
        &[1, 0, 0, 1],
        &[2, 0, 0, 1],
    );
}

fn random_image(rng: &mut ChaCha8Rng, shape: &[usize], density: f64) -> BinaryImage {
    let mut image = BinaryImage::zeros(shape).unwrap();
    for v in image.data_mut() {
        *v = rng.gen_bool(density) as u8;
    }
    image
}

fn agree_with_reference(d: usize, side: usize, n: usize, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let shape = vec![side; d];
    for trial in 0..n {
        let density = rng.gen_range(0.1..0.9);
        let image = random_image(&mut rng, &shape, density);
        let expected = reference::topology(&image);
        assert_eq!(topology(&image), expected, "{d}D trial {trial}: {image:?}");
        // The image padded in place goes the same way.
        assert_eq!(
            try_topology_owned(image.clone()).as_ref(),
            Ok(&expected),
            "{d}D trial {trial}: owned"
        );
        assert_eq!(
            euler::euler_characteristic(&image.padded(1)),
            expected.euler,
            "{d}D trial {trial}: Euler characteristic"
        );
    }
}

#[test]
fn agrees_with_reference_on_random_2d() {
    agree_with_reference(2, 6, 3000, 20);
}

#[test]
fn agrees_with_reference_on_random_3d() {
    agree_with_reference(3, 5, 1500, 30);
}

#[test]
fn agrees_with_reference_on_random_4d() {
    agree_with_reference(4, 3, 300, 40);
    agree_with_reference(4, 4, 60, 41);
}

/// Random images of density 0.2 to 0.8 at the largest sides the oracle affords (its plain
/// column reduction grows fast with the side), every route against it.
#[test]
fn every_route_agrees_with_reference_on_larger_random_images() {
    let mut rng = ChaCha8Rng::seed_from_u64(90);
    let mut general = 0;
    for (d, side, n) in [(2, 40, 200), (3, 14, 100), (4, 7, 16), (4, 8, 8)] {
        for trial in 0..n {
            let density = 0.2 + 0.6 * trial as f64 / (n - 1) as f64;
            let image = random_image(&mut rng, &vec![side; d], density);
            let name = format!("{d}D {side} density {density:.2} #{trial}");
            general += every_route_agrees(&name, &image, &reference::topology(&image));
        }
    }
    // The elimination met stalled remnants, not only free pivots.
    assert!(general > 100, "{general} general pivots");
}

/// Every route of [`topology`] on `image` against `expected`: the one it picks, counting
/// (2D, 3D), thinning the object with both final ranks, and in 4D thinning the background
/// (both final ranks when its cores stay off the frame). Returns the general pivots the
/// elimination took on the object route.
fn every_route_agrees(name: &str, image: &BinaryImage, expected: &Topology) -> u64 {
    assert_eq!(&topology(image), expected, "{name}: topology");
    let d = image.dim().get();
    if d < 4 {
        assert_eq!(
            &topology_from_counts(&image.padded(1)),
            expected,
            "{name}: counts"
        );
    } else {
        assert_eq!(
            &topology_by_background(image.padded(1)).unwrap(),
            expected,
            "{name}: background route"
        );
        let routes: [(&str, FinalRank); 2] = [
            ("elimination", rank_by_elimination),
            ("column reduction", column_reduction),
        ];
        for (route, final_rank) in routes {
            if let Ok(found) = background_cores(image.padded(1), final_rank).unwrap() {
                assert_eq!(&found, expected, "{name}: background cores, {route}");
            }
        }
    }
    let (found, _) = topology_by_thinning_with(image.padded(1), column_reduction).unwrap();
    assert_eq!(&found, expected, "{name}: thinning, column reduction");
    let (found, general) = topology_by_thinning_with(image.padded(1), rank_by_elimination).unwrap();
    assert_eq!(&found, expected, "{name}: thinning, elimination");
    general
}

/// Random 4D images too large for the oracle, where the remnant is big enough for the
/// elimination to take thousands of general pivots: every route on the same images, the
/// plain column reduction (slow but simple) as the judge, and the background's other
/// construction through duality (no thinning, no reduction pairs) on the smaller ones.
#[test]
fn every_4d_route_agrees_on_rough_images() {
    let mut rng = ChaCha8Rng::seed_from_u64(91);
    let mut general = 0;
    for (side, density) in [(10, 0.5), (12, 0.35), (12, 0.5), (12, 0.65), (16, 0.5)] {
        let image = random_image(&mut rng, &[side; 4], density);
        let name = format!("4D {side} density {density}");
        let (expected, _) = topology_by_thinning_with(image.padded(1), column_reduction).unwrap();
        if side <= 10 {
            assert_eq!(
                reference::topology_by_duality(&image),
                expected,
                "{name}: duality"
            );
        }
        general += every_route_agrees(&name, &image, &expected);
    }
    // Hundreds of general pivots (since the first coreduction wave starts at the centre,
    // these remnants stall on a few thousand cells, not tens of thousands).
    assert!(general > 500, "{general} general pivots");
}

/// Images large enough for the reduction to split across two threads: the split and the
/// unsplit reduction of the same remnant agree (and `topology`, which splits, with them),
/// on a random image and on a smooth one (a blob: a few loops and spheres, found by
/// waves that start in all four parts and meet in the seams).
#[test]
fn the_split_reduction_agrees_with_the_whole_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(92);
    let side = 30;
    let noise = random_image(&mut rng, &[side; 4], 0.5);
    // The blob: the noise summed over a box of radius 2 (one axis at a time, clamped at
    // the border), thresholded at half the box.
    let mut field: Vec<u32> = noise.data().iter().map(|&v| v as u32).collect();
    for axis in 0..4 {
        let stride = noise.strides()[axis];
        let before = field.clone();
        for (index, sum) in field.iter_mut().enumerate() {
            let x = noise.coords(index)[axis];
            *sum = (x.saturating_sub(2)..(x + 3).min(side))
                .map(|y| before[index - x * stride + y * stride])
                .sum();
        }
    }
    let mut blob = BinaryImage::zeros(&[side; 4]).unwrap();
    for (v, &sum) in blob.data_mut().iter_mut().zip(&field) {
        *v = (2 * sum > 625) as u8;
    }
    for (name, image) in [("random", &noise), ("blob", &blob)] {
        let mut padded = image.padded(1);
        let tester = simple::SimpleTester::new(padded.dim());
        let remaining = thin::thin(&mut padded, &tester, Phase::Foreground);
        let steps = flat_offsets(&padded, tester.offsets());
        let b0 = components::count_components_of(padded.data_mut(), &remaining, &steps);
        let mut split = remnant_complex(&padded, &remaining, &tester).unwrap();
        let whole = remnant_complex(&padded, &remaining, &tester).unwrap();
        assert!(
            split.splits(),
            "{name}: large enough to split, seam row included"
        );
        // The random image's remnant is rough enough to scan its owners, the blob's not:
        // both kinds of owners are reduced here, split and whole.
        assert_eq!(split.lists_owners(), name == "blob", "{name}");
        let found = split.betti_with(b0, rank_by_elimination).unwrap().0;
        assert_eq!(found, whole.betti_unsplit(b0).unwrap().0, "{name}");
        let mut betti = found;
        betti.truncate(4);
        assert_eq!(topology(image).betti, betti, "{name}: topology");
        assert!(betti[1] + betti[2] > 10, "{name}: {betti:?}");
    }
}

/// The remnant's complex built on two threads, its voxels cut at a brick row, has the same
/// cells as built on one, the cells that the second half's first plane owns on the first
/// half's side included.
#[test]
fn the_cut_complex_has_the_cells_of_the_uncut_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(93);
    for density in [0.3, 0.5, 0.7] {
        let image = random_image(&mut rng, &[14, 9, 9, 9], density);
        let mut padded = image.padded(1);
        let tester = simple::SimpleTester::new(padded.dim());
        let remaining = thin::thin(&mut padded, &tester, Phase::Foreground);
        let (mut whole, none) =
            remnant_complex_cut(&padded, &remaining, &tester, usize::MAX).unwrap();
        let (mut cut, held) = remnant_complex_cut(&padded, &remaining, &tester, 0).unwrap();
        assert_eq!(
            cut.cells_by_place(),
            whole.cells_by_place(),
            "density {density}"
        );
        assert_eq!(none, 0);
        assert!(held > 0, "density {density}: nothing held back");
    }
}

/// The thinning's slabs and the reduction's parts run on rayon's threads, and neither the
/// Betti numbers nor the work left to the elimination (its general pivots, which follow
/// the cells the pairs leave) depend on how many there are.
#[test]
fn results_do_not_depend_on_the_thread_count() {
    let mut rng = ChaCha8Rng::seed_from_u64(93);
    let image = random_image(&mut rng, &[30; 4], 0.5);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| topology_by_thinning_with(image.padded(1), rank_by_elimination))
            .unwrap()
    };
    let one = run(1);
    assert!(one.1 > 0, "the elimination met general pivots");
    for threads in [2, 4] {
        assert_eq!(run(threads), one, "{threads} threads");
    }
}

/// A pool that would pass its limit is an error of `try_topology`, not a panic or a wrong
/// rank: the limit lowered on this thread (the elimination runs on the caller's thread) to
/// below what a rough 4D image's remnant needs, then restored.
#[test]
fn a_pool_over_its_limit_is_an_error() {
    let mut rng = ChaCha8Rng::seed_from_u64(91);
    let image = random_image(&mut rng, &[16; 4], 0.5);
    let expected = topology(&image);
    assert!(expected.betti[2] > 0, "{:?}", expected.betti);
    for limit in [0, 10, 100] {
        let found = crate::eliminate::with_pool_limit(limit, || try_topology(&image));
        match found {
            Err(TopologyError::TooRough { needed, limit: l }) => {
                assert_eq!(l, limit as u64);
                assert!(needed > l, "{needed} > {l}");
            }
            other => panic!("limit {limit}: {other:?}"),
        }
    }
    let message = crate::eliminate::with_pool_limit(0, || try_topology(&image))
        .unwrap_err()
        .to_string();
    assert!(message.contains("over its limit of 0"), "{message}");
    // The limit is back, and so is the answer; a limit the image fits in changes nothing.
    assert_eq!(try_topology(&image), Ok(expected.clone()));
    assert_eq!(
        crate::eliminate::with_pool_limit(1 << 24, || try_topology(&image)),
        Ok(expected)
    );
}

#[test]
fn thinning_agrees_with_counting_in_2d_and_3d() {
    let mut rng = ChaCha8Rng::seed_from_u64(50);
    for (d, side) in [(2, 12), (3, 8)] {
        for _ in 0..300 {
            let density = rng.gen_range(0.2..0.8);
            let image = random_image(&mut rng, &vec![side; d], density);
            assert_eq!(
                topology_by_thinning(image.padded(1)).unwrap(),
                topology(&image),
                "{image:?}"
            );
        }
    }
}

/// Images that break naive methods: corner-only contacts, checkerboards, thin shells,
/// objects touching along edges.
fn adversarial(d: usize) -> Vec<(&'static str, BinaryImage)> {
    let side = match d {
        2 => 8,
        3 => 6,
        _ => 4,
    };
    let cube = |f: &dyn Fn(&[usize]) -> bool| {
        let mut image = BinaryImage::cube(Dim::new(d).unwrap(), side).unwrap();
        for index in 0..image.len() {
            let c = image.coords(index);
            image.data_mut()[index] = f(&c[..d]) as u8;
        }
        image
    };
    vec![
        ("checkerboard", cube(&|c| c.iter().sum::<usize>() % 2 == 0)),
        (
            "anti-checkerboard",
            cube(&|c| c.iter().sum::<usize>() % 2 == 1),
        ),
        ("diagonal", cube(&|c| c.iter().all(|&x| x == c[0]))),
        (
            "anti-diagonal corners",
            cube(&|c| c.iter().all(|&x| x % 2 == 0)),
        ),
        (
            "one-voxel shell",
            cube(&|c| {
                c.iter().all(|&x| (1..side - 1).contains(&x))
                    && c.iter().any(|&x| x == 1 || x == side - 2)
            }),
        ),
        ("full cube", cube(&|_| true)),
        (
            "slabs touching on an edge",
            cube(&|c| (c[0] < side / 2) == (c[1] < side / 2)),
        ),
    ]
}

#[test]
fn adversarial_images_agree_with_reference() {
    for d in 2..=4 {
        for (name, image) in adversarial(d) {
            let expected = reference::topology(&image);
            assert_eq!(topology(&image), expected, "{d}D {name}");
            assert_eq!(
                topology(&image.complement()),
                reference::topology(&image.complement()),
                "{d}D {name} complemented"
            );
        }
    }
    // Two diagonal voxels are one component; their complement has no hole.
    let mut pair = BinaryImage::zeros(&[2, 2]).unwrap();
    pair.set(&[0, 0], true);
    pair.set(&[1, 1], true);
    assert_eq!(topology(&pair).betti, vec![1, 0]);
}

/// Voxels flipped at random among simple points, keeping a border of background.
fn random_simple_flips(image: &mut BinaryImage, rng: &mut ChaCha8Rng, n_flips: usize) {
    let tester = SimpleTester::new(image.dim());
    let mut done = 0;
    for _ in 0..n_flips * 20 {
        let index = rng.gen_range(0..image.len());
        if !is_interior(image, index, 2) {
            continue;
        }
        if tester.is_simple(image, index) {
            image.data_mut()[index] ^= 1;
            done += 1;
            if done == n_flips {
                break;
            }
        }
    }
    assert!(done > 0, "no simple point was flipped");
}

#[test]
fn simple_flips_preserve_topology() {
    let mut rng = ChaCha8Rng::seed_from_u64(60);
    for (d, side, n) in [(2, 16, 40), (3, 10, 30), (4, 7, 10)] {
        for _ in 0..n {
            let density = rng.gen_range(0.3..0.7);
            let mut image = random_image(&mut rng, &vec![side; d], density);
            let before = topology(&image);
            random_simple_flips(&mut image, &mut rng, side * side);
            assert_eq!(topology(&image), before, "{d}D after simple flips");
        }
    }
}

#[test]
fn agrees_with_the_dual_construction_of_the_background() {
    let mut rng = ChaCha8Rng::seed_from_u64(70);
    for (d, side, n) in [(2, 7, 500), (3, 5, 300), (4, 3, 100)] {
        for _ in 0..n {
            let density = rng.gen_range(0.2..0.8);
            let image = random_image(&mut rng, &vec![side; d], density);
            assert_eq!(
                topology(&image),
                reference::topology_by_duality(&image),
                "{d}D {image:?}"
            );
        }
    }
}

#[test]
fn non_cubic_shapes_and_empty_images_agree_with_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(80);
    let shapes: [&[usize]; 7] = [
        &[1, 9],
        &[7, 3],
        &[1, 1, 6],
        &[2, 5, 4],
        &[6, 2, 3],
        &[1, 3, 2, 4],
        &[3, 2, 4, 2],
    ];
    for shape in shapes {
        let empty = BinaryImage::zeros(shape).unwrap();
        assert_eq!(topology(&empty).betti, vec![0; shape.len()], "{shape:?}");
        for _ in 0..40 {
            let density = rng.gen_range(0.2..0.8);
            let image = random_image(&mut rng, shape, density);
            assert_eq!(topology(&image), reference::topology(&image), "{image:?}");
        }
    }
}

/// 4D images with structure the thinning cannot remove (unions and differences of random
/// boxes: hollow shells, tunnels, several components, corner contacts), so the reduction
/// pairs of the remnant, with several vertex removals, decide the answer.
#[test]
fn structured_4d_images_agree_with_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(44);
    let side = 7;
    for trial in 0..40 {
        let mut image = BinaryImage::cube(Dim::Four, side).unwrap();
        for _ in 0..rng.gen_range(1..6) {
            let lo: Vec<usize> = (0..4).map(|_| rng.gen_range(0..side - 1)).collect();
            let hi: Vec<usize> = lo.iter().map(|&l| rng.gen_range(l + 1..=side)).collect();
            let value = rng.gen_bool(0.6) as u8;
            for index in 0..image.len() {
                let c = image.coords(index);
                if (0..4).all(|a| lo[a] <= c[a] && c[a] < hi[a]) {
                    image.data_mut()[index] = value;
                }
            }
        }
        if trial % 4 == 3 {
            // Sprinkle isolated changes: extra components and pinholes.
            for _ in 0..rng.gen_range(1..8) {
                let index = rng.gen_range(0..image.len());
                image.data_mut()[index] ^= 1;
            }
        }
        let expected = reference::topology(&image);
        assert_eq!(topology(&image), expected, "trial {trial}: {image:?}");
        assert_eq!(
            topology(&image.complement()),
            reference::topology(&image.complement()),
            "trial {trial} complemented"
        );
    }
}

/// Both 4D routes, forced, against the reference: thinning the object (its remnant ranked
/// by elimination, and by plain column reduction), and thinning its background (duality), on random images from sparse to nearly full (where the background
/// route is the one `topology` picks), the adversarial images and their complements,
/// carved cubes with cavities of every Table I type, and cavities that reach the border
/// (the background route must fall back).
#[test]
fn both_4d_routes_agree_with_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(80);
    let mut images: Vec<(String, BinaryImage)> = Vec::new();
    for trial in 0..300 {
        let side = [3, 4, 5, 6][trial % 4];
        let density = [0.2, 0.5, 0.7, 0.85, 0.95][trial % 5];
        let image = random_image(&mut rng, &[side; 4], density);
        images.push((format!("random {side}^4 density {density} #{trial}"), image));
    }
    for (name, image) in adversarial(4) {
        images.push((format!("{name} complemented"), image.complement()));
        images.push((name.to_string(), image));
    }
    // A full image: its background is only the padding (and the cavity reaches it).
    let mut full = BinaryImage::cube(Dim::Four, 6).unwrap();
    full.data_mut().fill(1);
    images.push(("full".into(), full.clone()));
    let mut notch = full.clone();
    notch.set(&[0, 2, 3, 3], false);
    notch.set(&[1, 2, 3, 3], false);
    images.push(("notch from the border".into(), notch));
    for (name, object) in [
        ("ball", shape(4, 10, |p| norm(p) <= 2.6)),
        ("S1xB3", shape(4, 12, |p| circle_distance(2.5, p) <= 1.6)),
        (
            "S2xB2",
            shape(4, 12, |p| {
                let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 2.5;
                r * r + p[3] * p[3] <= 1.6 * 1.6
            }),
        ),
        ("two balls", {
            let mut two = shape(4, 12, |p| norm(&[p[0] - 2.5, p[1], p[2], p[3]]) <= 1.6);
            let other = shape(4, 12, |p| norm(&[p[0] + 2.5, p[1], p[2], p[3]]) <= 1.6);
            for (a, &b) in two.data_mut().iter_mut().zip(other.data()) {
                *a |= b;
            }
            two
        }),
    ] {
        images.push((format!("carved {name}"), cavity(&object)));
    }
    let mut by_cores = 0;
    let mut walls = 0;
    let mut general = 0;
    for (name, image) in images {
        let expected = reference::topology(&image);
        // Carved cubes have a foreground wall, so `topology` takes the background route.
        if name.starts_with("carved") {
            assert!(has_foreground_wall(&image, 0), "{name}");
        }
        walls += has_foreground_wall(&image, 0) as usize;
        // The same boxes in the padded copy (`try_topology_padded`).
        assert_eq!(
            has_foreground_wall(&image.padded(1), 1),
            has_foreground_wall(&image, 0),
            "{name}: padded"
        );
        if let Ok(found) = background_cores(image.padded(1), rank_by_elimination).unwrap() {
            assert_eq!(found, expected, "{name}: background cores");
            by_cores += 1;
        } else {
            assert!(!name.starts_with("carved"), "{name} fell back");
        }
        let (found, pivots) =
            topology_by_thinning_with(image.padded(1), rank_by_elimination).unwrap();
        general += pivots;
        assert_eq!(found, expected, "{name}: object route");
        assert_eq!(
            topology_by_thinning_with(image.padded(1), column_reduction)
                .unwrap()
                .0,
            expected,
            "{name}: object route, column reduction"
        );
        assert_eq!(
            topology_by_background(image.padded(1)).unwrap(),
            expected,
            "{name}: background route"
        );
        assert_eq!(topology(&image), expected, "{name}");
    }
    // Most random images keep a core away from the frame; the full image and the notch
    // do not.
    assert!(by_cores > 100, "{by_cores}");
    // Random images mostly have none (their background reaches the border).
    assert!(walls < 100, "{walls}");
    // The object route's elimination met stalled remnants, not only free pivots.
    assert!(general > 0, "{general} general pivots");
}
