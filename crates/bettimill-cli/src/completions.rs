//! `bettimill completions SHELL`: a shell completion script on stdout.

use crate::commands::{Cli, ExitStatus};
use clap::CommandFactory;
use clap_complete::Shell;

/// Writes the completion script for `shell` to stdout.
pub fn run(shell: Shell) -> anyhow::Result<ExitStatus> {
    let mut command = Cli::command();
    // Generated into memory first: clap_complete panics when its writer fails, and stdout
    // can be a closed pipe.
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut command, "bettimill", &mut script);
    crate::printer::Printer::data(&script)?;
    Ok(ExitStatus::Success)
}
