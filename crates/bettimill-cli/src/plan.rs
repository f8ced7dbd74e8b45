//! `bettimill plan`: the strata table, counts per split and shard, size and time estimates.

use bettimill_manifest::Manifest;
use bettimill_plan::memory::{self, WorkerMemory};
use bettimill_plan::Plan;

/// Rough single-core cost of making and verifying one sample, in nanoseconds per voxel, by
/// dimension (2D, 3D, 4D). Measured on the 2-core reference machine (BENCHMARKS.md); an
/// estimate for planning, not a promise.
const NS_PER_VOXEL: [f64; 3] = [400.0, 300.0, 250.0];

/// The share of /proc/meminfo's MemAvailable that the default `--max-memory` hands out.
pub(crate) const DEFAULT_MEMORY_SHARE: f64 = 0.8;

/// The memory one worker may use: `--max-memory` if given, else inside a Slurm job its
/// allocation (`crate::cluster::job_memory_limit`), else
/// [`DEFAULT_MEMORY_SHARE`] of MemAvailable divided among `workers`; `None` when neither
/// is known (no /proc/meminfo: nothing is refused). With the words saying where it came
/// from, for messages.
pub(crate) fn memory_limit(max_memory: Option<u64>, workers: u64) -> Option<(u64, String)> {
    if let Some(limit) = max_memory {
        return Some((
            limit,
            format!("--max-memory {}", memory::human_bytes(limit)),
        ));
    }
    if let Some(job) = crate::cluster::job_memory_limit(workers) {
        return Some(job);
    }
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let available_kib: u64 = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    let workers = workers.max(1);
    let limit = (available_kib as f64 * 1024.0 * DEFAULT_MEMORY_SHARE / workers as f64) as u64;
    Some((
        limit,
        format!(
            "the default: {:.0}% of MemAvailable {}{}; set --max-memory to change it",
            DEFAULT_MEMORY_SHARE * 100.0,
            memory::human_bytes(available_kib * 1024),
            if workers == 1 {
                String::new()
            } else {
                format!(" / {workers} workers")
            }
        ),
    ))
}

/// Refuses `plan` when one worker running `threads` samples at once would need more than
/// the memory limit (see [`memory_limit`]).
pub(crate) fn check_memory(
    plan: &Plan,
    max_memory: Option<u64>,
    workers: u64,
    threads: u64,
) -> anyhow::Result<()> {
    if let Some((limit, origin)) = memory_limit(max_memory, workers) {
        memory::check(plan, threads, limit, &origin)?;
    }
    Ok(())
}

