//! `bettimill plan`: the strata table, counts per split and shard, size and time estimates.

use bettimill_manifest::Manifest;
use bettimill_plan::Plan;

/// Rough single-core cost of making and verifying one sample, in nanoseconds per voxel, by
/// dimension (2D, 3D, 4D). Measured on the 2-core reference machine (BENCHMARKS.md); an
/// estimate for planning, not a promise.
const NS_PER_VOXEL: [f64; 3] = [400.0, 300.0, 250.0];

/// Prints the plan of `manifest` (text, or JSON with `json`).
pub fn show(manifest: &Manifest, json: bool) -> anyhow::Result<()> {
    let plan = Plan::new(manifest)?;
    let voxels = (plan.side as f64).powi(plan.dimension.get() as i32);
    let bytes = plan.sample_bytes * plan.samples;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
    let seconds =
        plan.samples as f64 * voxels * NS_PER_VOXEL[plan.dimension.get() - 2] / 1e9 / cores;
    let totals = plan.total_counts();
    let per_shard: Vec<Vec<u64>> = plan.shards().map(|s| plan.shard_counts(&s)).collect();
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
        let shards: Vec<serde_json::Value> = plan
            .shards()
            .zip(&per_shard)
            .map(|(s, counts)| {
                serde_json::json!({
                    "name": s.name, "split": s.split, "first_sample": s.first_sample,
                    "samples": s.samples, "strata_counts": counts,
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
            "shards": shards,
            "estimated_bytes": bytes,
            "estimated_seconds": seconds,
        });
        outln!("{}", serde_json::to_string_pretty(&value)?);
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
            count(plan.split_shards(split).count() as u64, "shard"),
            count(plan.shard_size, "sample")
        );
    }
    let spread = per_shard
        .iter()
        .map(|c| c.iter().max().unwrap_or(&0) - c.iter().min().unwrap_or(&0))
        .max()
        .unwrap_or(0);
    outln!("per-shard balance: stratum counts differ by at most {spread} within any shard");
    outln!(
        "estimated output at most {} uncompressed ({} a sample), build time {} on {}",
        human_bytes(bytes),
        human_bytes(plan.sample_bytes),
        human_duration(seconds),
        count(cores as u64, "core")
    );
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
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
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
