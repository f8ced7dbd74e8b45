//! Audits of a built dataset: rebuild shards and compare bytes, or recompute labels.
//!
//! `verify` (in `bettimill-shard`) only proves that the files are the ones the index lists.
//! An audit goes further and checks the index against the manifest:
//!
//! - **rebuild**: regenerate chosen shards from the stored `manifest.toml` in a scratch
//!   directory and compare them byte for byte with the stored ones. Because every shard is a
//!   pure function of (manifest, shard index, tool version), any difference means the
//!   stored shard was not made by this manifest and version (or was altered and re-indexed).
//! - **relabel**: decode every stored array and recompute every label field that the voxels
//!   determine, comparing each with the stored label and naming the field: `betti`,
//!   `euler`, `hypervolume`, `shape`, `dim`, `components` (b0 of the object in embed mode,
//!   b_{d-1} (one cavity each) in carve mode, 1 for a tunnel), `hypervolume_bin` (the plan's
//!   bin of the sample's stratum, which must hold the hypervolume), the `cls` member, and for
//!   each downscaled copy its `side`, `betti`, `euler`, `hypervolume` and `preserved` (its
//!   Betti numbers equal the full image's). The stratum's `class_label`, `mode` and `family`
//!   are compared with the plan, and so are the fields the plan fixes for the sample (`key`,
//!   `field`, `class_index`, `seed`, `manifest_hash`, `tool_version`), the sample's members
//!   (exactly the plan's fields; every planned sample present, in order) and each array's
//!   `.npy` bytes (the writer's header and dtype). Neither derived from the voxels nor fixed
//!   by the plan, so not checked here: `betti_rational`, `knot_type`, `construction`,
//!   `attempt` (a rebuild checks those, byte for byte).
//! - **files** ([`check_files`], before either): the files that are pure functions of the
//!   plan and the records, regenerated and compared byte for byte.
//!
//! The scratch directory lives inside the dataset directory (`DIR/.audit-PID`) so it is on
//! the same file system, and is removed afterwards; nothing else in DIR is written. A
//! dataset in a bucket is audited from a local copy of everything but its shards (the
//! plan, the records, the finished files), its shards read by ranges from the bucket
//! ([`rebuild_from`], [`relabel_from`]); nothing in the bucket is written.

use bettimill_executor::{BuildError, Dataset};
use bettimill_format::{DatasetSource, Label, MemberName};
use bettimill_plan::ShardPlan;
use bettimill_shard::ShardError;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Which shards to rebuild.
#[derive(Clone, Debug, PartialEq)]
pub enum Selection {
    /// A fraction of the shards in (0, 1], chosen by a shuffle seeded from the manifest hash
    /// and `seed`, so an audit can be repeated exactly.
    Fraction {
        /// The fraction of shards to rebuild.
        fraction: f64,
        /// Extra seed to choose another subset.
        seed: u64,
    },
    /// Shards by number or by name (`NAME-000003`).
    Shards(Vec<String>),
}

