//! `bettimill stats`: counts per Betti vector, class, split, component count, knot type and
//! hypervolume; regeneration rates; build time; an optional histogram PNG.

use crate::commands::Status;
use anyhow::{bail, Context};
use bettimill_preview::{labels_in_tar, plot, RecordStats, Stats};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::{Path, PathBuf};

/// Runs `bettimill stats`.
pub fn run(
    dir: &Path,
    json: bool,
    plot_path: Option<&Path>,
    quiet: bool,
) -> anyhow::Result<Status> {
    if !dir.is_dir() {
        bail!(
            "{} is not a directory: give a dataset directory written by `bettimill build --out DIR`",
            dir.display()
        );
    }
    let shards = crate::preview::dataset_shards(dir)?;
    // indicatif draws nothing when stderr is not a terminal; --quiet hides the bar too.
    let target = if quiet {
        ProgressDrawTarget::hidden()
    } else {
        ProgressDrawTarget::stderr()
    };
    let bar = ProgressBar::with_draw_target(Some(shards.len() as u64), target).with_style(
        ProgressStyle::with_template("reading labels {bar:30} {pos}/{len} shards")
            .expect("the template is valid"),
    );
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
    let stats = Stats::collect(&labels, &records, shards.len() as u64);
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
    Ok(Status::Success)
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
