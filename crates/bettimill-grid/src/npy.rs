//! Reading and writing `.npy` files (NumPy format versions 1.0, 2.0 and 3.0).
//!
//! Layout: the magic `\x93NUMPY`, a major and minor version byte, the header length
//! (u16 little-endian for 1.0, u32 for 2.0 and 3.0), then an ASCII Python dict literal
//! `{'descr': '<u1', 'fortran_order': False, 'shape': (n0, n1, ...), }` padded with spaces
//! and a newline so that the data starts at a multiple of 64 bytes, then the raw data.
//!
//! Reading treats the file as untrusted: the header is at most 64 KiB, the shape is checked
//! against the bytes actually present before anything is allocated, and every failure is a
//! [`NpyError`] that says what was wrong. Accepted dtypes: bool and signed or unsigned
//! integers of 1, 2, 4 or 8 bytes in either byte order; any non-zero value is foreground.
//! Floats, objects and Fortran order are refused. Writing always produces version 1.0 with
//! a canonical header, so the same image always gives the same bytes.

use crate::{BinaryImage, GridError};
use std::io::Read;
use std::path::Path;

/// An integer or boolean element type of a `.npy` array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dtype {
    /// `b` (bool), `i` (signed) or `u` (unsigned).
    pub kind: char,
    /// Bytes per element: 1, 2, 4 or 8.
    pub size: usize,
    /// True when the bytes are big-endian.
    pub big_endian: bool,
}

impl Dtype {
    /// `|u1`, the dtype bettimill writes for its own samples.
    pub const U8: Dtype = Dtype {
        kind: 'u',
        size: 1,
        big_endian: false,
    };

    /// The NumPy `descr` string of this dtype.
    pub fn descr(&self) -> String {
        let order = if self.size == 1 {
            '|'
        } else if self.big_endian {
            '>'
        } else {
            '<'
        };
        format!("{order}{}{}", self.kind, self.size)
    }
}

/// Why a `.npy` file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    /// The file could not be read at all.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The file is not in the `.npy` format or its header is malformed.
    #[error("not a valid .npy file: {0}")]
    Format(String),
    /// The dtype is not boolean or integer.
    #[error(
        "unsupported dtype {0:?}: bettimill reads bool and integer arrays (non-zero = foreground)"
    )]
    Dtype(String),
    /// The array is stored in Fortran order.
    #[error("Fortran-order arrays are not supported; save with numpy.ascontiguousarray")]
    FortranOrder,
    /// The file holds fewer bytes than the header promises.
    #[error("truncated data: the header promises {expected} bytes of data, the file has {found}")]
    Truncated {
        /// Bytes the shape and dtype need.
        expected: u64,
        /// Bytes present.
        found: u64,
    },
    /// The file holds more bytes than the header promises.
    #[error("{extra} unexpected bytes after the array data")]
    TrailingBytes {
        /// Bytes past the end of the data.
        extra: u64,
    },
    /// A stream goes on past the bytes the header promises (a decompression bomb, or a
    /// header that lies about the shape); the rest of the stream is not read.
    #[error("the data goes on past the {expected} bytes the header promises")]
    Overlong {
        /// Bytes the shape and dtype need.
        expected: u64,
    },
    /// The header promises more data than the reader's limit.
    #[error("the header promises {expected} bytes of data, more than the {limit} allowed")]
    TooLarge {
        /// Bytes the shape and dtype need.
        expected: u64,
        /// The reader's limit.
        limit: u64,
    },
    /// The shape is not an image bettimill handles.
    #[error("unsupported shape: {0}")]
    Shape(#[from] GridError),
    /// The memory for the image could not be had: refused by the caller's check before
    /// any data was read, or an allocation failed.
    #[error("{0}")]
    Memory(String),
    /// `strict` reading met a value other than 0 or 1.
    #[error("voxel {index} has value {value}; with --strict only 0 and 1 are allowed")]
    NotBinary {
        /// Flat C-order index.
        index: usize,
        /// The value found.
        value: i128,
    },
}

/// A `.npy` array read as a binary image, remembering the dtype it came with.
#[derive(Clone, Debug)]
pub struct NpyImage {
    /// Non-zero voxels as 1.
    pub image: BinaryImage,
    /// The element type in the file.
    pub dtype: Dtype,
}

const MAGIC: &[u8] = b"\x93NUMPY";
const MAX_HEADER: usize = 65536;