/// One finding of an audit.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Finding {
    /// A rebuilt shard differs from the stored one.
    RebuildDiffers {
        /// The shard name.
        shard: String,
        /// First differing byte offset (or the shorter length).
        offset: u64,
        /// The stored member containing that offset, if any.
        member: Option<String>,
    },
    /// A rebuilt shard is missing from the directory.
    Missing {
        /// The shard name.
        shard: String,
    },
    /// A stored label disagrees with the voxels.
    LabelDiffers {
        /// The shard name.
        shard: String,
        /// The sample key (with `@rSIDE` for a downscaled copy).
        key: String,
        /// What the label says.
        stored: Vec<u64>,
        /// What the voxels say.
        computed: Vec<u64>,
    },
    /// A label field other than the Betti numbers disagrees with the voxels (or with the
    /// plan's stratum, for the fields the stratum fixes).
    FieldDiffers {
        /// The shard name.
        shard: String,
        /// The sample key (with `@rSIDE` for a downscaled copy).
        key: String,
        /// The label field, as written in `KEY.json` (`euler`, `resolutions[r10].preserved`).
        field: String,
        /// What the label says (JSON).
        stored: String,
        /// What the voxels (or the plan) say (JSON).
        computed: String,
    },
    /// A sample the plan puts in the shard is not in it.
    SampleMissing {
        /// The shard name.
        shard: String,
        /// The sample key the plan gives.
        key: String,
    },
    /// A sample (or member) in the shard that the plan does not put there.
    Unexpected {
        /// The shard name.
        shard: String,
        /// The member name.
        member: String,
    },
    /// A file that is a pure function of the plan (and of the completion records) differs
    /// from what the build writes.
    FileDiffers {
        /// The file, relative to the dataset directory.
        file: String,
        /// Where it first differs: a JSON path (`classes[3].topology_class`), a line
        /// (`line 12`) or a field of build.json.
        field: String,
        /// What the file says.
        stored: String,
        /// What the build writes.
        computed: String,
    },
    /// A member could not be decoded.
    Undecodable {
        /// The shard name.
        shard: String,
        /// The member.
        member: String,
        /// Why.
        reason: String,
    },
}

impl std::fmt::Display for Finding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Finding::RebuildDiffers {
                shard,
                offset,
                member,
            } => write!(
                f,
                "{shard}: rebuilt shard differs from the stored one at byte {offset}{}",
                member
                    .as_ref()
                    .map(|m| format!(" (member {m})"))
                    .unwrap_or_default()
            ),
            Finding::Missing { shard } => write!(f, "{shard}: missing from the dataset"),
            Finding::LabelDiffers {
                shard,
                key,
                stored,
                computed,
            } => write!(
                f,
                "{shard}: {key}: label says betti {stored:?}, the voxels give {computed:?}"
            ),
            Finding::FieldDiffers {
                shard,
                key,
                field,
                stored,
                computed,
            } => write!(
                f,
                "{shard}: {key}: label field `{field}` says {stored}, the voxels give {computed}"
            ),
            Finding::SampleMissing { shard, key } => write!(
                f,
                "{shard}: sample {key} of the plan is missing from the shard"
            ),
            Finding::Unexpected { shard, member } => write!(
                f,
                "{shard}: {member}: the plan puts no such sample or member in this shard"
            ),
            Finding::FileDiffers {
                file,
                field,
                stored,
                computed,
            } => write!(
                f,
                "{file}: {field} says {stored}, the build writes {computed}"
            ),
            Finding::Undecodable {
                shard,
                member,
                reason,
            } => write!(f, "{shard}: {member}: cannot decode: {reason}"),
        }
    }
}

/// The result of an audit.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct AuditReport {
    /// Shards rebuilt and compared.
    pub rebuilt: Vec<String>,
    /// Samples whose labels were recomputed.
    pub relabelled_samples: u64,
    /// Everything that differed.
    pub findings: Vec<Finding>,
}

/// Why an audit could not run.
#[derive(Debug, thiserror::Error)]
pub enum AuditError {
    /// The dataset could not be opened or a shard not rebuilt.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// Storage failed.
    #[error(transparent)]
    Shard(#[from] ShardError),
    /// A shard named on the command line does not exist in the plan.
    #[error("no shard {0:?} in this dataset's plan (give a number or a name like NAME-000003)")]
    UnknownShard(String),
    /// The fraction is not in (0, 1].
    #[error("--rebuild takes a fraction in (0, 1], not {0}")]
    BadFraction(f64),
    /// Scratch space could not be made or removed.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The reason.
        source: std::io::Error,
    },
}

