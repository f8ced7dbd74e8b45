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
        "dataset {}: {}D, side {}, {} samples",
        plan.name,
        plan.dimension,
        plan.side,
        plan.samples
    );
    outln!("manifest hash {}", plan.manifest_hash);
    outln!("plan hash     {}", plan.hash());
    outln!();
    outln!(
        "{:>4}  {:<40} {:<16} {:>8}",
        "cls",
        "stratum",
        "betti",
        "samples"
    );
    for (stratum, count) in plan.strata.iter().zip(&totals) {
        outln!(
            "{:>4}  {:<40} {:<16} {:>8}",
            stratum.index,
            stratum.label,
            format!("{:?}", stratum.betti),
            count
        );
    }
    if !plan.infeasible.is_empty() {
        outln!("\nleft out (cannot be built):");
        for item in &plan.infeasible {
            outln!("  {}: {}", item.label, item.reason);
        }
    }
    outln!();
    for (split, size) in &plan.splits {
        outln!(
            "split {split}: {size} samples in {} shards of up to {}",
            plan.split_shards(split).count(),
            plan.shard_size
        );
    }
    let spread = per_shard
        .iter()
        .map(|c| c.iter().max().unwrap_or(&0) - c.iter().min().unwrap_or(&0))
        .max()
        .unwrap_or(0);
    outln!("per-shard balance: stratum counts differ by at most {spread} within any shard");
    outln!(
        "estimated output {:.1} MiB uncompressed, build time about {} on {} cores",
        bytes as f64 / (1024.0 * 1024.0),
        human_duration(seconds),
        cores
    );
    Ok(())
}

fn human_duration(seconds: f64) -> String {
    if seconds < 90.0 {
        format!("{seconds:.0} s")
    } else if seconds < 5400.0 {
        format!("{:.0} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}
