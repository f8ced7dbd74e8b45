//! Everything the CLI says, and where. [`Printer`] is made once from the arguments (with
//! `--quiet`) and handed to the commands; no other file of this crate prints or reads the
//! flag (tests/tidy.rs).
//!
//! - Data on stdout ([`Printer::data`], `outln!`): reports, `--json`, tables, scripts.
//!   Never silenced; a reader that closes the pipe early ends it quietly.
//! - Notes on stderr ([`Printer::note`]): what was written, summaries, the way on.
//!   Silenced by `--quiet`.
//! - Lines on stderr that `--quiet` does not silence ([`Printer::always`]): errors,
//!   interruptions, a wait for another process.
//! - Progress on stderr ([`Printer::bar`], [`Printer::draw_target`], plain progress lines):
//!   bars only on a terminal, plain lines only elsewhere, neither with `--quiet`.

use anyhow::Context;
use indicatif::{ProgressBar, ProgressDrawTarget};
use std::fmt::Display;
use std::io::{IsTerminal, Write};

/// The CLI's output: stdout, stderr and whether `--quiet` was given. Cheap to copy into a
/// thread or a closure.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Printer {
    quiet: bool,
}

impl Printer {
    /// The printer of a command line that gave `--quiet` or not.
    pub(crate) fn new(quiet: bool) -> Printer {
        Printer { quiet }
    }

    /// Whether notes and progress are shown (not `--quiet`): for work done only to be
    /// shown, such as a thread that writes progress lines.
    pub(crate) fn shows_notes(self) -> bool {
        !self.quiet
    }

    /// A note on stderr, one line (or several, each ended); nothing with `--quiet`.
    pub(crate) fn note(self, line: impl Display) {
        if !self.quiet {
            eprintln!("{line}");
        }
    }

    /// A line on stderr that `--quiet` does not silence: an error, an interruption, a wait.
    pub(crate) fn always(line: impl Display) {
        eprintln!("{line}");
    }

    /// Writes data to stdout. A reader that stops early (`bettimill stats DIR | head`)
    /// closes the pipe; that is the reader's choice, not an error, so a broken pipe ends
    /// quietly instead of panicking the way `println!` does.
    pub(crate) fn data(bytes: &[u8]) -> anyhow::Result<()> {
        let mut stdout = std::io::stdout().lock();
        match stdout.write_all(bytes).and_then(|()| stdout.flush()) {
            Err(err) if err.kind() != std::io::ErrorKind::BrokenPipe => {
                Err(err).context("cannot write to stdout")
            }
            _ => Ok(()),
        }
    }

    /// Flushes stdout, for a caller that goes on after the command (the Python console
    /// script) and must see everything printed first.
    pub(crate) fn flush() {
        let _ = std::io::stdout().flush();
    }

    /// Where bars are drawn: stderr (indicatif draws nothing when it is not a terminal), or
    /// nowhere with `--quiet`.
    pub(crate) fn draw_target(self) -> ProgressDrawTarget {
        if self.quiet {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        }
    }

    /// A bar of `len` `unit`s on [`Printer::draw_target`] in the common style
    /// ([`crate::progress::style`]), showing `message`.
    pub(crate) fn bar(self, len: u64, unit: &str, message: &'static str) -> ProgressBar {
        let bar = ProgressBar::with_draw_target(Some(len), self.draw_target())
            .with_style(crate::progress::style(unit));
        bar.set_message(message);
        bar
    }

    /// Whether progress is written as plain lines (stderr is not a terminal: a cluster
    /// log, nohup, CI) rather than drawn as bars; never with `--quiet`.
    pub(crate) fn plain_progress(self) -> bool {
        !self.quiet && !std::io::stderr().is_terminal()
    }
}