/// Chooses the shards of `dataset` named by `selection`.
pub fn select(dataset: &Dataset, selection: &Selection) -> Result<Vec<ShardPlan>, AuditError> {
    let plan = &dataset.plan;
    let shard_count = plan.shard_count();
    match selection {
        Selection::Fraction { fraction, seed } => {
            if !(*fraction > 0.0 && *fraction <= 1.0) {
                return Err(AuditError::BadFraction(*fraction));
            }
            let count = ((shard_count as f64) * fraction).ceil() as usize;
            let mut order: Vec<u64> = (0..shard_count).collect();
            let mut rng = rand_chacha::ChaCha8Rng::from_seed(bettimill_plan::derive_seed(
                "bettimill audit selection v1",
                &[dataset.plan.manifest_hash.as_bytes(), &seed.to_le_bytes()],
            ));
            order.shuffle(&mut rng);
            let mut chosen: Vec<u64> = order.into_iter().take(count.max(1)).collect();
            chosen.sort_unstable();
            Ok(chosen.into_iter().map(|i| plan.shard(i)).collect())
        }
        Selection::Shards(names) => names
            .iter()
            .map(|name| {
                plan.shard_named(name.trim_end_matches(".tar"))
                    .or_else(|| {
                        name.parse::<u64>()
                            .ok()
                            .filter(|&i| i < shard_count)
                            .map(|i| plan.shard(i))
                    })
                    .ok_or_else(|| AuditError::UnknownShard(name.clone()))
            })
            .collect(),
    }
}

/// Every file of a finalized dataset that is a pure function of the plan and the
/// completion records (`classes.json`, the card `README.md`, the `shardindex-*.json` files
/// and `index.json`, whose shard entries and sample counts must also be the plan's),
/// regenerated and compared byte for byte, without reading a shard. A file that differs is
/// named with where it first differs (a JSON path such as `classes[2].topology_class`, or a
/// line of the card): an edit whose hashes were rewritten as an attacker would is found
/// here. Nothing for a directory that is not finalized.
pub fn check_files(dataset: &Dataset) -> Vec<Finding> {
    if !dataset.layout().is_finalized() {
        return Vec::new();
    }
    let relative = |path: &Path| {
        path.strip_prefix(&dataset.dir)
            .unwrap_or(path)
            .display()
            .to_string()
    };
    let unusable = |err: BuildError| {
        let (file, reason) = match err {
            BuildError::Corrupt { path, reason } => (relative(&path), reason),
            other => (
                bettimill_format::dir::INDEX_FILE.to_string(),
                other.to_string(),
            ),
        };
        vec![Finding::FileDiffers {
            file,
            field: "(record)".into(),
            stored: reason,
            computed: "a record of the plan's shard".into(),
        }]
    };
    let differing = match dataset.finalized_differences() {
        Ok(differing) if differing.is_empty() => return Vec::new(),
        Ok(differing) => differing,
        Err(err) => return unusable(err),
    };
    let written = match dataset.finalized_bytes() {
        Ok(written) => written,
        Err(err) => return unusable(err),
    };
    let mut findings = Vec::new();
    for path in differing {
        let Some((_, computed)) = written.iter().find(|(p, _)| *p == path) else {
            continue;
        };
        // Read no further than the file the build would write, and a little more.
        let limit = computed.len() as u64 + 4096;
        let mut stored = Vec::new();
        let read = std::fs::File::open(&path).and_then(|file| {
            std::io::Read::read_to_end(&mut std::io::Read::take(file, limit), &mut stored)
        });
        let (field, was, is) = match read {
            Err(err) => ("(file)".to_string(), err.to_string(), "a file".to_string()),
            Ok(_) => bettimill_format::diff::first_difference_in(&path, &stored, computed),
        };
        findings.push(Finding::FileDiffers {
            file: relative(&path),
            field,
            stored: was,
            computed: is,
        });
    }
    findings
}

/// Rebuilds `shards` of the dataset in `dir` and compares them byte for byte.
pub fn rebuild(dir: &Path, shards: &[ShardPlan]) -> Result<AuditReport, AuditError> {
    rebuild_with_progress(dir, shards, &|| {})
}

