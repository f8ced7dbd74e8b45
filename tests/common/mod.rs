//! Helpers shared by the process-level test files (`workers.rs`, `reliability.rs`): run the
//! real `bettimill` binary and look at its child processes and output directory.
//!
//! Each test binary uses a different subset, so unused ones are expected.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

pub fn bettimill() -> Command {
    Command::new(env!("CARGO_BIN_EXE_bettimill"))
}

pub fn run(args: &[&str]) -> Output {
    bettimill().args(args).output().expect("bettimill runs")
}

pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

pub fn build(manifest: &Path, out: &Path, workers: u32) -> Output {
    run(&[
        "build",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--workers",
        &workers.to_string(),
    ])
}

/// The child processes of `pid` (from /proc; Linux only).
pub fn children(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return out;
    };
    for task in tasks.flatten() {
        if let Ok(list) = std::fs::read_to_string(task.path().join("children")) {
            out.extend(
                list.split_whitespace()
                    .filter_map(|p| p.parse::<u32>().ok()),
            );
        }
    }
    out
}

pub fn shard_files(out: &Path) -> Vec<String> {
    std::fs::read_dir(out.join("shards"))
        .map(|rd| {
            rd.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default()
}
