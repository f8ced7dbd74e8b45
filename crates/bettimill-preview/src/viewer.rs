//! The browser viewer: one self-contained HTML file (no server, no network) in which a
//! researcher slides through the 4th and 3rd axes of a 4D sample (the 3rd of a 3D one),
//! sees the cavities highlighted, reads each slice's own Betti numbers and the label, and
//! switches between the sample and its downscaled copies.
//!
//! Everything the page shows is computed here and embedded as JSON: per image its voxel
//! classes (background reaching the border, foreground, cavity: background the object
//! encloses, as in [`crate::focus::cavities`]) packed four to a byte in base64, the Betti
//! numbers of every 2D slice `a[:, :, k, l]` and, in 4D, of every 3D slice `a[:, :, :, l]`
//! (from `bettimill-homology`, so the page does no topology), and how many cavity voxels
//! each 2D slice holds (the marks under the sliders). The page's JavaScript only draws.

use crate::canvas::{BAR, EMPTY, FOREGROUND};
use crate::focus::cavities;
use crate::PreviewError;
use base64::Engine;
use bettimill_grid::{BinaryImage, Mode};
use serde::Serialize;

/// The page, with `__TITLE__` and `__DATA__` to fill.
const TEMPLATE: &str = include_str!("viewer.html");

/// Images over this many voxels are not embedded (a 64^4 sample is 2^24): the page holds
/// two bits a voxel in base64, and a browser tab would need several times that.
pub const MAX_VOXELS: usize = 1 << 26;

/// The colour of background voxels that reach the image's border.
pub const OUTSIDE: [u8; 3] = EMPTY;
/// The colour of foreground voxels (the object; in carve mode, the solid).
pub const SOLID: [u8; 3] = FOREGROUND;
/// The colour of cavity voxels: background the foreground encloses.
pub const CAVITY: [u8; 3] = BAR;

/// How many pixels the longer side of a slice is drawn at, about.
const TARGET_PIXELS: usize = 512;

/// One image the viewer offers: the sample or one of its downscaled copies.
#[derive(Clone, Debug)]
pub struct ViewerImage<'a> {
    /// A short name for the page's address (`full`, `r16`).
    pub name: String,
    /// What the image selector says (`the sample, 48^4`).
    pub label: String,
    /// The voxels.
    pub image: &'a BinaryImage,
    /// The image's Betti numbers from its label.
    pub betti: Vec<u64>,
    /// A remark after the label's Betti numbers (`preserved by max pooling`).
    pub note: String,
}

#[derive(Serialize)]
struct Colours {
    outside: [u8; 3],
    foreground: [u8; 3],
    cavity: [u8; 3],
}

#[derive(Serialize)]
struct CopyData {
    name: String,
    label: String,
    title: String,
    shape: Vec<usize>,
    betti: Vec<u64>,
    note: String,
    voxels: String,
    /// b0, b1 of every 2D slice, index `k * s3 + l`.
    slices2d: Vec<u64>,
    /// b0, b1, b2 of every 3D slice along the 4th axis (4D only).
    slices3d: Vec<u64>,
    /// Cavity voxels of every 2D slice.
    cavity: Vec<u32>,
    /// The 3rd- and 4th-axis positions shown first.
    start: [usize; 2],
}

#[derive(Serialize)]
struct PageData<'a> {
    title: &'a str,
    caption: &'a [String],
    mode: &'a str,
    target: usize,
    colours: Colours,
    copies: Vec<CopyData>,
}

/// The voxel classes of `image`: 0 background reaching the border, 1 foreground, 2 cavity.
pub fn voxel_classes(image: &BinaryImage) -> Vec<u8> {
    let enclosed = cavities(image);
    image
        .data()
        .iter()
        .enumerate()
        .map(|(i, &v)| match (v != 0, &enclosed) {
            (true, _) => 1,
            (false, Some(c)) if c.data()[i] != 0 => 2,
            _ => 0,
        })
        .collect()
}

/// The image's shape as four axes (missing trailing axes have length 1).
fn shape4(image: &BinaryImage) -> [usize; 4] {
    let mut s = [1; 4];
    s[..image.shape().len()].copy_from_slice(image.shape());
    s
}

