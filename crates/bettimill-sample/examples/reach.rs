//! Measures how far hypervolume targeting really takes each binned stratum of a manifest,
//! beside the plan's estimate ([`bettimill_plan::Plan::reach`]): for the first samples of
//! every binned stratum and their first attempts, the construction a build starts from
//! (sized for the bin) is shrunk, and grown, by the build's own targeting as far as
//! topology-preserving flips go, and the counts where they stop are printed.
//! Usage: `cargo run --release -p bettimill-sample --example reach -- MANIFEST [N] [A]`
//! (N samples per stratum, 4 by default; A attempts each, 4 by default).

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]
use bettimill_deform::DeformError;
use bettimill_plan::Plan;
use std::path::Path;

/// Where targeting towards `goal` stops: the goal, or the count at which no simple
/// frontier voxel is left.
fn stop(
    construction: &bettimill_sample::Construction,
    goal: u64,
    seed: u64,
) -> Result<u64, DeformError> {
    let mut image = construction.image.clone();
    // Each run from the construction's image starts from the phase made from it.
    let mut phase = construction.phase;
    match bettimill_deform::target_hypervolume_phase(
        &mut image, goal, goal, goal, &mut phase, None, seed,
    ) {
        Ok(report) => Ok(report.foreground_after),
        Err(DeformError::HypervolumeUnreachable { reached, .. }) => Ok(reached),
        Err(err) => Err(err),
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: reach MANIFEST [N] [A]");
    let n: usize = args.next().map_or(4, |s| s.parse().expect("N is a count"));
    let attempts: u32 = args.next().map_or(4, |s| s.parse().expect("A is a count"));
    let text = std::fs::read_to_string(&path).expect("read the manifest");
    let plan = Plan::parse(&text, Path::new(&path)).expect("a manifest that plans");
    let voxels = plan.side.pow(plan.dimension.get() as u32) as u64;
    println!("stratum bin | estimate lowest highest | measured lowest min..max, highest min..max");
    for stratum in &plan.strata {
        let Some((lo, hi)) = stratum.hypervolume else {
            continue;
        };
        let tasks: Vec<_> = (0..plan.samples)
            .filter_map(|i| plan.task(i))
            .filter(|t| t.stratum == stratum.index)
            .take(n)
            .collect();
        let (mut lowest, mut highest) = (Vec::new(), Vec::new());
        for task in &tasks {
            for attempt in 0..attempts {
                let Ok(construction) = bettimill_sample::construction(&plan, task, attempt) else {
                    continue;
                };
                let seed = u64::from(task.seed[0]) << 8 | u64::from(attempt);
                lowest.push(stop(&construction, 1, seed).expect("targeting runs"));
                highest.push(stop(&construction, voxels, seed).expect("targeting runs"));
            }
        }
        lowest.sort_unstable();
        highest.sort_unstable();
        let r = plan.reach(stratum);
        let span = |v: &[u64]| match (v.first(), v.last()) {
            (Some(a), Some(b)) => format!(
                "{a}..{b} (quartiles {} {} {})",
                v[v.len() / 4],
                v[v.len() / 2],
                v[v.len() * 3 / 4]
            ),
            _ => "none built".to_string(),
        };
        println!(
            "{} {lo}-{hi} | {} {} | {} ; {}",
            stratum.label,
            r.lowest,
            r.highest,
            span(&lowest),
            span(&highest)
        );
    }
}
