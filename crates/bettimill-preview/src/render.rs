//! Layouts: one sample as a captioned picture, and contact sheets of many samples.
//!
//! Every view is cropped to the object (embed) or the cavities (carve) plus a small margin,
//! and cut where the topology shows ([`crate::focus`]): the plane of the slices is the pair
//! of axes whose slice (or, failing that, thin slab) shows the most holes, and that view is
//! always drawn, outlined.
//! Axes are named i, j, k, l (axes 0, 1, 2, 3 of the array), positions are those of the
//! whole array, and every slice is labelled with its own Betti numbers.
//!
//! - 2D: the image as it is (cropped), scaled up by nearest neighbour to a readable size.
//! - 3D: a projection along the sliced axis, then the slices along it that hold part of
//!   the object (all of them, or evenly spaced ones, the chosen one included).
//! - 4D: one row per 3D slice along the first sliced axis (with its own Betti numbers);
//!   each row shows that 3D slice's projection and its 2D slices along the second.
//!
//! Rows of a plane are its first axis, columns its second, so a 2D array shows the way
//! `matplotlib.pyplot.imshow` shows it.

use crate::canvas::{Canvas, Plane, BAR, FRAME, INK, MUTED, PAGE};
use crate::focus::{arrange, choose_slice, slab_view, slice_betti, spread, Choice, Focus};
use crate::font;
use crate::PreviewError;
use bettimill_format::Label;
use bettimill_grid::{BinaryImage, Mode};

const MARGIN: usize = 16;
const GAP: usize = 8;
/// Height of a one-line label under a tile, in pixels.
fn tile_label() -> usize {
    font::line_height(font::SMALL) + 4
}
/// The names of the axes in pictures.
const AXES: [char; 4] = ['i', 'j', 'k', 'l'];

/// What a picture knows of a sample besides its voxels.
#[derive(Clone, Copy, Debug)]
pub struct Subject<'a> {
    /// The voxels.
    pub image: &'a BinaryImage,
    /// Embed (the foreground is the object) or carve (the cavities are).
    pub mode: Mode,
    /// The sample's Betti numbers (from its label, or computed).
    pub betti: &'a [u64],
}

impl Subject<'_> {
    /// b1 + ... + b_{d-1}: how many holes and cavities a slice could show.
    fn holes(&self) -> u64 {
        self.betti.iter().skip(1).sum()
    }
}

/// The mode named by a label (`carve`, otherwise embed).
pub fn label_mode(label: &Label) -> Mode {
    if label.mode == Mode::Carve.name() {
        Mode::Carve
    } else {
        Mode::Embed
    }
}

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

/// `[1,0,0]`, for tile labels.
fn betti_short(betti: &[u64]) -> String {
    let parts: Vec<String> = betti.iter().map(|b| b.to_string()).collect();
    format!("[{}]", parts.join(","))
}

/// `a[3:20, 5:18]`: the drawn box as a numpy slice.
fn box_text(crop: &[std::ops::Range<usize>]) -> String {
    let parts: Vec<String> = crop
        .iter()
        .map(|r| format!("{}:{}", r.start, r.end))
        .collect();
    format!("a[{}]", parts.join(", "))
}

/// `k=12`.
fn at_text(axis: usize, at: usize) -> String {
    format!("{}={at}", AXES[axis])
}

/// What the picture shows, as caption lines.
fn legend(focus: &Focus, choice: Option<&Choice>) -> Vec<String> {
    let d = focus.interest.dim().get();
    let names: Vec<String> = AXES[..d].iter().map(|c| c.to_string()).collect();
    let what = match focus.mode {
        Mode::Embed => "the object",
        Mode::Carve => "the cavities",
    };
    let mut lines = vec![format!(
        "{d}D, axes {}: shown {} ({what} and {} voxels around)",
        names.join(","),
        box_text(&focus.crop),
        crate::focus::MARGIN
    )];
    let Some(choice) = choice else {
        lines.push(format!("rows = {}, columns = {}", AXES[0], AXES[1]));
        return lines;
    };
    let o = &choice.order;
    let projection = match focus.mode {
        Mode::Embed => "darker = more voxels",
        Mode::Carve => "lighter = more cavity",
    };
    lines.push(if d == 3 {
        format!(
            "projection along {} ({projection}), then slices {}=.. (rows {}, columns {})",
            AXES[o[0]], AXES[o[0]], AXES[o[1]], AXES[o[2]]
        )
    } else {
        format!(
            "rows: 3D slices {}=..; in each, projection along {} ({projection}), slices {}=.. (rows {}, columns {})",
            AXES[o[0]], AXES[o[1]], AXES[o[1]], AXES[o[2]], AXES[o[3]]
        )
    });
    lines.push(
        "[..] = each view's own betti numbers; outlined: the slice (or i=a:b, the union of slices a..b-1) that best shows a hole"
            .to_string(),
    );
    lines
}

