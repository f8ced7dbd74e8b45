//! `bettimill stats`: counts per Betti vector, class, split, component count, knot type and
//! hypervolume; regeneration rates; build time (from file modification times); an optional
//! histogram PNG.

use crate::commands::ExitStatus;
use anyhow::{bail, Context};
use bettimill_preview::{labels_in_tar, plot, BuildTime, RecordStats, Stats};
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

/// Runs `bettimill stats`.
pub fn run(
    dir: &Path,
    json: bool,
    plot_path: Option<&Path>,
    quiet: bool,
) -> anyhow::Result<ExitStatus> {
    if !dir.is_dir() {
        bail!(
            "{} is not a directory: give a dataset directory written by `bettimill build --out DIR`",
            dir.display()
        );
    }
    let shards = crate::preview::dataset_shards(dir)?;
    let bar = crate::progress::bar(shards.len() as u64, "shards", "reading labels", quiet);
    let mut labels = Vec::new();
    for (split, shard) in &shards {
        bar.inc(1);
        let bytes = std::fs::read(shard)
            .with_context(|| format!("cannot read shard {}", shard.display()))?;
        let shard_labels = labels_in_tar(&bytes)
            .with_context(|| format!("cannot read the labels of {}", shard.display()))?;
        labels.extend(shard_labels.into_iter().map(|l| (split.clone(), l)));
    }
    let mut record_paths: Vec<PathBuf> = match std::fs::read_dir(dir.join("records")) {
        Ok(entries) => entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "json"))
            .collect(),
        Err(_) => Vec::new(),
    };
    record_paths.sort();
    let mut records = Vec::new();
    for path in &record_paths {
        let bytes =
            std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let record: RecordStats = serde_json::from_slice(&bytes)
            .with_context(|| format!("{} is not a completion record", path.display()))?;
        records.push(record);
    }
    bar.finish_and_clear();
    let mut stats = Stats::collect(&labels, &records, shards.len() as u64);
    stats.build_time = build_time(dir, &record_paths, stats.samples);
    let output = if json {
        serde_json::to_string_pretty(&stats)? + "\n"
    } else {
        stats.to_text()
    };
    write_stdout(output.as_bytes())?;
    if let Some(path) = plot_path {
        let canvas = plot(&stats)?;
        std::fs::write(path, canvas.to_png())
            .with_context(|| format!("cannot write {}", path.display()))?;
        if !quiet {
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(ExitStatus::Success)
}

/// The build's wall-clock span from file modification times: from `DIR/build.json` (written
/// once, when the directory is created) to `DIR/index.json` (written last), or to the newest
/// completion record when the build is unfinished. The dataset itself stores no timings, so
/// that a rebuild is byte-identical. `None` when a time cannot be read.
fn build_time(dir: &Path, record_paths: &[PathBuf], samples: u64) -> Option<BuildTime> {
    let mtime = |path: &Path| -> Option<f64> {
        let modified = std::fs::metadata(path).ok()?.modified().ok()?;
        Some(modified.duration_since(UNIX_EPOCH).ok()?.as_secs_f64())
    };
    let start = mtime(&dir.join("build.json"))?;
    let index = dir.join("index.json");
    let (end, finished) = if index.exists() {
        (mtime(&index)?, true)
    } else {
        let newest = record_paths
            .iter()
            .filter_map(|path| mtime(path))
            .max_by(f64::total_cmp)?;
        (newest, false)
    };
    BuildTime::from_file_times(start, end, finished, samples)
}

/// Writes data to stdout. A reader that stops early (`bettimill stats DIR | head`) closes
/// the pipe; that is the reader's choice, not an error, so a broken pipe ends quietly
/// instead of panicking the way `println!` does.
pub(crate) fn write_stdout(bytes: &[u8]) -> anyhow::Result<()> {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    match stdout.write_all(bytes).and_then(|()| stdout.flush()) {
        Err(err) if err.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(err).context("cannot write to stdout")
        }
        _ => Ok(()),
    }
}
