//! `bettimill stats`: counts per Betti vector, class, split, component count, knot type and
//! hypervolume; regeneration rates; build time (from the timings the builds recorded in DIR/timings/, never file times); an optional
//! histogram PNG.

use crate::commands::ExitStatus;
use crate::printer::Printer;
use anyhow::{bail, Context};
use bettimill_preview::{labels_in_stream, plot, BuildTime, Stats};
use std::path::Path;

/// Runs `bettimill stats`.
pub fn run(
    dir: &Path,
    json: bool,
    plot_path: Option<&Path>,
    printer: Printer,
) -> anyhow::Result<ExitStatus> {
    let source = crate::preview::open_source(dir)?;
    if let Some(path) = plot_path {
        refuse_inside_dataset(path, "--plot")?;
        require_extension(path, "--plot", "png")?;
    }
    let shards = crate::preview::dataset_shards(&source)?;
    let bar = printer.bar(shards.len() as u64, "shards", "reading labels");
    let mut labels = Vec::new();
    for shard in &shards {
        bar.inc(1);
        let mut stream =
            crate::preview::open_shard(crate::preview::ShardAt::InDataset(&source, &shard.name))
                .inspect_err(|_| bar.finish_and_clear())?;
        let shard_labels = labels_in_stream(&mut stream).with_context(|| {
            format!(
                "cannot read the labels of {}",
                source.tar_location(&shard.name).display()
            )
        })?;
        labels.extend(shard_labels.into_iter().map(|l| (shard.split.clone(), l)));
    }
    // The records and timings of the shards read, not every file in records/: a leftover
    // (a stray file, a record no shard names) is never data (docs/format.md), so it must
    // neither stop stats nor be counted as a shard.
    let mut records = Vec::new();
    let mut timings = Vec::new();
    for shard in &shards {
        if let Some(record) = source.read_record(&shard.name)? {
            records.push(record);
            if let Some(t) = source.read_timing(&shard.name) {
                timings.push((t.started_unix, t.seconds, t.samples));
            }
        }
    }
    bar.finish_and_clear();
    let mut stats = Stats::collect(&labels, &records, shards.len() as u64);
    stats.build_time = BuildTime::from_timings(&timings, source.is_finalized()?);
    let output = if json {
        serde_json::to_string_pretty(&stats)? + "\n"
    } else {
        stats.to_text()
    };
    Printer::data(output.as_bytes())?;
    if let Some(path) = plot_path {
        let canvas = plot(&stats)?;
        std::fs::write(path, canvas.to_png()?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        printer.note(format_args!("wrote {}", path.display()));
    }
    Ok(ExitStatus::Success)
}

/// Refuses an output file whose extension names a format other than `ext` (`x.jpg` for
/// a PNG), so a file never holds bytes its name does not promise.
pub(crate) fn require_extension(path: &Path, flag: &str, ext: &str) -> anyhow::Result<()> {
    let given = path.extension().map(|e| e.to_string_lossy().to_lowercase());
    if given.as_deref() != Some(ext) {
        let what = match &given {
            Some(e) => format!("cannot write .{e} files"),
            None => "has no extension".to_string(),
        };
        bail!(
            "{flag} {}: {what}; the supported extension is .{ext}",
            path.display()
        );
    }
    Ok(())
}

/// Refuses an output file (`preview --out`, `stats --plot`, `deform --out`) that would land
/// inside a dataset directory, a link followed: every file there is bettimill's, and
/// overwriting one (index.json, a shard) would damage the dataset.
pub(crate) fn refuse_inside_dataset(path: &Path, flag: &str) -> anyhow::Result<()> {
    if let Some(dir) = bettimill_format::dataset_containing(path) {
        bail!(
            "{flag} {}: that is inside the dataset directory {}, whose files are all bettimill's; write it outside the dataset",
            path.display(),
            dir.display()
        );
    }
    Ok(())
}