fn slice_plane(data: &[u8], rows: usize, cols: usize) -> Plane {
    Plane {
        rows,
        cols,
        values: data.iter().map(|&v| if v != 0 { 255 } else { 0 }).collect(),
    }
}

/// Counts voxels of interest along `layers` stacked `rows x cols` slices. Embed: an empty
/// ray is 0, a ray with any voxel at least a clearly visible 96, darker with more. Carve:
/// a ray through solid only is 255, a ray through any cavity at most 159, lighter with more.
fn projection_plane(interest: &[u8], layers: usize, rows: usize, cols: usize, mode: Mode) -> Plane {
    let area = rows * cols;
    let mut counts = vec![0usize; area];
    for layer in interest.chunks(area).take(layers) {
        for (count, &v) in counts.iter_mut().zip(layer) {
            *count += (v != 0) as usize;
        }
    }
    let layers = layers.max(1);
    let values = counts
        .iter()
        .map(|&c| match (mode, c) {
            (Mode::Embed, 0) => 0,
            (Mode::Embed, c) => (96 + 159 * c / layers) as u8,
            (Mode::Carve, 0) => 255,
            (Mode::Carve, c) => (159 - 159 * c / layers) as u8,
        })
        .collect();
    Plane { rows, cols, values }
}

/// The factor that makes the longer side of a plane about `target` pixels (at least 1).
fn scale_for(rows: usize, cols: usize, target: usize) -> usize {
    (target / rows.max(cols).max(1)).max(1)
}

/// A titled tile: a plane drawn at a scale with a short label underneath.
struct Tile {
    plane: Plane,
    label: String,
    /// Outlined: the chosen slice.
    chosen: bool,
}

impl Tile {
    fn new(plane: Plane, label: String) -> Tile {
        Tile {
            plane,
            label,
            chosen: false,
        }
    }
}

fn tile_size(tile: &Tile, scale: usize) -> (usize, usize) {
    (
        (tile.plane.cols * scale).max(font::text_width(&tile.label, font::SMALL)),
        tile.plane.rows * scale + tile_label(),
    )
}

fn draw_tile(canvas: &mut Canvas, x: usize, y: usize, tile: &Tile, scale: usize) {
    let (w, h) = (tile.plane.cols * scale, tile.plane.rows * scale);
    canvas.plane(x, y, &tile.plane, scale);
    if tile.chosen {
        for k in 1..=3 {
            canvas.frame(
                x.saturating_sub(k),
                y.saturating_sub(k),
                w + 2 * k,
                h + 2 * k,
                BAR,
            );
        }
    } else {
        canvas.frame(
            x.saturating_sub(1),
            y.saturating_sub(1),
            w + 2,
            h + 2,
            FRAME,
        );
    }
    let colour = if tile.chosen { INK } else { MUTED };
    canvas.text(x, y + h + 4, &tile.label, font::SMALL, colour);
}

/// A cropped image with its axes in drawing order: the sliced axes first.
struct Arranged {
    focus: Focus,
    choice: Option<Choice>,
    order: Vec<usize>,
    shape: Vec<usize>,
    voxels: Vec<u8>,
    interest: Vec<u8>,
}

impl Arranged {
    fn new(subject: &Subject) -> Arranged {
        let focus = Focus::new(subject.image, subject.mode);
        let choice = choose_slice(&focus, subject.holes());
        let d = subject.image.dim().get();
        let order = choice
            .as_ref()
            .map_or_else(|| (0..d).collect(), |c| c.order.clone());
        let (shape, voxels) = arrange(subject.image, &order, &focus.crop);
        let (_, interest) = arrange(&focus.interest, &order, &focus.crop);
        Arranged {
            focus,
            choice,
            order,
            shape,
            voxels,
            interest,
        }
    }

    fn plane_size(&self) -> (usize, usize) {
        let d = self.shape.len();
        (self.shape[d - 2], self.shape[d - 1])
    }

    /// Where arranged axis `k` starts in the image.
    fn start(&self, k: usize) -> usize {
        self.focus.crop[self.order[k]].start
    }

