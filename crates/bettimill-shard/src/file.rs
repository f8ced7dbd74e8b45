//! Files as storage sees them: plain files only, hashed as a stream through a fixed
//! buffer, so that neither a device nor a huge file is read whole.

use std::path::Path;

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

/// Whether the file at `path` has `bytes` bytes and blake3 `blake3`, hashed through a fixed
/// buffer. The error says what differs (or why the file cannot be read).
pub fn file_matches(path: &Path, bytes: u64, blake3: &str) -> Result<(), String> {
    let size = regular_len(path).map_err(|err| format!("{}: {err}", path.display()))?;
    if size != bytes {
        return Err(format!(
            "{} has {size} bytes, its record says {bytes}",
            path.display()
        ));
    }
    let file = std::fs::File::open(path).map_err(|err| format!("{}: {err}", path.display()))?;
    let mut hasher = blake3::Hasher::new();
    hasher
        .update_reader(std::io::Read::take(file, bytes + 1))
        .map_err(|err| format!("{}: {err}", path.display()))?;
    let found = hasher.finalize().to_hex();
    if found.as_str() != blake3 {
        return Err(format!(
            "{} has blake3 {found}, its record says {blake3}",
            path.display()
        ));
    }
    Ok(())
}
