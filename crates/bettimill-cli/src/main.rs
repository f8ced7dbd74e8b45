//! The `bettimill` binary: the command line of [`bettimill_cli::run`], whose return value
//! is the exit code (documented in README.md).

use std::process::ExitCode;

fn main() -> ExitCode {
    // First thing: from here on a SIGINT or SIGTERM to a build exits 130 with a message.
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    bettimill_cli::install_signal_handlers(&args);
    let code = bettimill_cli::run(args);
    ExitCode::from(u8::try_from(code).unwrap_or(2))
}
