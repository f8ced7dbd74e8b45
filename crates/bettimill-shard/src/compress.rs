//! Deterministic per-member compression.
//!
//! A compressed member keeps its field and gains a suffix: `KEY.npy` becomes
//! `KEY.npy.gz` ([`Compression::Gzip`]) or `KEY.npy.zst` ([`Compression::Zstd`]). The
//! compressed bytes depend only on the input (and the pinned codec versions in
//! `Cargo.lock`), never on the machine, the time or the file name:
//!
//! - gzip: RFC 1952 header with mtime 0, no file name, no comment, OS byte 255
//!   ("unknown"), then DEFLATE at level [`GZIP_LEVEL`] from the pure-Rust `miniz_oxide`
//!   backend of `flate2`, then CRC-32 and length.
//! - zstd: one frame at level [`ZSTD_LEVEL`], compressed in one call on the calling thread
//!   (no worker threads, so no dependence on the core count), with the content size in the
//!   frame header and no checksum.
//!
//! Decompression takes a limit on the output size so that a corrupt or hostile member
//! cannot make a reader allocate without bound.

use crate::ShardError;
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};

/// DEFLATE level used for gzip members.
pub const GZIP_LEVEL: u32 = 6;
/// zstd level used for zstd members.
pub const ZSTD_LEVEL: i32 = 9;

/// How each member of a shard is compressed.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    /// Stored as is.
    #[default]
    None,
    /// gzip, member name suffix `.gz`.
    Gzip,
    /// zstd, member name suffix `.zst`.
    Zstd,
}

impl Compression {
    /// The suffix appended to a compressed member's name: `""`, `".gz"` or `".zst"`.
    pub fn suffix(self) -> &'static str {
        match self {
            Compression::None => "",
            Compression::Gzip => ".gz",
            Compression::Zstd => ".zst",
        }
    }

    /// Splits a compression suffix off a member name or field: `npy.gz` gives
    /// (`npy`, [`Compression::Gzip`]), `npy.zst` gives (`npy`, [`Compression::Zstd`]),
    /// anything else itself and [`Compression::None`]. The one parser of the suffixes that
    /// [`Compression::suffix`] writes.
    pub fn split_suffix(name: &str) -> (&str, Compression) {
        for compression in [Compression::Gzip, Compression::Zstd] {
            if let Some(base) = name.strip_suffix(compression.suffix()) {
                return (base, compression);
            }
        }
        (name, Compression::None)
    }

    /// The lowercase name used in JSON and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Compression::None => "none",
            Compression::Gzip => "gzip",
            Compression::Zstd => "zstd",
        }
    }

    /// Parses `none`, `gzip` or `zstd`.
    pub fn from_name(name: &str) -> Option<Compression> {
        match name {
            "none" => Some(Compression::None),
            "gzip" => Some(Compression::Gzip),
            "zstd" => Some(Compression::Zstd),
            _ => None,
        }
    }
}

impl std::fmt::Display for Compression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Compresses one member's bytes deterministically (see the module documentation).
pub fn compress(data: &[u8], compression: Compression) -> Result<Vec<u8>, ShardError> {
    match compression {
        Compression::None => Ok(data.to_vec()),
        Compression::Gzip => {
            let codec_error = |source| ShardError::Codec {
                codec: "gzip",
                action: "compression",
                source,
            };
            let mut encoder = flate2::GzBuilder::new()
                .mtime(0)
                .operating_system(255)
                .write(Vec::new(), flate2::Compression::new(GZIP_LEVEL));
            encoder.write_all(data).map_err(codec_error)?;
            encoder.finish().map_err(codec_error)
        }
        Compression::Zstd => {
            let codec_error = |source| ShardError::Codec {
                codec: "zstd",
                action: "compression",
                source,
            };
            let mut compressor = zstd::bulk::Compressor::new(ZSTD_LEVEL).map_err(codec_error)?;
            compressor.include_checksum(false).map_err(codec_error)?;
            compressor.include_contentsize(true).map_err(codec_error)?;
            compressor.compress(data).map_err(codec_error)
        }
    }
}

/// Upper bound of the bytes [`compress`] makes of `bytes` bytes of any content, so that a
/// shard's largest size follows from its plan whatever the voxels are. Incompressible input
/// grows a little: zstd's frame bound (`ZSTD_compressBound`) adds 1/256 and a few dozen
/// bytes, DEFLATE's stored blocks 5 bytes a block of at most 64 KiB, gzip 18 more; 1/128 and
/// 1 KiB cover both with room to spare.
pub fn max_compressed_bytes(bytes: u64, compression: Compression) -> u64 {
    match compression {
        Compression::None => bytes,
        Compression::Gzip | Compression::Zstd => {
            bytes.saturating_add(bytes / 128).saturating_add(1024)
        }
    }
}

/// The codec a stream starts with, told by its magic bytes (gzip `1f 8b`, zstd
/// `28 b5 2f fd`); anything else is [`Compression::None`].
pub fn sniff(prefix: &[u8]) -> Compression {
    if prefix.starts_with(&[0x1f, 0x8b]) {
        Compression::Gzip
    } else if prefix.starts_with(&[0x28, 0xb5, 0x2f, 0xfd]) {
        Compression::Zstd
    } else {
        Compression::None
    }
}

