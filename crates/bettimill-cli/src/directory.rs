//! Commands on a dataset directory built elsewhere (by array tasks, or interrupted):
//! `finalize` (write the index once every shard is complete) and `status` (judge every
//! shard from the directory alone). Exit code 2 when the dataset is incomplete.

use crate::commands::ExitStatus;
use crate::printer::Printer;
use bettimill_executor::cluster::{self};
use bettimill_executor::Dataset;
use std::path::Path;

/// `bettimill finalize DIR`.
pub fn finalize(dir: &Path, printer: Printer) -> anyhow::Result<ExitStatus> {
    if let Some(url) = crate::commands::object_url(dir) {
        let options = bettimill_executor::remote::ObjectOptions::default();
        bettimill_executor::remote::bucket_finalize(url, &options)?;
        printer.note(format_args!("finalized {url}/index.json"));
        return Ok(ExitStatus::Success);
    }
    // The lock keeps finalize from removing the temporaries of a running build (or of
    // another finalize) and from racing it to the same renames. A Slurm finalize job and
    // a user's finalize, a finalize during a build's last step or while array tasks still
    // write, must not fail: it waits for them, then finds its work done or what is left.
    let wait = || {
        bettimill_executor::DirLock::wait(dir, |lock, holder| {
            let who = match holder {
                bettimill_executor::Holder::Build => {
                    "another bettimill process is building or finalizing"
                }
                bettimill_executor::Holder::ArrayTasks => {
                    "array tasks (`bettimill worker --task-count N`) are writing into"
                }
            };
            Printer::always(format_args!(
                "{who} {} (holding {}); waiting for them to finish",
                dir.display(),
                lock.display()
            ))
        })
    };
    // A build that is creating the directory holds the lock before build.json exists: a
    // directory with the lock file and no build.json is waited for before it is opened
    // (a creation that was killed is then refused as unfinished, as without the wait).
    let layout = bettimill_format::DatasetDir::new(dir);
    let creating = !layout.has_build_info() && dir.join(bettimill_format::dir::LOCK_FILE).is_file();
    let early = if creating { Some(wait()?) } else { None };
    let dataset = Dataset::open(dir)?;
    let _lock = match early {
        Some(lock) => lock,
        None => wait()?,
    };
    let status = cluster::status(&dataset);
    let incomplete: Vec<&str> = status
        .missing
        .iter()
        .map(String::as_str)
        .chain(status.invalid.iter().map(|s| s.shard.as_str()))
        .collect();
    let not_complete = status.missing_count + status.invalid_count;
    if not_complete > 0 {
        const SHOWN: usize = 20;
        let mut names = incomplete[..incomplete.len().min(SHOWN)].join(", ");
        if not_complete > SHOWN as u64 {
            names.push_str(&format!(
                " and {} more (`bettimill status {}` lists them)",
                not_complete - SHOWN as u64,
                dir.display()
            ));
        }
        Printer::always(format_args!(
            "error: {} of {} shards are not complete: {}\nindex.json not written; build them (resubmit `bettimill slurm ... --submit`, or run `bettimill build ... --out {}`), then finalize again",
            not_complete,
            status.shards,
            names,
            dir.display()
        ));
        return Ok(ExitStatus::Failure);
    }
    // Every shard is complete and the lock is held, so no writer has work left: leftovers
    // of killed ones can go.
    dataset.remove_temporaries()?;
    // `status` has just hashed every shard and found each complete: finalize checks their
    // records and sizes only, so a standalone finalize reads every byte once, not twice.
    // A finalize that finds every file already as it would write it writes nothing (not
    // even a temporary); otherwise every file is renamed into place, index.json last, so
    // the identity of index.json tells the two apart.
    let index_path = dataset.layout().index_path();
    let before = file_identity(&index_path);
    dataset.finalize_checked(&|_| true)?;
    if before.is_some() && before == file_identity(&index_path) {
        printer.note(format_args!(
            "{} shards complete; index.json and the other files were already up to date, nothing changed",
            status.shards
        ));
    } else {
        printer.note(format_args!(
            "{} shards complete; wrote {}",
            status.shards,
            index_path.display()
        ));
    }
    Ok(ExitStatus::Success)
}

/// What changes when a file is replaced (a rename puts a new inode in place) or written.
fn file_identity(path: &Path) -> Option<(u64, u64, Option<std::time::SystemTime>)> {
    let meta = std::fs::metadata(path).ok()?;
    #[cfg(unix)]
    let inode = std::os::unix::fs::MetadataExt::ino(&meta);
    #[cfg(not(unix))]
    let inode = 0;
    Some((inode, meta.len(), meta.modified().ok()))
}

/// `bettimill status DIR`.
pub fn status(dir: &Path, json: bool) -> anyhow::Result<ExitStatus> {
    let report = match crate::commands::object_url(dir) {
        Some(url) => bettimill_executor::remote::bucket_status(url, None)?,
        None => {
            bettimill_format::DatasetDir::new(dir).require_bound()?;
            cluster::status(&Dataset::open(dir)?)
        }
    };
    let mut text = String::new();
    if json {
        text = serde_json::to_string_pretty(&report)?;
        text.push('\n');
    } else {
        text.push_str(&format!(
            "{}: {} of {} shards complete, {} missing, {} invalid; index.json {}\n",
            dir.display(),
            report.complete_count,
            report.shards,
            report.missing_count,
            report.invalid_count,
            if report.finalized {
                "written"
            } else {
                "not written"
            }
        ));
        for name in &report.missing {
            text.push_str(&format!("missing {name}\n"));
        }
        for invalid in &report.invalid {
            text.push_str(&format!("invalid {}: {}\n", invalid.shard, invalid.reason));
        }
        for (count, listed, state) in [
            (report.missing_count, report.missing.len(), "missing"),
            (report.invalid_count, report.invalid.len(), "invalid"),
        ] {
            if count > listed as u64 {
                text.push_str(&format!(
                    "... and {} more {state} shards (the first {listed} are listed)\n",
                    count - listed as u64
                ));
            }
        }
    }
    // A reader that stops early (`| head`) is not an error.
    Printer::data(text.as_bytes())?;
    Ok(ExitStatus::Success)
}

/// `bettimill cat s3://BUCKET/PREFIX/NAME`: the object to stdout, by ranged reads (one range
/// in memory), so `pipe:bettimill cat URL` streams a shard to webdataset.
pub fn cat(url: &str) -> anyhow::Result<ExitStatus> {
    let bucket = bettimill_executor::remote::open_bucket(url, None)?;
    let objects = bucket.objects();
    let Some(size) = objects.size("")? else {
        anyhow::bail!("{url}: no such object");
    };
    let mut reader = objects.reader("", size);
    let mut buffer = vec![0u8; 1 << 20];
    loop {
        // A failed range names the object's URL.
        let read = std::io::Read::read(&mut reader, &mut buffer)?;
        if read == 0 {
            return Ok(ExitStatus::Success);
        }
        Printer::data(&buffer[..read])?;
    }
}
