//! The lock of a dataset in object storage: a lease, with the semantics of the directory
//! lock ([`crate::lock`]). One build holds it for its whole run; a second is refused at once
//! ([`LockError::Busy`]); the lease of a process that died (killed, kill -9 included) is
//! free without cleaning up.
//!
//! Object storage has neither locks nor overwrites we use, so the lease is a sequence of
//! create-only objects `.lease/GENERATION` (20 digits): the newest generation is the lease.
//! Taking it, and renewing it (every [`RENEW_EVERY`]), both create the next generation, so
//! of two processes racing for it exactly one succeeds, and a holder whose renewal is
//! refused knows it lost the lease ([`Lease::lost`]). A lease is free when its object says it
//! was renewed more than [`LEASE_TTL`] ago, or when its holder ran on this host and that
//! process is gone (so a build killed here resumes at once). Released, the holder deletes
//! its objects.

use crate::bucket::BucketDir;
use crate::lock::LockError;
use crate::FormatError;
use bettimill_shard::object::{ObjectDir, ObjectError};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Where the lease's generations live under the prefix.
pub const LEASE_DIR: &str = ".lease/";
/// A lease not renewed for this long is free.
pub const LEASE_TTL: Duration = Duration::from_secs(60);
/// How often the holder renews its lease.
pub const RENEW_EVERY: Duration = Duration::from_secs(15);

/// What a lease object says: who holds it, and when it was last renewed.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Holder {
    /// The holder's host name.
    host: String,
    /// Its process id.
    pid: u32,
    /// Its start time in clock ticks since boot (tells a reused process id).
    start: u64,
    /// When it took or renewed the lease, in seconds since the Unix epoch.
    renewed_unix: u64,
}

impl Holder {
    fn this_process() -> Holder {
        Holder {
            host: host_name(),
            pid: std::process::id(),
            start: process_start(std::process::id()).unwrap_or(0),
            renewed_unix: now_unix(),
        }
    }

    /// Whether this lease binds others still: renewed within the TTL by a process that is
    /// not known to be gone.
    fn is_live(&self) -> bool {
        let fresh = now_unix().saturating_sub(self.renewed_unix) <= LEASE_TTL.as_secs();
        let gone_here = self.host == host_name() && process_start(self.pid) != Some(self.start);
        fresh && !gone_here
    }

    fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = serde_json::to_vec_pretty(self).expect("holders serialise");
        bytes.push(b'\n');
        bytes
    }
}

fn now_unix() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|name| name.trim().to_string())
        .unwrap_or_default()
}

/// A process's start time (field 22 of `/proc/PID/stat`), or `None` when it is gone.
fn process_start(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) may hold spaces and parentheses: fields after it are
    // counted from its closing parenthesis.
    let rest = &stat[stat.rfind(')')? + 1..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    if matches!(fields.first(), Some(&"Z") | Some(&"X")) {
        return None;
    }
    fields.get(19)?.parse().ok()
}

fn generation_name(generation: u64) -> String {
    format!("{LEASE_DIR}{generation:020}")
}

/// A held lease; released (its objects deleted) on drop.
#[derive(Debug)]
pub struct Lease {
    shared: Arc<Shared>,
    renewer: Option<std::thread::JoinHandle<()>>,
}

#[derive(Debug)]
struct Shared {
    objects: Arc<ObjectDir>,
    generation: Mutex<u64>,
    stop: (Mutex<bool>, Condvar),
    lost: AtomicBool,
}

impl Lease {
    /// Takes the lease of the dataset at `bucket` without waiting, or says who holds it.
    pub fn acquire(bucket: &BucketDir) -> Result<Lease, FormatError> {
        let dir = bucket.objects();
        let busy = |generation: u64| {
            FormatError::Lock(LockError::Busy {
                dir: PathBuf::from(dir.url()),
                path: PathBuf::from(dir.object_url(&generation_name(generation))),
            })
        };
        let generations: Vec<u64> = dir
            .list_under(LEASE_DIR.trim_end_matches('/'))?
            .iter()
            .filter_map(|entry| entry.name.strip_prefix(LEASE_DIR)?.parse().ok())
            .collect();
        let newest = generations.iter().copied().max().unwrap_or(0);
        if newest > 0 {
            if let Some(bytes) = dir.get(&generation_name(newest))? {
                // An unreadable lease object is another program's: it binds as a live one.
                let live = serde_json::from_slice::<Holder>(&bytes)
                    .map(|holder| holder.is_live())
                    .unwrap_or(true);
                if live {
                    return Err(busy(newest));
                }
            }
        }
        let generation = newest + 1;
        match dir.put_new(
            &generation_name(generation),
            Holder::this_process().to_bytes(),
        ) {
            Err(ObjectError::Exists { .. }) => return Err(busy(generation)),
            other => other?,
        }
        // The dead holders' generations go; ours stays the newest.
        for old in generations {
            dir.delete(&generation_name(old))?;
        }
        let shared = Arc::new(Shared {
            objects: Arc::clone(dir),
            generation: Mutex::new(generation),
            stop: (Mutex::new(false), Condvar::new()),
            lost: AtomicBool::new(false),
        });
        let renewer = {
            let shared = Arc::clone(&shared);
            std::thread::Builder::new()
                .name("bettimill-lease".into())
                .spawn(move || shared.renew_until_stopped())
                .map_err(|source| FormatError::Io {
                    path: PathBuf::from(dir.url()),
                    source,
                })?
        };
        Ok(Lease {
            shared,
            renewer: Some(renewer),
        })
    }

    /// Whether another process took the lease (this one failed to renew it in time): the
    /// holder stops writing.
    pub fn lost(&self) -> bool {
        self.shared.lost.load(Ordering::SeqCst)
    }

    /// The URL of the lease object now held.
    pub fn url(&self) -> String {
        let generation = *self.shared.generation.lock().expect("lease state");
        self.shared.objects.object_url(&generation_name(generation))
    }
}

impl Shared {
    fn renew_until_stopped(&self) {
        let (stop, wake) = &self.stop;
        let mut stopped = stop.lock().expect("lease state");
        loop {
            let (guard, _) = wake
                .wait_timeout_while(stopped, RENEW_EVERY, |stopped| !*stopped)
                .expect("lease state");
            stopped = guard;
            if *stopped || self.lost.load(Ordering::SeqCst) {
                return;
            }
            let mut generation = self.generation.lock().expect("lease state");
            let next = *generation + 1;
            match self
                .objects
                .put_new(&generation_name(next), Holder::this_process().to_bytes())
            {
                Ok(()) => {
                    let _ = self.objects.delete(&generation_name(*generation));
                    *generation = next;
                }
                // Another process took the lease: ours is gone.
                Err(ObjectError::Exists { .. }) => self.lost.store(true, Ordering::SeqCst),
                // An unreachable server: the next round tries again, and the lease
                // expires for others only after LEASE_TTL.
                Err(_) => {}
            }
        }
    }
}

impl Drop for Lease {
    fn drop(&mut self) {
        {
            let (stop, wake) = &self.shared.stop;
            *stop.lock().expect("lease state") = true;
            wake.notify_all();
        }
        if let Some(renewer) = self.renewer.take() {
            let _ = renewer.join();
        }
        if !self.lost() {
            let generation = *self.shared.generation.lock().expect("lease state");
            let _ = self.shared.objects.delete(&generation_name(generation));
        }
    }
}
