//! `bettimill plan`: the strata table, counts per split and shard, size and time estimates.

use bettimill_grid::Mode;
use bettimill_manifest::Manifest;
use bettimill_plan::estimate::{self, Estimate};
use bettimill_plan::memory::{self, WorkerMemory};
use bettimill_plan::{Plan, TubeFloor};

/// A pilot keeps building samples of a stratum until they took this many CPU seconds (or
/// [`PILOT_MAX_SAMPLES`]), so that small samples are timed above the clock's resolution.
const PILOT_MIN_CPU_SECONDS: f64 = 0.2;

/// The most samples a pilot builds of one stratum.
const PILOT_MAX_SAMPLES: usize = 32;

/// What `plan --pilot` measured: samples of the first strata built in-process, their CPU
/// seconds and their bytes as stored, extrapolated to the plan.
#[derive(Clone, Debug)]
pub struct Pilot {
    /// Strata built.
    pub strata: usize,
    /// Samples built.
    pub samples: u64,
    /// CPU seconds of the samples built.
    pub cpu_seconds: f64,
    /// Mean CPU seconds of one sample of the plan (strata weighted by their counts).
    pub cpu_seconds_per_sample: f64,
    /// CPU seconds of the whole build, extrapolated.
    pub build_cpu_seconds: f64,
    /// Bytes of the whole dataset's shards, extrapolated.
    pub compressed_bytes: u64,
}

/// CPU seconds (user + system, every thread) of this process so far, from /proc/self/stat;
/// `None` where there is no /proc.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let fields: Vec<&str> = stat.rsplit(')').next()?.split_whitespace().collect();
    let ticks = |i: usize| fields.get(i).and_then(|f| f.parse::<f64>().ok());
    // utime and stime, in clock ticks of 1/100 s (USER_HZ on Linux).
    Some((ticks(11)? + ticks(12)?) / 100.0)
}

/// Builds samples of the first `strata` strata that have samples (every one when `None`)
/// as a build would, measures their CPU seconds and their members' bytes with the plan's compression,
/// and extrapolates to the plan: strata not built take the model's figures scaled by how
/// the built ones compared with the model.
pub fn pilot(plan: &Plan, model: &Estimate, strata: Option<usize>) -> anyhow::Result<Pilot> {
    let counts = plan.total_counts();
    // Strata without samples (more strata than samples) cost nothing and are skipped.
    let selected: Vec<usize> = (0..plan.strata.len())
        .filter(|&s| counts[s] > 0)
        .take(strata.unwrap_or(usize::MAX).max(1))
        .collect();
    let wanted = selected.len();
    let mut slot = vec![None; plan.strata.len()];
    for (i, &s) in selected.iter().enumerate() {
        slot[s] = Some(i);
    }
    let mut tasks: Vec<Vec<bettimill_plan::SampleTask>> = vec![Vec::new(); wanted];
    'shards: for shard in plan.shards() {
        for task in plan.shard_tasks(&shard) {
            if let Some(i) = slot[task.stratum] {
                if tasks[i].len() < PILOT_MAX_SAMPLES {
                    tasks[i].push(task);
                }
            }
        }
        if tasks.iter().all(|t| t.len() >= PILOT_MAX_SAMPLES) {
            break 'shards;
        }
    }
    let clock = || {
        cpu_seconds().ok_or_else(|| {
            anyhow::anyhow!("plan --pilot: cannot read this process's CPU time (/proc/self/stat)")
        })
    };
    let (mut built, mut spent) = (0u64, 0.0);
    let mut measured = vec![None; plan.strata.len()];
    for (&stratum, stratum_tasks) in selected.iter().zip(&tasks) {
        let start = clock()?;
        let (mut n, mut bytes) = (0u64, 0u64);
        for task in stratum_tasks {
            let sample = bettimill_sample::make_sample(plan, task)
                .map_err(|err| anyhow::anyhow!("plan --pilot: sample {}: {err}", task.key))?;
            for (field, data) in sample.fields() {
                let len = if bettimill_format::member::is_array_field(&field)
                    && plan.compression != bettimill_shard::Compression::None
                {
                    bettimill_shard::compress(&data, plan.compression)?.len()
                } else {
                    data.len()
                };
                bytes += bettimill_shard::ustar::member_bytes(len as u64);
            }
            n += 1;
            if clock()? - start >= PILOT_MIN_CPU_SECONDS {
                break;
            }
        }
        if n > 0 {
            let cpu = clock()? - start;
            measured[stratum] = Some((cpu / n as f64, bytes as f64 / n as f64));
            built += n;
            spent += cpu;
        }
    }
    // Strata not built: the model, scaled by the built strata's measured / model ratio.
    let (mut cpu_ratio, mut byte_ratio) = ((0.0, 0.0), (0.0, 0.0));
    for (m, e) in measured.iter().zip(&model.strata) {
        if let Some((cpu, bytes)) = m {
            cpu_ratio = (cpu_ratio.0 + cpu, cpu_ratio.1 + e.cpu_seconds);
            byte_ratio = (
                byte_ratio.0 + bytes,
                byte_ratio.1 + e.compressed_bytes as f64,
            );
        }
    }
    let ratio = |(a, b): (f64, f64)| if b > 0.0 { a / b } else { 1.0 };
    let (cpu_ratio, byte_ratio) = (ratio(cpu_ratio), ratio(byte_ratio));
    let (mut sample_cpu, mut bytes) = (0.0, 0.0);
    for ((m, e), &count) in measured.iter().zip(&model.strata).zip(&counts) {
        let (cpu, b) = m.unwrap_or((
            e.cpu_seconds * cpu_ratio,
            e.compressed_bytes as f64 * byte_ratio,
        ));
        sample_cpu += cpu * count as f64;
        bytes += b * count as f64;
    }
    Ok(Pilot {
        strata: wanted,
        samples: built,
        cpu_seconds: spent,
        cpu_seconds_per_sample: if plan.samples == 0 {
            0.0
        } else {
            sample_cpu / plan.samples as f64
        },
        build_cpu_seconds: sample_cpu + estimate::BUILD_FIXED_SECONDS,
        compressed_bytes: (bytes as u64).saturating_add(plan.shard_count().saturating_mul(1024)),
    })
}

