//! Subcommands. Each returns an [`ExitStatus`] or an error that `main` reports with exit code 2.

use crate::printer::Printer;
use bettimill_grid::Dim;
use bettimill_manifest::{Manifest, DEMO_MANIFEST};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};

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
    ///
    /// Example: bettimill build manifests/demo-3d.toml --out s3://my-bucket/demo-3d
    Build {
        /// The manifest (TOML). Without it, the embedded demo manifest is built.
        manifest: Option<PathBuf>,
        /// Output directory: new, empty, or a partial build of the same manifest to resume;
        /// or s3://BUCKET/PREFIX (credentials from the AWS_* variables, see --endpoint).
        #[arg(long)]
        out: PathBuf,
        /// Worker processes (default: the number of cores). An s3:// build makes its
        /// shards in this process, on all cores, and ignores it.
        #[arg(long)]
        workers: Option<usize>,
        /// The S3-compatible server of an s3:// --out (MinIO, R2, Garage, ...), e.g.
        /// http://127.0.0.1:9000 (default: AWS_ENDPOINT_URL, else AWS S3).
        #[arg(long, value_name = "URL")]
        endpoint: Option<String>,
        /// Shards of an s3:// build uploaded at once; local disk holds at most one more.
        #[arg(long, value_name = "N", default_value_t = bettimill_executor::remote::DEFAULT_MAX_UPLOADS, value_parser = clap::builder::TypedValueParser::map(clap::value_parser!(u16).range(1..), usize::from))]
        max_uploads: usize,
        /// Give a shard up after this many failed attempts (worker deaths included).
        #[arg(long, default_value_t = bettimill_executor::coordinator::DEFAULT_MAX_SHARD_FAILURES)]
        max_shard_failures: u32,
        /// Seconds between plain progress lines on stderr when it is not a terminal (a
        /// cluster log, nohup, CI); on a terminal a progress bar is drawn instead.
        #[arg(long, default_value_t = 10.0)]
        progress_interval: f64,
        /// Kill and retry a worker that sends nothing (not even its heartbeat, every second)
        /// for this many seconds: a frozen or stopped worker.
        #[arg(long, default_value_t = bettimill_executor::coordinator::DEFAULT_WORKER_TIMEOUT.as_secs_f64(), value_parser = parse_worker_timeout)]
        worker_timeout: f64,
        /// Memory one worker may use, e.g. 8G (default: 80% of MemAvailable divided by the
        /// workers). A plan whose samples need more is refused before any worker starts.
        #[arg(long, value_name = "SIZE", value_parser = parse_memory)]
        max_memory: Option<u64>,
    },
    /// Internal: a build worker (started by `build`, or as an array task on a cluster).
    #[command(hide = true)]
    Worker(crate::cluster::WorkerArgs),
    /// Write Slurm array and finalize scripts for a dataset (and submit them).
    ///
    /// Example: bettimill slurm manifests/demo-3d.toml --out /shared/demo --tasks 8 --submit
    ///
    /// Example: bettimill slurm manifests/demo-3d.toml --out s3://my-bucket/demo --scripts ~/demo-slurm --tasks 8 --submit
    Slurm(crate::cluster::SlurmArgs),
    /// Print a Kubernetes Indexed Job that builds a dataset.
    ///
    /// Example: bettimill k8s manifests/demo-3d.toml --out /data/demo --tasks 8
    K8s(crate::cluster::KubernetesArgs),
    /// Write index.json once every shard of a dataset is complete.
    ///
    /// Example: bettimill finalize /shared/demo
    Finalize {
        /// The dataset directory, or s3://BUCKET/PREFIX (read with the AWS_* variables).
        dir: PathBuf,
    },
    /// Show which shards of a dataset are complete, missing or invalid.
    ///
    /// Example: bettimill status /shared/demo --json
    Status {
        /// The dataset directory, or s3://BUCKET/PREFIX (read with the AWS_* variables).
        dir: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Rebuild shards from the stored manifest and compare bytes, and/or recompute labels.
    ///
    /// Exit 0 when everything matches, 1 when something differs.
    ///
    /// Example: bettimill audit demo-out --rebuild 0.1 --relabel
    Audit(crate::audit::AuditArgs),
    /// Check every shard and member of a dataset against its index.json.
    ///
    /// Example: bettimill verify demo-out
    Verify {
        /// The dataset directory, or s3://BUCKET/PREFIX (read with the AWS_* variables).
        dir: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Deform a .npy image without changing its topology (moves, dilation, erosion).
    ///
    /// Example: bettimill deform disc.npy --out moved.npy --method moves --steps 600 --seed 1
    Deform(crate::deform::DeformArgs),
    /// Compute the Betti numbers of a binary image stored as .npy.
    ///
    /// The file may be gzip- or zstd-compressed (a dataset's KEY.npy.gz or KEY.npy.zst
    /// members), told by its content; `-` reads standard input.
    ///
    /// Example: bettimill betti image.npy --json
    /// Example: tar -xOf shard-000000.tar s000000.npy.gz | bettimill betti -
    Betti {
        /// A .npy, .npy.gz or .npy.zst file (or - for standard input) of bool or integer
        /// dtype with 2 to 4 axes (non-zero = foreground).
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
        /// Memory one worker may use, e.g. 8G (default: 80% of MemAvailable): a plan whose
        /// worker would need more is printed, then refused (exit 2).
        #[arg(long, value_name = "SIZE", value_parser = parse_memory)]
        max_memory: Option<u64>,
        /// Also build samples of every stratum (or of the first STRATA) here, one worker,
        /// and print their measured CPU time and compressed size extrapolated to the plan,
        /// beside the model's estimate. Nothing is written.
        #[arg(long, value_name = "STRATA", num_args = 0..=1, default_missing_value = "0")]
        pilot: Option<usize>,
        /// Where the dataset will be built (a directory or s3://BUCKET/PREFIX), to refuse
        /// here what `build --out` would refuse there: on s3://, shards that could be larger
        /// than 5 GiB (exit 2). Nothing is written.
        #[arg(long, value_name = "DIR|URL")]
        out: Option<PathBuf>,
    },
    /// Draw a sample, or a contact sheet of several, as a PNG with its label, or open one
    /// sample in a browser viewer.
    ///
    /// Every view is cropped to the object (carve: the cavities) and cut where a hole shows:
    /// the slice (or thin slab) whose own Betti numbers show the most holes is drawn
    /// outlined. 2D images are drawn as they are, 3D images as a projection and slices along
    /// the chosen axis, 4D images as one row per 3D slice; each slice is labelled with its
    /// own Betti numbers.
    ///
    /// --html writes one self-contained HTML file (no server, no network): sliders move
    /// through the 4th and 3rd axes, cavities are highlighted, every slice shows its own
    /// Betti numbers, and a selector switches to the sample's downscaled copies.
    ///
    /// Example: bettimill preview demo-out --n 16 --out sheet.png
    ///
    /// Example: bettimill preview demo-out --key s000006 --html s000006.html
    Preview {
        /// A dataset directory, s3://BUCKET/PREFIX (read by ranges with the AWS_*
        /// variables), one .tar shard, or a .npy image (.npy.gz, .npy.zst, or - for
        /// standard input, as for `betti`).
        input: PathBuf,
        /// The key of the sample to draw (default: the first sample).
        #[arg(long, conflicts_with = "n")]
        key: Option<String>,
        /// Draw a contact sheet of the first N samples instead.
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..=400))]
        n: Option<u32>,
        /// The PNG file to write.
        #[arg(long, value_name = "FILE.png", required_unless_present = "html")]
        out: Option<PathBuf>,
        /// Also (or instead) write the browser viewer of the sample to this HTML file.
        #[arg(long, value_name = "FILE.html", conflicts_with = "n")]
        html: Option<PathBuf>,
        /// Draw each sample's undeformed construction (remade from the dataset's manifest),
        /// to compare with the deformed samples.
        #[arg(long)]
        undeformed: bool,
    },
    /// Count a dataset's samples per Betti vector, class, split and more.
    ///
    /// Also per component count, knot or link type and hypervolume (bins and a histogram),
    /// the regeneration rate of each class, and the build's wall time and samples per second
    /// from the timings its builds recorded (DIR/timings/), never from file times.
    ///
    /// Example: bettimill stats demo-out --plot stats.png
    Stats {
        /// The dataset directory, or s3://BUCKET/PREFIX (read by ranges with the AWS_*
        /// variables).
        dir: PathBuf,
        /// Print the statistics as JSON.
        #[arg(long)]
        json: bool,
        /// Also draw the counts and the hypervolume histogram as a PNG.
        #[arg(long, value_name = "FILE.png")]
        plot: Option<PathBuf>,
    },
    /// Write one object of an s3:// dataset to stdout, read by ranges (for webdataset's
    /// `pipe:` URLs; credentials and server from the AWS_* variables).
    ///
    /// Example: bettimill cat s3://my-bucket/ds/shards/ds-000000.tar | tar -t
    Cat {
        /// The object: s3://BUCKET/PREFIX/NAME.
        url: String,
    },
    /// Print a shell completion script.
    ///
    /// Example: bettimill completions bash > ~/.local/share/bash-completion/completions/bettimill
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
}

