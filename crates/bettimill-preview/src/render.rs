//! Layouts: one sample as a captioned picture, and contact sheets of many samples.
//!
//! - 2D: the image as it is, scaled up by nearest neighbour to a readable size.
//! - 3D: a projection along the first axis (darker where more voxels lie along the ray),
//!   then slices along the first axis (all of them, or evenly spaced ones for large sides).
//! - 4D: one row per 3D slice along the first axis; each row shows that 3D slice's
//!   projection and its 2D slices along its own first axis.
//!
//! Rows of a plane are the image's second-to-last axis, columns its last axis, so a 2D
//! array shows the way `matplotlib.pyplot.imshow` shows it.

use crate::canvas::{Canvas, Plane, FRAME, INK, MUTED, PAGE};
use crate::font;
use crate::PreviewError;
use bettimill_format::Label;
use bettimill_grid::BinaryImage;

const MARGIN: usize = 16;
const GAP: usize = 8;
const CAPTION_SCALE: usize = 2;
/// Height of a one-line label under a tile (font scale 1).
const TILE_LABEL: usize = font::LINE_HEIGHT + 2;

/// The caption lines for a labelled sample.
pub fn caption(label: &Label) -> Vec<String> {
    let shape: Vec<String> = label.shape.iter().map(|n| n.to_string()).collect();
    let voxels: u64 = label.shape.iter().map(|&n| n as u64).product();
    let percent = if voxels == 0 {
        0.0
    } else {
        label.hypervolume as f64 * 100.0 / voxels as f64
    };
    let mut lines = vec![
        format!(
            "{}  class {}: {}",
            label.key, label.stratum, label.class_label
        ),
        format!(
            "betti {}  euler {}  ({})",
            betti_text(&label.betti),
            label.euler,
            label.field
        ),
        format!(
            "family {}  mode {}  components {}",
            label.family, label.mode, label.components
        ),
        format!(
            "hypervolume {} of {} voxels ({percent:.1}%)  shape {}",
            label.hypervolume,
            voxels,
            shape.join("x")
        ),
    ];
    if label.knot_type != "none" {
        lines.push(format!("knot/link {}", label.knot_type));
    }
    if let Some(rational) = &label.betti_rational {
        lines.push(format!("betti over Q {}", betti_text(rational)));
    }
    lines
}

/// `[1, 0, 0]`.
pub fn betti_text(betti: &[u64]) -> String {
    let parts: Vec<String> = betti.iter().map(|b| b.to_string()).collect();
    format!("[{}]", parts.join(", "))
}

/// What the picture of a `dim`-dimensional image shows, as one caption line.
pub fn legend(image: &BinaryImage) -> String {
    match image.dim().get() {
        2 => "2D image: rows = axis 0, columns = axis 1".to_string(),
        3 => "3D: projection along axis 0 (darker = more voxels), then slices i of axis 0"
            .to_string(),
        _ => "4D: rows = slices i of axis 0; in each, projection along axis 1, slices j of axis 1"
            .to_string(),
    }
}

fn slice_plane(data: &[u8], rows: usize, cols: usize) -> Plane {
    Plane {
        rows,
        cols,
        values: data.iter().map(|&v| if v != 0 { 255 } else { 0 }).collect(),
    }
}

/// Counts foreground voxels along `layers` stacked `rows x cols` slices; an empty ray is
/// 0, a ray with any voxel at least a clearly visible 96.
fn projection_plane(data: &[u8], layers: usize, rows: usize, cols: usize) -> Plane {
    let area = rows * cols;
    let mut counts = vec![0usize; area];
    for layer in data.chunks(area).take(layers) {
        for (count, &v) in counts.iter_mut().zip(layer) {
            *count += (v != 0) as usize;
        }
    }
    let values = counts
        .iter()
        .map(|&c| {
            if c == 0 {
                0
            } else {
                (96 + 159 * c / layers.max(1)) as u8
            }
        })
        .collect();
    Plane { rows, cols, values }
}

