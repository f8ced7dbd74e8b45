//! Subcommands. Each returns a [`Status`] or an error that `main` reports with exit code 2.

use anyhow::Context;
use bettimill_executor::Dataset;
use bettimill_manifest::{Manifest, DEMO_MANIFEST};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// bettimill builds reproducible datasets of 2D, 3D and 4D binary images whose Betti
/// numbers are known exactly.
#[derive(Parser, Debug)]
#[command(name = "bettimill", version, about, long_about = None)]
pub struct Cli {
    /// Print nothing but errors and data.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Build a dataset from a manifest (or the embedded 3D demo).
    ///
    /// Example: bettimill build --out demo-out
    Build {
        /// The manifest (TOML). Without it, the embedded demo manifest is built.
        manifest: Option<PathBuf>,
        /// Output directory: new, empty, or a partial build of the same manifest to resume.
        #[arg(long)]
        out: PathBuf,
    },
    /// Check every shard and member of a dataset against its index.json.
    ///
    /// Example: bettimill verify demo-out
    Verify {
        /// The dataset directory.
        dir: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Compute the Betti numbers of a binary image stored as .npy.
    ///
    /// Example: bettimill betti image.npy --json
    Betti {
        /// A .npy file of bool or integer dtype with 2 to 4 axes (non-zero = foreground).
        image: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
        /// Refuse values other than 0 and 1.
        #[arg(long)]
        strict: bool,
    },
    /// Show the plan of a manifest: strata, shards, seeds' origin.
    ///
    /// Example: bettimill plan manifests/demo-3d.toml
    Plan {
        /// The manifest (TOML). Without it, the embedded demo manifest.
        manifest: Option<PathBuf>,
        /// Print the plan summary as JSON.
        #[arg(long)]
        json: bool,
    },
}

/// How a command ended.
pub enum Status {
    /// Exit 0.
    Success,
    /// Exit 1: a check found differences.
    Differs,
    /// Exit 2: usage error, bad input, or failure.
    Failure,
}

impl From<Status> for ExitCode {
    fn from(status: Status) -> ExitCode {
        ExitCode::from(match status {
            Status::Success => 0,
            Status::Differs => 1,
            Status::Failure => 2,
        })
    }
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<Status> {
    match cli.command {
        Command::Build { manifest, out } => build(manifest.as_deref(), &out, cli.quiet),
        Command::Verify { dir, json } => verify(&dir, json),
        Command::Betti {
            image,
            json,
            strict,
        } => betti(&image, json, strict),
        Command::Plan { manifest, json } => {
            let (_, manifest) = load_manifest(manifest.as_deref())?;
            crate::plan::show(&manifest, json)?;
            Ok(Status::Success)
        }
    }
}

pub(crate) fn load_manifest(path: Option<&Path>) -> anyhow::Result<(String, Manifest)> {
    match path {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read manifest {}", path.display()))?;
            let manifest = Manifest::parse(&text, path)?;
            Ok((text, manifest))
        }
        None => {
            let manifest = Manifest::parse(DEMO_MANIFEST, Path::new("<embedded demo manifest>"))?;
            Ok((DEMO_MANIFEST.to_string(), manifest))
        }
    }
}

fn build(manifest: Option<&Path>, out: &Path, quiet: bool) -> anyhow::Result<Status> {
    let (text, manifest) = load_manifest(manifest)?;
    let dataset = Dataset::create(out, &text, manifest)?;
    let started = std::time::Instant::now();
    let summary = dataset.build_in_process(|done, total| {
        if !quiet {
            eprint!("\rshards {done}/{total}");
        }
    })?;
    if !quiet {
        eprintln!(
            "\rbuilt {} shards, skipped {} complete ones; {} samples, {} regenerations, {:.1} s\n{}",
            summary.built,
            summary.skipped,
            summary.samples,
            summary.regenerations,
            started.elapsed().as_secs_f64(),
            out.join("index.json").display()
        );
    }
    Ok(Status::Success)
}

fn verify(dir: &Path, json: bool) -> anyhow::Result<Status> {
    let report = bettimill_shard::verify(dir)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else if report.problems.is_empty() {
        println!(
            "ok: {} shards match {}",
            report.shards_checked,
            dir.join("index.json").display()
        );
    } else {
        for problem in &report.problems {
            println!("{problem}");
        }
        println!("{} problem(s) found", report.problems.len());
    }
    Ok(if report.problems.is_empty() {
        Status::Success
    } else {
        Status::Differs
    })
}

fn betti(path: &Path, json: bool, strict: bool) -> anyhow::Result<Status> {
    let npy = bettimill_grid::npy::read_path(path, strict)
        .with_context(|| format!("cannot use {} as an image", path.display()))?;
    let topology = bettimill_homology::topology(&npy.image);
    if json {
        let value = serde_json::json!({
            "betti": topology.betti,
            "euler": topology.euler,
            "shape": npy.image.shape(),
            "hypervolume": npy.image.count_foreground(),
            "field": "Z/2",
        });
        println!("{value}");
    } else {
        let betti: Vec<String> = topology.betti.iter().map(|b| b.to_string()).collect();
        println!("betti: [{}]  euler: {}", betti.join(", "), topology.euler);
    }
    Ok(Status::Success)
}
