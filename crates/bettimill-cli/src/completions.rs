//! `bettimill completions SHELL`: a shell completion script on stdout.

use crate::commands::{Cli, Status};
use clap::CommandFactory;
use clap_complete::Shell;

/// Writes the completion script for `shell` to stdout.
pub fn run(shell: Shell) -> anyhow::Result<Status> {
    let mut command = Cli::command();
    clap_complete::generate(shell, &mut command, "bettimill", &mut std::io::stdout());
    Ok(Status::Success)
}