/// Reads a `.npy` file from disk.
pub fn read_path(path: &Path, strict: bool) -> Result<NpyImage, NpyError> {
    let bytes = std::fs::read(path).map_err(|source| NpyError::Io {
        path: path.display().to_string(),
        source,
    })?;
    read_bytes(&bytes, strict)
}

/// Reads a `.npy` array from a stream (a pipe, a decompressor) without trusting it: the
/// header is read and checked first, a header that promises more than `limit` bytes of data
/// is refused before anything is allocated for it, then exactly the promised bytes are read
/// (the buffer grows only with bytes actually received) and one byte more is asked for, so
/// a stream that goes on past the header's size is refused without reading the rest.
pub fn read_from<R: Read>(reader: R, strict: bool, limit: u64) -> Result<NpyImage, NpyError> {
    read_from_padded(reader, strict, limit, 0)
}

/// [`read_from`], its image the copy surrounded by `width` layers of background
/// ([`BinaryImage::padded`]): the voxels are placed there as they arrive, with no second
/// pass to pad them afterwards (a 4D image's pages are most of the time of reading it). An
/// image whose first row would start too far in (more background placed ahead of the data
/// than 16 MiB) is read as it comes and padded afterwards; the errors are
/// [`read_from`]'s.
pub fn read_from_padded<R: Read>(
    reader: R,
    strict: bool,
    limit: u64,
    width: usize,
) -> Result<NpyImage, NpyError> {
    read_padded_within(reader, strict, limit, width, Placer::AHEAD, &|_| None)
}

/// [`read_from_padded`] that asks `admit` about the shape (the header's) once the header is
/// read, before any voxel is allocated; a refusal (its reason) becomes [`NpyError::Memory`].
pub fn read_from_padded_admitted<R: Read>(
    reader: R,
    strict: bool,
    limit: u64,
    width: usize,
    admit: &dyn Fn(&[usize]) -> Option<String>,
) -> Result<NpyImage, NpyError> {
    read_padded_within(reader, strict, limit, width, Placer::AHEAD, admit)
}

