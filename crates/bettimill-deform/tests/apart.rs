//! The components of a deformed phase keep the placement's gap: two objects (or two
//! cavities) that start three voxels apart (two voxels between them) are never brought
//! closer by growth, moves, tentacles, walks or targeting, and the separation is the
//! same on any number of threads. Without it (`apart` = `None`), growth presses them to
//! one voxel apart, which the first test shows.

use bettimill_deform::{
    deform, deform_phase, target_hypervolume, target_hypervolume_phase, Apart, DeformSettings,
    Method, Phase,
};
use bettimill_grid::BinaryImage;
use bettimill_homology::topology;

/// A `side`^3 image of `background`, with two balls of `radius` of the other value centred
/// on the middle row, `gap` background voxels apart along the first axis.
fn two_balls(side: usize, radius: i64, gap: i64, background: u8) -> BinaryImage {
    let mut image = BinaryImage::zeros(&[side, side, side]).unwrap();
    let mid = side as i64 / 2;
    // The balls' innermost voxels sit at mid - 1 - gap / 2 and mid - 1 - gap / 2 + gap + 1.
    let first = mid - 1 - gap / 2 - radius;
    let second = first + 2 * radius + gap + 1;
    for v in 0..image.len() {
        let c = image.coords(v);
        let (x, y, z) = (c[0] as i64, c[1] as i64, c[2] as i64);
        let inside =
            |cx: i64| (x - cx).pow(2) + (y - mid).pow(2) + (z - mid).pow(2) <= radius.pow(2);
        let ball = inside(first) || inside(second);
        image.data_mut()[v] = if ball { 1 - background } else { background };
    }
    image
}

/// The smallest Chebyshev distance between voxels of value `value` in different
/// components (face-connected for 0, (3^3 - 1)-connected for 1), looking up to 7 apart;
/// 8 when no two components come that close.
fn closest_components(image: &BinaryImage, value: u8) -> i64 {
    let shape = image.shape().to_vec();
    let mut labels = vec![0u32; image.len()];
    let mut next = 0;
    let index = |c: [i64; 3]| (c[0] as usize * shape[1] + c[1] as usize) * shape[2] + c[2] as usize;
    let inside = |c: [i64; 3]| (0..3).all(|a| c[a] >= 0 && c[a] < shape[a] as i64);
    for v in 0..image.len() {
        if image.data()[v] != value || labels[v] != 0 {
            continue;
        }
        next += 1;
        labels[v] = next;
        let mut stack = vec![v];
        while let Some(u) = stack.pop() {
            let c = image.coords(u);
            for o in 0..27 {
                let off = [o / 9 - 1, o / 3 % 3 - 1, o % 3 - 1];
                let faces = off.iter().filter(|&&x| x != 0).count();
                if faces == 0 || (value == 0 && faces > 1) {
                    continue;
                }
                let w = [
                    c[0] as i64 + off[0],
                    c[1] as i64 + off[1],
                    c[2] as i64 + off[2],
                ];
                if inside(w) {
                    let w = index(w);
                    if image.data()[w] == value && labels[w] == 0 {
                        labels[w] = next;
                        stack.push(w);
                    }
                }
            }
        }
    }
    let mut closest = 8;
    for v in 0..image.len() {
        if labels[v] == 0 {
            continue;
        }
        let c = image.coords(v);
        for o in 0..15i64.pow(3) {
            let off = [o / 225 - 7, o / 15 % 15 - 7, o % 15 - 7];
            let w = [
                c[0] as i64 + off[0],
                c[1] as i64 + off[1],
                c[2] as i64 + off[2],
            ];
            if inside(w) {
                let l = labels[index(w)];
                if l != 0 && l != labels[v] {
                    closest = closest.min(off.iter().map(|x| x.abs()).max().unwrap());
                }
            }
        }
    }
    closest
}

fn grow(method: Method, steps: u32, count: u32) -> DeformSettings {
    DeformSettings {
        growth_probability: 1.0,
        count,
        ..DeformSettings::new(method, steps)
    }
}

