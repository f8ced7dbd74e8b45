//! A sample's Betti numbers are computed from `verification_window`: in a carved solid,
//! the box around the cavities grown by one voxel, not the whole solid. Its homology must
//! be the whole image's, in every degree: here on random solids with random cavities (the
//! cut made, and the cases where it must not be: cavities reaching the wall's surface,
//! foreground outside the solid) and on the samples of carve-mode manifests.

use bettimill_grid::BinaryImage;
use bettimill_homology::topology;
use bettimill_plan::Plan;
use bettimill_sample::{foreground_window, make_sample, verification_window};
use bettimill_testkit::Xorshift;

/// Sets every voxel of the inclusive box `lo ..= hi` with `value`, or, when `density` is
/// below 1000, each with probability `density / 1000`.
fn fill(
    image: &mut BinaryImage,
    lo: &[usize],
    hi: &[usize],
    value: bool,
    density: u64,
    rng: &mut Xorshift,
) {
    for v in 0..image.len() {
        let c = image.coords(v);
        if (0..lo.len()).all(|a| lo[a] <= c[a] && c[a] <= hi[a])
            && (density >= 1000 || rng.next_u64() % 1000 < density)
        {
            image.data_mut()[v] = value as u8;
        }
    }
}

/// A solid box in an image with cavities of random voxels in a box inside it, sometimes
/// cavities on the solid's surface and specks of foreground outside it. Returns the image
/// and whether the cut must be made (cavities two voxels in from every face of the solid,
/// nothing outside the solid).
fn carved(rng: &mut Xorshift) -> (BinaryImage, bool) {
    let d = 2 + rng.below(3);
    let (least, spread) = match d {
        2 => (8, 20),
        3 => (8, 10),
        _ => (7, 4),
    };
    let shape: Vec<usize> = (0..d).map(|_| least + rng.below(spread)).collect();
    let mut image = BinaryImage::zeros(&shape).unwrap();
    // The solid: up to two voxels in from each face of the image (or on it).
    let solid_lo: Vec<usize> = (0..d).map(|_| rng.below(3)).collect();
    let solid_hi: Vec<usize> = shape.iter().map(|&n| n - 1 - rng.below(3)).collect();
    fill(&mut image, &solid_lo, &solid_hi, true, 1000, rng);
    // The cavities' box: in most images 2 or 3 voxels in from each face of the solid (the
    // cut is made), in the others 0 to 3 (the cut is made only when each is 2 or more).
    let least_margin = if rng.below(4) == 0 { 0 } else { 2 };
    let mut margin = || least_margin + rng.below(4 - least_margin);
    let cavity_lo: Vec<usize> = (0..d).map(|a| solid_lo[a] + margin()).collect();
    let cavity_hi: Vec<usize> = (0..d)
        .map(|a| (solid_hi[a] - margin()).max(cavity_lo[a]))
        .collect();
    let density = [150, 400, 700, 950][rng.below(4)];
    fill(&mut image, &cavity_lo, &cavity_hi, false, density, rng);
    // Two opposite corners of the cavities' box are background, so the box is the
    // background's bounding box.
    image.set(&cavity_lo, false);
    image.set(&cavity_hi, false);
    let mut cut =
        (0..d).all(|a| cavity_lo[a] >= solid_lo[a] + 2 && cavity_hi[a] + 2 <= solid_hi[a]);
    // Some images get a speck of foreground in the empty space, or a dent in the solid's
    // surface: the window is then not a solid around its cavities.
    match rng.below(6) {
        0 if (0..d).any(|a| solid_lo[a] > 0) => {
            let a = (0..d).find(|&a| solid_lo[a] > 0).unwrap();
            let mut at: Vec<usize> = (0..d)
                .map(|b| solid_lo[b] + rng.below(solid_hi[b] - solid_lo[b] + 1))
                .collect();
            at[a] = 0;
            image.set(&at, true);
            cut = false;
        }
        1 => {
            let mut at: Vec<usize> = (0..d)
                .map(|b| solid_lo[b] + rng.below(solid_hi[b] - solid_lo[b] + 1))
                .collect();
            at[0] = solid_lo[0];
            image.set(&at, false);
            cut = false;
        }
        _ => {}
    }
    (image, cut)
}

#[test]
fn the_verification_window_has_the_homology_of_the_whole_image() {
    let mut rng = Xorshift(0x5eed_0fca_7171_3500);
    let (mut cuts, mut kept) = (0, 0);
    for case in 0..600 {
        let (image, cut) = carved(&mut rng);
        let window = verification_window(&image);
        let whole = topology(&image);
        let part = topology(&window);
        assert_eq!(part, whole, "case {case}: shape {:?}", image.shape());
        let full_window = foreground_window(&image);
        let smaller = window.len() < full_window.len();
        assert_eq!(smaller, cut, "case {case}: shape {:?}", image.shape());
        if cut {
            // The cut image's outer layer is foreground (the cavities are inside it), and
            // it holds every background voxel of the window.
            let w_background = full_window.len() as u64 - full_window.count_foreground();
            assert_eq!(
                window.len() as u64 - window.count_foreground(),
                w_background,
                "case {case}"
            );
            cuts += 1;
        } else {
            assert_eq!(window.data(), full_window.data(), "case {case}");
            kept += 1;
        }
    }
    // Both branches are exercised, each many times.
    assert!(cuts >= 150 && kept >= 150, "{cuts} cut, {kept} kept");
}

/// Carve-mode samples of 2D, 3D and 4D manifests with every deformation: the cut is made
/// and gives the Betti numbers of the whole image (which the label carries).
#[test]
fn carved_samples_are_verified_on_a_cut_with_the_whole_images_homology() {
    let manifests = [
        (2, 32, "[\"ball\", \"handle\"]", 12),
        (
            3,
            28,
            "[\"ball\", \"handle\", \"shell\", \"torus_shell\"]",
            12,
        ),
        (4, 20, "[\"ball\", \"handle\"]", 4),
    ];
    let mut cuts = 0;
    for (dimension, side, families, samples) in manifests {
        let text = format!(
            "schema_version = 1\nname = \"cut\"\ndimension = {dimension}\nside = {side}\n\
             mode = \"carve\"\nsamples = {samples}\nshard_size = {samples}\nseed = 5\n\
             [[deform]]\nmethod = \"dilate\"\nsteps = [0, 2]\ngrowth_probability = [0.2, 0.6]\n\
             noise_frequency = [0.1, 0.3]\n\
             [[deform]]\nmethod = \"tentacles\"\ncount = [1, 3]\nsteps = [0, 8]\n\
             [[deform]]\nmethod = \"moves\"\nsteps = [0, 100]\n\
             [[classes]]\nfamily = {families}\n"
        );
        let plan = Plan::parse(&text, std::path::Path::new("cut.toml")).unwrap();
        for index in 0..plan.samples {
            let sample = make_sample(&plan, &plan.task(index).unwrap()).unwrap();
            let whole = topology(&sample.image);
            assert_eq!(
                whole.betti, sample.label.betti,
                "{dimension}D sample {index}"
            );
            assert_eq!(
                whole.euler, sample.label.euler,
                "{dimension}D sample {index}"
            );
            let window = verification_window(&sample.image);
            assert_eq!(topology(&window), whole, "{dimension}D sample {index}");
            if window.len() < foreground_window(&sample.image).len() {
                cuts += 1;
            }
        }
    }
    assert!(cuts >= 20, "only {cuts} of 28 carved samples were cut");
}
