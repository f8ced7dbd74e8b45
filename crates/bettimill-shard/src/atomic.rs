//! Crash-safe file replacement.
//!
//! [`write_atomic`] writes to a temporary file in the same directory
//! (`.NAME.tmp-PID`), flushes it to disk, renames it over the target and flushes the
//! directory, so that after a crash the target holds either its old bytes or the new ones,
//! never a prefix. A crash can leave the temporary file behind; `bettimill verify` reports
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
    write_atomic_then(path, bytes, || {})
}

/// [`write_atomic`], calling `before_rename` once the temporary file is durable and before
/// it is renamed into place: the one write path, with a seam where the executor's test
/// hook waits so that tests can kill a build in exactly that window.
pub fn write_atomic_then(
    path: &Path,
    bytes: &[u8],
    before_rename: impl FnOnce(),
) -> Result<(), ShardError> {
    if path.file_name().is_none() {
        return Err(ShardError::io(
            "cannot write",
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "path has no file name"),
        ));
    }
    let temporary = temporary_path(path);
    let result = write_and_rename(&temporary, path, bytes, before_rename);
    if result.is_err() {
        // Best effort: the error being returned is the one that matters.
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

/// A file written piece by piece under its temporary name and put in place atomically by
/// [`AtomicFile::commit`] (fsync, rename, fsync of the directory), for files too large to
/// hold in memory. Dropped without commit, the temporary file is removed.
pub struct AtomicFile {
    path: PathBuf,
    temporary: PathBuf,
    file: Option<std::io::BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing `path` (its parent directory must exist).
    pub fn create(path: &Path) -> Result<AtomicFile, ShardError> {
        let temporary = temporary_path(path);
        let file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&temporary)
            .map_err(|e| ShardError::io("cannot create", &temporary, e))?;
        Ok(AtomicFile {
            path: path.to_path_buf(),
            temporary,
            file: Some(std::io::BufWriter::new(file)),
        })
    }

    /// The temporary path being written.
    pub fn temporary(&self) -> &Path {
        &self.temporary
    }

    /// Flushes, fsyncs and renames the file into place.
    pub fn commit(mut self) -> Result<(), ShardError> {
        let writer = self.file.take().expect("not yet committed");
        let file = writer
            .into_inner()
            .map_err(|e| ShardError::io("cannot write", &self.temporary, e.into_error()))?;
        file.sync_all()
            .map_err(|e| ShardError::io("cannot fsync", &self.temporary, e))?;
        drop(file);
        std::fs::rename(&self.temporary, &self.path)
            .map_err(|e| ShardError::io("cannot rename into", &self.path, e))?;
        sync_parent(&self.path)
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.file.as_mut().expect("not yet committed").write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.as_mut().expect("not yet committed").flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            // Best effort: an uncommitted file must not linger under its temporary name.
            let _ = std::fs::remove_file(&self.temporary);
        }
    }
}

fn write_and_rename(
    temporary: &Path,
    path: &Path,
    bytes: &[u8],
    before_rename: impl FnOnce(),
) -> Result<(), ShardError> {
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
    before_rename();
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
    fn the_seam_runs_with_the_durable_temporary_and_before_the_rename() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.tar");
        write_atomic(&path, b"old").unwrap();
        let mut seen = None;
        write_atomic_then(&path, b"new", || {
            seen = Some((
                std::fs::read(temporary_path(&path)).unwrap(),
                std::fs::read(&path).unwrap(),
            ));
        })
        .unwrap();
        assert_eq!(seen, Some((b"new".to_vec(), b"old".to_vec())));
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert!(!temporary_path(&path).exists());
    }

    #[test]
    fn missing_directory_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/x.tar");
        let err = write_atomic(&path, b"x").unwrap_err();
        assert!(err.to_string().contains("no/such/dir"), "{err}");
    }
}