    /// The positions (image coordinates) along arranged axis `k` that hold part of the
    /// object within `data` (a chunk of `self.interest` whose leading axis is `k`).
    fn occupied(&self, data: &[u8], k: usize) -> Vec<usize> {
        let n = self.shape[k];
        let len = data.len() / n.max(1);
        (0..n)
            .filter(|&x| data[x * len..(x + 1) * len].iter().any(|&v| v != 0))
            .map(|x| x + self.start(k))
            .collect()
    }
}

/// The chosen view as an outlined tile, cropped like the rest, labelled with its position
/// (`j=8:12` for a slab of slices 8 to 11) and its own Betti numbers.
fn chosen_tile(subject: &Subject, view: &Arranged, choice: &Choice) -> Tile {
    let fixed = choice.fixed();
    let whole = slab_view(subject.image, subject.mode, &fixed);
    let betti = bettimill_homology::topology(&whole).betti;
    let d = view.order.len();
    let plane_crop = [
        view.focus.crop[view.order[d - 2]].clone(),
        view.focus.crop[view.order[d - 1]].clone(),
    ];
    let (shape, data) = arrange(&whole, &[0, 1], &plane_crop);
    let at: Vec<String> = fixed
        .iter()
        .map(|(a, r)| {
            if r.len() == 1 {
                at_text(*a, r.start)
            } else {
                format!("{}={}:{}", AXES[*a], r.start, r.end)
            }
        })
        .collect();
    Tile {
        plane: slice_plane(&data, shape[0], shape[1]),
        label: format!("{} {}", at.join(","), betti_short(&betti)),
        chosen: true,
    }
}

/// Up to `max` evenly spaced values of `among`, with `must` (when given and present)
/// replacing the nearest pick.
fn pick_with(among: &[usize], max: usize, must: Option<usize>) -> Vec<usize> {
    let mut picks: Vec<usize> = spread(0..among.len(), max)
        .into_iter()
        .map(|i| among[i])
        .collect();
    if let Some(m) = must.filter(|m| among.contains(m) && !picks.contains(m)) {
        if let Some(nearest) = (0..picks.len()).min_by_key(|&i| picks[i].abs_diff(m)) {
            picks[nearest] = m;
            picks.sort_unstable();
        }
    }
    picks
}