/// [`read_from_padded`] with at most `ahead` bytes of background placed ahead of the data.
fn read_padded_within<R: Read>(
    mut reader: R,
    strict: bool,
    limit: u64,
    width: usize,
    ahead: usize,
    admit: &dyn Fn(&[usize]) -> Option<String>,
) -> Result<NpyImage, NpyError> {
    let io = |source| NpyError::Io {
        path: "the stream".to_string(),
        source,
    };
    let mut prefix = Vec::with_capacity(12);
    (&mut reader)
        .take(10)
        .read_to_end(&mut prefix)
        .map_err(io)?;
    if prefix.len() < 10 || &prefix[..6] != MAGIC {
        return Err(NpyError::Format("missing the \\x93NUMPY magic".into()));
    }
    if matches!(prefix[6], 2 | 3) {
        (&mut reader).take(2).read_to_end(&mut prefix).map_err(io)?;
    }
    // The header length field is checked by `split_header` below; read at most the
    // allowed header size so a lying length cannot make this allocate more.
    let header_len = match prefix[6] {
        1 => u16::from_le_bytes([prefix[8], prefix[9]]) as u64,
        2 | 3 if prefix.len() == 12 => {
            u32::from_le_bytes([prefix[8], prefix[9], prefix[10], prefix[11]]) as u64
        }
        _ => 0,
    };
    (&mut reader)
        .take(header_len.min(MAX_HEADER as u64 + 1))
        .read_to_end(&mut prefix)
        .map_err(io)?;
    let (header, data_start) = split_header(&prefix)?;
    // Exactly the header was read: the data comes next from the reader.
    debug_assert_eq!(data_start, prefix.len());
    let (dtype, shape) = parse_header(header)?;
    let expected = shape
        .iter()
        .try_fold(dtype.size as u64, |acc, &n| acc.checked_mul(n as u64))
        .ok_or_else(|| NpyError::Format(format!("shape {shape:?} overflows")))?;
    if expected > limit {
        return Err(NpyError::TooLarge { expected, limit });
    }
    if let Some(refusal) = admit(&shape) {
        return Err(NpyError::Memory(refusal));
    }
    // The data goes straight into the voxels as it arrives, a chunk at a time: no buffer
    // of the file's bytes beside the image (half the peak for a one-byte dtype), and the
    // voxels grow only with what was received. Errors come in the order `read_bytes`
    // gives them: truncation and overlong data first, then the shape, then a value.
    let size = dtype.size;
    let mut voxels: Vec<u8> = Vec::new();
    let mut placer = match width {
        0 => None,
        _ => Placer::new(&shape, width, ahead),
    };
    let total = match &placer {
        Some(placer) => placer.len,
        None => usize::try_from(expected / size as u64).unwrap_or(usize::MAX),
    };
    // The elements converted so far, and the chunk's, converted, when they are placed.
    let mut elements = 0usize;
    let mut converted = Vec::new();
    let mut chunk = vec![0u8; (1 << 16) / size * size];
    let mut filled = 0usize;
    let mut found = 0u64;
    let mut not_binary: Option<(usize, i128)> = None;
    let mut data = (&mut reader).take(expected);
    loop {
        let n = match data.read(&mut chunk[filled..]) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(io(e)),
        };
        filled += n;
        found += n as u64;
        // Whole elements are converted; a partial one waits at the front for its rest.
        let whole = filled - filled % size;
        let first = elements;
        elements += whole / size;
        let out = match placer {
            Some(_) => {
                converted.clear();
                &mut converted
            }
            None => {
                crate::reserve(&mut voxels, whole / size, total)?;
                &mut voxels
            }
        };
        if size == 1 {
            out.extend(chunk[..whole].iter().map(|&b| (b != 0) as u8));
        } else {
            out.extend(
                chunk[..whole]
                    .chunks_exact(size)
                    .map(|c| (element_value(c, dtype) != 0) as u8),
            );
        }
        if let Some(placer) = &mut placer {
            placer.place(&mut voxels, &converted)?;
        }
        if strict && not_binary.is_none() {
            not_binary = chunk[..whole]
                .chunks_exact(size)
                .position(|c| !matches!(element_value(c, dtype), 0 | 1))
                .map(|j| {
                    (
                        first + j,
                        element_value(&chunk[j * size..(j + 1) * size], dtype),
                    )
                });
        }
        chunk.copy_within(whole..filled, 0);
        filled -= whole;
    }
    if found < expected {
        return Err(NpyError::Truncated { expected, found });
    }
    let mut one = [0u8; 1];
    loop {
        match reader.read(&mut one) {
            Ok(0) => break,
            Ok(_) => return Err(NpyError::Overlong { expected }),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(io(e)),
        }
    }
    check_shape(&shape)?;
    if let Some((index, value)) = not_binary {
        return Err(NpyError::NotBinary { index, value });
    }
    let image = match placer {
        Some(placer) => {
            let rest = placer.len - voxels.len();
            crate::reserve(&mut voxels, rest, placer.len)?;
            voxels.resize(placer.len, 0);
            voxels.shrink_to_fit();
            BinaryImage::from_vec(&placer.shape, voxels)?
        }
        None => {
            // Grown by doubling as the data came: the room past the image goes back.
            voxels.shrink_to_fit();
            let image = BinaryImage::from_vec(&shape, voxels)?;
            match width {
                0 => image,
                _ => image
                    .try_into_padded(width)
                    .map_err(|err| NpyError::Memory(err.to_string()))?,
            }
        }
    };
    Ok(NpyImage { image, dtype })
}

/// Where [`read_from_padded`] puts the voxels it receives, in C order: each row along the
/// last axis at its place in the padded image, the background before it filled in.
struct Placer {
    /// The padded image's shape and length.
    shape: Vec<usize>,
    len: usize,
    width: usize,
    /// The padded image's strides, and the image's own sides.
    strides: [usize; 4],
    sides: [usize; 4],
    /// The row being received: its coordinates along the axes before the last, where it
    /// starts in the padded image, and how many of its voxels came.
    row: Vec<usize>,
    start: usize,
    received: usize,
}

impl Placer {
    /// The most background placed ahead of the data by [`read_from_padded`].
    const AHEAD: usize = 16 << 20;

    /// None for a shape [`read_from`] refuses, one whose padded copy has more than
    /// `usize::MAX` voxels, or one that would place more than `ahead` bytes of background
    /// ahead of the data.
    fn new(shape: &[usize], width: usize, ahead: usize) -> Option<Placer> {
        check_shape(shape).ok()?;
        let padded: Vec<usize> = shape
            .iter()
            .map(|&n| n.checked_add(width.checked_mul(2)?))
            .collect::<Option<_>>()?;
        let len = padded
            .iter()
            .try_fold(1usize, |len, &n| len.checked_mul(n))?;
        let d = shape.len();
        let mut sides = [0usize; 4];
        sides[..d].copy_from_slice(shape);
        let mut placer = Placer {
            strides: crate::strides_of(&padded),
            shape: padded,
            len,
            width,
            sides,
            row: vec![0; d - 1],
            start: 0,
            received: 0,
        };
        placer.start = placer.row_start();
        // The background placed ahead of the data is at most twice the first row's start
        // (the largest step between rows): bounded, as the voxels must grow only with what
        // was received (a 256^4 image's start is 17 MB: read unpadded, then padded).
        (placer.start <= ahead / 2).then_some(placer)
    }