/// `n` indices or `max` evenly spaced ones among `0..n`, first and last included.
fn pick(n: usize, max: usize) -> Vec<usize> {
    if n <= max || max < 2 {
        (0..n.min(max.max(1))).collect()
    } else {
        (0..max).map(|k| k * (n - 1) / (max - 1)).collect()
    }
}

/// Up to `max` evenly spaced indices among the slices of `data` (`n` slices of `slice_len`
/// values) that hold foreground, widened by one empty slice on each side so the reader sees
/// where the object ends; all of `0..n` when nothing is foreground.
fn pick_occupied(data: &[u8], n: usize, slice_len: usize, max: usize) -> Vec<usize> {
    let occupied = |i: &usize| {
        data[i * slice_len..(i + 1) * slice_len]
            .iter()
            .any(|&v| v != 0)
    };
    let (Some(first), Some(last)) = ((0..n).find(occupied), (0..n).rev().find(occupied)) else {
        return pick(n, max);
    };
    let lo = first.saturating_sub(1);
    let hi = (last + 1).min(n - 1);
    pick(hi - lo + 1, max).into_iter().map(|i| lo + i).collect()
}

/// The factor that makes the longer side of a plane about `target` pixels (at least 1).
fn scale_for(rows: usize, cols: usize, target: usize) -> usize {
    (target / rows.max(cols).max(1)).max(1)
}

/// A titled tile: a plane drawn at a scale with a short label underneath.
struct Tile {
    plane: Plane,
    label: String,
}

fn tile_size(tile: &Tile, scale: usize) -> (usize, usize) {
    (
        (tile.plane.cols * scale).max(font::text_width(&tile.label, 1)),
        tile.plane.rows * scale + TILE_LABEL,
    )
}

fn draw_tile(canvas: &mut Canvas, x: usize, y: usize, tile: &Tile, scale: usize) {
    let (w, h) = (tile.plane.cols * scale, tile.plane.rows * scale);
    canvas.plane(x, y, &tile.plane, scale);
    canvas.frame(
        x.saturating_sub(1),
        y.saturating_sub(1),
        w + 2,
        h + 2,
        FRAME,
    );
    canvas.text(x, y + h + 3, &tile.label, 1, MUTED);
}

/// The tiles of one sample's body, as rows of tiles.
fn body_rows(image: &BinaryImage) -> (Vec<(String, Vec<Tile>)>, usize) {
    let shape = image.shape();
    let data = image.data();
    match image.dim().get() {
        2 => {
            let (rows, cols) = (shape[0], shape[1]);
            let tile = Tile {
                plane: slice_plane(data, rows, cols),
                label: String::new(),
            };
            (
                vec![(String::new(), vec![tile])],
                scale_for(rows, cols, 512),
            )
        }
        3 => {
            let (layers, rows, cols) = (shape[0], shape[1], shape[2]);
            let scale = scale_for(rows, cols, 128);
            let max = if rows.max(cols) * scale > 160 { 12 } else { 24 };
            let mut tiles = vec![Tile {
                plane: projection_plane(data, layers, rows, cols),
                label: "projection".to_string(),
            }];
            let area = rows * cols;
            for i in pick_occupied(data, layers, area, max) {
                tiles.push(Tile {
                    plane: slice_plane(&data[i * area..(i + 1) * area], rows, cols),
                    label: format!("i={i}"),
                });
            }
            // A near-square grid of tiles.
            let per_row = (1..).find(|k| k * k >= tiles.len()).unwrap_or(1);
            let mut grid = Vec::new();
            let mut tiles = tiles.into_iter().peekable();
            while tiles.peek().is_some() {
                grid.push((String::new(), tiles.by_ref().take(per_row).collect()));
            }
            (grid, scale)
        }
        _ => {
            let (blocks, layers, rows, cols) = (shape[0], shape[1], shape[2], shape[3]);
            let scale = scale_for(rows, cols, 64);
            let area = rows * cols;
            let block = layers * area;
            let mut grid = Vec::new();
            for i in pick_occupied(data, blocks, block, 8) {
                let block_data = &data[i * block..(i + 1) * block];
                let mut tiles = vec![Tile {
                    plane: projection_plane(block_data, layers, rows, cols),
                    label: "proj".to_string(),
                }];
                for j in pick_occupied(block_data, layers, area, 12) {
                    tiles.push(Tile {
                        plane: slice_plane(&block_data[j * area..(j + 1) * area], rows, cols),
                        label: format!("j={j}"),
                    });
                }
                grid.push((format!("i={i}"), tiles));
            }
            (grid, scale)
        }
    }
}

