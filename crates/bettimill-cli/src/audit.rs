//! `bettimill audit`: rebuild chosen shards and compare bytes, and/or recompute labels.

use crate::commands::ExitStatus;
use crate::printer::Printer;
use bettimill_audit::{AuditReport, Selection};
use bettimill_executor::Dataset;
use bettimill_format::DatasetSource;
use clap::Args;
use std::path::{Path, PathBuf};

/// Arguments of `bettimill audit`.
#[derive(Args, Debug)]
pub struct AuditArgs {
    /// The dataset directory, or s3://BUCKET/PREFIX (read with the AWS_* variables; its
    /// shards by ranges, nothing written there).
    dir: PathBuf,
    /// Rebuild this fraction of the shards (chosen reproducibly) and compare bytes.
    #[arg(long, value_name = "FRACTION", conflicts_with = "shards")]
    rebuild: Option<f64>,
    /// Rebuild these shards (numbers or names, comma-separated) and compare bytes.
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    shards: Option<Vec<String>>,
    /// Seed for choosing the shards of --rebuild FRACTION.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Recompute the Betti numbers of every stored sample (of the chosen shards, or of all
    /// shards when none are chosen) and compare them with the stored labels.
    #[arg(long)]
    relabel: bool,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// Runs an audit, with a progress bar per sample on stderr (see `crate::progress`).
pub fn run(args: &AuditArgs, printer: Printer) -> anyhow::Result<ExitStatus> {
    let changed = |err: bettimill_executor::BuildError| match err {
        bettimill_executor::BuildError::Format(
            bettimill_format::FormatError::DifferentManifest {
                expected, found, ..
            },
        ) => changed_manifest(&args.dir, &expected, &found),
        other => other.into(),
    };
    // A bucket is audited from a local copy of its metadata, its shards read by ranges.
    let copy = match crate::commands::object_url(&args.dir) {
        Some(url) => Some(bettimill_executor::remote::bucket_copy(url, None).map_err(changed)?),
        None => None,
    };
    let local;
    let (dataset, source) = match &copy {
        Some(copy) => (&copy.dataset, &copy.source),
        None => {
            // An index of an older format is named as such before the plan is compared.
            bettimill_format::DatasetDir::new(&args.dir).check_index()?;
            local = (
                Dataset::open(&args.dir).map_err(changed)?,
                DatasetSource::Dir(bettimill_format::DatasetDir::new(&args.dir)),
            );
            (&local.0, &local.1)
        }
    };
    let selection = match (&args.rebuild, &args.shards) {
        (Some(fraction), _) => Some(Selection::Fraction {
            fraction: *fraction,
            seed: args.seed,
        }),
        (None, Some(list)) => Some(Selection::Shards(list.clone())),
        (None, None) => None,
    };
    if selection.is_none() && !args.relabel {
        anyhow::bail!("nothing to audit: give --rebuild FRACTION, --shards LIST and/or --relabel");
    }
    let chosen = match &selection {
        Some(selection) => bettimill_audit::select(dataset, selection)?,
        None => dataset.plan.shards().collect(),
    };
    // The files that are pure functions of the plan and the records, byte for byte.
    let files = bettimill_audit::check_files(dataset);
    // One bar over both passes: every chosen sample once per pass.
    let samples: u64 = chosen.iter().map(|shard| shard.samples).sum();
    let passes = u64::from(selection.is_some()) + u64::from(args.relabel);
    let bar = printer.bar(samples * passes, "samples", "");
    let tick = || bar.inc(1);
    let mut report = AuditReport::default();
    if selection.is_some() {
        bar.set_message("rebuilding");
        report = bettimill_audit::rebuild_from(dataset, source, &chosen, &tick)
            .inspect_err(|_| bar.finish_and_clear())?;
    }
    if args.relabel {
        bar.set_message("relabelling");
        let relabelled = bettimill_audit::relabel_from(dataset, source, &chosen, &tick)
            .inspect_err(|_| bar.finish_and_clear())?;
        report.relabelled_samples = relabelled.relabelled_samples;
        report.findings.extend(relabelled.findings);
    }
    bar.finish_and_clear();
    report.findings.splice(0..0, files);
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        for finding in &report.findings {
            outln!("{finding}");
        }
        outln!(
            "{}: rebuilt {} shard(s), relabelled {} sample(s), {} difference(s)",
            if report.findings.is_empty() {
                "ok"
            } else {
                "DIFFERS"
            },
            report.rebuilt.len(),
            report.relabelled_samples,
            report.findings.len()
        );
    }
    Ok(if report.findings.is_empty() {
        ExitStatus::Success
    } else {
        ExitStatus::Differs
    })
}

/// Build's advice for a different manifest (another --out directory) does not fit an
/// audit: the dataset's own manifest was changed after it was built.
fn changed_manifest(dir: &Path, expected: &str, found: &str) -> anyhow::Error {
    let location = match crate::commands::object_url(dir) {
        Some(url) => format!("{url}/{}", bettimill_format::dir::MANIFEST_FILE),
        None => dir
            .join(bettimill_format::dir::MANIFEST_FILE)
            .display()
            .to_string(),
    };
    anyhow::anyhow!(
        "{location}: its canonical hash is {expected}, but build.json says the dataset was built from {found}: the manifest was changed after the build, so nothing in {} can be audited against it; restore the manifest.toml it was built from (`bettimill verify {}` names the files that differ)",
        dir.display(),
        dir.display()
    )
}
