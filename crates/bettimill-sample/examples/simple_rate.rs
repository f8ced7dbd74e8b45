//! The simple-point test's throughput on the configurations deformation and targeting
//! meet: for the first samples of a manifest, every voxel on the boundary of the phase
//! that carries the topology (a phase voxel with a face neighbour outside it, or the
//! reverse, inside the phase's box) of the final sample, in scan order, is tested on one
//! thread without a memo and then through a `SimpleCache` of 2^20 slots (the size the
//! morphology uses). Prints tests per CPU-second both ways, and the share of lookups that
//! repeat an earlier configuration (the best hit rate a memo can have on that sequence).
//! Usage: `cargo run --release -p bettimill-sample --example simple_rate -- MANIFEST [N]`.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]
#[path = "common/cpu.rs"]
mod cpu;
use bettimill_grid::neighbourhood::is_interior;
use bettimill_homology::simple::{SimpleCache, SimpleTester};
use bettimill_plan::Plan;
use bettimill_sample::{construction, make_sample};
use std::collections::HashSet;
use std::path::Path;
use std::time::Instant;

/// Per-thread CPU time, so that other processes on the machine do not count.
fn thread_cpu_seconds() -> f64 {
    cpu::cpu_seconds("/proc/thread-self/stat")
}

/// Runs `work` until it has used at least a CPU-second; returns CPU seconds per run.
fn per_run(mut work: impl FnMut() -> usize) -> (f64, usize) {
    let start = thread_cpu_seconds();
    let wall = Instant::now();
    let mut runs = 0;
    let mut answer = 0;
    while thread_cpu_seconds() - start < 1.0 || runs < 2 {
        answer = std::hint::black_box(work());
        runs += 1;
        if wall.elapsed().as_secs() > 120 {
            break;
        }
    }
    ((thread_cpu_seconds() - start) / runs as f64, answer)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: simple_rate MANIFEST [N]");
    let n: u64 = args.next().map_or(2, |s| s.parse().expect("N is a count"));
    let text = std::fs::read_to_string(&path).expect("read the manifest");
    let plan = Plan::parse(&text, Path::new(&path)).expect("a valid manifest");
    let (mut tests, mut plain_s, mut memo_s, mut repeats) = (0usize, 0.0, 0.0, 0usize);
    for index in 0..n.min(plan.samples) {
        let task = plan.task(index).expect("a planned sample");
        let sample = make_sample(&plan, &task).expect("the sample builds");
        let phase = construction(&plan, &task, sample.label.attempt)
            .expect("constructs")
            .phase;
        let image = &sample.image;
        let tester = SimpleTester::new(image.dim());
        let strides = image.strides().to_vec();
        let data = image.data();
        let inside = phase.voxels(image);
        let mut boundary = Vec::new();
        let mut seen = HashSet::new();
        // Boundary voxels on either side, each once, in scan order.
        for &i in &inside {
            for &s in &strides {
                for j in [i - s, i + s] {
                    if data[j] != phase.value && is_interior(image, j, 1) && seen.insert(j) {
                        boundary.push(j);
                    }
                }
            }
            if strides
                .iter()
                .any(|&s| data[i - s] != phase.value || data[i + s] != phase.value)
                && seen.insert(i)
            {
                boundary.push(i);
            }
        }
        boundary.sort_unstable();
        let configs: Vec<u128> = boundary
            .iter()
            .map(|&i| tester.configuration(image, i))
            .collect();
        let distinct: HashSet<u128> = configs.iter().copied().collect();
        let (plain, simple) = per_run(|| {
            configs
                .iter()
                .filter(|&&c| tester.is_simple_configuration(c))
                .count()
        });
        let (memo, simple_memo) = per_run(|| {
            let mut cache = SimpleCache::new(20);
            configs
                .iter()
                .filter(|&&c| cache.is_simple(&tester, c))
                .count()
        });
        assert_eq!(simple, simple_memo, "the memo changes no answer");
        println!(
            "{} {}: {} boundary voxels ({} simple), {:.2} M tests/CPU-s plain, {:.2} M through the memo, {:.1}% repeats",
            task.key,
            sample.label.class_label,
            configs.len(),
            simple,
            configs.len() as f64 / plain / 1e6,
            configs.len() as f64 / memo / 1e6,
            100.0 * (configs.len() - distinct.len()) as f64 / configs.len() as f64
        );
        tests += configs.len();
        plain_s += plain;
        memo_s += memo;
        repeats += configs.len() - distinct.len();
    }
    println!(
        "all: {tests} tests, {:.2} M tests/CPU-s plain, {:.2} M through the memo, {:.1}% repeats",
        tests as f64 / plain_s / 1e6,
        tests as f64 / memo_s / 1e6,
        100.0 * repeats as f64 / tests as f64
    );
}
