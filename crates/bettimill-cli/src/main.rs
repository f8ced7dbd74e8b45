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
mod stats;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = commands::Cli::parse();
    match commands::run(cli) {
        Ok(status) => status.into(),
        Err(err) => {
            eprintln!("error: {}", error_line(&err));
            commands::ExitStatus::Failure.into()
        }
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