    /// Where the row `self.row` starts in the padded image.
    fn row_start(&self) -> usize {
        crate::padded_row_start(&self.row, &self.strides, self.width)
    }

    /// Appends `values`, the next voxels in C order, to `voxels` at their places.
    fn place(&mut self, voxels: &mut Vec<u8>, mut values: &[u8]) -> Result<(), NpyError> {
        let line = self.sides[self.row.len()];
        while !values.is_empty() {
            let take = (line - self.received).min(values.len());
            let end = if self.received == 0 {
                self.start
            } else {
                voxels.len()
            };
            crate::reserve(voxels, end + take - voxels.len(), self.len)?;
            if self.received == 0 {
                voxels.resize(self.start, 0);
            }
            voxels.extend_from_slice(&values[..take]);
            values = &values[take..];
            self.received += take;
            if self.received == line {
                self.received = 0;
                // The next row (past the last row the start is never used: no value is
                // left).
                crate::next_row(&mut self.row, &self.sides);
                self.start = self.row_start();
            }
        }
        Ok(())
    }
}

/// Parses `.npy` bytes. With `strict`, values other than 0 and 1 are an error; otherwise
/// every non-zero value is foreground.
pub fn read_bytes(bytes: &[u8], strict: bool) -> Result<NpyImage, NpyError> {
    let (header, data_start) = split_header(bytes)?;
    let (dtype, shape) = parse_header(header)?;
    let n_voxels = shape
        .iter()
        .try_fold(1u64, |acc, &n| acc.checked_mul(n as u64))
        .ok_or_else(|| NpyError::Format(format!("shape {shape:?} overflows")))?;
    let expected = n_voxels
        .checked_mul(dtype.size as u64)
        .ok_or_else(|| NpyError::Format(format!("shape {shape:?} overflows")))?;
    let found = (bytes.len() - data_start) as u64;
    if found < expected {
        return Err(NpyError::Truncated { expected, found });
    }
    if found > expected {
        return Err(NpyError::TrailingBytes {
            extra: found - expected,
        });
    }
    // Shape validity (rank, zero axes) is checked before the voxel buffer is allocated.
    check_shape(&shape)?;
    let raw = &bytes[data_start..];
    let mut voxels = Vec::with_capacity(n_voxels as usize);
    if dtype.size == 1 {
        // One byte per element (bool, u1, i1): zero is zero whatever the kind, so the bytes
        // are read directly, which is most of the time of reading a large image otherwise.
        if strict {
            if let Some(index) = raw.iter().position(|&b| b > 1) {
                let value = element_value(&raw[index..index + 1], dtype);
                return Err(NpyError::NotBinary { index, value });
            }
        }
        voxels.extend(raw.iter().map(|&b| (b != 0) as u8));
        let image = BinaryImage::from_vec(&shape, voxels)?;
        return Ok(NpyImage { image, dtype });
    }
    let values = raw
        .chunks_exact(dtype.size)
        .map(|c| element_value(c, dtype));
    let image = image_from_values(&shape, values, strict)?;
    Ok(NpyImage { image, dtype })
}

/// Checks that `shape` is one of an image bettimill handles (2 to 4 axes, none of length
/// 0), before anything is allocated for it. The error is the one reading a `.npy` file of
/// that shape gives.
pub fn check_shape(shape: &[usize]) -> Result<(), NpyError> {
    if !(2..=4).contains(&shape.len()) {
        return Err(GridError::BadRank(shape.len()).into());
    }
    if let Some(axis) = shape.iter().position(|&n| n == 0) {
        return Err(GridError::EmptyAxis { axis }.into());
    }
    Ok(())
}

