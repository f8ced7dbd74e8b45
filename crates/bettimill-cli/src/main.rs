//! The `bettimill` binary: parse arguments, dispatch, map errors to exit codes.
//!
//! Exit codes (documented in README.md): 0 success; 1 a check found differences (verify);
//! 2 bad input, usage error or failure; 3 a cluster task failed on purpose (test hook);
//! 130 interrupted (resumable). Everything else lives in library crates; this crate
//! is the only one that prints.

// This crate is the one place that prints or writes to stdout/stderr (the workspace denies
// it everywhere else: Cargo.toml [workspace.lints], clippy.toml).
#![allow(clippy::print_stdout, clippy::print_stderr, clippy::disallowed_methods)]

/// `println!` for data on stdout that ends quietly when the reader closes the pipe
/// (`bettimill plan | head`) instead of panicking; see `stats::write_stdout`. Only usable
/// in functions that return `anyhow::Result`.
macro_rules! outln {
    () => {
        crate::stats::write_stdout(b"\n")?
    };
    ($($arg:tt)*) => {
        crate::stats::write_stdout(format!("{}\n", format_args!($($arg)*)).as_bytes())?
    };
}

mod audit;
mod build;
mod build_display;
mod cluster;
mod commands;
mod completions;
mod deform;
mod directory;
mod image;
mod plan;
mod preview;
mod progress;
mod signals;
mod stats;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // Before anything else (arguments, manifest, plan): a signal at any moment of a build
    // gives exit code 130 and a resumable directory (see `signals`).
    let first_word = std::env::args_os()
        .skip(1)
        .find(|arg| !arg.to_string_lossy().starts_with('-'));
    if first_word.as_deref() == Some(std::ffi::OsStr::new("build")) {
        signals::install();
    }
    let cli = commands::Cli::parse();
    match commands::run(cli) {
        Ok(status) => status.into(),
        Err(err) => {
            eprintln!("error: {err:#}");
            commands::ExitStatus::Failure.into()
        }
    }
}