/// Prints the plan of `manifest` (text, or JSON with `json`). A plan whose worker would not
/// fit the memory limit (`max_memory`, or the machine's default for one worker) is printed
/// and then refused.
pub fn show(manifest: &Manifest, json: bool, max_memory: Option<u64>) -> anyhow::Result<()> {
    let plan = Plan::new(manifest)?;
    let worker_memory = WorkerMemory::of(&plan);
    let voxels = (plan.side as f64).powi(plan.dimension.get() as i32);
    let bytes = plan.sample_bytes.saturating_mul(plan.samples);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
    let seconds =
        plan.samples as f64 * voxels * NS_PER_VOXEL[plan.dimension.get() - 2] / 1e9 / cores;
    let totals = plan.total_counts();
    if json {
        let strata: Vec<serde_json::Value> = plan
            .strata
            .iter()
            .zip(&totals)
            .map(|(s, &count)| {
                serde_json::json!({
                    "cls": s.index,
                    "label": s.label,
                    "betti": s.betti,
                    "mode": bettimill_plan::mode_name(s.mode),
                    "components": s.components,
                    "hypervolume": s.hypervolume,
                    "samples": count,
                })
            })
            .collect();
        let value = serde_json::json!({
            "name": plan.name,
            "dimension": plan.dimension.get(),
            "side": plan.side,
            "manifest_hash": plan.manifest_hash,
            "plan_hash": plan.hash(),
            "samples": plan.samples,
            "shard_size": plan.shard_size,
            "splits": plan.splits,
            "strata": strata,
            "infeasible": plan.infeasible,
            "estimated_bytes": bytes,
            "estimated_seconds": seconds,
            "worker_memory_bytes": worker_memory.total(1),
            "sample_memory_bytes": worker_memory.sample_bytes,
        });
        // The shard list is streamed, one shard at a time: a plan of 10^8 shards prints
        // gigabytes but holds one shard in memory.
        let head = serde_json::to_string_pretty(&value)?;
        let head = head
            .strip_suffix("\n}")
            .expect("a pretty-printed JSON object ends with a closing brace on its own line");
        crate::stats::write_stdout(format!("{head},\n  \"shards\": [").as_bytes())?;
        for shard in plan.shards() {
            let entry = serde_json::json!({
                "name": shard.name, "split": shard.split, "first_sample": shard.first_sample,
                "samples": shard.samples, "strata_counts": plan.shard_counts(&shard),
            });
            let comma = if shard.index == 0 { "" } else { "," };
            crate::stats::write_stdout(format!("{comma}\n    {entry}").as_bytes())?;
        }
        outln!("\n  ]\n}}");
        check_memory(&plan, max_memory, 1, 1)?;
        return Ok(());
    }
    outln!(
        "dataset {}: {}D, side {}, {}",
        plan.name,
        plan.dimension,
        plan.side,
        count(plan.samples, "sample")
    );
    outln!("manifest hash {}", plan.manifest_hash);
    outln!("plan hash     {}", plan.hash());
    outln!();
    // Columns as wide as their widest entry, so long stratum names (connected sums with
    // bins) do not push the numbers out of line.
    let betti: Vec<String> = plan
        .strata
        .iter()
        .map(|s| format!("{:?}", s.betti))
        .collect();
    let label_width = plan
        .strata
        .iter()
        .map(|s| s.label.len())
        .max()
        .unwrap_or(0)
        .max(7);
    let betti_width = betti.iter().map(String::len).max().unwrap_or(0).max(5);
    let count_width = totals
        .iter()
        .map(|c| c.to_string().len())
        .max()
        .unwrap_or(0)
        .max(7);
    let cls_width = plan.strata.len().saturating_sub(1).to_string().len().max(3);
    outln!(
        "{:>cls_width$}  {:<label_width$}  {:<betti_width$}  {:>count_width$}",
        "cls",
        "stratum",
        "betti",
        "samples"
    );
    for ((stratum, count), betti) in plan.strata.iter().zip(&totals).zip(&betti) {
        outln!(
            "{:>cls_width$}  {:<label_width$}  {:<betti_width$}  {:>count_width$}",
            stratum.index,
            stratum.label,
            betti,
            count
        );
    }
    if !plan.infeasible.is_empty() {
        outln!(
            "\nleft out ({} that cannot be built; `bettimill build` says so too):",
            count(plan.infeasible.len() as u64, "combination")
        );
        for item in &plan.infeasible {
            outln!("  {}: {}", item.label, item.reason);
        }
    }
    outln!();
    for (split, size) in &plan.splits {
        outln!(
            "split {split}: {} in {} of up to {}",
            count(*size, "sample"),
            count(size.div_ceil(plan.shard_size), "shard"),
            count(plan.shard_size, "sample")
        );
    }
    // Shards are contiguous ranges dealt cyclically, so a shard's spread depends only on
    // its length: the counts of the first and last shard of each split (every length there
    // is) give the spread of all of them without walking 10^8 shards.
    let mut first_shard = 0;
    let mut spread = 0;
    for (_, size) in &plan.splits {
        let shards = size.div_ceil(plan.shard_size);
        for index in [first_shard, first_shard + shards.saturating_sub(1)] {
            if shards > 0 {
                let counts = plan.shard_counts(&plan.shard(index));
                let max = counts.iter().max().unwrap_or(&0);
                spread = spread.max(max - counts.iter().min().unwrap_or(&0));
            }
        }
        first_shard += shards;
    }
    outln!("per-shard balance: stratum counts differ by at most {spread} within any shard");
    outln!(
        "estimated output at most {} uncompressed ({} a sample), build time {} on {}",
        human_bytes(bytes),
        human_bytes(plan.sample_bytes),
        human_duration(seconds),
        count(cores as u64, "core")
    );
    outln!(
        "worker memory: about {} a worker ({} for one sample of {} voxels in flight + {} for the shard being written)",
        memory::human_bytes(worker_memory.total(1)),
        memory::human_bytes(worker_memory.sample_bytes),
        worker_memory.voxels,
        memory::human_bytes(worker_memory.shard_bytes),
    );
    check_memory(&plan, max_memory, 1, 1)?;
    Ok(())
}

/// `1 shard`, `6 shards`.
fn count(n: u64, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// Bytes in binary units: `512 B`, `5.6 MiB`, `3.2 TiB`.
fn human_bytes(bytes: u64) -> String {
    memory::human_bytes(bytes)
}

fn human_duration(seconds: f64) -> String {
    if seconds < 1.0 {
        "under 1 s".to_string()
    } else if seconds < 90.0 {
        format!("about {seconds:.0} s")
    } else if seconds < 5400.0 {
        format!("about {:.0} min", seconds / 60.0)
    } else {
        format!("about {:.1} h", seconds / 3600.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_read_as_a_person_would_write_them() {
        assert_eq!(count(1, "shard"), "1 shard");
        assert_eq!(count(6, "shard"), "6 shards");
        assert_eq!(count(0, "sample"), "0 samples");
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(5_872_025), "5.6 MiB");
        assert_eq!(human_bytes(3 << 40), "3.0 TiB");
        assert_eq!(human_duration(0.2), "under 1 s");
        assert_eq!(human_duration(30.0), "about 30 s");
        assert_eq!(human_duration(600.0), "about 10 min");
        assert_eq!(human_duration(89.5 * 3600.0), "about 89.5 h");
    }
}
