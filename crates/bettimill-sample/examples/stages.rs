//! Times the stages of `make_sample` (generate, deform, hypervolume targeting, verify,
//! downscaling) for the first samples of a manifest, in CPU seconds, with the peak RSS
//! after each stage, through the same observer the build's progress uses.
//! Usage: `cargo run --release -p bettimill-sample --example stages -- MANIFEST [N]`.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]
#[path = "common/cpu.rs"]
mod cpu;
use bettimill_plan::Plan;
use bettimill_sample::{make_sample_observed, Stage};
use std::path::Path;

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
    cpu::cpu_seconds("/proc/self/stat")
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: stages MANIFEST [N]");
    let n: u64 = args.next().map_or(4, |s| s.parse().expect("N is a count"));
    let text = std::fs::read_to_string(&path).expect("read the manifest");
    let plan = Plan::parse(&text, Path::new(&path)).expect("a valid manifest");
    for index in 0..n.min(plan.samples) {
        let task = plan.task(index).expect("a planned sample");
        let mut marks: Vec<(Stage, u32, f64, u64)> = Vec::new();
        let start = cpu_seconds();
        let sample = make_sample_observed(&plan, &task, &mut |p| {
            marks.push((p.stage, p.attempt, cpu_seconds(), peak_rss_mib()))
        });
        let end = cpu_seconds();
        let label = match &sample {
            Ok(s) => format!(
                "{} attempt {} hypervolume {}",
                s.label.class_label, s.label.attempt, s.label.hypervolume
            ),
            Err(err) => format!("failed: {err}"),
        };
        println!("{} {label}: {:.2} cpu-s", task.key, end - start);
        for (i, (stage, attempt, at, rss)) in marks.iter().enumerate() {
            let next = marks.get(i + 1).map_or(end, |m| m.2);
            println!(
                "  attempt {attempt} {stage:<24} {:>7.2} cpu-s  peak {rss} MiB",
                next - at
            );
        }
    }
}
