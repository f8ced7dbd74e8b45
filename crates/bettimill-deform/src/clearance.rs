//! Keeping the gaps of a growing phase open.
//!
//! Growth by simple points keeps the topology but not the width of what carries it: a
//! hole, a cavity's wall or the space between two parts narrows until one voxel is left,
//! because that last voxel is the first one whose flip is not simple. Constructions leave
//! gaps of two or three voxels, and growth towards a hypervolume bin or a few dilation
//! steps take most of them to one, so nearly every hole of a binned sample closes under a
//! single dilation. A network trained on such data learns holes of one width only.
//!
//! A phase with a clearance `c` (see [`crate::Phase::with_clearance`]) lets a voxel join
//! only if it leaves at least `c` voxels outside the phase between itself and any part of
//! the phase ahead of it: along each of the 3^d - 1 directions from a neighbour inside the
//! phase through the voxel to a neighbour outside, the next `c - 1` voxels must be outside
//! the phase too. A direction whose next voxel is already inside is a concave corner, not
//! a gap, and decides nothing. Gaps narrower than `c` at construction stay as they are:
//! growth next to them is refused, and no flip here ever widens a gap by growth.
//!
//! The test reads only the image. A parity subfield of `morphology` decides its members
//! one after another against the image as the earlier ones left it, so two voxels of one
//! subfield never narrow one gap from both sides.

use bettimill_grid::neighbourhood::full_offsets;
use bettimill_grid::{BinaryImage, Dim};
use std::sync::OnceLock;

/// The 3^d - 1 directions of each dimension, listed once: every growth candidate reads them.
fn directions(dim: Dim) -> &'static [[i8; 4]] {
    static TABLES: [OnceLock<Vec<[i8; 4]>>; 4] = [const { OnceLock::new() }; 4];
    TABLES[dim.get() - 1].get_or_init(|| full_offsets(dim))
}

/// Whether `v`, outside the phase of value `value`, may join it with the clearance
/// `clearance` (always when `clearance` is 0 or 1).
pub(crate) fn leaves_room(image: &BinaryImage, v: usize, value: u8, clearance: u32) -> bool {
    if clearance < 2 {
        return true;
    }
    let data = image.data();
    let d = image.dim().get();
    let shape = image.shape();
    let strides = image.strides();
    let c = image.coords(v);
    let reach = i64::from(clearance);
    // Every voxel read lies within `clearance` of `v` along each axis: far enough from the
    // faces, a read is a flat offset with no bounds to test.
    let deep = (0..d).all(|a| c[a] as i64 >= reach && c[a] as i64 + reach < shape[a] as i64);
    if deep {
        for o in directions(image.dim()) {
            let step: isize = (0..d)
                .map(|a| isize::from(o[a]) * strides[a] as isize)
                .sum();
            let at = |t: isize| data[(v as isize + t * step) as usize];
            if at(-1) != value || at(1) == value {
                continue;
            }
            if (2..=reach as isize).any(|t| at(t) == value) {
                return false;
            }
        }
        return true;
    }
    leaves_room_anywhere(image, c, value, reach)
}

/// [`leaves_room`] for the voxel at `c` anywhere in the image, each read tested against
/// its faces; `reach` is the clearance.
fn leaves_room_anywhere(image: &BinaryImage, c: [usize; 4], value: u8, reach: i64) -> bool {
    let (data, shape, strides) = (image.data(), image.shape(), image.strides());
    let d = image.dim().get();
    // The voxel `t` steps from `v` along `o`, or `None` outside the image.
    let at = |o: &[i8; 4], t: i64| -> Option<usize> {
        let mut flat = 0usize;
        for a in 0..d {
            let x = c[a] as i64 + t * i64::from(o[a]);
            if x < 0 || x >= shape[a] as i64 {
                return None;
            }
            flat += x as usize * strides[a];
        }
        Some(flat)
    };
    for o in directions(image.dim()) {
        let behind = at(o, -1).is_some_and(|u| data[u] == value);
        let open_ahead = at(o, 1).is_some_and(|u| data[u] != value);
        if !(behind && open_ahead) {
            continue;
        }
        for t in 2..=reach {
            match at(o, t) {
                None => break,
                Some(u) if data[u] == value => return false,
                Some(_) => {}
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2D image of `rows` (`#` the phase).
    fn picture(rows: &[&str]) -> BinaryImage {
        let mut image = BinaryImage::zeros(&[rows.len(), rows[0].len()]).unwrap();
        for (y, row) in rows.iter().enumerate() {
            for (x, ch) in row.chars().enumerate() {
                if ch == '#' {
                    let i = image.index(&[y, x]);
                    image.data_mut()[i] = 1;
                }
            }
        }
        image
    }

    /// Far from the faces, flat offsets answer as reads tested against the faces.
    #[test]
    fn deep_voxels_answer_as_voxels_anywhere() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        for shape in [vec![30usize, 31], vec![14, 15, 13], vec![11, 12, 10, 13]] {
            let mut image = BinaryImage::zeros(&shape).unwrap();
            for voxel in image.data_mut() {
                *voxel = u8::from(rng.gen_bool(0.3));
            }
            for clearance in [2, 3, 4] {
                let (mut open, mut shut) = (0, 0);
                for v in 0..image.len() {
                    let fast = leaves_room(&image, v, 1, clearance);
                    let anywhere =
                        leaves_room_anywhere(&image, image.coords(v), 1, i64::from(clearance));
                    assert_eq!(fast, anywhere);
                    if fast {
                        open += 1;
                    } else {
                        shut += 1;
                    }
                }
                assert!(open > 0 && shut > 0, "{shape:?} {clearance}: {open} {shut}");
            }
        }
    }

    #[test]
    fn a_voxel_that_would_narrow_a_gap_below_the_clearance_is_refused() {
        // Column 2 faces the far wall (column 5) across columns 2-4.
        let image = picture(&["#.....#", "##...##", "##...##", "##...##", "#.....#"]);
        let v = image.index(&[2, 2]);
        // Joining leaves 2 voxels (columns 3, 4) before the far wall.
        assert!(leaves_room(&image, v, 1, 2));
        assert!(!leaves_room(&image, v, 1, 3));
        assert!(leaves_room(&image, v, 1, 0));
        assert!(leaves_room(&image, v, 1, 1));
    }

    #[test]
    fn growth_on_an_open_face_or_into_a_concave_corner_is_free() {
        let image = picture(&["......", "......", "###...", "###...", "#####.", "#####."]);
        // Beside a flat face with nothing ahead.
        assert!(leaves_room(&image, image.index(&[1, 1]), 1, 8));
        // Into the corner where the step meets the face: the next voxel ahead along the
        // diagonal is inside already.
        assert!(leaves_room(&image, image.index(&[3, 3]), 1, 8));
    }
}
