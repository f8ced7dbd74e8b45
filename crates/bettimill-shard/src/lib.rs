//! The storage layer of bettimill: deterministic USTAR bytes, per-member compression,
//! crash-safe file replacement and streamed hashing. It knows no dataset directory, paths,
//! records or index: those are `bettimill-format`'s, which builds on this crate.
//!
//! - [`ustar`]: the byte layout of a shard and a safe reader for untrusted tars.
//! - [`mod@compress`]: deterministic per-member gzip and zstd (`KEY.npy.gz`, `KEY.npy.zst`).
//! - [`atomic`]: crash-safe file replacement used for every file the build writes.
//! - [`mod@file`]: plain files only, their size and blake3 streamed through a fixed buffer.
//! - [`object`]: objects under an `s3://BUCKET/PREFIX` URL: create-only puts, ranged reads.
//!
//! Architecture invariant: the same members always give the same bytes; nothing here
//! reads the clock, the environment, the user name or the file system order (object
//! storage gets its endpoint and credentials from its caller).

pub mod atomic;
pub mod compress;
mod error;
pub mod file;
pub mod object;
pub mod ustar;

pub use atomic::{write_atomic, AtomicFile};
pub use compress::{compress, decoder, decompress, sniff, Compression};
pub use error::ShardError;
pub use file::{blake3_hex, file_matches, regular_len, FileMismatch, RegularFileError};
pub use ustar::{
    read_tar, read_tar_with_limit, split_key, tar_bytes, tar_entries, Member, TarEntry, TarStream,
};