/// [`rebuild`], calling `progress` once per sample rebuilt (from the threads that make
/// the samples).
pub fn rebuild_with_progress(
    dir: &Path,
    shards: &[ShardPlan],
    progress: &(dyn Fn() + Sync),
) -> Result<AuditReport, AuditError> {
    let (stored, source) = open_local(dir)?;
    rebuild_from(&stored, &source, shards, progress)
}

/// A local dataset directory whose index is checked first, and the same directory as the
/// source its shards are read from.
fn open_local(dir: &Path) -> Result<(Dataset, DatasetSource), AuditError> {
    let local = bettimill_format::DatasetDir::new(dir);
    local.check_index().map_err(BuildError::from)?;
    Ok((Dataset::open(dir)?, DatasetSource::Dir(local)))
}

/// [`rebuild_with_progress`] of the shards of `source` (a directory or a bucket), whose
/// plan and records `stored` holds (the directory itself, or a copy of a bucket's
/// metadata, [`bettimill_format::bucket::BucketDir::copy_metadata`]). The scratch
/// directory is made inside `stored`'s directory.
pub fn rebuild_from(
    stored: &Dataset,
    source: &DatasetSource,
    shards: &[ShardPlan],
    progress: &(dyn Fn() + Sync),
) -> Result<AuditReport, AuditError> {
    let scratch = stored.dir.join(format!(".audit-{}", std::process::id()));
    let io = |source| AuditError::Io {
        path: scratch.clone(),
        source,
    };
    if scratch.exists() {
        std::fs::remove_dir_all(&scratch).map_err(io)?;
    }
    let result = (|| {
        let fresh = Dataset::bind(&scratch, &stored.manifest_text, stored.manifest.clone())?;
        let mut report = AuditReport::default();
        for shard in shards {
            fresh.write_shard_with_progress(shard, &|_| progress())?;
            report.rebuilt.push(shard.name.clone());
            let original = match source.tar_reader(&shard.name) {
                Ok(reader) => reader,
                Err(_) => {
                    report.findings.push(Finding::Missing {
                        shard: shard.name.clone(),
                    });
                    continue;
                }
            };
            let rebuilt_path = fresh.tar_path(shard);
            let rebuilt = std::fs::File::open(&rebuilt_path).map_err(|source| AuditError::Io {
                path: rebuilt_path.clone(),
                source,
            })?;
            let rebuilt_len = rebuilt
                .metadata()
                .map_err(|source| AuditError::Io {
                    path: rebuilt_path.clone(),
                    source,
                })?
                .len();
            // Streamed through fixed buffers (a bucket's tar by ranges); the stored tar is
            // read no further than one byte past the rebuilt length (a shard inflated to
            // gigabytes, or a link to /dev/zero, differs there at the latest).
            let stored_path = source.tar_location(&shard.name);
            let difference =
                first_difference(std::io::Read::take(original, rebuilt_len + 1), rebuilt).map_err(
                    |source| AuditError::Io {
                        path: stored_path,
                        source,
                    },
                )?;
            if let Some(offset) = difference {
                let member = fresh
                    .layout()
                    .read_record(&shard.name)
                    .ok()
                    .flatten()
                    .and_then(|record| {
                        record
                            .shard
                            .members
                            .iter()
                            .find(|m| {
                                let start = m.offset - 512;
                                let end = m.offset + m.bytes.div_ceil(512) * 512;
                                (start..end).contains(&offset)
                            })
                            .map(|m| m.name.clone())
                    });
                report.findings.push(Finding::RebuildDiffers {
                    shard: shard.name.clone(),
                    offset,
                    member,
                });
            }
        }
        Ok(report)
    })();
    std::fs::remove_dir_all(&scratch).map_err(io)?;
    result
}

