//! Crash-safe file replacement.
//!
//! [`write_atomic`] writes to a temporary file in the same directory
//! (`.NAME.tmp-PID`), flushes it to disk, renames it over the target and flushes the
//! directory, so that after a crash the target holds either its old bytes or the new ones,
//! never a prefix. A crash can leave the temporary file behind; [`crate::verify()`] reports
//! it as an extra file and it is safe to delete.

use crate::ShardError;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The temporary name [`write_atomic`] uses for `path` in this process.
pub fn temporary_path(path: &Path) -> PathBuf {
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{file_name}.tmp-{}", std::process::id()))
}

/// Replaces `path` with `bytes` atomically and durably (see the module documentation).
/// The parent directory must exist.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ShardError> {
    if path.file_name().is_none() {
        return Err(ShardError::io(
            "cannot write",
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "path has no file name"),
        ));
    }
    let temporary = temporary_path(path);
    let result = write_and_rename(&temporary, path, bytes);
    if result.is_err() {
        // Best effort: the error being returned is the one that matters.
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

fn write_and_rename(temporary: &Path, path: &Path, bytes: &[u8]) -> Result<(), ShardError> {
    let mut file = OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(temporary)
        .map_err(|e| ShardError::io("cannot create", temporary, e))?;
    file.write_all(bytes)
        .map_err(|e| ShardError::io("cannot write", temporary, e))?;
    file.sync_all()
        .map_err(|e| ShardError::io("cannot fsync", temporary, e))?;
    drop(file);
    std::fs::rename(temporary, path).map_err(|e| ShardError::io("cannot rename into", path, e))?;
    sync_parent(path)
}

#[cfg(unix)]
fn sync_parent(path: &Path) -> Result<(), ShardError> {
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let dir = File::open(parent).map_err(|e| ShardError::io("cannot open directory", parent, e))?;
    dir.sync_all()
        .map_err(|e| ShardError::io("cannot fsync directory", parent, e))
}

#[cfg(not(unix))]
fn sync_parent(_path: &Path) -> Result<(), ShardError> {
    // Directories cannot be opened for syncing on this platform; the rename is still
    // atomic, only its durability across power loss is weaker.
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("index.json");
        write_atomic(&path, b"one").unwrap();
        write_atomic(&path, b"two").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("index.json")]);
    }

    #[test]
    fn missing_directory_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/x.tar");
        let err = write_atomic(&path, b"x").unwrap_err();
        assert!(err.to_string().contains("no/such/dir"), "{err}");
    }
}
