//! Opening a user's `.npy` image for `betti`, `deform` and `preview`: a file or `-` for
//! standard input, plain or compressed (`.npy.gz`, `.npy.zst`, the members a dataset
//! holds), told apart by content rather than by name.
//!
//! The input is untrusted. The compressed stream is decoded as it is read, and
//! [`bettimill_grid::npy::read_from`] reads exactly the bytes the `.npy` header promises (at
//! most [`MAX_IMAGE_BYTES`]) and refuses a stream that goes on past them, so a
//! decompression bomb is stopped after one byte too many, never expanded in full.

use anyhow::Context;
use bettimill_grid::npy::NpyImage;
use bettimill_shard::Compression;
use std::io::{BufRead, BufReader, Cursor, Read};
use std::path::Path;

/// The most data (bytes after the `.npy` header) an image may hold: the same limit the
/// audit puts on one member of a shard.
pub const MAX_IMAGE_BYTES: u64 = 1 << 34;

/// True when `path` names standard input (`-`).
pub fn is_stdin(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// True when `path` is `-` or its name ends in `.npy`, `.npy.gz` or `.npy.zst`.
pub fn looks_like_image(path: &Path) -> bool {
    let name = path.to_string_lossy();
    is_stdin(path)
        || [".npy", ".npy.gz", ".npy.zst"]
            .iter()
            .any(|s| name.ends_with(s))
}

/// Reads a `.npy` image from `path` (`-` for standard input), decompressing gzip or zstd
/// found by its magic bytes.
pub fn read_image(path: &Path, strict: bool) -> anyhow::Result<NpyImage> {
    read_image_padded(path, strict, 0)
}

/// [`read_image`], its image surrounded by `width` layers of background as it is read
/// ([`bettimill_grid::npy::read_from_padded`]).
pub fn read_image_padded(path: &Path, strict: bool, width: usize) -> anyhow::Result<NpyImage> {
    let shown = if is_stdin(path) {
        "standard input".to_string()
    } else {
        path.display().to_string()
    };
    let reader: Box<dyn BufRead> = if is_stdin(path) {
        Box::new(std::io::stdin().lock())
    } else {
        let file = std::fs::File::open(path).with_context(|| format!("cannot open {shown}"))?;
        Box::new(BufReader::new(file))
    };
    read_stream(reader, strict, width).with_context(|| format!("cannot use {shown} as an image"))
}

fn read_stream(
    mut reader: Box<dyn BufRead>,
    strict: bool,
    width: usize,
) -> anyhow::Result<NpyImage> {
    let mut magic = Vec::with_capacity(4);
    (&mut reader)
        .take(4)
        .read_to_end(&mut magic)
        .context("cannot read the first bytes")?;
    let compression = bettimill_shard::sniff(&magic);
    let whole = Cursor::new(magic).chain(reader);
    let decoded = bettimill_shard::decoder(whole, compression)?;
    // The shape is checked against the memory available before any voxel is allocated:
    // a valid array larger than memory would otherwise be read for minutes and then abort
    // the process.
    let admit = |shape: &[usize]| {
        if !(2..=4).contains(&shape.len()) {
            // Refused by its rank once read.
            return None;
        }
        let voxels = shape.iter().fold(1u64, |n, &side| {
            n.saturating_mul((side as u64).saturating_add(2 * width as u64))
        });
        bettimill_plan::memory::admit_image("the image", shape.len(), voxels)
            .err()
            .map(|refusal| refusal.to_string())
    };
    let read = bettimill_grid::npy::read_from_padded_admitted(
        decoded,
        strict,
        MAX_IMAGE_BYTES,
        width,
        &admit,
    );
    Ok(match compression {
        Compression::None => read?,
        c => read.with_context(|| format!("{c}-compressed data"))?,
    })
}