/// Builds an image of `shape` from its element values in C order, with the rules (and the
/// errors) of reading a `.npy` file: the shape is checked first ([`check_shape`]), any
/// non-zero value is foreground, and with `strict` a value other than 0 or 1 is refused,
/// naming its flat C-order index. This is how arrays that are not files (the Python
/// package's numpy arrays, in any memory order) are read exactly as `bettimill betti` reads
/// a file.
pub fn image_from_values<T: Into<i128>>(
    shape: &[usize],
    values: impl IntoIterator<Item = T>,
    strict: bool,
) -> Result<BinaryImage, NpyError> {
    check_shape(shape)?;
    let n_voxels = shape
        .iter()
        .try_fold(1usize, |acc, &n| acc.checked_mul(n))
        .ok_or_else(|| NpyError::Format(format!("shape {shape:?} overflows")))?;
    let mut voxels = Vec::new();
    voxels
        .try_reserve_exact(n_voxels)
        .map_err(|_| crate::out_of_memory(n_voxels))?;
    for (index, value) in values.into_iter().enumerate() {
        let value: i128 = value.into();
        if strict && value != 0 && value != 1 {
            return Err(NpyError::NotBinary { index, value });
        }
        voxels.push((value != 0) as u8);
    }
    Ok(BinaryImage::from_vec(shape, voxels)?)
}

/// The dtype a NumPy `descr` string (`'|b1'`, `'<i8'`, `'>u2'`...) names, if bettimill
/// reads it; anything else (floats, objects, strings) is [`NpyError::Dtype`], the error a
/// `.npy` file of that dtype gives.
pub fn parse_dtype(descr: &str) -> Result<Dtype, NpyError> {
    parse_descr(descr)
}

fn element_value(chunk: &[u8], dtype: Dtype) -> i128 {
    let mut buf = [0u8; 8];
    if dtype.big_endian {
        for (k, &b) in chunk.iter().rev().enumerate() {
            buf[k] = b;
        }
    } else {
        buf[..chunk.len()].copy_from_slice(chunk);
    }
    let unsigned = u64::from_le_bytes(buf);
    if dtype.kind == 'i' {
        let shift = 64 - 8 * dtype.size as u32;
        (((unsigned << shift) as i64) >> shift) as i128
    } else {
        unsigned as i128
    }
}

fn split_header(bytes: &[u8]) -> Result<(&str, usize), NpyError> {
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err(NpyError::Format("missing the \\x93NUMPY magic".into()));
    }
    let major = bytes[6];
    let (header_len, start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err(NpyError::Format("file ends inside the header".into()));
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => return Err(NpyError::Format(format!("unknown format version {v}"))),
    };
    if header_len > MAX_HEADER {
        return Err(NpyError::Format(format!(
            "header of {header_len} bytes (at most {MAX_HEADER} allowed)"
        )));
    }
    let end = start + header_len;
    if bytes.len() < end {
        return Err(NpyError::Format("file ends inside the header".into()));
    }
    let header = std::str::from_utf8(&bytes[start..end])
        .map_err(|_| NpyError::Format("header is not text".into()))?;
    Ok((header, end))
}

/// Finds `'key': value` in the header dict and returns the value text up to the next
/// top-level comma or closing brace.
fn dict_value<'a>(header: &'a str, key: &str) -> Result<&'a str, NpyError> {
    let needle_single = format!("'{key}'");
    let needle_double = format!("\"{key}\"");
    // A key given twice is ambiguous (numpy's dict literal keeps the last, a reader that
    // takes the first sees another array): refuse it.
    let as_key = |needle: &String| {
        header
            .match_indices(needle.as_str())
            .filter(|(i, _)| header[i + needle.len()..].trim_start().starts_with(':'))
            .count()
    };
    if as_key(&needle_single) + as_key(&needle_double) > 1 {
        return Err(NpyError::Format(format!(
            "header gives '{key}' more than once (numpy would use the last one); refusing an ambiguous header"
        )));
    }
    let pos = header
        .find(&needle_single)
        .or_else(|| header.find(&needle_double))
        .ok_or_else(|| NpyError::Format(format!("header has no '{key}'")))?;
    let rest = &header[pos + key.len() + 2..];
    let rest = rest
        .trim_start()
        .strip_prefix(':')
        .ok_or_else(|| NpyError::Format(format!("no ':' after '{key}'")))?
        .trim_start();
    let mut depth = 0i32;
    for (i, ch) in rest.char_indices() {
        match ch {
            '(' | '[' => depth += 1,
            ')' | ']' => {
                depth -= 1;
                if depth < 0 {
                    return Ok(rest[..i].trim());
                }
                if depth == 0 && ch == ')' {
                    return Ok(rest[..=i].trim());
                }
            }
            ',' | '}' if depth == 0 => return Ok(rest[..i].trim()),
            _ => {}
        }
    }
    Err(NpyError::Format(format!("unterminated value of '{key}'")))
}