/// The offset of the first byte where two streams differ (or where the shorter ends).
fn first_difference(a: impl std::io::Read, b: impl std::io::Read) -> std::io::Result<Option<u64>> {
    let mut a = std::io::BufReader::with_capacity(1 << 16, a);
    let mut b = std::io::BufReader::with_capacity(1 << 16, b);
    let mut offset = 0u64;
    loop {
        let (x, y) = (
            std::io::BufRead::fill_buf(&mut a)?,
            std::io::BufRead::fill_buf(&mut b)?,
        );
        if x.is_empty() || y.is_empty() {
            return Ok((x.len() != y.len()).then_some(offset));
        }
        let n = x.len().min(y.len());
        if let Some(i) = x[..n].iter().zip(&y[..n]).position(|(p, q)| p != q) {
            return Ok(Some(offset + i as u64));
        }
        std::io::BufRead::consume(&mut a, n);
        std::io::BufRead::consume(&mut b, n);
        offset += n as u64;
    }
}

/// Recomputes the Betti numbers of every sample (and downscaled copy) in `shards` from the
/// stored arrays and compares them with the stored labels.
pub fn relabel(dir: &Path, shards: &[ShardPlan]) -> Result<AuditReport, AuditError> {
    relabel_with_progress(dir, shards, &|| {})
}

/// [`relabel`], calling `progress` once per sample as its check starts (from several
/// threads).
pub fn relabel_with_progress(
    dir: &Path,
    shards: &[ShardPlan],
    progress: &(dyn Fn() + Sync),
) -> Result<AuditReport, AuditError> {
    let (dataset, source) = open_local(dir)?;
    relabel_from(&dataset, &source, shards, progress)
}

/// [`relabel_with_progress`] of the shards of `source` (a directory or a bucket, read by
/// ranges), against the plan of `dataset` (see [`rebuild_from`]).
pub fn relabel_from(
    dataset: &Dataset,
    source: &DatasetSource,
    shards: &[ShardPlan],
    progress: &(dyn Fn() + Sync),
) -> Result<AuditReport, AuditError> {
    let per_shard: Vec<(u64, Vec<Finding>)> = shards
        .par_iter()
        .map(|shard| relabel_shard(dataset, source, shard, progress))
        .collect::<Result<_, _>>()?;
    let mut report = AuditReport::default();
    for (samples, findings) in per_shard {
        report.relabelled_samples += samples;
        report.findings.extend(findings);
    }
    Ok(report)
}

/// A sample's fields (`json`, `npy`, ...) with their bytes, in tar order.
type Fields = Vec<(String, Vec<u8>)>;

fn relabel_shard(
    dataset: &Dataset,
    source: &DatasetSource,
    shard: &ShardPlan,
    progress: &(dyn Fn() + Sync),
) -> Result<(u64, Vec<Finding>), AuditError> {
    let mut findings = Vec::new();
    let undecodable = |member: &str, reason: String| Finding::Undecodable {
        shard: shard.name.clone(),
        member: member.to_string(),
        reason,
    };
    // Checked against its record before reading, then read one member at a time: a shard
    // inflated to gigabytes or replaced by a link to a device is a finding, not a read.
    let mut stream = match source.open_tar(
        &shard.name,
        bettimill_shard::ustar::DEFAULT_MAX_MEMBER_BYTES,
    ) {
        Ok(stream) => stream,
        Err(bettimill_format::FormatError::Io { source, .. })
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            return Ok((
                0,
                vec![Finding::Missing {
                    shard: shard.name.clone(),
                }],
            ));
        }
        Err(err) => return Ok((0, vec![undecodable("(tar)", err.to_string())])),
    };
    // Members grouped by key in tar order; a sample is checked once its last member is
    // read, so one sample's members are held at a time. The samples must be the plan's,
    // in the plan's order: one missing or added is a finding.
    let tasks = dataset.plan.shard_tasks(shard);
    let mut next_task = 0usize;
    let mut samples = 0u64;
    let mut current: Option<(String, Fields)> = None;
    let mut finish = |sample: Option<(String, Fields)>, findings: &mut Vec<Finding>| {
        if let Some((key, fields)) = sample {
            progress();
            samples += 1;
            let Some(found) = tasks[next_task..].iter().position(|t| t.key == key) else {
                findings.push(Finding::Unexpected {
                    shard: shard.name.clone(),
                    member: key,
                });
                return;
            };
            for skipped in &tasks[next_task..next_task + found] {
                findings.push(Finding::SampleMissing {
                    shard: shard.name.clone(),
                    key: skipped.key.clone(),
                });
            }
            let task = &tasks[next_task + found];
            next_task += found + 1;
            findings.extend(relabel_sample(dataset, &shard.name, task, &fields));
        }
    };
    loop {
        let (name, data) = match stream.next_entry() {
            Ok(Some((name, _, data))) => (name, data),
            Ok(None) => break,
            Err(err) => {
                findings.push(undecodable("(tar)", err.to_string()));
                break;
            }
        };
        let Some(parsed) = MemberName::parse(name) else {
            findings.push(undecodable(name, "no field".into()));
            continue;
        };
        let key = parsed.key;
        if current.as_ref().map(|s| s.0.as_str()) != Some(key) {
            finish(current.take(), &mut findings);
            current = Some((key.to_string(), Vec::new()));
        }
        let field = name[key.len() + 1..].to_string();
        let last = current.as_mut().expect("just set");
        last.1.push((field, data.to_vec()));
    }
    finish(current.take(), &mut findings);
    for task in &tasks[next_task..] {
        findings.push(Finding::SampleMissing {
            shard: shard.name.clone(),
            key: task.key.clone(),
        });
    }
    Ok((samples, findings))
}

