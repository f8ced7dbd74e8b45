//! Progress bars on stderr, one look and one hiding rule for every command (`build`,
//! `verify`, `audit`, `stats`): drawn only when stderr is a terminal (indicatif checks) and
//! never with `--quiet`. Progress never goes to stdout, so `--json` output is unchanged.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Where bars are drawn: stderr (indicatif draws nothing when it is not a terminal), or
/// nowhere with `--quiet`.
pub fn target(quiet: bool) -> ProgressDrawTarget {
    if quiet {
        ProgressDrawTarget::hidden()
    } else {
        ProgressDrawTarget::stderr()
    }
}

/// The style of a main bar counting `unit` (`samples`, `shards`); the message follows.
pub fn style(unit: &str) -> ProgressStyle {
    ProgressStyle::with_template(&format!(
        "{{elapsed_precise}} [{{bar:30}}] {{pos}}/{{len}} {unit} {{per_sec}} ETA {{eta}} {{msg}}"
    ))
    .expect("the template is valid")
    .progress_chars("=> ")
}

/// A bar of `len` `unit`s on [`target`] in [`style`], showing `message`.
pub fn bar(len: u64, unit: &str, message: &'static str, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(len), target(quiet)).with_style(style(unit));
    bar.set_message(message);
    bar
}
