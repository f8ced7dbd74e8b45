//! Audits of a built dataset: rebuild shards and compare bytes, or recompute labels.
//!
//! `verify` (in `bettimill-shard`) only proves that the files are the ones the index lists.
//! An audit goes further and checks the index against the manifest:
//!
//! - **rebuild**: regenerate chosen shards from the stored `manifest.toml` in a scratch
//!   directory and compare them byte for byte with the stored ones. Because every shard is a
//!   pure function of (manifest, shard index, tool version), any difference means the
//!   stored shard was not made by this manifest and version (or was altered and re-indexed).
//! - **relabel**: decode every stored array and recompute its Betti numbers and Euler
//!   characteristic (and those of its downscaled copies), comparing them with the stored
//!   label.
//!
//! The scratch directory lives inside the dataset directory (`DIR/.audit-PID`) so it is on
//! the same file system, and is removed afterwards; nothing else in DIR is written.

use bettimill_executor::{BuildError, Dataset};
use bettimill_format::{Label, MemberName};
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
    bettimill_format::DatasetDir::new(dir)
        .check_index()
        .map_err(BuildError::from)?;
    let stored = Dataset::open(dir)?;
    let scratch = dir.join(format!(".audit-{}", std::process::id()));
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
            let rebuilt =
                std::fs::read(fresh.tar_path(shard)).map_err(|source| AuditError::Io {
                    path: fresh.tar_path(shard),
                    source,
                })?;
            report.rebuilt.push(shard.name.clone());
            let Ok(original) = std::fs::read(stored.tar_path(shard)) else {
                report.findings.push(Finding::Missing {
                    shard: shard.name.clone(),
                });
                continue;
            };
            if let Some(offset) = first_difference(&original, &rebuilt) {
                let member = bettimill_shard::tar_entries(&rebuilt, u64::MAX)
                    .ok()
                    .and_then(|entries| {
                        entries
                            .iter()
                            .find(|e| {
                                let start = e.header_offset;
                                let end = start + 512 + (e.data.len() as u64).div_ceil(512) * 512;
                                (start..end).contains(&offset)
                            })
                            .map(|e| e.name.to_string())
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

fn first_difference(a: &[u8], b: &[u8]) -> Option<u64> {
    match a.iter().zip(b).position(|(x, y)| x != y) {
        Some(i) => Some(i as u64),
        None if a.len() != b.len() => Some(a.len().min(b.len()) as u64),
        None => None,
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
    bettimill_format::DatasetDir::new(dir)
        .check_index()
        .map_err(BuildError::from)?;
    let dataset = Dataset::open(dir)?;
    let per_shard: Vec<(u64, Vec<Finding>)> = shards
        .par_iter()
        .map(|shard| relabel_shard(&dataset, shard, progress))
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
    shard: &ShardPlan,
    progress: &(dyn Fn() + Sync),
) -> Result<(u64, Vec<Finding>), AuditError> {
    let path = dataset.tar_path(shard);
    let mut findings = Vec::new();
    let Ok(bytes) = std::fs::read(&path) else {
        return Ok((
            0,
            vec![Finding::Missing {
                shard: shard.name.clone(),
            }],
        ));
    };
    let undecodable = |member: &str, reason: String| Finding::Undecodable {
        shard: shard.name.clone(),
        member: member.to_string(),
        reason,
    };
    let members = match bettimill_shard::read_tar(&bytes) {
        Ok(m) => m,
        Err(err) => return Ok((0, vec![undecodable("(tar)", err.to_string())])),
    };
    // Group members by key, keeping the tar order.
    let mut samples: Vec<(String, Fields)> = Vec::new();
    for member in members {
        let Some(parsed) = MemberName::parse(&member.name) else {
            findings.push(undecodable(&member.name, "no field".into()));
            continue;
        };
        let key = parsed.key;
        if samples.last().map(|s| s.0.as_str()) != Some(key) {
            samples.push((key.to_string(), Vec::new()));
        }
        let field = member.name[key.len() + 1..].to_string();
        let last = samples.last_mut().expect("just pushed");
        last.1.push((field, member.data));
    }
    let limit = 1 << 34;
    for (key, fields) in &samples {
        progress();
        let Some((_, json)) = fields
            .iter()
            .find(|f| f.0 == bettimill_format::member::LABEL_FIELD)
        else {
            findings.push(undecodable(key, "no json label".into()));
            continue;
        };
        let label = match Label::from_json(json) {
            Ok(label) => label,
            Err(err) => {
                findings.push(undecodable(&format!("{key}.json"), err.to_string()));
                continue;
            }
        };
        for (field, data) in fields {
            let member = format!("{key}.{field}");
            let parsed = MemberName::parse(&member).expect("grouped members have a field");
            if !parsed.is_array() {
                continue;
            }
            let raw = match bettimill_shard::decompress(data, parsed.compression, limit) {
                Ok(raw) => raw,
                Err(err) => {
                    findings.push(undecodable(&member, err.to_string()));
                    continue;
                }
            };
            let image = match bettimill_grid::npy::read_bytes(&raw, true) {
                Ok(npy) => npy.image,
                Err(err) => {
                    findings.push(undecodable(&member, err.to_string()));
                    continue;
                }
            };
            let side = (!parsed.is_image()).then(|| image.shape()[0] as u32);
            let stored: Vec<u64> = label
                .betti_at(side)
                .map(<[u64]>::to_vec)
                .unwrap_or_default();
            let computed = bettimill_homology::topology(&image).betti;
            if stored != computed {
                findings.push(Finding::LabelDiffers {
                    shard: shard.name.clone(),
                    key: if parsed.is_image() {
                        key.clone()
                    } else {
                        format!("{key}@{}", parsed.field.trim_end_matches(".npy"))
                    },
                    stored,
                    computed,
                });
            }
        }
    }
    Ok((samples.len() as u64, findings))
}

#[cfg(test)]
mod tests;