fn parse_header(header: &str) -> Result<(Dtype, Vec<usize>), NpyError> {
    let header = header.trim();
    if !header.starts_with('{') || !header.ends_with('}') {
        return Err(NpyError::Format("header is not a dict".into()));
    }
    let descr = dict_value(header, "descr")?;
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    let dtype = parse_descr(descr)?;
    let fortran = dict_value(header, "fortran_order")?;
    match fortran {
        "False" => {}
        "True" => return Err(NpyError::FortranOrder),
        other => {
            return Err(NpyError::Format(format!(
                "fortran_order is {other:?}, not True or False"
            )))
        }
    }
    let shape_text = dict_value(header, "shape")?;
    let inner = shape_text
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| NpyError::Format(format!("shape {shape_text:?} is not a tuple")))?;
    let mut shape = Vec::new();
    for part in inner.split(',') {
        let part = part.trim();
        if part.is_empty() {
            continue;
        }
        let part = part.trim_end_matches('L');
        let n: usize = part
            .parse()
            .map_err(|_| NpyError::Format(format!("shape entry {part:?} is not a length")))?;
        shape.push(n);
        if shape.len() > 32 {
            return Err(NpyError::Format("shape has more than 32 axes".into()));
        }
    }
    Ok((dtype, shape))
}

fn parse_descr(descr: &str) -> Result<Dtype, NpyError> {
    let bad = || NpyError::Dtype(descr.to_string());
    let mut chars = descr.chars();
    let first = chars.next().ok_or_else(bad)?;
    let (big_endian, rest) = match first {
        '<' | '|' | '=' => (false, &descr[1..]),
        '>' => (true, &descr[1..]),
        _ => (false, descr),
    };
    let mut rest_chars = rest.chars();
    let kind = rest_chars.next().ok_or_else(bad)?;
    let size: usize = rest_chars.as_str().parse().map_err(|_| bad())?;
    let ok = match kind {
        'b' => size == 1,
        'i' | 'u' => matches!(size, 1 | 2 | 4 | 8),
        _ => false,
    };
    if !ok {
        return Err(bad());
    }
    Ok(Dtype {
        kind,
        size,
        big_endian,
    })
}