/// One sample as a picture: caption lines on top, then the body described in the module
/// documentation.
pub fn render_sample(image: &BinaryImage, caption: &[String]) -> Result<Canvas, PreviewError> {
    let mut lines: Vec<String> = caption.to_vec();
    lines.push(legend(image));
    let (rows, scale) = body_rows(image);
    let row_label_width = rows
        .iter()
        .map(|(label, _)| font::text_width(label, 1))
        .max()
        .unwrap_or(0);
    let row_label_width = if row_label_width > 0 {
        row_label_width + GAP
    } else {
        0
    };
    // Every tile of a sample has the same plane size, so one cell size fits all.
    let (cell_w, cell_h) = rows
        .iter()
        .flat_map(|(_, tiles)| tiles.iter())
        .map(|tile| tile_size(tile, scale))
        .fold((0, 0), |(w, h), (tw, th)| (w.max(tw), h.max(th)));
    let per_row = rows.iter().map(|(_, t)| t.len()).max().unwrap_or(0);
    let body_w = row_label_width + per_row * (cell_w + GAP);
    let body_h = rows.len() * (cell_h + GAP);
    let caption_h = lines.len() * font::LINE_HEIGHT * CAPTION_SCALE + GAP;
    let caption_w = lines
        .iter()
        .map(|l| font::text_width(l, CAPTION_SCALE))
        .max()
        .unwrap_or(0);
    let mut canvas = Canvas::new(
        2 * MARGIN + body_w.max(caption_w),
        2 * MARGIN + caption_h + body_h,
        PAGE,
    )?;
    for (n, line) in lines.iter().enumerate() {
        let colour = if n + 1 == lines.len() { MUTED } else { INK };
        canvas.text(
            MARGIN,
            MARGIN + n * font::LINE_HEIGHT * CAPTION_SCALE,
            line,
            CAPTION_SCALE,
            colour,
        );
    }
    let top = MARGIN + caption_h;
    for (r, (label, tiles)) in rows.iter().enumerate() {
        let y = top + r * (cell_h + GAP);
        canvas.text(MARGIN, y + (cell_h - TILE_LABEL) / 2, label, 1, INK);
        for (c, tile) in tiles.iter().enumerate() {
            let x = MARGIN + row_label_width + c * (cell_w + GAP);
            draw_tile(&mut canvas, x, y, tile, scale);
        }
    }
    Ok(canvas)
}

/// The 2D slice (among `layers` slices of `area` voxels) whose foreground covers closest to
/// half of it, the first on ties: the widest cross-section of an object in empty space, the
/// widest cavity in a solid cube, so a single slice shows as much of the shape as one can.
fn most_mixed_slice(data: &[u8], layers: usize, area: usize) -> usize {
    (0..layers)
        .min_by_key(|&i| {
            let count = data[i * area..(i + 1) * area]
                .iter()
                .filter(|&&v| v != 0)
                .count();
            (2 * count).abs_diff(area)
        })
        .unwrap_or(0)
}

/// The small views of one sample in a contact sheet: the image itself in 2D; in 3D and 4D
/// a projection along every axis but the last two, and the most telling 2D slice
/// ([`most_mixed_slice`]).
fn thumbnails(image: &BinaryImage) -> Vec<Tile> {
    let shape = image.shape();
    let data = image.data();
    let d = shape.len();
    let (rows, cols) = (shape[d - 2], shape[d - 1]);
    let area = rows * cols;
    if d == 2 {
        return vec![Tile {
            plane: slice_plane(data, rows, cols),
            label: String::new(),
        }];
    }
    let layers: usize = shape[..d - 2].iter().product();
    let slice = most_mixed_slice(data, layers, area);
    let label = if d == 3 {
        format!("i={slice}")
    } else {
        format!("i={},j={}", slice / shape[1], slice % shape[1])
    };
    vec![
        Tile {
            plane: projection_plane(data, layers, rows, cols),
            label: "proj".to_string(),
        },
        Tile {
            plane: slice_plane(&data[slice * area..(slice + 1) * area], rows, cols),
            label,
        },
    ]
}

