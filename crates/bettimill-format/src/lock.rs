//! The lock that keeps two builds out of one dataset directory.
//!
//! `DIR/.lock` is an empty file that a coordinator locks exclusively (`flock`-style advisory
//! lock through [`std::fs::File::try_lock`]) for its whole run. The operating system drops
//! the lock when the process exits in any way, kill -9 included, so a lock left by a dead
//! process is never mistaken for a live one and needs no cleaning up: the file stays, the
//! lock does not. The file is always empty, so it never makes two directories differ.
//!
//! It is taken before anything is written into a new directory ([`crate::DatasetDir::bind`]
//! creates the directory, locks it, then writes `manifest.toml` and `build.json`), and a
//! build holds it from that binding to its end ([`crate::DatasetDir::bind_locked`]), so a
//! `finalize` (which waits for it) never slips in between. A `.lock` that is a symbolic link
//! is refused: the lock never creates a file outside the directory.
//!
//! Cluster workers (`bettimill worker --task-index-from-env`) do not take it: they build
//! disjoint shards on shared file systems where such locks may not work, and every write is
//! atomic with deterministic bytes anyway.

use std::fs::{File, OpenOptions, TryLockError};
use std::path::{Path, PathBuf};

/// Why the directory could not be locked.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another live process (a build or a finalize) holds the lock.
    #[error("another bettimill build or finalize is running in {dir} (it holds {path}); wait for it to finish or stop it, or use another --out directory")]
    Busy {
        /// The dataset directory.
        dir: PathBuf,
        /// The lock file.
        path: PathBuf,
    },
    /// The lock file could not be opened or locked.
    #[error("cannot lock {path}: {source}")]
    Io {
        /// The lock file.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
}

/// An exclusive lock on a dataset directory, released on drop or process exit.
#[derive(Debug)]
pub struct DirLock {
    _file: File,
    path: PathBuf,
}

impl DirLock {
    /// Takes the lock on `dir` (which must exist) without waiting.
    pub fn acquire(dir: &Path) -> Result<DirLock, LockError> {
        let (file, path) = Self::open(dir)?;
        match file.try_lock() {
            Ok(()) => Ok(DirLock { _file: file, path }),
            Err(TryLockError::WouldBlock) => Err(LockError::Busy {
                dir: dir.to_path_buf(),
                path,
            }),
            Err(TryLockError::Error(source)) => Err(LockError::Io { path, source }),
        }
    }

    /// Takes the lock on `dir` (which must exist), waiting for the process that holds it
    /// to release it; `waiting` is called once, before the wait, when the lock is busy.
    /// For commands that must not fail because another one runs (two `finalize`, or a
    /// `finalize` during a build's last step): the second runs after the first, and finds
    /// its work done.
    pub fn wait(dir: &Path, waiting: impl FnOnce(&Path)) -> Result<DirLock, LockError> {
        let (file, path) = Self::open(dir)?;
        match file.try_lock() {
            Ok(()) => return Ok(DirLock { _file: file, path }),
            Err(TryLockError::WouldBlock) => waiting(&path),
            Err(TryLockError::Error(source)) => return Err(LockError::Io { path, source }),
        }
        match file.lock() {
            Ok(()) => Ok(DirLock { _file: file, path }),
            Err(source) => Err(LockError::Io { path, source }),
        }
    }

    fn open(dir: &Path) -> Result<(File, PathBuf), LockError> {
        let path = dir.join(crate::dir::LOCK_FILE);
        if std::fs::symlink_metadata(&path).is_ok_and(|meta| meta.file_type().is_symlink()) {
            return Err(LockError::Io {
                source: std::io::Error::other(
                    "it is a symbolic link; bettimill writes nothing through links inside a dataset directory",
                ),
                path,
            });
        }
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|source| LockError::Io {
                path: path.clone(),
                source,
            })?;
        Ok((file, path))
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_until_the_first_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let first = DirLock::acquire(dir.path()).unwrap();
        let err = DirLock::acquire(dir.path()).unwrap_err();
        assert!(matches!(err, LockError::Busy { .. }), "{err}");
        assert!(err.to_string().contains("another bettimill build"), "{err}");
        drop(first);
        let again = DirLock::acquire(dir.path()).unwrap();
        assert_eq!(std::fs::read(again.path()).unwrap(), b"");
    }

    #[test]
    fn a_waiting_lock_is_taken_once_the_holder_releases_it() {
        let dir = tempfile::tempdir().unwrap();
        let first = DirLock::acquire(dir.path()).unwrap();
        let (told, heard) = std::sync::mpsc::channel();
        let path = dir.path().to_path_buf();
        let waiter = std::thread::spawn(move || {
            DirLock::wait(&path, |lock| told.send(lock.to_path_buf()).unwrap()).map(|_| ())
        });
        // The waiter says it waits only while the lock is held, so this returns.
        assert_eq!(
            heard.recv().unwrap(),
            dir.path().join(crate::dir::LOCK_FILE)
        );
        drop(first);
        waiter.join().unwrap().unwrap();
        // Free lock: no waiting, no message.
        DirLock::wait(dir.path(), |_| panic!("the lock is free")).unwrap();
    }
}
