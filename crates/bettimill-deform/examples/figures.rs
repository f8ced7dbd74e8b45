//! Draws the paper's deformation figures as PNG files (default directory `docs/figures`):
//!
//! - `moves_disc_64.png`, `moves_figure_eight_64.png`: a 64^2 seed (left) and the result of
//!   600 hypervolume-preserving moves (right).
//! - `morphology_2d.png`: a scene of the shape library (curves, annuli, disks with two
//!   holes, some with tentacles) thinned by simple-point erosion (left: a one-voxel-thin
//!   remnant with the same Betti numbers; contractible objects end as single voxels),
//!   three iterations of simple-point dilation of that remnant (middle) and a lumpy
//!   variant where only half of the frontier, at the highest noise, grows (right).
//! - `morphology_3d.png`: the paper's 3D seed scene (`bettimill_shapes::paper_scene_3d`: a
//!   curve, two connected circles, a Hopf link and a trefoil, some with tentacles) at
//!   96^3, thinned the same way (top), and the result of three iterations (bottom),
//!   each as depth-shaded views along two axes.
//!
//! Run with `cargo run --release -p bettimill-deform --example figures [DIR]`. PNG is
//! written by hand (greyscale, one IDAT chunk compressed with flate2), so the example needs
//! no image crate.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]

use bettimill_deform::{deform, DeformSettings, Method};
use bettimill_grid::BinaryImage;
use bettimill_homology::topology;
use bettimill_shapes::{generate, paper_scene_3d, Dim, Family, Generated, Mode};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::io::Write;
use std::path::Path;

/// A greyscale picture, one byte per pixel, row-major.
struct Picture {
    width: usize,
    height: usize,
    pixels: Vec<u8>,
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn write_png(path: &Path, picture: &Picture) -> std::io::Result<()> {
    let mut raw = Vec::with_capacity((picture.width + 1) * picture.height);
    for row in picture.pixels.chunks(picture.width) {
        raw.push(0); // filter: none
        raw.extend_from_slice(row);
    }
    let mut encoder = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    encoder.write_all(&raw)?;
    let z = encoder.finish()?;

    let mut out = vec![0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
    let mut chunk = |kind: &[u8; 4], data: &[u8]| {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32(&body).to_be_bytes());
    };
    let mut header = Vec::new();
    header.extend_from_slice(&(picture.width as u32).to_be_bytes());
    header.extend_from_slice(&(picture.height as u32).to_be_bytes());
    header.extend_from_slice(&[8, 0, 0, 0, 0]); // 8-bit greyscale
    chunk(b"IHDR", &header);
    chunk(b"IDAT", &z);
    chunk(b"IEND", &[]);
    std::fs::write(path, out)
}

/// A 2D image as black foreground on white, each voxel `scale` pixels wide.
fn render_2d(image: &BinaryImage, scale: usize) -> Picture {
    let (h, w) = (image.shape()[0], image.shape()[1]);
    let mut pixels = vec![255u8; h * w * scale * scale];
    for y in 0..h * scale {
        for x in 0..w * scale {
            if image.get(&[y / scale, x / scale]) {
                pixels[y * w * scale + x] = 20;
            }
        }
    }
    Picture {
        width: w * scale,
        height: h * scale,
        pixels,
    }
}

/// A depth-shaded orthographic view of a 3D image along `axis` (near = bright).
fn render_3d(image: &BinaryImage, axis: usize, scale: usize) -> Picture {
    let n = image.shape()[0];
    let others: Vec<usize> = (0..3).filter(|&a| a != axis).collect();
    let mut depth = vec![None; n * n];
    for (i, slot) in depth.iter_mut().enumerate() {
        let (u, v) = (i / n, i % n);
        for t in 0..n {
            let mut c = [0usize; 3];
            c[axis] = t;
            c[others[0]] = u;
            c[others[1]] = v;
            if image.get(&c) {
                *slot = Some(t);
                break;
            }
        }
    }
    let mut pixels = vec![255u8; n * n * scale * scale];
    for y in 0..n * scale {
        for x in 0..n * scale {
            let (u, v) = (y / scale, x / scale);
            if let Some(t) = depth[u * n + v] {
                // Brightness by depth, darkened where the depth jumps (silhouettes).
                let mut shade = 230.0 - 190.0 * t as f64 / n as f64;
                let right = depth[u * n + (v + 1).min(n - 1)].unwrap_or(n);
                let down = depth[(u + 1).min(n - 1) * n + v].unwrap_or(n);
                let jump = (right as f64 - t as f64).abs() + (down as f64 - t as f64).abs();
                shade -= (jump * 12.0).min(120.0);
                pixels[y * n * scale + x] = shade.clamp(0.0, 255.0) as u8;
            }
        }
    }
    Picture {
        width: n * scale,
        height: n * scale,
        pixels,
    }
}

/// Pictures side by side with a grey gap.
fn row(pictures: &[Picture]) -> Picture {
    let gap = 8;
    let height = pictures.iter().map(|p| p.height).max().unwrap_or(0);
    let width = pictures.iter().map(|p| p.width).sum::<usize>() + gap * (pictures.len() - 1);
    let mut pixels = vec![160u8; width * height];
    let mut x0 = 0;
    for p in pictures {
        for y in 0..p.height {
            pixels[y * width + x0..y * width + x0 + p.width]
                .copy_from_slice(&p.pixels[y * p.width..(y + 1) * p.width]);
        }
        x0 += p.width + gap;
    }
    Picture {
        width,
        height,
        pixels,
    }
}

/// Pictures stacked vertically with a grey gap (all the same width).
fn column(pictures: &[Picture]) -> Picture {
    let gap = 8;
    let width = pictures.iter().map(|p| p.width).max().unwrap_or(0);
    let height = pictures.iter().map(|p| p.height).sum::<usize>() + gap * (pictures.len() - 1);
    let mut pixels = vec![160u8; width * height];
    let mut y0 = 0;
    for p in pictures {
        for y in 0..p.height {
            pixels[(y0 + y) * width..(y0 + y) * width + p.width]
                .copy_from_slice(&p.pixels[y * p.width..(y + 1) * p.width]);
        }
        y0 += p.height + gap;
    }
    Picture {
        width,
        height,
        pixels,
    }
}

fn disc(side: usize, radius: f64) -> BinaryImage {
    let mut image = BinaryImage::zeros(&[side, side]).expect("valid shape");
    let c = (side as f64 - 1.0) / 2.0;
    for y in 0..side {
        for x in 0..side {
            let (dx, dy) = (x as f64 - c, y as f64 - c);
            if dx * dx + dy * dy <= radius * radius {
                image.set(&[y, x], true);
            }
        }
    }
    image
}

fn figure_eight(side: usize) -> BinaryImage {
    let mut image = BinaryImage::zeros(&[side, side]).expect("valid shape");
    let r = side as f64 / 5.0;
    let cy = (side as f64 - 1.0) / 2.0;
    for cx in [cy - r, cy + r] {
        for y in 0..side {
            for x in 0..side {
                let d = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt();
                if d <= r + 1.0 && d >= r - 3.0 {
                    image.set(&[y, x], true);
                }
            }
        }
    }
    image
}

fn tentacled(object: Family, tentacles: u32) -> Family {
    Family::Tentacled {
        object: Box::new(object),
        tentacles,
    }
}

/// A scene's image after 200 iterations of simple-point erosion (a thin remnant with the
/// scene's Betti numbers: the seed to grow), and those Betti numbers.
fn thinned(scene: Generated) -> Result<(BinaryImage, Vec<u64>), Box<dyn std::error::Error>> {
    let mut image = scene.image;
    let erode = DeformSettings {
        method: Method::Erode,
        steps: 200,
        ..DeformSettings::default()
    };
    deform(&mut image, &erode, 1)?;
    assert_eq!(topology(&image).betti, scene.betti);
    Ok((image, scene.betti))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "docs/figures".into());
    let dir = Path::new(&dir);
    std::fs::create_dir_all(dir)?;
    let moves = DeformSettings {
        method: Method::Moves,
        steps: 600,
        ..DeformSettings::default()
    };