/// A grid of samples, each shown small with a few caption lines (font scale 1).
pub fn contact_sheet(samples: &[(BinaryImage, Vec<String>)]) -> Result<Canvas, PreviewError> {
    if samples.is_empty() {
        return Err(PreviewError::Empty);
    }
    let cells: Vec<(Vec<Tile>, usize, Vec<String>)> = samples
        .iter()
        .map(|(image, caption)| {
            let shape = image.shape();
            let d = shape.len();
            let scale = scale_for(shape[d - 2], shape[d - 1], 128);
            let tiles = thumbnails(image);
            let views_w: usize = tiles.iter().map(|t| tile_size(t, scale).0 + GAP).sum();
            let caption = wrap(caption, (views_w / font::ADVANCE).max(20));
            (tiles, scale, caption)
        })
        .collect();
    let cell_size = |(tiles, scale, caption): &(Vec<Tile>, usize, Vec<String>)| {
        let views_w: usize = tiles.iter().map(|t| tile_size(t, *scale).0 + GAP).sum();
        let views_h = tiles
            .iter()
            .map(|t| tile_size(t, *scale).1)
            .max()
            .unwrap_or(0);
        let text_w = caption
            .iter()
            .map(|l| font::text_width(l, 1))
            .max()
            .unwrap_or(0);
        (
            views_w.max(text_w + GAP),
            views_h + GAP + caption.len() * font::LINE_HEIGHT,
        )
    };
    let (cell_w, cell_h) = cells
        .iter()
        .map(cell_size)
        .fold((0, 0), |(w, h), (cw, ch)| (w.max(cw), h.max(ch)));
    let per_row = (1..).find(|k| k * k >= cells.len()).unwrap_or(1);
    let n_rows = cells.len().div_ceil(per_row);
    let mut canvas = Canvas::new(
        2 * MARGIN + per_row * (cell_w + GAP),
        2 * MARGIN + n_rows * (cell_h + 2 * GAP),
        PAGE,
    )?;
    for (n, (tiles, scale, caption)) in cells.iter().enumerate() {
        let x0 = MARGIN + (n % per_row) * (cell_w + GAP);
        let y0 = MARGIN + (n / per_row) * (cell_h + 2 * GAP);
        let mut x = x0;
        let mut views_h = 0;
        for tile in tiles {
            draw_tile(&mut canvas, x, y0, tile, *scale);
            let (w, h) = tile_size(tile, *scale);
            x += w + GAP;
            views_h = views_h.max(h);
        }
        for (k, line) in caption.iter().enumerate() {
            let colour = if k == 0 { INK } else { MUTED };
            canvas.text(
                x0,
                y0 + views_h + GAP + k * font::LINE_HEIGHT,
                line,
                1,
                colour,
            );
        }
    }
    Ok(canvas)
}

/// Breaks every line longer than `width` characters, after the last `,` or space that
/// keeps a piece within `width` (or at `width` when there is none), so long class names
/// do not widen every cell of a contact sheet.
fn wrap(lines: &[String], width: usize) -> Vec<String> {
    let mut out = Vec::new();
    for line in lines {
        let mut rest: Vec<char> = line.chars().collect();
        while rest.len() > width {
            let cut = rest[..width]
                .iter()
                .rposition(|&c| c == ',' || c == ' ')
                .map_or(width, |i| i + 1);
            out.push(
                rest[..cut]
                    .iter()
                    .collect::<String>()
                    .trim_end()
                    .to_string(),
            );
            rest.drain(..cut);
        }
        out.push(rest.into_iter().collect());
    }
    out
}