/// Why a stored array cannot be decoded.
#[derive(Debug, thiserror::Error)]
enum ArrayError {
    #[error(transparent)]
    Decompress(#[from] ShardError),
    #[error("voxel {index} has value {value}; a dataset array holds only 0 and 1")]
    NotBinary { index: usize, value: i128 },
    #[error(transparent)]
    Npy(bettimill_grid::npy::NpyError),
}

/// Decodes one array member (`KEY.npy`, `KEY.r10.npy.gz`, ...) into an image, and says
/// whether its `.npy` bytes are exactly the ones the build writes for that image (uint8,
/// C order, the writer's header): another dtype or header holding the same values is a
/// finding, not an equivalent.
fn decode_array(
    data: &[u8],
    parsed: &MemberName,
) -> Result<(bettimill_grid::BinaryImage, Option<String>), ArrayError> {
    let limit = 1 << 34;
    let raw = bettimill_shard::decompress(data, parsed.compression, limit)?;
    // Stored arrays are 0/1 by construction; a value other than 0 or 1 is damage.
    bettimill_grid::npy::read_bytes(&raw, true)
        .map(|npy| {
            let written =
                bettimill_grid::npy::write_bytes(&npy.image, bettimill_grid::npy::Dtype::U8);
            // The header's dictionary (after magic, version and length), as text.
            let header = |bytes: &[u8]| -> String {
                let rest = bytes.get(10..).unwrap_or_default();
                let line = rest.split(|&b| b == b'\n').next().unwrap_or_default();
                String::from_utf8_lossy(&line[..line.len().min(200)])
                    .trim()
                    .to_string()
            };
            let differs = (written != raw)
                .then(|| format!("{} (the build writes {})", header(&raw), header(&written)));
            (npy.image, differs)
        })
        .map_err(|err| match err {
            bettimill_grid::npy::NpyError::NotBinary { index, value } => {
                ArrayError::NotBinary { index, value }
            }
            other => ArrayError::Npy(other),
        })
}

/// The findings of one sample, as they are made.
struct SampleFindings<'a> {
    shard: &'a str,
    findings: Vec<Finding>,
}

