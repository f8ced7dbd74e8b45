//! The `bettimill` binary: the command line of [`bettimill_cli::run`], whose return value
//! is the exit code (documented in README.md).

use std::process::ExitCode;

fn main() -> ExitCode {
    let code = bettimill_cli::run(std::env::args_os());
    ExitCode::from(u8::try_from(code).unwrap_or(2))
}