/// How a command ended.
pub enum ExitStatus {
    /// Exit 0.
    Success,
    /// Exit 1: a check found differences.
    Differs,
    /// Exit 2: usage error, bad input, or failure.
    Failure,
    /// Exit 130: interrupted by Ctrl-C or SIGTERM (resumable).
    Interrupted,
}

impl ExitStatus {
    /// The process exit code.
    pub fn code(self) -> i32 {
        match self {
            ExitStatus::Success => 0,
            ExitStatus::Differs => 1,
            ExitStatus::Failure => 2,
            ExitStatus::Interrupted => 130,
        }
    }
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<ExitStatus> {
    let printer = Printer::new(cli.quiet);
    match cli.command {
        Command::Build {
            manifest,
            out,
            workers,
            max_shard_failures,
            progress_interval,
            worker_timeout,
            max_memory,
            endpoint,
            max_uploads,
        } => crate::build::build(
            manifest.as_deref(),
            &out,
            workers,
            max_shard_failures,
            progress_interval,
            crate::build::Limits {
                worker_timeout: std::time::Duration::from_secs_f64(worker_timeout),
                max_memory,
                object: bettimill_executor::remote::ObjectOptions {
                    endpoint,
                    max_uploads,
                },
            },
            printer,
        ),
        Command::Worker(args) => crate::cluster::worker(args, printer),
        Command::Slurm(args) => crate::cluster::slurm(args, printer),
        Command::K8s(args) => crate::cluster::kubernetes(args),
        Command::Finalize { dir } => crate::directory::finalize(&dir, printer),
        Command::Status { dir, json } => crate::directory::status(&dir, json),
        Command::Audit(args) => crate::audit::run(&args, printer),
        Command::Verify { dir, json } => verify(&dir, json, printer),
        Command::Deform(args) => crate::deform::run(&args),
        Command::Betti {
            image,
            json,
            strict,
        } => betti(&image, json, strict),
        Command::Plan {
            manifest,
            json,
            max_memory,
            pilot,
            out,
        } => {
            let (_, manifest) = load_manifest(manifest.as_deref())?;
            let pilot = pilot.map(|n| (n > 0).then_some(n));
            let to_bucket = out.as_deref().and_then(object_url).is_some();
            crate::plan::show(&manifest, json, max_memory, pilot, to_bucket)?;
            Ok(ExitStatus::Success)
        }
        Command::Preview {
            input,
            key,
            n,
            out,
            html,
            undeformed,
        } => crate::preview::run(&crate::preview::Request {
            input: &input,
            key: key.as_deref(),
            n: n.map(|n| n as usize),
            out: out.as_deref(),
            html: html.as_deref(),
            undeformed,
            printer,
        }),
        Command::Stats { dir, json, plot } => {
            crate::stats::run(&dir, json, plot.as_deref(), printer)
        }
        Command::Cat { url } => crate::directory::cat(&url),
        Command::Completions { shell } => crate::completions::run(shell),
    }
}

/// `--max-memory`: a size such as `8G`, `512M` or a number of bytes.
pub(crate) fn parse_memory(text: &str) -> Result<u64, String> {
    bettimill_plan::memory::parse_bytes(text).map_err(|err| err.to_string())
}

/// `--worker-timeout`: seconds, at least 3 heartbeat intervals.
fn parse_worker_timeout(text: &str) -> Result<f64, String> {
    let seconds: f64 = text
        .parse()
        .map_err(|_| format!("{text:?} is not a number of seconds"))?;
    let minimum = 3.0 * bettimill_executor::protocol::HEARTBEAT_INTERVAL.as_secs_f64();
    if !(seconds.is_finite() && seconds >= minimum && seconds <= 1e9) {
        return Err(format!(
            "{text} s is too short: workers send a heartbeat every {} s, so the timeout must be at least {minimum} s",
            bettimill_executor::protocol::HEARTBEAT_INTERVAL.as_secs_f64()
        ));
    }
    Ok(seconds)
}

/// Refuses an `--out` that cannot become a dataset directory for a reason the operating
/// system would only report as `File exists`: a symbolic link to nothing.
pub(crate) fn check_out_dir(out: &Path) -> anyhow::Result<()> {
    if let Ok(target) = std::fs::read_link(out) {
        if !out.exists() {
            anyhow::bail!(
                "--out {} is a symbolic link to {}, which does not exist: create that directory, \
                 remove the link, or give another --out",
                out.display(),
                target.display()
            );
        }
    }
    Ok(())
}

pub(crate) fn load_manifest(path: Option<&Path>) -> anyhow::Result<(String, Manifest)> {
    match path {
        Some(path) => {
            let text = bettimill_manifest::read_text(path)?;
            let manifest = Manifest::parse(&text, path)?;
            Ok((text, manifest))
        }
        None => {
            let manifest = Manifest::parse(DEMO_MANIFEST, Path::new("<embedded demo manifest>"))?;
            Ok((DEMO_MANIFEST.to_string(), manifest))
        }
    }
}

/// What `verify` adds to the hashes: the files that are pure functions of the plan and the
/// records (index.json's own bytes, classes.json, the card, the wids indexes) regenerated
/// and compared byte for byte, and manifest.toml against build.json's manifest hash. Cheap:
/// no shard is read. A dataset in a bucket (`s3://...`, reached with `endpoint` or
/// `AWS_ENDPOINT_URL`) is checked from a local copy of its metadata, as `audit` checks it.
/// A dataset that cannot be opened adds nothing here (the hash check has said why).
pub fn plan_file_problems(dir: &Path, endpoint: Option<&str>) -> Vec<bettimill_format::Problem> {
    match object_url(dir) {
        Some(url) => {
            let copy = bettimill_executor::remote::bucket_copy(url, endpoint);
            plan_problems_of(copy.as_ref().map(|copy| &copy.dataset))
        }
        None => plan_problems_of(bettimill_executor::Dataset::open(dir).as_ref()),
    }
}

fn plan_problems_of(
    opened: Result<&bettimill_executor::Dataset, &bettimill_executor::BuildError>,
) -> Vec<bettimill_format::Problem> {
    use bettimill_executor::BuildError;
    use bettimill_format::FormatError;
    let file = |path: &str, reason: String| bettimill_format::Problem::File {
        path: path.into(),
        reason,
    };
    match opened {
        Ok(dataset) => bettimill_audit::check_files(dataset)
            .into_iter()
            .map(|finding| match finding {
                bettimill_audit::Finding::FileDiffers {
                    file: name,
                    field,
                    stored,
                    computed,
                } => file(
                    &name,
                    format!("{field} says {stored}, the build writes {computed}"),
                ),
                other => file(bettimill_format::dir::INDEX_FILE, other.to_string()),
            })
            .collect(),
        Err(BuildError::Format(FormatError::DifferentManifest {
            expected, found, ..
        })) => vec![file(
            bettimill_format::dir::MANIFEST_FILE,
            format!(
                "its canonical hash is {expected}, build.json's manifest_hash is {found}: the manifest was changed after the build"
            ),
        )],
        Err(_) => Vec::new(),
    }
}

/// The `s3://BUCKET/PREFIX` URL a dataset argument names, if it names one.
pub(crate) fn object_url(dir: &Path) -> Option<&str> {
    dir.to_str()
        .filter(|d| bettimill_shard::object::is_object_url(d))
}

fn verify(dir: &Path, json: bool, printer: Printer) -> anyhow::Result<ExitStatus> {
    // The bar appears once the index is read and the number of shards known.
    let mut bar = None;
    let mut progress = |done, total| {
        bar.get_or_insert_with(|| printer.bar(total, "shards", "verifying"))
            .set_position(done);
    };
    let (report, index) = match object_url(dir) {
        Some(url) => {
            let bucket = bettimill_executor::remote::open_bucket(url, None)?;
            let report = bucket.verify(&mut progress);
            (report, format!("{url}/index.json"))
        }
        None => (
            bettimill_format::DatasetDir::new(dir).verify(&mut progress),
            bettimill_format::DatasetDir::new(dir)
                .index_path()
                .display()
                .to_string(),
        ),
    };
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let mut report = report?;
    report.problems.extend(plan_file_problems(dir, None));
    if json {
        outln!("{}", serde_json::to_string_pretty(&report)?);
    } else if report.problems.is_empty() {
        outln!(
            "ok: {} shards and {} other files match {index}",
            report.shards_checked,
            report.files_checked,
        );
    } else {
        for problem in &report.problems {
            outln!("{problem}");
        }
        outln!("{} problem(s) found", report.problems.len());
    }
    Ok(if report.problems.is_empty() {
        ExitStatus::Success
    } else {
        ExitStatus::Differs
    })
}

fn betti(path: &Path, json: bool, strict: bool) -> anyhow::Result<ExitStatus> {
    // The thread pool starts, and the 4D simple-point tables are built, on another thread
    // while the file is read: on a small image they are a noticeable share of the run.
    rayon::spawn(|| drop(bettimill_homology::simple::SimpleTester::new(Dim::Four)));
    // Read into its copy with a background border, as the homology wants it: one copy at
    // the peak, and no second pass to pad it.
    let padded = crate::image::read_image_padded(path, strict, 1)?.image;
    let shape: Vec<usize> = padded.shape().iter().map(|&n| n - 2).collect();
    let hypervolume = padded.count_foreground();
    let topology = bettimill_homology::try_topology_padded(padded)?;
    if json {
        let value = serde_json::json!({
            "betti": topology.betti,
            "euler": topology.euler,
            "shape": shape,
            "hypervolume": hypervolume,
            "field": "Z/2",
        });
        outln!("{value}");
    } else {
        let betti: Vec<String> = topology.betti.iter().map(|b| b.to_string()).collect();
        outln!("betti: [{}]  euler: {}", betti.join(", "), topology.euler);
    }
    Ok(ExitStatus::Success)
}