/// Prints the plan of `manifest` (text, or JSON with `json`), with the cost model's time
/// and size estimates and, with `pilot` (`Some(None)`: every stratum; `Some(Some(n))`: the
/// first n), the figures of samples built and measured here. A plan whose worker would not
/// fit the memory limit (`max_memory`, or the machine's default for one worker) is printed
/// and then refused. With `to_bucket` (`--out s3://...`), a plan whose shards could be
/// larger than an object bettimill can write there is refused before anything is printed.
pub fn show(
    manifest: &Manifest,
    json: bool,
    max_memory: Option<u64>,
    pilot_strata: Option<Option<usize>>,
    to_bucket: bool,
) -> anyhow::Result<()> {
    let plan = Plan::new(manifest)?;
    if to_bucket {
        plan.check_object_storage(manifest)?;
    }
    let worker_memory = WorkerMemory::of(&plan);
    let bytes = plan.sample_bytes.saturating_mul(plan.samples);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    let model = estimate::estimate(&plan);
    let seconds = model.wall_seconds(cores);
    let pilot = match pilot_strata {
        Some(strata) => {
            bettimill_executor::memory::check(&plan, max_memory, 1, 1)?;
            Some(pilot(&plan, &model, strata)?)
        }
        None => None,
    };
    let pilot_json = pilot.as_ref().map(|p| {
        serde_json::json!({
            "strata": p.strata,
            "samples_built": p.samples,
            "cpu_seconds_spent": p.cpu_seconds,
            "cpu_seconds_per_sample": p.cpu_seconds_per_sample,
            "estimated_cpu_seconds": p.build_cpu_seconds,
            "estimated_seconds": estimate::wall_seconds(p.build_cpu_seconds, cores, plan.samples),
            "estimated_compressed_bytes": p.compressed_bytes,
        })
    });
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
            "estimated_compressed_bytes": model.compressed_bytes,
            "compression": plan.compression.name(),
            "estimated_seconds": seconds,
            "estimated_cpu_seconds": model.cpu_seconds,
            "estimated_cpu_seconds_per_sample": model.cpu_seconds_per_sample,
            "estimate_cores": cores,
            "pilot": pilot_json,
            "worker_memory_bytes": worker_memory.total(1),
            "sample_memory_bytes": worker_memory.sample_bytes,
        });
        // The shard list is streamed, one shard at a time: a plan of 10^8 shards prints
        // gigabytes but holds one shard in memory.
        let head = serde_json::to_string_pretty(&value)?;
        let head = head
            .strip_suffix("\n}")
            .expect("a pretty-printed JSON object ends with a closing brace on its own line");
        crate::printer::Printer::data(format!("{head},\n  \"shards\": [").as_bytes())?;
        for shard in plan.shards() {
            let entry = serde_json::json!({
                "name": shard.name, "split": shard.split, "first_sample": shard.first_sample,
                "samples": shard.samples, "strata_counts": plan.shard_counts(&shard),
            });
            let comma = if shard.index == 0 { "" } else { "," };
            crate::printer::Printer::data(format!("{comma}\n    {entry}").as_bytes())?;
        }
        outln!("\n  ]\n}}");
        bettimill_executor::memory::check(&plan, max_memory, 1, 1)?;
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
    // Carve-mode copies: which strata got cavities thick enough for the largest copy.
    if let Some(largest) = plan.resolutions.iter().max() {
        let carved = plan.strata.iter().filter(|s| s.mode == Mode::Carve);
        let thick: Vec<f64> = carved
            .clone()
            .map(|s| s.tube_floor)
            .filter(|&floor| floor.thickens())
            .map(TubeFloor::radius)
            .collect();
        if let Some(radius) = thick.first() {
            outln!(
                "copies: carved tubes at least {radius:.2} voxels for the {largest}-side copy in {} of {} carved strata (the others: {:.0})",
                thick.len(),
                carved.count(),
                TubeFloor::USUAL.radius()
            );
        }
    }
    outln!(
        "estimated output: about {} with {} members (model), at most {} uncompressed ({} a sample)",
        human_bytes(model.compressed_bytes),
        plan.compression.name(),
        human_bytes(bytes),
        human_bytes(plan.sample_bytes),
    );
    outln!(
        "estimated build time: {} on {} (model: {} CPU-s a sample, {} CPU in all; calibrated on the 2-core reference machine)",
        human_duration(seconds),
        count(cores, "core"),
        cpu_figure(model.cpu_seconds_per_sample),
        human_duration(model.cpu_seconds).trim_start_matches("about "),
    );
    // The model prices one attempt a sample; the check makes again every attempt whose
    // holes a dilation closes, how many depends on the shapes and the bins.
    if let Some(n) = plan.survives_dilations.filter(|&n| n > 0) {
        outln!(
            "survives_dilations = {n}: the model counts one attempt a sample, the check makes again those a dilation changes (3 times the CPU on the learnability bench's 4D families); --pilot measures it"
        );
    }
    if let Some(p) = &pilot {
        outln!(
            "pilot (measured here: {} of {} built in {} CPU-s): {} CPU-s and {} a sample; build time {} on {}, output about {}",
            count(p.samples, "sample"),
            count(p.strata as u64, "stratum").replace("stratums", "strata"),
            cpu_figure(p.cpu_seconds),
            cpu_figure(p.cpu_seconds_per_sample),
            human_bytes(p.compressed_bytes / plan.samples.max(1)),
            human_duration(estimate::wall_seconds(p.build_cpu_seconds, cores, plan.samples)),
            count(cores, "core"),
            human_bytes(p.compressed_bytes),
        );
    }
    outln!(
        "worker memory: about {} a worker ({} for one sample of {} voxels in flight + {} for the shard being written)",
        memory::human_bytes(worker_memory.total(1)),
        memory::human_bytes(worker_memory.sample_bytes),
        worker_memory.voxels,
        memory::human_bytes(worker_memory.shard_bytes),
    );
    bettimill_executor::memory::check(&plan, max_memory, 1, 1)?;
    Ok(())
}

/// CPU seconds with three significant digits: `10.7`, `0.0123`.
fn cpu_figure(seconds: f64) -> String {
    if seconds >= 100.0 {
        format!("{seconds:.0}")
    } else if seconds >= 10.0 {
        format!("{seconds:.1}")
    } else if seconds >= 1.0 {
        format!("{seconds:.2}")
    } else if seconds >= 0.001 {
        format!("{seconds:.4}")
    } else {
        format!("{seconds:.1e}")
    }
}

use crate::build_display::count;

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
