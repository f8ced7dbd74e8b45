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
//! Array tasks (`bettimill worker --task-count N`) hold it shared ([`DirLock::share`]): any
//! number of tasks, of one job or of several, write side by side, while a build or a
//! `finalize` (exclusive) and tasks exclude each other and the one refused is told which
//! kind of writer holds the directory ([`Holder`]). On a shared file system whose locks do
//! not work the tasks write without it (every write is atomic with deterministic bytes, and
//! temporaries are locked by their writers, so a build beside them still ends identical).

use std::fs::{File, OpenOptions, TryLockError};
use std::path::{Path, PathBuf};

/// Which kind of process holds a busy directory lock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Holder {
    /// A build or a `finalize` (an exclusive holder).
    Build,
    /// Array tasks (shared holders).
    ArrayTasks,
}

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
    /// Array tasks hold the lock: a build does not write beside them.
    #[error("array tasks (`bettimill worker --task-count N`) are writing into {dir} (they hold {path}); wait for their job to end or cancel it, then run this again to build what is left, or use another --out directory")]
    ArrayTasks {
        /// The dataset directory.
        dir: PathBuf,
        /// The lock file.
        path: PathBuf,
    },
    /// A build or a finalize holds the lock: an array task does not write beside it.
    #[error("a bettimill build or finalize is running in {dir} (it holds {path}); array tasks do not write beside it: let it finish (a build makes every shard), or stop it and submit the array job again")]
    BuildRunning {
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
    /// Takes the lock on `dir` (which must exist) exclusively, without waiting: a build.
    pub fn acquire(dir: &Path) -> Result<DirLock, LockError> {
        let (file, path) = Self::open(dir)?;
        match file.try_lock() {
            Ok(()) => Ok(DirLock { _file: file, path }),
            Err(TryLockError::WouldBlock) => Err(match Self::holder(&path) {
                Holder::Build => LockError::Busy {
                    dir: dir.to_path_buf(),
                    path,
                },
                Holder::ArrayTasks => LockError::ArrayTasks {
                    dir: dir.to_path_buf(),
                    path,
                },
            }),
            Err(TryLockError::Error(source)) => Err(LockError::Io { path, source }),
        }
    }

    /// Takes the lock on `dir` (which must exist) shared, without waiting: an array task,
    /// beside any number of others. `Ok(None)` when the file system has no working locks
    /// (some cluster file systems): the task then writes unlocked, which is safe (see the
    /// module documentation) but tells nobody.
    pub fn share(dir: &Path) -> Result<Option<DirLock>, LockError> {
        let (file, path) = Self::open(dir)?;
        match file.try_lock_shared() {
            Ok(()) => Ok(Some(DirLock { _file: file, path })),
            Err(TryLockError::WouldBlock) => Err(LockError::BuildRunning {
                dir: dir.to_path_buf(),
                path,
            }),
            Err(TryLockError::Error(_)) => Ok(None),
        }
    }

    /// Who holds the busy lock at `path`: array tasks if a shared lock can be had beside
    /// them, else a build or finalize (or a holder that has just gone: the caller's own
    /// attempt decides).
    fn holder(path: &Path) -> Holder {
        let shared = File::open(path).is_ok_and(|probe| probe.try_lock_shared().is_ok());
        if shared {
            Holder::ArrayTasks
        } else {
            Holder::Build
        }
    }

    /// Takes the lock on `dir` (which must exist) exclusively, waiting for the processes
    /// that hold it to release it; `waiting` is called once, before the wait, when the lock
    /// is busy, with the kind of holder. For commands that must not fail because another
    /// one runs (two `finalize`, a `finalize` during a build's last step or while array
    /// tasks still write): it runs after them, and finds its work done.
    pub fn wait(dir: &Path, waiting: impl FnOnce(&Path, Holder)) -> Result<DirLock, LockError> {
        let (file, path) = Self::open(dir)?;
        match file.try_lock() {
            Ok(()) => return Ok(DirLock { _file: file, path }),
            Err(TryLockError::WouldBlock) => waiting(&path, Self::holder(&path)),
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
            DirLock::wait(&path, |lock, _| told.send(lock.to_path_buf()).unwrap()).map(|_| ())
        });
        // The waiter says it waits only while the lock is held, so this returns.
        assert_eq!(
            heard.recv().unwrap(),
            dir.path().join(crate::dir::LOCK_FILE)
        );
        drop(first);
        waiter.join().unwrap().unwrap();
        // Free lock: no waiting, no message.
        DirLock::wait(dir.path(), |_, _| panic!("the lock is free")).unwrap();
    }

    #[test]
    fn array_tasks_share_the_lock_and_exclude_builds_both_ways() {
        let dir = tempfile::tempdir().unwrap();
        let first = DirLock::share(dir.path())
            .unwrap()
            .expect("flock works in tmp");
        let second = DirLock::share(dir.path()).unwrap().expect("tasks share");
        let err = DirLock::acquire(dir.path()).unwrap_err();
        assert!(matches!(err, LockError::ArrayTasks { .. }), "{err}");
        assert!(err.to_string().contains("array tasks"), "{err}");
        drop((first, second));
        let build = DirLock::acquire(dir.path()).unwrap();
        let err = DirLock::acquire(dir.path()).unwrap_err();
        assert!(matches!(err, LockError::Busy { .. }), "{err}");
        let err = DirLock::share(dir.path()).unwrap_err();
        assert!(matches!(err, LockError::BuildRunning { .. }), "{err}");
        drop(build);
        DirLock::share(dir.path()).unwrap().unwrap();
    }
}