#[test]
fn growth_keeps_two_objects_apart_and_without_the_separation_does_not() {
    let image = two_balls(32, 6, 2, 0);
    assert_eq!(closest_components(&image, 1), 3);
    let before = topology(&image).betti;
    for (method, steps, count) in [
        (Method::Dilate, 8, 1),
        (Method::Moves, 3000, 1),
        (Method::Tentacles, 20, 6),
        (Method::Walk, 80, 4),
    ] {
        let mut out = image.clone();
        let report = deform(&mut out, &grow(method, steps, count), 5).unwrap();
        assert!(report.applied > 0, "{method:?}: {report:?}");
        assert_eq!(topology(&out).betti, before, "{method:?}");
        assert_eq!(closest_components(&out, 1), 3, "{method:?}");
    }
    let mut targeted = image.clone();
    let start = image.count_foreground();
    target_hypervolume(&mut targeted, start * 3, start * 3, 5).unwrap();
    assert_eq!(targeted.count_foreground(), start * 3);
    assert_eq!(closest_components(&targeted, 1), 3);
    // The simple-point rule alone lets growth close the gap to one voxel.
    let mut phase = Phase::foreground(&image);
    let mut pressed = image.clone();
    deform_phase(
        &mut pressed,
        &grow(Method::Dilate, 8, 1),
        &mut phase,
        None,
        5,
    )
    .unwrap();
    assert_eq!(closest_components(&pressed, 1), 2);
}

#[test]
fn growing_cavities_keep_their_gap() {
    // Two cavities in a solid cube; the phase's box keeps two voxels of solid at the faces.
    let image = two_balls(32, 6, 2, 1);
    let lo = [2usize; 3];
    let hi = [29usize; 3];
    let phase = Phase::cavities(&image, &lo, &hi);
    let before = topology(&image).betti;
    for (method, steps) in [(Method::Dilate, 8), (Method::Moves, 3000)] {
        let mut out = image.clone();
        let mut apart = Apart::new(&image, &phase);
        assert!(apart.is_some(), "two cavities are labelled");
        // Each run from `image` starts from the phase made from it.
        let mut deformed = phase;
        let settings = grow(method, steps, 1);
        deform_phase(&mut out, &settings, &mut deformed, apart.as_mut(), 9).unwrap();
        assert_eq!(topology(&out).betti, before, "{method:?}");
        assert_eq!(closest_components(&out, 0), 3, "{method:?}");
    }
    // Targeting a lower foreground count grows the cavities.
    let goal = image.count_foreground() - 2000;
    let targeted = targeted(&image, phase, Apart::new(&image, &phase), goal, 9);
    assert_eq!(closest_components(&targeted, 0), 3);
}

/// `image` brought to exactly `goal` foreground voxels by targeting `phase`, its parts kept
/// apart by `apart`.
fn targeted(
    image: &BinaryImage,
    mut phase: Phase,
    mut apart: Option<Apart>,
    goal: u64,
    seed: u64,
) -> BinaryImage {
    let mut out = image.clone();
    target_hypervolume_phase(&mut out, goal, goal, goal, &mut phase, apart.as_mut(), seed).unwrap();
    assert_eq!(out.count_foreground(), goal);
    out
}

#[test]
fn a_wider_gap_is_kept_as_wide() {
    // Two balls five voxels apart, kept so by growth that would press them to three.
    let image = two_balls(40, 6, 5, 0);
    assert_eq!(closest_components(&image, 1), 6);
    let start = image.count_foreground();
    for gap in [5, 2] {
        let phase = Phase::foreground(&image);
        for (method, steps) in [(Method::Dilate, 8), (Method::Moves, 3000)] {
            let mut out = image.clone();
            let mut apart = Apart::keeping(&image, &phase, gap);
            assert_eq!(apart.as_ref().map(Apart::gap), Some(gap));
            let mut deformed = phase;
            deform_phase(
                &mut out,
                &grow(method, steps, 1),
                &mut deformed,
                apart.as_mut(),
                5,
            )
            .unwrap();
            assert_eq!(
                closest_components(&out, 1),
                gap + 1,
                "{method:?}, gap {gap}"
            );
        }
        let apart = Apart::keeping(&image, &phase, gap);
        let targeted = targeted(&image, phase, apart, start * 3, 5);
        assert_eq!(closest_components(&targeted, 1), gap + 1, "gap {gap}");
    }
}

#[test]
fn separation_is_the_same_on_any_number_of_threads() {
    // Balls big enough that a subfield's decisions go to rayon.
    let image = two_balls(72, 20, 2, 0);
    let run = |threads: usize| {
        let mut out = image.clone();
        let settings = DeformSettings {
            growth_probability: 0.6,
            ..DeformSettings::new(Method::Dilate, 3)
        };
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| deform(&mut out, &settings, 3).unwrap());
        out
    };
    let one = run(1);
    assert_ne!(one, image);
    for threads in [2, 4] {
        assert_eq!(one, run(threads), "{threads} threads");
    }
}