/// The 2D slice `a[:, :, k, l]` of `classes` (shape `s`), as foreground and as cavity.
fn slice2d(classes: &[u8], s: [usize; 4], k: usize, l: usize) -> (BinaryImage, u32) {
    let mut data = Vec::with_capacity(s[0] * s[1]);
    let mut cavity = 0;
    for i in 0..s[0] {
        for j in 0..s[1] {
            let c = classes[((i * s[1] + j) * s[2] + k) * s[3] + l];
            data.push((c == 1) as u8);
            cavity += (c == 2) as u32;
        }
    }
    let plane = BinaryImage::from_vec(&[s[0], s[1]], data).expect("a plane of a valid image");
    (plane, cavity)
}

/// The 3D slice `a[:, :, :, l]` of a 4D image.
fn slice3d(image: &BinaryImage, l: usize) -> BinaryImage {
    let s = shape4(image);
    let data = image.data().iter().skip(l).step_by(s[3]).copied().collect();
    BinaryImage::from_vec(&s[..3], data).expect("a slice of a valid image")
}

fn copy_data(view: &ViewerImage) -> Result<CopyData, PreviewError> {
    let image = view.image;
    let s = shape4(image);
    let classes = voxel_classes(image);
    let mut packed = vec![0u8; classes.len().div_ceil(4)];
    for (x, &c) in classes.iter().enumerate() {
        packed[x / 4] |= c << ((x % 4) * 2);
    }
    let mut slices2d = Vec::with_capacity(2 * s[2] * s[3]);
    let mut cavity = Vec::with_capacity(s[2] * s[3]);
    // Shown first: the slice with the most cavity voxels, then the most holes, then the
    // most foreground; the middle when all are alike.
    let mut best = (0u32, 0u64, 0usize, s[2] / 2, s[3] / 2);
    for k in 0..s[2] {
        for l in 0..s[3] {
            let (plane, cavities) = slice2d(&classes, s, k, l);
            let betti = bettimill_homology::try_topology(&plane)?.betti;
            let score = (cavities, betti[1], plane.count_foreground() as usize);
            if score > (best.0, best.1, best.2) {
                best = (score.0, score.1, score.2, k, l);
            }
            slices2d.extend_from_slice(&betti);
            cavity.push(cavities);
        }
    }
    let mut slices3d = Vec::new();
    if image.shape().len() == 4 {
        for l in 0..s[3] {
            slices3d.extend(bettimill_homology::try_topology(&slice3d(image, l))?.betti);
        }
    }
    let sides: Vec<String> = image.shape().iter().map(|n| n.to_string()).collect();
    Ok(CopyData {
        name: view.name.clone(),
        label: view.label.clone(),
        title: format!("shape {}", sides.join("x")),
        shape: image.shape().to_vec(),
        betti: view.betti.clone(),
        note: view.note.clone(),
        voxels: base64::engine::general_purpose::STANDARD.encode(&packed),
        slices2d,
        slices3d,
        cavity,
        start: [best.3, best.4],
    })
}