/// Encodes an image as `.npy` bytes with the given dtype (voxels written as 0 or 1).
/// The header is canonical, so equal images give equal bytes.
pub fn write_bytes(image: &BinaryImage, dtype: Dtype) -> Vec<u8> {
    let shape: Vec<String> = image.shape().iter().map(|n| n.to_string()).collect();
    let shape_text = if shape.len() == 1 {
        format!("({},)", shape[0])
    } else {
        format!("({})", shape.join(", "))
    };
    let mut header = format!(
        "{{'descr': '{}', 'fortran_order': False, 'shape': {}, }}",
        dtype.descr(),
        shape_text
    );
    // Pad so that magic (6) + version (2) + length (2) + header is a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    let padding = (64 - unpadded % 64) % 64;
    header.extend(std::iter::repeat_n(' ', padding));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + image.len() * dtype.size);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    if dtype.size == 1 {
        // A voxel is its own element: one copy of the data.
        out.extend_from_slice(image.data());
        return out;
    }
    for &v in image.data() {
        let mut element = [0u8; 8];
        if dtype.big_endian {
            element[dtype.size - 1] = v;
        } else {
            element[0] = v;
        }
        out.extend_from_slice(&element[..dtype.size]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn replace(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
        assert_eq!(from.len(), to.len(), "replacements keep the header length");
        let pos = bytes
            .windows(from.len())
            .position(|w| w == from.as_bytes())
            .expect("pattern present");
        let mut out = bytes.to_vec();
        out[pos..pos + to.len()].copy_from_slice(to.as_bytes());
        out
    }

    fn sample() -> BinaryImage {
        let mut img = BinaryImage::zeros(&[2, 3, 4]).unwrap();
        img.set(&[1, 2, 3], true);
        img.set(&[0, 1, 0], true);
        img
    }

    /// A reader that gives one byte per read, as a slow pipe may.
    struct Trickle<'a>(&'a [u8]);

    impl std::io::Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let Some((first, rest)) = self.0.split_first() else {
                return Ok(0);
            };
            buf[0] = *first;
            self.0 = rest;
            Ok(1)
        }
    }

    #[test]
    fn reads_a_stream_exactly_as_bytes() {
        let img = sample();
        for descr in ["|u1", ">i2", "<u8"] {
            let bytes = write_bytes(&img, parse_descr(descr).unwrap());
            let streamed = read_from(&bytes[..], true, 1 << 20).unwrap();
            assert_eq!(streamed.image, img, "{descr}");
            // One byte at a time, as a slow pipe delivers it.
            let trickled = read_from(Trickle(&bytes), true, 1 << 20).unwrap();
            assert_eq!(trickled.image, img, "{descr}");
        }
    }

    /// A stream is read, and refused, exactly as its bytes are: values over 1 in every
    /// dtype, in the first and in a later chunk, with truncation (reported first), and
    /// delivered a byte at a time (elements split across reads).
    #[test]
    fn a_stream_gives_the_answers_and_errors_of_its_bytes() {
        let mut img = BinaryImage::zeros(&[40, 41, 43]).unwrap();
        for index in (0..img.len()).step_by(7) {
            img.data_mut()[index] = 1;
        }
        for descr in ["|u1", "|i1", "<u2", ">i2", "<i4", ">u8"] {
            let dtype = parse_descr(descr).unwrap();
            let good = write_bytes(&img, dtype);
            let data_start = good.len() - img.len() * dtype.size;
            let mut cases = vec![good.clone(), good[..good.len() - 3].to_vec()];
            for element in [5, 70_000 / dtype.size, img.len() - 1] {
                let mut bad = good.clone();
                // The element's most significant byte: a value over 1 (or negative).
                let at = data_start
                    + element * dtype.size
                    + if dtype.big_endian { 0 } else { dtype.size - 1 };
                bad[at] = 0x80;
                cases.push(bad.clone());
                cases.push(bad[..bad.len() - 1].to_vec());
            }
            for (case, bytes) in cases.iter().enumerate() {
                for strict in [false, true] {
                    let expected = format!("{:?}", read_bytes(bytes, strict));
                    let streamed = format!("{:?}", read_from(&bytes[..], strict, 1 << 30));
                    assert_eq!(streamed, expected, "{descr} case {case} strict {strict}");
                    if case < 3 {
                        let trickled = read_from(Trickle(bytes), strict, 1 << 30);
                        assert_eq!(format!("{trickled:?}"), expected, "{descr} case {case}");
                    }
                    // Read into the padded copy: that copy, or the same error.
                    let expected_padded = format!(
                        "{:?}",
                        read_bytes(bytes, strict).map(|npy| npy.image.padded(2))
                    );
                    for trickle in [false, true].into_iter().take(if case < 3 { 2 } else { 1 }) {
                        let padded = match trickle {
                            false => read_from_padded(&bytes[..], strict, 1 << 30, 2),
                            true => read_from_padded(Trickle(bytes), strict, 1 << 30, 2),
                        };
                        let padded = format!("{:?}", padded.map(|npy| npy.image));
                        assert_eq!(padded, expected_padded, "{descr} case {case} padded");
                    }
                }
            }
        }
    }

    /// Every shape of 2 to 4 axes reads into its padded copy; a shape whose first row would
    /// start too far in (the background placed ahead of any data) is read unpadded first.
    #[test]
    fn a_padded_read_is_the_padded_image() {
        for shape in [
            &[1, 1][..],
            &[3, 1, 2],
            &[2, 3, 1, 4],
            &[1, 5, 1, 1],
            &[5, 6, 7],
        ] {
            let mut img = BinaryImage::zeros(shape).unwrap();
            for index in (0..img.len()).step_by(3) {
                img.data_mut()[index] = 1;
            }
            let bytes = write_bytes(&img, Dtype::U8);
            for width in [1, 3] {
                let padded = read_from_padded(Trickle(&bytes), true, 1 << 20, width).unwrap();
                assert_eq!(padded.image, img.padded(width), "{shape:?} by {width}");
                // Nothing may be placed ahead: read, then padded.
                let after =
                    read_padded_within(&bytes[..], true, 1 << 20, width, 0, &|_| None).unwrap();
                assert_eq!(
                    after.image,
                    img.padded(width),
                    "{shape:?} by {width}, after"
                );
            }
        }
        let ahead = Placer::AHEAD;
        assert!(Placer::new(&[2, 2000, 2000], 1, ahead).is_some());
        assert!(Placer::new(&[2, 3000, 3000], 1, ahead).is_none());
        assert!(Placer::new(&[2, 0, 3], 1, ahead).is_none());
    }

    #[test]
    fn a_stream_is_held_to_its_header() {
        let bytes = write_bytes(&sample(), Dtype::U8);
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(matches!(
            read_from(&longer[..], false, 1 << 20),
            Err(NpyError::Overlong { expected: 24 })
        ));
        assert!(matches!(
            read_from(&bytes[..bytes.len() - 1], false, 1 << 20),
            Err(NpyError::Truncated {
                expected: 24,
                found: 23
            })
        ));
        assert!(matches!(
            read_from(&bytes[..], false, 23),
            Err(NpyError::TooLarge {
                expected: 24,
                limit: 23
            })
        ));
        // A header promising an enormous array is refused before any data is read.
        let huge = replace(&bytes, "(2, 3, 4)", "(9999999)");
        assert!(matches!(
            read_from(&huge[..], false, 1 << 20),
            Err(NpyError::TooLarge { .. })
        ));
        for short in [&b""[..], b"\x93NUM", b"not npy at all"] {
            assert!(matches!(
                read_from(short, false, 1 << 20),
                Err(NpyError::Format(_))
            ));
        }
        assert_eq!(read_from(&bytes[..], false, 24).unwrap().image, sample());
    }

    #[test]
    fn round_trips_every_integer_dtype() {
        let img = sample();
        for descr in [
            "|u1", "|i1", "|b1", "<u2", ">i2", "<i4", ">u4", "<i8", ">u8",
        ] {
            let dtype = parse_descr(descr).unwrap();
            let bytes = write_bytes(&img, dtype);
            assert_eq!((bytes.len() - img.len() * dtype.size) % 64, 0);
            let back = read_bytes(&bytes, true).unwrap();
            assert_eq!(back.image, img, "{descr}");
            assert_eq!(back.dtype, dtype);
        }
    }

    #[test]
    fn refuses_floats_fortran_and_truncation() {
        let img = sample();
        let good = write_bytes(&img, Dtype::U8);
        let text = replace(&good, "|u1", "<f4");
        assert!(matches!(read_bytes(&text, false), Err(NpyError::Dtype(_))));
        let text = replace(&good, "False", "True ");
        assert!(matches!(
            read_bytes(&text, false),
            Err(NpyError::FortranOrder)
        ));
        assert!(matches!(
            read_bytes(&good[..good.len() - 1], false),
            Err(NpyError::Truncated { .. })
        ));
        assert!(matches!(
            read_bytes(&good[..20], false),
            Err(NpyError::Format(_))
        ));
        let mut extra = good.clone();
        extra.push(0);
        assert!(matches!(
            read_bytes(&extra, false),
            Err(NpyError::TrailingBytes { extra: 1 })
        ));
    }

    #[test]
    fn a_lying_header_does_not_allocate() {
        let img = sample();
        let good = write_bytes(&img, Dtype::U8);
        let text = replace(&good, "(2, 3, 4)", "(99,99,9)");
        assert!(matches!(
            read_bytes(&text, false),
            Err(NpyError::Truncated { .. })
        ));
    }

    #[test]
    fn a_header_with_a_key_twice_is_refused() {
        let img = BinaryImage::zeros(&[2, 3]).unwrap();
        let good = write_bytes(&img, Dtype::U8);
        // Same length, so the header stays aligned: the second descr replaces padding.
        let (old, new) = (
            b"'shape': (2, 3), }".as_slice(),
            b"'shape': (2, 3), 'descr': '<i8', }".as_slice(),
        );
        let at = good.windows(old.len()).position(|w| w == old).unwrap();
        let mut twice = good[..at].to_vec();
        twice.extend_from_slice(new);
        let rest = &good[at + old.len()..];
        twice.extend_from_slice(&rest[new.len() - old.len()..]);
        assert_eq!(twice.len(), good.len());
        let err = read_bytes(&twice, false).unwrap_err().to_string();
        assert!(err.contains("'descr' more than once"), "{err}");
        assert!(err.contains("numpy would use the last"), "{err}");
        read_bytes(&good, false).unwrap();
    }

    #[test]
    fn strict_refuses_values_other_than_0_and_1() {
        let img = sample();
        let mut bytes = write_bytes(&img, Dtype::U8);
        let last = bytes.len() - 1;
        bytes[last] = 7;
        assert!(matches!(
            read_bytes(&bytes, true),
            Err(NpyError::NotBinary { value: 7, .. })
        ));
        let lenient = read_bytes(&bytes, false).unwrap();
        assert!(lenient.image.data()[img.len() - 1] == 1);
    }

    #[test]
    fn wrong_rank_is_refused() {
        let img = sample();
        let bytes = write_bytes(&img, Dtype::U8);
        let text = replace(&bytes, "(2, 3, 4)", "(24,)    ");
        assert!(matches!(
            read_bytes(&text, false),
            Err(NpyError::Shape(GridError::BadRank(1)))
        ));
    }
}