impl SampleFindings<'_> {
    /// Records a [`Finding::FieldDiffers`] when `stored` and `computed` differ as JSON.
    fn compare(
        &mut self,
        key: &str,
        field: &str,
        stored: impl Serialize,
        computed: impl Serialize,
    ) {
        let (stored, computed) = (to_json(&stored), to_json(&computed));
        if stored != computed {
            self.findings.push(Finding::FieldDiffers {
                shard: self.shard.to_string(),
                key: key.to_string(),
                field: field.to_string(),
                stored,
                computed,
            });
        }
    }

    fn undecodable(&mut self, member: &str, reason: String) {
        self.findings.push(Finding::Undecodable {
            shard: self.shard.to_string(),
            member: member.to_string(),
            reason,
        });
    }

    fn betti(&mut self, key: &str, stored: &[u64], computed: &[u64]) {
        if stored != computed {
            self.findings.push(Finding::LabelDiffers {
                shard: self.shard.to_string(),
                key: key.to_string(),
                stored: stored.to_vec(),
                computed: computed.to_vec(),
            });
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn to_json(value: &impl Serialize) -> String {
    serde_json::to_string(value).unwrap_or_else(|err| format!("(unserialisable: {err})"))
}

/// Every finding of one sample: each label field recomputed from its arrays (and the plan's
/// stratum) and compared.
fn relabel_sample(
    dataset: &Dataset,
    shard: &str,
    task: &bettimill_plan::SampleTask,
    fields: &Fields,
) -> Vec<Finding> {
    let key = task.key.as_str();
    let mut out = SampleFindings {
        shard,
        findings: Vec::new(),
    };
    let plan = &dataset.plan;
    // The members are exactly the plan's fields: cls, json, the image and one copy per
    // resolution (any compression suffix).
    let mut expected: Vec<String> = [
        bettimill_format::member::CLASS_FIELD,
        bettimill_format::member::LABEL_FIELD,
        bettimill_format::member::IMAGE_FIELD,
    ]
    .iter()
    .map(|f| f.to_string())
    .chain(plan.resolutions.iter().map(|r| format!("r{r}.npy")))
    .collect();
    for (field, _) in fields {
        let bare = bettimill_shard::Compression::split_suffix(field).0;
        match expected.iter().position(|e| e == bare) {
            Some(i) => {
                expected.remove(i);
            }
            None => out.findings.push(Finding::Unexpected {
                shard: shard.to_string(),
                member: format!("{key}.{field}"),
            }),
        }
    }
    for missing in expected {
        out.undecodable(&format!("{key}.{missing}"), "the member is missing".into());
    }
    let Some((_, json)) = fields
        .iter()
        .find(|f| f.0 == bettimill_format::member::LABEL_FIELD)
    else {
        out.undecodable(key, "no json label".into());
        return out.findings;
    };
    let label = match Label::from_json(json) {
        Ok(label) => label,
        Err(err) => {
            out.undecodable(&format!("{key}.json"), err.to_string());
            return out.findings;
        }
    };
    // Fields the plan fixes for this sample: its key, stratum and seed, the manifest and
    // the version (a label moved from another sample, or a manifest.toml changed after the
    // build and its hashes rewritten, differs here).
    out.compare(key, "key", &label.key, key);
    out.compare(key, "field", &label.field, "Z/2");
    out.compare(key, "class_index", label.stratum, task.stratum);
    out.compare(key, "seed", &label.seed, hex(&task.seed));
    out.compare(
        key,
        "manifest_hash",
        &label.manifest_hash,
        &plan.manifest_hash,
    );
    out.compare(
        key,
        "tool_version",
        &label.tool_version,
        bettimill_format::TOOL_VERSION,
    );
    // Fields the plan's stratum fixes.
    match plan.strata.get(label.stratum) {
        None => out.compare(
            key,
            "class_index",
            label.stratum,
            format!("a stratum below {}", plan.strata.len()),
        ),
        Some(stratum) => {
            out.compare(key, "class_label", &label.class_label, &stratum.label);
            out.compare(
                key,
                "mode",
                &label.mode,
                bettimill_plan::mode_name(stratum.mode),
            );
            out.compare(key, "family", &label.family, stratum.family.label());
            out.compare(
                key,
                "hypervolume_bin",
                label.hypervolume_bin,
                stratum.hypervolume,
            );
        }
    }
    if let Some((_, cls)) = fields.iter().find(|f| f.0 == "cls") {
        out.compare(
            &format!("{key}.cls"),
            "cls",
            String::from_utf8_lossy(cls),
            label.stratum.to_string(),
        );
    }
    // The full image first: the copies' `preserved` compares with its Betti numbers.
    let mut arrays: Vec<(String, &Vec<u8>)> = fields
        .iter()
        .map(|(field, data)| (format!("{key}.{field}"), data))
        .filter(|(member, _)| MemberName::parse(member).is_some_and(|m| m.is_array()))
        .collect();
    arrays.sort_by_key(|(member, _)| !MemberName::parse(member).is_some_and(|m| m.is_image()));
    let mut full: Option<Vec<u64>> = None;
    let mut copies_seen = Vec::new();
    for (member, data) in &arrays {
        let parsed = MemberName::parse(member).expect("filtered above");
        let image = match decode_array(data, &parsed) {
            Ok((image, header)) => {
                if let Some(header) = header {
                    out.undecodable(member, format!(".npy header {header}"));
                }
                image
            }
            Err(reason) => {
                out.undecodable(member, reason.to_string());
                continue;
            }
        };
        let topology = match bettimill_homology::try_topology(&image) {
            Ok(topology) => topology,
            Err(error) => {
                out.undecodable(member, error.to_string());
                continue;
            }
        };
        let hypervolume = image.count_foreground();
        if parsed.is_image() {
            let d = image.dim().get();
            out.betti(key, &label.betti, &topology.betti);
            out.compare(key, "euler", label.euler, topology.euler);
            out.compare(key, "hypervolume", label.hypervolume, hypervolume);
            out.compare(key, "shape", &label.shape, image.shape());
            out.compare(key, "dim", label.dim, d);
            // One object is b0 of its voxels in embed mode, one cavity is a (d-1)-cycle in
            // carve mode (Alexander duality); a tunnel is one object however it is counted.
            let components = if label.family == "tunnel" {
                1
            } else if label.mode == "carve" {
                topology.betti[d - 1]
            } else {
                topology.betti[0]
            };
            out.compare(key, "components", label.components, components);
            if let Some((lo, hi)) = label.hypervolume_bin {
                if !(lo..=hi).contains(&hypervolume) {
                    out.compare(
                        key,
                        "hypervolume_bin",
                        label.hypervolume_bin,
                        format!("a bin holding the hypervolume {hypervolume}"),
                    );
                }
            }
            full = Some(topology.betti);
            continue;
        }
        let side = image.shape()[0] as u32;
        let copy_key = format!("{key}@{}", parsed.field.trim_end_matches(".npy"));
        copies_seen.push(side);
        let Some((position, stored)) = label
            .resolutions
            .iter()
            .enumerate()
            .find(|(_, r)| r.side == side)
        else {
            out.compare(
                &copy_key,
                "resolutions",
                "no entry",
                format!("a copy of side {side}"),
            );
            continue;
        };
        let at = |name: &str| format!("resolutions[{position}].{name}");
        out.betti(&copy_key, &stored.betti, &topology.betti);
        out.compare(&copy_key, &at("euler"), stored.euler, topology.euler);
        out.compare(
            &copy_key,
            &at("hypervolume"),
            stored.hypervolume,
            hypervolume,
        );
        if let Some(full) = &full {
            out.compare(
                &copy_key,
                &at("preserved"),
                stored.preserved,
                topology.betti == *full,
            );
        }
    }
    for (position, stored) in label.resolutions.iter().enumerate() {
        if !copies_seen.contains(&stored.side) {
            out.compare(
                key,
                &format!("resolutions[{position}].side"),
                stored.side,
                "no stored copy of that side",
            );
        }
    }
    out.findings
}

#[cfg(test)]
mod tests;