/// Escapes text for an HTML element's content.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The viewer page for `images` (the sample first), titled `title`, with the label's
/// `caption` lines. Images over [`MAX_VOXELS`] are refused.
pub fn viewer_html(
    title: &str,
    caption: &[String],
    mode: Mode,
    images: &[ViewerImage],
) -> Result<String, PreviewError> {
    if images.is_empty() {
        return Err(PreviewError::Empty);
    }
    let mut copies = Vec::with_capacity(images.len());
    for view in images {
        if view.image.len() > MAX_VOXELS {
            return Err(PreviewError::TooManyVoxels {
                name: view.name.clone(),
                voxels: view.image.len(),
            });
        }
        copies.push(copy_data(view)?);
    }
    let data = PageData {
        title,
        caption,
        mode: mode.name(),
        target: TARGET_PIXELS,
        colours: Colours {
            outside: OUTSIDE,
            foreground: SOLID,
            cavity: CAVITY,
        },
        copies,
    };
    // Inside a <script> element a "</" could close it: JSON allows "<\/" for the same text.
    let json = serde_json::to_string(&data)
        .expect("the page data serialises")
        .replace("</", "<\\/");
    Ok(TEMPLATE
        .replace("__TITLE__", &escape(title))
        .replace("__DATA__", &json))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4D solid cube with a cavity ball in the middle (and a one-voxel margin).
    fn carved_ball(side: usize) -> BinaryImage {
        let mut image = BinaryImage::zeros(&[side; 4]).unwrap();
        let c = (side as f64 - 1.0) / 2.0;
        for i in 0..image.len() {
            let x = image.coords(i);
            let inside = (0..4).all(|a| x[a] >= 1 && x[a] + 1 < side);
            let r2: f64 = (0..4).map(|a| (x[a] as f64 - c).powi(2)).sum();
            image.data_mut()[i] = (inside && r2 > 6.0) as u8;
        }
        image
    }

    fn page_data(html: &str) -> serde_json::Value {
        let start = html.find("id=\"data\">").unwrap() + "id=\"data\">".len();
        let end = start + html[start..].find("</script>").unwrap();
        serde_json::from_str(&html[start..end]).unwrap()
    }

    #[test]
    fn the_page_is_self_contained_and_carries_every_slice() {
        let image = carved_ball(10);
        let betti = bettimill_homology::topology(&image).betti;
        assert_eq!(betti, vec![1, 0, 0, 1]);
        let caption = vec!["s000001 </script><b>".to_string()];
        let views = [ViewerImage {
            name: "full".into(),
            label: "the sample".into(),
            image: &image,
            betti: betti.clone(),
            note: String::new(),
        }];
        let html = viewer_html("s000001 <x>", &caption, Mode::Carve, &views).unwrap();
        assert_eq!(
            html,
            viewer_html("s000001 <x>", &caption, Mode::Carve, &views).unwrap()
        );
        for outside in ["http://", "https://", "src=", "href=", "@import", "fetch("] {
            assert!(
                !html.contains(outside),
                "the page refers outside: {outside}"
            );
        }
        assert!(html.contains("<title>s000001 &lt;x&gt;</title>"));
        let data = page_data(&html);
        assert_eq!(data["caption"][0], "s000001 </script><b>");
        let copy = &data["copies"][0];
        // Every voxel's class survives the packing.
        let packed = base64::engine::general_purpose::STANDARD
            .decode(copy["voxels"].as_str().unwrap())
            .unwrap();
        let classes = voxel_classes(&image);
        for (x, &c) in classes.iter().enumerate() {
            assert_eq!((packed[x / 4] >> ((x % 4) * 2)) & 3, c, "voxel {x}");
        }
        assert!(classes.contains(&2) && classes.contains(&1) && classes.contains(&0));
        // Each 2D slice's Betti numbers and cavity count are that slice's own.
        let slices = copy["slices2d"].as_array().unwrap();
        assert_eq!(slices.len(), 2 * 100);
        for (k, l) in [(0, 0), (4, 5), (5, 4), (9, 2)] {
            let (plane, cavity) = slice2d(&classes, [10; 4], k, l);
            let b = bettimill_homology::topology(&plane).betti;
            let x = k * 10 + l;
            assert_eq!(slices[2 * x], b[0]);
            assert_eq!(slices[2 * x + 1], b[1]);
            assert_eq!(copy["cavity"][x], cavity);
        }
        // Through the ball's middle the slice is a square ring of solid: one hole.
        assert_eq!(
            (slices[2 * 45].as_u64(), slices[2 * 45 + 1].as_u64()),
            (Some(1), Some(1))
        );
        let start = copy["start"].as_array().unwrap();
        let (k, l) = (start[0].as_u64().unwrap(), start[1].as_u64().unwrap());
        assert!(copy["cavity"][(k * 10 + l) as usize].as_u64().unwrap() > 0);
        // 3D slices: the middle one holds the ball's cavity.
        let volume = bettimill_homology::topology(&slice3d(&image, 4)).betti;
        assert_eq!(volume, vec![1, 0, 1]);
        assert_eq!(copy["slices3d"][12], 1);
        assert_eq!(copy["slices3d"].as_array().unwrap().len(), 30);
    }

    #[test]
    fn images_of_every_dimension_fit_and_huge_ones_are_refused() {
        for shape in [vec![7, 5], vec![4, 6, 3]] {
            let mut image = BinaryImage::zeros(&shape).unwrap();
            image.data_mut()[3] = 1;
            let views = [ViewerImage {
                name: "full".into(),
                label: "x".into(),
                image: &image,
                betti: vec![1; shape.len()],
                note: String::new(),
            }];
            let data = page_data(&viewer_html("t", &[], Mode::Embed, &views).unwrap());
            let n = shape.get(2).copied().unwrap_or(1);
            assert_eq!(
                data["copies"][0]["slices2d"].as_array().unwrap().len(),
                2 * n
            );
        }
        assert!(matches!(
            viewer_html("t", &[], Mode::Embed, &[]),
            Err(PreviewError::Empty)
        ));
    }
}
