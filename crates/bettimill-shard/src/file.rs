//! Files as storage sees them: plain files only, hashed as a stream through a fixed
//! buffer, so that neither a device nor a huge file is read whole.

use std::path::{Path, PathBuf};

/// Why [`regular_len`] gives no size.
#[derive(Debug, thiserror::Error)]
pub enum RegularFileError {
    /// The file cannot be looked at (the operating system's reason).
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// Something other than a plain file: a link to `/dev/zero` reports no size and never
    /// ends.
    #[error(
        "not a regular file (a device, a directory or a link to one); a shard is a plain file"
    )]
    NotRegular,
}

/// The size of the regular file at `path` (links followed); an error for anything else.
pub fn regular_len(path: &Path) -> Result<u64, RegularFileError> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(RegularFileError::NotRegular);
    }
    Ok(meta.len())
}

/// Lowercase hex BLAKE3 of `bytes`.
pub fn blake3_hex(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

/// Why a file is not the one a record describes ([`file_matches`]).
#[derive(Debug, thiserror::Error)]
pub enum FileMismatch {
    /// The file cannot be looked at or read, or is not a plain file.
    #[error("{path}: {reason}")]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: RegularFileError,
    },
    /// The file has another size.
    #[error("{path} has {found} bytes, its record says {expected}")]
    Size {
        /// The file.
        path: PathBuf,
        /// Its size.
        found: u64,
        /// The recorded size.
        expected: u64,
    },
    /// The file has another blake3.
    #[error("{path} has blake3 {found}, its record says {expected}")]
    Hash {
        /// The file.
        path: PathBuf,
        /// Its blake3.
        found: String,
        /// The recorded blake3.
        expected: String,
    },
}

/// Whether the file at `path` has `bytes` bytes and blake3 `blake3`, hashed through a fixed
/// buffer. The error says what differs (or why the file cannot be read).
pub fn file_matches(path: &Path, bytes: u64, blake3: &str) -> Result<(), FileMismatch> {
    let unreadable = |reason| FileMismatch::Unreadable {
        path: path.to_path_buf(),
        reason,
    };
    let size = regular_len(path).map_err(unreadable)?;
    if size != bytes {
        return Err(FileMismatch::Size {
            path: path.to_path_buf(),
            found: size,
            expected: bytes,
        });
    }
    let file = std::fs::File::open(path).map_err(|e| unreadable(e.into()))?;
    let mut hasher = blake3::Hasher::new();
    hasher
        .update_reader(std::io::Read::take(file, bytes + 1))
        .map_err(|e| unreadable(e.into()))?;
    let found = hasher.finalize().to_hex();
    if found.as_str() != blake3 {
        return Err(FileMismatch::Hash {
            path: path.to_path_buf(),
            found: found.to_string(),
            expected: blake3.to_string(),
        });
    }
    Ok(())
}
