//! The `bettimill` command line as a library: [`run`] parses arguments, dispatches, prints
//! and returns the exit code. The `bettimill` binary (`main.rs`) and the Python package's
//! console script (`bettimill-python`) both call it, so both are the same CLI with the same
//! exit codes.
//!
//! Exit codes (documented in README.md): 0 success; 1 a check found differences (verify);
//! 2 bad input, usage error or failure; 130 interrupted (resumable). Everything else lives
//! in library crates; this crate is the only one that prints.

// This crate is the one place that prints or writes to stdout/stderr (the workspace denies
// it everywhere else: Cargo.toml [workspace.lints], clippy.toml).
#![allow(clippy::print_stdout, clippy::print_stderr, clippy::disallowed_methods)]

/// `println!` for data on stdout that ends quietly when the reader closes the pipe
/// (`bettimill plan | head`) instead of panicking; see `printer::Printer::data`. Only
/// usable in functions that return `anyhow::Result`.
macro_rules! outln {
    () => {
        crate::printer::Printer::data(b"\n")?
    };
    ($($arg:tt)*) => {
        crate::printer::Printer::data(format!("{}\n", format_args!($($arg)*)).as_bytes())?
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
mod printer;
mod progress;
mod signals;
mod stats;

pub use commands::plan_file_problems;

use anyhow::Context;
use clap::Parser;
use std::ffi::OsString;
use std::path::PathBuf;
use std::sync::OnceLock;

/// The program that runs this CLI, when it is not the running executable (see
/// [`run_as`]).
static PROGRAM: OnceLock<PathBuf> = OnceLock::new();

/// Runs the command line `args` (the first is the program name, as in `std::env::args`)
/// and returns the process exit code.
pub fn run(args: impl IntoIterator<Item = OsString>) -> i32 {
    let args: Vec<OsString> = args.into_iter().collect();
    // Before anything else (arguments, manifest, plan); the binary's `main` has done it
    // already, the Python console script has not.
    install_signal_handlers(&args);
    let cli = match commands::Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(err) => {
            // What clap's `parse` does before exiting: help and version on stdout with
            // code 0, usage errors on stderr with code 2.
            let _ = err.print();
            return err.exit_code();
        }
    };
    let status = match commands::run(cli) {
        Ok(status) => status,
        Err(err) => {
            printer::Printer::always(format_args!("error: {}", error_line(&err)));
            commands::ExitStatus::Failure
        }
    };
    // A process that ends in `main` flushes stdout on exit; a caller that goes on (the
    // Python console script) must see everything printed before the code is returned.
    printer::Printer::flush();
    status.code()
}

/// For `build` (the first word of `args` that is not an option): installs the handling of
/// SIGINT and SIGTERM, so that a signal at any moment of a build gives exit code 130 and a
/// resumable directory (see `signals`). Other commands keep the default action. The
/// binary calls it first thing in `main`; [`run`] calls it too (a second call does
/// nothing).
pub fn install_signal_handlers(args: &[OsString]) {
    let first_word = args
        .iter()
        .skip(1)
        .find(|arg| !arg.as_encoded_bytes().starts_with(b"-"));
    if first_word.is_some_and(|word| word == "build") {
        signals::install();
    }
}

/// [`run`] for a CLI that is not its own executable: `program` is the file that runs this
/// CLI (the Python package's `bettimill` console script), used wherever the CLI starts
/// itself again (the worker processes of `build`, the scripts `slurm` writes). The first
/// call's `program` holds for the life of the process.
pub fn run_as(args: impl IntoIterator<Item = OsString>, program: PathBuf) -> i32 {
    let _ = PROGRAM.set(program);
    run(args)
}

/// The program that runs this CLI: the one given to [`run_as`], else the running
/// executable.
pub(crate) fn own_program() -> anyhow::Result<PathBuf> {
    match PROGRAM.get() {
        Some(program) => Ok(program.clone()),
        None => std::env::current_exe().context("cannot find the running bettimill binary"),
    }
}

/// An error and its causes on one line, `outer: cause: cause`, leaving out a cause whose
/// text the line already holds (many errors print their source in their own message, and
/// `No space left on device (os error 28)` should be said once).
fn error_line(err: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

#[cfg(test)]
mod tests {
    #[test]
    fn an_os_reason_is_printed_once() {
        /// Like the library errors: the source in the message and as `source()`.
        #[derive(Debug)]
        struct Wrapped {
            path: String,
            source: std::io::Error,
        }
        impl std::fmt::Display for Wrapped {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{}: {}", self.path, self.source)
            }
        }
        impl std::error::Error for Wrapped {
            fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
                Some(&self.source)
            }
        }
        let os = std::io::Error::from_raw_os_error(28);
        let err = anyhow::Error::from(Wrapped {
            path: "shards/x.tar".into(),
            source: os,
        })
        .context("cannot write shard x");
        let line = super::error_line(&err);
        assert_eq!(line.matches("os error 28").count(), 1, "{line}");
        assert!(
            line.starts_with("cannot write shard x: shards/x.tar: "),
            "{line}"
        );
        // Causes that add something are kept.
        let err = anyhow::anyhow!("inner").context("outer");
        assert_eq!(super::error_line(&err), "outer: inner");
    }
}