/// The short caption of a sample in a contact sheet.
pub fn short_caption(label: &Label) -> Vec<String> {
    vec![
        label.key.clone(),
        format!("betti {}", betti_text(&label.betti)),
        format!("{} {}", label.family, label.mode),
        format!("hypervolume {}", label.hypervolume),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canvas::{EMPTY, FOREGROUND};

    #[test]
    fn pick_spreads_evenly_and_keeps_both_ends() {
        assert_eq!(pick(5, 24), vec![0, 1, 2, 3, 4]);
        assert_eq!(pick(100, 5), vec![0, 24, 49, 74, 99]);
    }

    #[test]
    fn slices_are_picked_where_the_foreground_is() {
        // Five 1x2 slices, foreground only in slice 3.
        let data = [0, 0, 0, 0, 0, 0, 1, 0, 0, 0];
        assert_eq!(pick_occupied(&data, 5, 2, 24), vec![2, 3, 4]);
        assert_eq!(pick_occupied(&[0; 10], 5, 2, 24), vec![0, 1, 2, 3, 4]);
    }

    #[test]
    fn the_thumbnail_slice_is_the_one_closest_to_half_full() {
        // Three 1x4 slices holding 0, 3 and 2 voxels.
        let data = [0, 0, 0, 0, 1, 1, 1, 0, 1, 1, 0, 0];
        assert_eq!(most_mixed_slice(&data, 3, 4), 2);
    }

    #[test]
    fn long_caption_lines_wrap_after_commas_or_spaces() {
        let lines = vec![
            "scene(curve,handle,knot) carve".to_string(),
            "short".to_string(),
        ];
        assert_eq!(
            wrap(&lines, 12),
            vec!["scene(curve,", "handle,", "knot) carve", "short"]
        );
        assert_eq!(wrap(&["abcdefgh".to_string()], 3), vec!["abc", "def", "gh"]);
    }

    #[test]
    fn projection_is_darker_where_more_voxels_lie_along_the_ray() {
        // Two 1x3 layers: column 0 empty, column 1 in one layer, column 2 in both.
        let plane = projection_plane(&[0, 1, 1, 0, 0, 1], 2, 1, 3);
        assert_eq!(plane.values[0], 0);
        assert!(plane.values[1] >= 96);
        assert_eq!(plane.values[2], 255);
        assert!(plane.values[1] < plane.values[2]);
    }

    #[test]
    fn a_2d_pixel_becomes_a_block_of_foreground_colour() {
        let mut image = BinaryImage::zeros(&[8, 8]).unwrap();
        image.set(&[2, 5], true);
        let canvas = render_sample(&image, &["test".to_string()]).unwrap();
        // 512 / 8 = 64 pixels per voxel, below a two-line caption.
        let top = MARGIN + 2 * font::LINE_HEIGHT * CAPTION_SCALE + GAP;
        let at = |row: usize, col: usize| canvas.pixel(MARGIN + col * 64 + 10, top + row * 64 + 10);
        assert_eq!(at(2, 5), Some(FOREGROUND));
        assert_eq!(at(5, 2), Some(EMPTY));
        assert_eq!(at(0, 0), Some(EMPTY));
    }

    #[test]
    fn every_dimension_renders_and_equal_inputs_give_equal_bytes() {
        for shape in [vec![9, 7], vec![6, 5, 4], vec![3, 4, 5, 6]] {
            let mut image = BinaryImage::zeros(&shape).unwrap();
            let n = image.len();
            for i in (0..n).step_by(3) {
                image.data_mut()[i] = 1;
            }
            let a = render_sample(&image, &["x".to_string()]).unwrap().to_png();
            let b = render_sample(&image, &["x".to_string()]).unwrap().to_png();
            assert_eq!(a, b);
            let sheet = contact_sheet(&[(image.clone(), vec!["k".to_string()])]).unwrap();
            assert!(sheet.width() > 0);
        }
        assert!(matches!(contact_sheet(&[]), Err(PreviewError::Empty)));
    }
}
