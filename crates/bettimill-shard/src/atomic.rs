//! Crash-safe file replacement.
//!
//! [`write_atomic`] writes to a temporary file in the same directory
//! (`.NAME.tmp-PID`), flushes it to disk, renames it over the target and flushes the
//! directory, so that after a crash the target holds either its old bytes or the new ones,
//! never a prefix. A crash can leave the temporary file behind; `bettimill verify` reports
//! it as an extra file and it is safe to delete.
//!
//! The writer holds an exclusive lock (`flock`-style, [`File::try_lock`]) on its temporary
//! file from just after creating it until it is renamed into place, and the operating system
//! drops the lock when the writer dies in any way. [`remove_if_abandoned`] removes a
//! temporary only when it can take that lock: several processes write into one dataset
//! directory without sharing a lock (array tasks, a resubmitted job's tasks beside the old
//! job's), and a cleaner must not remove the temporary of a writer that is still running,
//! whose rename would then fail.

use crate::ShardError;
use std::fs::{File, OpenOptions, TryLockError};
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
        hold(&file);
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
    pub fn commit(self) -> Result<(), ShardError> {
        self.commit_then(|| {})
    }

    /// [`AtomicFile::commit`], calling `before_rename` once the file is durable under its
    /// temporary name, just before the rename (the seam where a crash leaves a complete
    /// temporary and no file).
    pub fn commit_then(mut self, before_rename: impl FnOnce()) -> Result<(), ShardError> {
        let writer = self.file.take().expect("not yet committed");
        let file = writer
            .into_inner()
            .map_err(|e| ShardError::io("cannot write", &self.temporary, e.into_error()))?;
        file.sync_all()
            .map_err(|e| ShardError::io("cannot fsync", &self.temporary, e))?;
        before_rename();
        // The file (and its lock) stays open through the rename.
        std::fs::rename(&self.temporary, &self.path)
            .map_err(|e| ShardError::io("cannot rename into", &self.path, e))?;
        drop(file);
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
    hold(&file);
    file.write_all(bytes)
        .map_err(|e| ShardError::io("cannot write", temporary, e))?;
    file.sync_all()
        .map_err(|e| ShardError::io("cannot fsync", temporary, e))?;
    before_rename();
    // The file (and its lock) stays open through the rename.
    std::fs::rename(temporary, path).map_err(|e| ShardError::io("cannot rename into", path, e))?;
    drop(file);
    sync_parent(path)
}

/// Locks a temporary file for its writer, so that [`remove_if_abandoned`] leaves it alone
/// while the writer lives. Best effort: on a file system without locks the write goes on
/// unlocked (and a cleaner there cannot tell a live writer from a dead one either).
fn hold(file: &File) {
    let _ = file.try_lock();
}

/// Removes the temporary file `path` of an atomic write unless its writer is still running
/// (it holds the file's lock; see the module documentation). Returns whether it was
/// removed: `false` for a live writer's file and for one that is already gone (renamed into
/// place or removed meanwhile). Where the file system has no locks, the file is removed,
/// as it would be without them.
pub fn remove_if_abandoned(path: &Path) -> std::io::Result<bool> {
    // Opened for writing: an exclusive lock over NFS needs a writable descriptor.
    let file = match OpenOptions::new().write(true).open(path) {
        Ok(file) => file,
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(err) => return Err(err),
    };
    match file.try_lock() {
        Ok(()) | Err(TryLockError::Error(_)) => {}
        Err(TryLockError::WouldBlock) => return Ok(false),
    }
    match std::fs::remove_file(path) {
        Ok(()) => Ok(true),
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(err) => Err(err),
    }
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
    fn a_temporary_is_removed_only_once_its_writer_is_gone() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.tar");
        let mut writer = AtomicFile::create(&path).unwrap();
        writer.write_all(b"half").unwrap();
        let temporary = writer.temporary().to_path_buf();
        // The writer holds it: a cleaner leaves it, and the writer still commits.
        assert!(!remove_if_abandoned(&temporary).unwrap());
        writer.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"half");
        assert!(!remove_if_abandoned(&temporary).unwrap(), "gone already");
        // The same file left by a writer that died (nobody holds it) is removed.
        std::fs::write(&temporary, b"left").unwrap();
        assert!(remove_if_abandoned(&temporary).unwrap());
        assert!(!temporary.exists());
        // A write waiting before its rename holds its temporary too.
        write_atomic_then(&path, b"new", || {
            assert!(!remove_if_abandoned(&temporary_path(&path)).unwrap());
        })
        .unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
    }

    #[test]
    fn missing_directory_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/x.tar");
        let err = write_atomic(&path, b"x").unwrap_err();
        assert!(err.to_string().contains("no/such/dir"), "{err}");
    }
}