/// A streaming decoder of `compression` over `reader`. It does not limit its output:
/// the caller reads from it through a bound of its own (for a `.npy`,
/// `bettimill_grid::npy::read_from` reads exactly what the header promises).
pub fn decoder<'a, R: std::io::BufRead + 'a>(
    reader: R,
    compression: Compression,
) -> Result<Box<dyn Read + 'a>, ShardError> {
    Ok(match compression {
        Compression::None => Box::new(reader),
        Compression::Gzip => Box::new(flate2::bufread::GzDecoder::new(reader)),
        Compression::Zstd => Box::new(zstd::stream::read::Decoder::with_buffer(reader).map_err(
            |source| ShardError::Codec {
                codec: "zstd",
                action: "decompression",
                source,
            },
        )?),
    })
}

/// Decompresses one member's bytes, refusing output larger than `limit` bytes.
pub fn decompress(
    data: &[u8],
    compression: Compression,
    limit: u64,
) -> Result<Vec<u8>, ShardError> {
    let (codec, reader): (&'static str, Box<dyn Read + '_>) = match compression {
        Compression::None => {
            if data.len() as u64 > limit {
                return Err(ShardError::DecompressedTooLarge {
                    codec: "none",
                    limit,
                });
            }
            return Ok(data.to_vec());
        }
        Compression::Gzip => ("gzip", Box::new(flate2::read::GzDecoder::new(data))),
        Compression::Zstd => (
            "zstd",
            Box::new(
                zstd::stream::read::Decoder::with_buffer(data).map_err(|source| {
                    ShardError::Codec {
                        codec: "zstd",
                        action: "decompression",
                        source,
                    }
                })?,
            ),
        ),
    };
    let mut out = Vec::new();
    // Reading one byte past the limit tells "exactly at the limit" from "beyond it".
    reader
        .take(limit.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|source| ShardError::Codec {
            codec,
            action: "decompression",
            source,
        })?;
    if out.len() as u64 > limit {
        return Err(ShardError::DecompressedTooLarge { codec, limit });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> Vec<u8> {
        (0..5000u32).map(|i| ((i * 7919) % 3 == 0) as u8).collect()
    }

    #[test]
    fn round_trips_and_is_repeatable() {
        for c in [Compression::None, Compression::Gzip, Compression::Zstd] {
            let a = compress(&data(), c).unwrap();
            let b = compress(&data(), c).unwrap();
            assert_eq!(a, b, "{c}");
            assert_eq!(decompress(&a, c, 5000).unwrap(), data(), "{c}");
            assert!(matches!(
                decompress(&a, c, 4999),
                Err(ShardError::DecompressedTooLarge { limit: 4999, .. })
            ));
            assert_eq!(Compression::from_name(c.name()), Some(c));
        }
    }

    #[test]
    fn compressed_members_stay_within_their_bound_even_for_incompressible_input() {
        // xorshift64: bytes no codec can shrink.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let noise: Vec<u8> = (0..300_000)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 24) as u8
            })
            .collect();
        for c in [Compression::None, Compression::Gzip, Compression::Zstd] {
            for len in [0, 1, 100, 65_535, 65_536, 300_000] {
                let out = compress(&noise[..len], c).unwrap().len() as u64;
                let bound = max_compressed_bytes(len as u64, c);
                assert!(out <= bound, "{c} of {len} random bytes: {out} > {bound}");
                if c != Compression::None && len >= 65_536 {
                    // The bound is not loose by orders: random bytes do not shrink.
                    assert!(out >= len as u64, "{c} of {len} random bytes: {out}");
                }
            }
        }
    }

    #[test]
    fn gzip_header_has_no_time_and_no_name() {
        let gz = compress(b"abc", Compression::Gzip).unwrap();
        assert_eq!(&gz[..3], &[0x1f, 0x8b, 8]);
        assert_eq!(gz[3], 0, "no FNAME/FCOMMENT/FEXTRA flags");
        assert_eq!(&gz[4..8], &[0, 0, 0, 0], "mtime 0");
        assert_eq!(gz[9], 255, "OS unknown");
    }

    #[test]
    fn zstd_frame_has_no_checksum() {
        let z = compress(&data(), Compression::Zstd).unwrap();
        assert_eq!(&z[..4], &[0x28, 0xb5, 0x2f, 0xfd]);
        assert_eq!(z[4] & 0b100, 0, "content checksum flag clear");
    }

    #[test]
    fn sniffs_and_streams_what_it_writes() {
        for c in [Compression::None, Compression::Gzip, Compression::Zstd] {
            let packed = compress(&[b'x'; 100], c).unwrap();
            assert_eq!(sniff(&packed), c);
            let mut out = Vec::new();
            decoder(&packed[..], c)
                .unwrap()
                .read_to_end(&mut out)
                .unwrap();
            assert_eq!(out, [b'x'; 100], "{c}");
        }
        assert_eq!(sniff(&[0x1f]), Compression::None);
        assert_eq!(sniff(b"\x93NUMPY"), Compression::None);
    }

    #[test]
    fn garbage_is_an_error_not_a_panic() {
        for c in [Compression::Gzip, Compression::Zstd] {
            assert!(decompress(b"definitely not compressed", c, 1 << 20).is_err());
        }
    }

    #[test]
    fn serde_names_are_lowercase() {
        assert_eq!(
            serde_json::to_string(&Compression::Zstd).unwrap(),
            "\"zstd\""
        );
    }
}
