//! Times the stages of `make_sample` (generate, hypervolume targeting, homology,
//! downscaling) for the first samples of a manifest, with the peak RSS after each stage.
//! Usage: `cargo run --release -p bettimill-sample --example stages -- MANIFEST [N]`.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]
use bettimill_plan::{attempt_rng, derive_seed, Plan};
use bettimill_sample::Pooling;
use std::path::Path;
use std::time::Instant;

fn peak_rss_mib() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|k| k.parse::<u64>().ok())
        .map_or(0, |k| k / 1024)
}

/// CPU seconds (user + system, all threads) of this process so far.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let fields: Vec<&str> = stat
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}

/// Faces between a foreground and a background voxel.
fn surface_faces(image: &bettimill_grid::BinaryImage) -> u64 {
    let data = image.data();
    let mut faces = 0u64;
    for (axis, &stride) in image.strides().iter().enumerate() {
        let n = image.shape()[axis];
        for (i, &v) in data.iter().enumerate() {
            if (i / stride) % n + 1 < n && v != data[i + stride] {
                faces += 1;
            }
        }
    }
    faces
}

fn fnv(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(2).map_or(1, |s| s.parse().expect("N"));
    let plan = Plan::from_path(Path::new(&args[1])).expect("plan");
    let side = plan.side as usize;
    let tasks: Vec<_> = plan
        .shards()
        .flat_map(|s| plan.shard_tasks(&s))
        .take(n)
        .collect();
    for task in tasks {
        let stratum = &plan.strata[task.stratum];
        let mut rng = attempt_rng(&task.seed, 0);
        let foreground = stratum
            .hypervolume
            .map(|(lo, hi)| bettimill_sample::position_in_bin(lo, hi, &task.seed, 0));
        let t = Instant::now();
        let c = cpu_seconds();
        let generated = bettimill_shapes::generate_planned_for(
            &stratum.family,
            plan.dimension,
            side,
            stratum.mode,
            foreground,
            stratum.tube_floor,
            &mut rng,
        )
        .expect("generate");
        println!(
            "{} {}: generate {:.2?} cpu {:.2}s (peak {} MiB), foreground {} (built for {:?})",
            task.key,
            stratum.label,
            t.elapsed(),
            cpu_seconds() - c,
            peak_rss_mib(),
            generated.image.count_foreground(),
            foreground,
        );
        for object in generated.construction["objects"]
            .as_array()
            .into_iter()
            .flatten()
        {
            let params = &object["params"];
            println!(
                "  object {}: voxels {} tube_radius {} grow {} scale {}",
                object["family"],
                object["voxels"],
                params["tube_radius"],
                params["grow"],
                params["scale"]
            );
        }
        let mut image = generated.image;
        if let Some((lo, hi)) = stratum.hypervolume {
            let bytes = derive_seed(
                "bettimill hypervolume seed v1",
                &[&task.seed, &0u32.to_le_bytes()],
            );
            let seed = u64::from_le_bytes(bytes[..8].try_into().unwrap());
            let t = Instant::now();
            let c = cpu_seconds();
            let report = bettimill_deform::target_hypervolume(&mut image, lo, hi, seed);
            println!(
                "  target [{lo}, {hi}]: {:.2?} cpu {:.2}s (peak {} MiB) {report:?}",
                t.elapsed(),
                cpu_seconds() - c,
                peak_rss_mib()
            );
        }
        println!(
            "  surface/volume {:.4} (foreground-background faces per foreground voxel)",
            surface_faces(&image) as f64 / image.count_foreground().max(1) as f64
        );
        let t = Instant::now();
        let c = cpu_seconds();
        let topology = bettimill_homology::topology(&bettimill_sample::foreground_window(&image));
        println!(
            "  topology {:?} (expected {:?}): {:.2?} cpu {:.2}s (peak {} MiB)",
            topology.betti,
            generated.betti,
            t.elapsed(),
            cpu_seconds() - c,
            peak_rss_mib()
        );
        // Both pooling rules on the same voxels, the mode's own first.
        let own = bettimill_sample::pooling_for(stratum.mode);
        let other = match own {
            Pooling::ForegroundAny => Pooling::BackgroundAny,
            Pooling::BackgroundAny => Pooling::ForegroundAny,
        };
        for pooling in [own, other] {
            for &r in &plan.resolutions {
                let t = Instant::now();
                let small = bettimill_sample::downscale(&image, side / r as usize, pooling);
                let ds = t.elapsed();
                let t = Instant::now();
                let c = cpu_seconds();
                let top = bettimill_homology::topology(&small);
                let preserved = top.betti == topology.betti;
                println!(
                    "  r{r} {pooling:?}: downscale {ds:.2?}, topology {:?} preserved {preserved} \
                     {:.2?} cpu {:.2}s (peak {} MiB)",
                    top.betti,
                    t.elapsed(),
                    cpu_seconds() - c,
                    peak_rss_mib()
                );
            }
        }
        println!("  fingerprint {:#018x}", fnv(image.data()));
    }
}