/// The tiles of one sample's body, as labelled rows of tiles, and the scale.
fn body_rows(subject: &Subject, view: &Arranged) -> (Vec<(String, Vec<Tile>)>, usize) {
    let image = subject.image;
    let mode = subject.mode;
    let (rows, cols) = view.plane_size();
    let area = rows * cols;
    let o = &view.order;
    match (image.dim().get(), &view.choice) {
        (3, Some(choice)) => {
            let scale = scale_for(rows, cols, 128);
            let max = if rows.max(cols) * scale > 160 { 12 } else { 24 };
            let layers = view.shape[0];
            let mut tiles = vec![Tile::new(
                projection_plane(&view.interest, layers, rows, cols, mode),
                format!("proj {}", AXES[o[0]]),
            )];
            let slice = choice.width == 1;
            if !slice {
                tiles.push(chosen_tile(subject, view, choice));
            }
            let occupied = view.occupied(&view.interest, 0);
            for at in pick_with(&occupied, max, slice.then_some(choice.at[0])) {
                let x = at - view.start(0);
                let betti = slice_betti(image, &[(o[0], at)]);
                let mut tile = Tile::new(
                    slice_plane(&view.voxels[x * area..(x + 1) * area], rows, cols),
                    format!("{} {}", at_text(o[0], at), betti_short(&betti)),
                );
                tile.chosen = slice && at == choice.at[0];
                tiles.push(tile);
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
        (4, Some(choice)) => {
            let scale = scale_for(rows, cols, 80);
            let layers = view.shape[1];
            let block = layers * area;
            let mut grid = Vec::new();
            let slice = choice.width == 1;
            if !slice {
                grid.push(("slab".to_string(), vec![chosen_tile(subject, view, choice)]));
            }
            let occupied = view.occupied(&view.interest, 0);
            for at in pick_with(&occupied, 8, slice.then_some(choice.at[0])) {
                let x = at - view.start(0);
                let voxels = &view.voxels[x * block..(x + 1) * block];
                let interest = &view.interest[x * block..(x + 1) * block];
                let mut tiles = vec![Tile::new(
                    projection_plane(interest, layers, rows, cols, mode),
                    format!("proj {}", AXES[o[1]]),
                )];
                let chosen_row = slice && at == choice.at[0];
                let inner = view.occupied(interest, 1);
                let must = chosen_row.then_some(choice.at[1]);
                for at2 in pick_with(&inner, 12, must) {
                    let y = at2 - view.start(1);
                    let betti = slice_betti(image, &[(o[0], at), (o[1], at2)]);
                    let mut tile = Tile::new(
                        slice_plane(&voxels[y * area..(y + 1) * area], rows, cols),
                        format!("{} {}", at_text(o[1], at2), betti_short(&betti)),
                    );
                    tile.chosen = chosen_row && at2 == choice.at[1];
                    tiles.push(tile);
                }
                let betti = slice_betti(image, &[(o[0], at)]);
                grid.push((
                    format!("{} {}", at_text(o[0], at), betti_short(&betti)),
                    tiles,
                ));
            }
            (grid, scale)
        }
        _ => {
            let tile = Tile::new(slice_plane(&view.voxels, rows, cols), String::new());
            (
                vec![(String::new(), vec![tile])],
                scale_for(rows, cols, 512),
            )
        }
    }
}

/// One sample as a picture: caption lines on top, then what the picture shows, then the
/// body described in the module documentation.
pub fn render_sample(subject: &Subject, caption: &[String]) -> Result<Canvas, PreviewError> {
    let view = Arranged::new(subject);
    let mut lines: Vec<(String, bool)> = caption.iter().map(|l| (l.clone(), false)).collect();
    lines.extend(
        legend(&view.focus, view.choice.as_ref())
            .into_iter()
            .map(|l| (l, true)),
    );
    let (rows, scale) = body_rows(subject, &view);
    let row_label_width = rows
        .iter()
        .map(|(label, _)| font::text_width(label, font::SMALL))
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
    let line_h = |legend: bool| font::line_height(if legend { font::BODY } else { font::TITLE });
    let caption_h = lines.iter().map(|(_, l)| line_h(*l)).sum::<usize>() + GAP;
    let caption_w = lines
        .iter()
        .map(|(l, legend)| font::text_width(l, if *legend { font::BODY } else { font::TITLE }))
        .max()
        .unwrap_or(0);
    let mut canvas = Canvas::new(
        2 * MARGIN + body_w.max(caption_w),
        2 * MARGIN + caption_h + body_h,
        PAGE,
    )?;
    let mut y = MARGIN;
    for (line, legend) in &lines {
        let (colour, scale) = if *legend {
            (MUTED, font::BODY)
        } else {
            (INK, font::TITLE)
        };
        canvas.text(MARGIN, y, line, scale, colour);
        y += line_h(*legend);
    }
    let top = MARGIN + caption_h;
    for (r, (label, tiles)) in rows.iter().enumerate() {
        let y = top + r * (cell_h + GAP);
        canvas.text(
            MARGIN,
            y + (cell_h - tile_label()) / 2,
            label,
            font::SMALL,
            INK,
        );
        for (c, tile) in tiles.iter().enumerate() {
            let x = MARGIN + row_label_width + c * (cell_w + GAP);
            draw_tile(&mut canvas, x, y, tile, scale);
        }
    }
    Ok(canvas)
}

/// The small views of one sample in a contact sheet: the (cropped) image itself in 2D; in
/// 3D and 4D a projection along the sliced axes and the chosen slice.
fn thumbnails(subject: &Subject) -> Vec<Tile> {
    let view = Arranged::new(subject);
    let (rows, cols) = view.plane_size();
    let Some(choice) = &view.choice else {
        return vec![Tile::new(
            slice_plane(&view.voxels, rows, cols),
            String::new(),
        )];
    };
    let d = view.shape.len();
    let layers: usize = view.shape[..d - 2].iter().product();
    let along: Vec<String> = choice.order[..d - 2]
        .iter()
        .map(|&a| AXES[a].to_string())
        .collect();
    let mut chosen = chosen_tile(subject, &view, choice);
    chosen.chosen = false;
    vec![
        Tile::new(
            projection_plane(&view.interest, layers, rows, cols, subject.mode),
            format!("proj {}", along.join(",")),
        ),
        chosen,
    ]
}

/// A grid of samples, each shown small with a few caption lines (font scale 1), under a
/// line saying what the views are.
pub fn contact_sheet(samples: &[(Subject, Vec<String>)]) -> Result<Canvas, PreviewError> {
    if samples.is_empty() {
        return Err(PreviewError::Empty);
    }
    let cells: Vec<(Vec<Tile>, usize, Vec<String>)> = samples
        .iter()
        .map(|(subject, caption)| {
            let tiles = thumbnails(subject);
            let (rows, cols) = (tiles[0].plane.rows, tiles[0].plane.cols);
            let scale = scale_for(rows, cols, 128);
            let views_w: usize = tiles.iter().map(|t| tile_size(t, scale).0 + GAP).sum();
            let caption = wrap(caption, font::chars_in(views_w, font::BODY).max(20));
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
            .map(|l| font::text_width(l, font::BODY))
            .max()
            .unwrap_or(0);
        (
            views_w.max(text_w + GAP),
            views_h + GAP + caption.len() * font::line_height(font::BODY),
        )
    };
    let (cell_w, cell_h) = cells
        .iter()
        .map(cell_size)
        .fold((0, 0), |(w, h), (cw, ch)| (w.max(cw), h.max(ch)));
    let per_row = (1..).find(|k| k * k >= cells.len()).unwrap_or(1);
    let n_rows = cells.len().div_ceil(per_row);
    let width = 2 * MARGIN + per_row * (cell_w + GAP);
    let d = samples[0].0.image.dim().get();
    let header = if d == 2 {
        vec![
            "each image cropped to the object (carve: the cavities) and 2 voxels around"
                .to_string(),
        ]
    } else {
        wrap(
            &[
                "each sample cropped to the object (carve: the cavities) and 2 voxels around: \
               its projection along the sliced axes, and the slice that best shows a hole, \
               with that slice's own betti numbers; the label's betti numbers below"
                    .to_string(),
            ],
            font::chars_in(width - 2 * MARGIN, font::BODY).max(20),
        )
    };
    let line = font::line_height(font::BODY);
    let header_h = header.len() * line + GAP;
    let mut canvas = Canvas::new(
        width,
        2 * MARGIN + header_h + n_rows * (cell_h + 2 * GAP),
        PAGE,
    )?;
    for (k, text) in header.iter().enumerate() {
        canvas.text(MARGIN, MARGIN + k * line, text, font::BODY, MUTED);
    }
    for (n, (tiles, scale, caption)) in cells.iter().enumerate() {
        let x0 = MARGIN + (n % per_row) * (cell_w + GAP);
        let y0 = MARGIN + header_h + (n / per_row) * (cell_h + 2 * GAP);
        let mut x = x0;
        let mut views_h = 0;
        for tile in tiles {
            draw_tile(&mut canvas, x, y0, tile, *scale);
            let (w, h) = tile_size(tile, *scale);
            x += w + GAP;
            views_h = views_h.max(h);
        }
        for (k, text) in caption.iter().enumerate() {
            let colour = if k == 0 { INK } else { MUTED };
            canvas.text(x0, y0 + views_h + GAP + k * line, text, font::BODY, colour);
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
    use crate::focus::bounding_box;
    use bettimill_homology::topology;

    /// A solid torus in a cube of `side`: the ring of radius `big` lies in the plane of
    /// axes `plane` through the centre, the tube has radius `small`.
    fn solid_torus(
        dim: usize,
        side: usize,
        plane: (usize, usize),
        big: f64,
        small: f64,
    ) -> BinaryImage {
        let mut image = BinaryImage::zeros(&vec![side; dim]).unwrap();
        let c = (side as f64 - 1.0) / 2.0;
        for i in 0..image.len() {
            let x = image.coords(i);
            let p = |a: usize| x[a] as f64 - c;
            let radial = (p(plane.0).powi(2) + p(plane.1).powi(2)).sqrt() - big;
            let rest: f64 = (0..dim)
                .filter(|&a| a != plane.0 && a != plane.1)
                .map(|a| p(a).powi(2))
                .sum();
            if radial * radial + rest <= small * small {
                image.data_mut()[i] = 1;
            }
        }
        image
    }

    fn subject<'a>(image: &'a BinaryImage, mode: Mode, betti: &'a [u64]) -> Subject<'a> {
        Subject { image, mode, betti }
    }

    #[test]
    fn the_chosen_slice_of_a_solid_torus_cuts_through_its_hole() {
        // The ring lies in the plane of axes 0 and 2 (3D) or 0 and 1 (4D), so the default
        // planes (the last two axes) cut it into two discs and the choice must turn.
        for (dim, plane, betti) in [(3, (0, 2), vec![1, 1, 0]), (4, (0, 1), vec![1, 1, 0, 0])] {
            let image = solid_torus(dim, 20, plane, 5.0, 2.0);
            assert_eq!(topology(&image).betti, betti);
            let focus = Focus::new(&image, Mode::Embed);
            let choice = choose_slice(&focus, 1).unwrap();
            assert_eq!(choice.width, 1, "{dim}D: a plain slice shows this hole");
            let view = slab_view(&image, Mode::Embed, &choice.fixed());
            assert_eq!(topology(&view).betti, vec![1, 1], "{dim}D: {choice:?}");
            assert_eq!(&choice.order[dim - 2..], &[plane.0, plane.1]);

            // Carved out of a solid cube, the same ring is a cavity, and the chosen slice
            // cuts through it too: the foreground there has a hole.
            let mut carved = BinaryImage::zeros(image.shape()).unwrap();
            for i in 0..carved.len() {
                let x = carved.coords(i);
                let inside = (0..dim).all(|a| x[a] > 0 && x[a] + 1 < 20);
                carved.data_mut()[i] = (inside && image.data()[i] == 0) as u8;
            }
            let betti = topology(&carved).betti;
            let focus = Focus::new(&carved, Mode::Carve);
            let choice = choose_slice(&focus, betti[1..].iter().sum()).unwrap();
            let view = slab_view(&carved, Mode::Carve, &choice.fixed());
            assert!(topology(&view).betti[1] > 0, "{dim}D carve: {choice:?}");
            assert_eq!(&choice.order[dim - 2..], &[plane.0, plane.1]);
        }
    }

    #[test]
    fn carved_samples_are_cut_through_a_cavity_never_through_a_rough_outer_surface() {
        // A solid box whose outer layer is eaten away to a field of 2x2 pillars (what a
        // deformation of the outer surface leaves): every slice through that layer holds
        // dozens of solid islands in background, more "holes" than the cavity's. The
        // cavity, a solid torus carved inside, is what the picture must show.
        for dim in [3, 4] {
            let side = 20;
            let torus = solid_torus(dim, side, (dim - 2, dim - 1), 4.0, 1.5);
            let mut carved = BinaryImage::zeros(&vec![side; dim]).unwrap();
            for i in 0..carved.len() {
                let x = carved.coords(i);
                let in_box = (0..dim).all(|a| x[a] >= 1 && x[a] + 1 < side);
                let eaten = x[0] <= 2 && (1..dim).any(|a| x[a] % 4 >= 2);
                carved.data_mut()[i] = (in_box && !eaten && torus.data()[i] == 0) as u8;
            }
            let betti = topology(&carved).betti;
            // The solid with a carved ring: b0 = 1, the ring's dual (b1 in 3D, b2 in 4D)
            // and its enclosed cavity (b_{d-1}).
            let expected = if dim == 3 {
                vec![1, 1, 1]
            } else {
                vec![1, 0, 1, 1]
            };
            assert_eq!(betti, expected, "{dim}D");
            let cavity = bounding_box(&torus).unwrap();
            let focus = Focus::new(&carved, Mode::Carve);
            assert_eq!(
                focus.interest.data(),
                torus.data(),
                "{dim}D: only the cavity"
            );
            assert_eq!(focus.object, cavity, "{dim}D");
            let choice = choose_slice(&focus, betti[1..].iter().sum()).unwrap();
            for (axis, range) in choice.fixed() {
                assert!(
                    cavity[axis].start <= range.start && range.end <= cavity[axis].end,
                    "{dim}D: {choice:?} leaves the cavity"
                );
            }
            let view = slab_view(&focus.interest, Mode::Embed, &choice.fixed());
            assert_eq!(topology(&view).betti, vec![1, 1], "{dim}D: {choice:?}");
            // The picture draws that cavity: the crop is the cavity and its margin.
            let s = subject(&carved, Mode::Carve, &betti);
            let arranged = Arranged::new(&s);
            assert_eq!(arranged.choice.as_ref(), Some(&choice));
        }
    }

    #[test]
    fn an_annulus_is_drawn_with_its_hole() {
        // 2D: drawn whole (cropped), so the picture has page-free foreground around
        // an empty centre.
        let image = solid_torus(2, 16, (0, 1), 4.0, 1.5);
        assert_eq!(topology(&image).betti, vec![1, 1]);
        let s = subject(&image, Mode::Embed, &[1, 1]);
        assert!(choose_slice(&Focus::new(&image, Mode::Embed), 1).is_none());
        let (rows, _) = body_rows(&s, &Arranged::new(&s));
        let plane = &rows[0].1[0].plane;
        let view = BinaryImage::from_vec(
            &[plane.rows, plane.cols],
            plane.values.iter().map(|&v| (v != 0) as u8).collect(),
        )
        .unwrap();
        assert_eq!(topology(&view).betti, vec![1, 1]);
    }

    #[test]
    fn a_tilted_thin_ring_is_shown_by_a_slab() {
        // A ring of single voxels along a circle tilted out of every coordinate plane:
        // no axis-aligned slice holds a closed loop, a slab does.
        let side = 24;
        let mut image = BinaryImage::zeros(&[side, side, side]).unwrap();
        let c = 11.5;
        for step in 0..720 {
            let t = step as f64 * std::f64::consts::PI / 360.0;
            let (u, v) = (7.0 * t.cos(), 7.0 * t.sin());
            // Tilted: the plane spanned by (1, 0, 0.45) and (0, 1, 0.45), roughly.
            let p = [c + u, c + v, c + 0.45 * (u + v)];
            let x: Vec<usize> = p.iter().map(|&q| q.round() as usize).collect();
            image.set(&x, true);
        }
        let betti = topology(&image).betti;
        assert_eq!(betti, vec![1, 1, 0]);
        let focus = Focus::new(&image, Mode::Embed);
        let choice = choose_slice(&focus, 1).unwrap();
        assert!(choice.width > 1, "{choice:?}");
        let view = slab_view(&image, Mode::Embed, &choice.fixed());
        assert!(topology(&view).betti[1] >= 1, "{choice:?}");
    }

    #[test]
    fn rows_and_tiles_of_a_small_4d_object_all_hold_part_of_it() {
        // A small object in a big 4D image: no row of the sheet may be empty.
        let mut image = BinaryImage::zeros(&[24, 24, 24, 24]).unwrap();
        let small = solid_torus(4, 10, (2, 3), 2.5, 1.2);
        for i in 0..small.len() {
            if small.data()[i] != 0 {
                let x = small.coords(i);
                image.set(&[x[0] + 9, x[1] + 3, x[2] + 11, x[3] + 7], true);
            }
        }
        let betti = topology(&image).betti;
        let s = subject(&image, Mode::Embed, &betti);
        let view = Arranged::new(&s);
        let (rows, scale) = body_rows(&s, &view);
        assert!(rows.len() >= 2);
        for (label, tiles) in &rows {
            // Every slice tile (not the projection) has foreground: no empty row or tile.
            assert!(tiles.len() >= 2, "{label}");
            for tile in &tiles[1..] {
                assert!(
                    tile.plane.values.iter().any(|&v| v != 0),
                    "{label} {}",
                    tile.label
                );
            }
        }
        // The crop makes the tiles big: the planes are at most the object plus margins.
        let tile = &rows[0].1[1];
        assert!(tile.plane.rows <= 10 + 2 * crate::focus::MARGIN);
        assert!(tile.plane.cols * scale >= 64);
        // Exactly one tile is outlined, and it shows a hole.
        let chosen: Vec<&Tile> = rows
            .iter()
            .flat_map(|(_, t)| t)
            .filter(|t| t.chosen)
            .collect();
        assert_eq!(chosen.len(), 1);
        assert!(chosen[0].label.ends_with("[1,1]"), "{}", chosen[0].label);
    }

    #[test]
    fn the_sheet_has_no_empty_row() {
        let images: Vec<BinaryImage> = (0..5)
            .map(|n| solid_torus(3, 16 + n, (n % 3, 2 - n % 2), 4.0, 1.5))
            .collect();
        let bettis: Vec<Vec<u64>> = images.iter().map(|i| topology(i).betti).collect();
        let samples: Vec<(Subject, Vec<String>)> = images
            .iter()
            .zip(&bettis)
            .map(|(i, b)| (subject(i, Mode::Embed, b), vec!["k".to_string()]))
            .collect();
        let sheet = contact_sheet(&samples).unwrap();
        // 5 samples in rows of 3: two rows; every horizontal band of a row's height in the
        // drawing area holds foreground.
        let (w, h) = (sheet.width(), sheet.height());
        let band = (h - 2 * MARGIN) / 2;
        for r in 0..2 {
            let y0 = MARGIN + r * band;
            let any =
                (y0..y0 + band).any(|y| (0..w).any(|x| sheet.pixel(x, y) == Some(FOREGROUND)));
            assert!(any, "row {r} is empty");
        }
        // And the bottom margin is no taller than a row's gap (no trailing empty row).
        let last_ink = (0..h)
            .rev()
            .find(|&y| (0..w).any(|x| sheet.pixel(x, y) != Some(PAGE)))
            .unwrap();
        assert!(h - last_ink <= MARGIN + 3 * GAP, "{h} {last_ink}");
    }

    #[test]
    fn projection_is_darker_where_more_voxels_lie_along_the_ray() {
        // Two 1x3 layers: column 0 empty, column 1 in one layer, column 2 in both.
        let plane = projection_plane(&[0, 1, 1, 0, 0, 1], 2, 1, 3, Mode::Embed);
        assert_eq!(plane.values[0], 0);
        assert!(plane.values[1] >= 96);
        assert_eq!(plane.values[2], 255);
        assert!(plane.values[1] < plane.values[2]);
        // Carve: the same counts are cavities, lighter where there are more.
        let plane = projection_plane(&[0, 1, 1, 0, 0, 1], 2, 1, 3, Mode::Carve);
        assert_eq!(plane.values[0], 255);
        assert!(plane.values[1] <= 159);
        assert!(plane.values[1] > plane.values[2]);
    }

    #[test]
    fn a_2d_pixel_becomes_a_block_of_foreground_colour() {
        let mut image = BinaryImage::zeros(&[40, 40]).unwrap();
        image.set(&[20, 25], true);
        image.set(&[23, 22], true);
        let s = subject(&image, Mode::Embed, &[2, 0]);
        let canvas = render_sample(&s, &["test".to_string()]).unwrap();
        // Cropped to rows 18..26, columns 20..28 (8 x 8): 512 / 8 = 64 pixels per voxel,
        // below a one-line caption and a two-line legend.
        let top = MARGIN + font::line_height(font::TITLE) + 2 * font::line_height(font::BODY) + GAP;
        let at = |row: usize, col: usize| canvas.pixel(MARGIN + col * 64 + 10, top + row * 64 + 10);
        assert_eq!(at(2, 5), Some(FOREGROUND));
        assert_eq!(at(5, 2), Some(FOREGROUND));
        assert_eq!(at(0, 0), Some(EMPTY));
        assert_eq!(at(7, 7), Some(EMPTY));
        assert_eq!(canvas.pixel(MARGIN + 8 * 64 + 2, top + 10), Some(PAGE));
    }

    #[test]
    fn every_dimension_renders_and_equal_inputs_give_equal_bytes() {
        for shape in [vec![9, 7], vec![6, 5, 4], vec![3, 4, 5, 6]] {
            let mut image = BinaryImage::zeros(&shape).unwrap();
            let n = image.len();
            for i in (0..n).step_by(3) {
                image.data_mut()[i] = 1;
            }
            let betti = topology(&image).betti;
            for mode in [Mode::Embed, Mode::Carve] {
                let s = subject(&image, mode, &betti);
                let a = render_sample(&s, &["x".to_string()])
                    .unwrap()
                    .to_png()
                    .unwrap();
                let copy = image.clone();
                let b = render_sample(&subject(&copy, mode, &betti), &["x".to_string()])
                    .unwrap()
                    .to_png()
                    .unwrap();
                assert_eq!(a, b);
                let sheet = |img: &BinaryImage| {
                    contact_sheet(&[(subject(img, mode, &betti), vec!["k".to_string()])])
                        .unwrap()
                        .to_png()
                        .unwrap()
                };
                assert_eq!(sheet(&image), sheet(&copy));
            }
        }
        // A torus picture twice, byte for byte.
        let torus = solid_torus(4, 14, (1, 3), 3.5, 1.5);
        let betti = topology(&torus).betti;
        let draw = || {
            render_sample(&subject(&torus, Mode::Embed, &betti), &[])
                .unwrap()
                .to_png()
                .unwrap()
        };
        assert_eq!(draw(), draw());
        assert!(matches!(contact_sheet(&[]), Err(PreviewError::Empty)));
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
    fn picks_keep_the_chosen_slice() {
        assert_eq!(pick_with(&[1, 2, 3], 24, Some(2)), vec![1, 2, 3]);
        assert_eq!(
            pick_with(&(0..100).collect::<Vec<_>>(), 5, Some(30)),
            vec![0, 30, 49, 74, 99]
        );
        assert_eq!(pick_with(&[4, 5], 24, Some(9)), vec![4, 5]);
    }
}