    for (name, seed_image) in [
        ("moves_disc_64.png", disc(64, 15.0)),
        ("moves_figure_eight_64.png", figure_eight(64)),
    ] {
        let mut moved = seed_image.clone();
        let report = deform(&mut moved, &moves, 1)?;
        assert_eq!(topology(&moved), topology(&seed_image));
        eprintln!("{name}: {report:?}");
        let picture = row(&[render_2d(&seed_image, 4), render_2d(&moved, 4)]);
        write_png(&dir.join(name), &picture)?;
    }

    let objects_2d = Family::Scene {
        objects: vec![
            tentacled(Family::Curve, 1),
            Family::Curve,
            tentacled(Family::Handle, 2),
            Family::Handle,
            Family::Handlebody { genus: 2 },
            tentacled(Family::Handlebody { genus: 2 }, 1),
        ],
    };
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (seed_2d, betti_2d) =
        thinned(generate(&objects_2d, Dim::Two, 128, Mode::Embed, &mut rng)?)?;
    let dilate = DeformSettings {
        method: Method::Dilate,
        steps: 3,
        ..DeformSettings::default()
    };
    let mut full = seed_2d.clone();
    deform(&mut full, &dilate, 3)?;
    let mut lumpy = seed_2d.clone();
    let lumpy_settings = DeformSettings {
        growth_probability: 0.5,
        steps: 6,
        ..dilate.clone()
    };
    deform(&mut lumpy, &lumpy_settings, 3)?;
    for image in [&full, &lumpy] {
        assert_eq!(topology(image).betti, betti_2d);
    }
    eprintln!("morphology_2d: betti {betti_2d:?}");
    let picture = row(&[
        render_2d(&seed_2d, 3),
        render_2d(&full, 3),
        render_2d(&lumpy, 3),
    ]);
    write_png(&dir.join("morphology_2d.png"), &picture)?;

    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (seed_3d, betti_3d) = thinned(paper_scene_3d(96, &mut rng)?)?;
    let mut grown = seed_3d.clone();
    deform(&mut grown, &dilate, 5)?;
    assert_eq!(topology(&grown).betti, betti_3d);
    eprintln!("morphology_3d: betti {betti_3d:?}");
    let picture = column(&[
        row(&[render_3d(&seed_3d, 0, 3), render_3d(&seed_3d, 2, 3)]),
        row(&[render_3d(&grown, 0, 3), render_3d(&grown, 2, 3)]),
    ]);
    write_png(&dir.join("morphology_3d.png"), &picture)?;
    Ok(())
}
