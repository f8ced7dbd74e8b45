//! The look of progress bars, one for every command (`build`, `verify`, `audit`, `stats`).
//! Where and whether they are drawn is the [`crate::printer::Printer`]'s: only when stderr
//! is a terminal (indicatif checks) and never with `--quiet`. Progress never goes to
//! stdout, so `--json` output is unchanged.

use indicatif::ProgressStyle;

/// The style of a main bar counting `unit` (`samples`, `shards`); the message follows.
pub fn style(unit: &str) -> ProgressStyle {
    ProgressStyle::with_template(&format!(
        "{{elapsed_precise}} [{{bar:30}}] {{pos}}/{{len}} {unit} {{per_sec}} ETA {{eta}} {{msg}}"
    ))
    .expect("the template is valid")
    .progress_chars("=> ")
}

/// The style of a bar whose position counts thousandths of a `unit` (`samples`), so that it
/// advances within one sample: `3.4/8 samples`, the rate in whole units, then the message.
pub fn thousandths_style(unit: &str) -> ProgressStyle {
    ProgressStyle::with_template(&format!(
        "{{elapsed_precise}} [{{bar:30}}] {{done}} {unit} {{rate}} ETA {{eta}} {{msg}}"
    ))
    .expect("the template is valid")
    .with_key(
        "done",
        |state: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = write!(
                w,
                "{}/{}",
                thousandths(state.pos()),
                state.len().unwrap_or(0) / 1000
            );
        },
    )
    .with_key(
        "rate",
        |state: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&crate::build_display::rate_per_second(
                state.per_sec() / 1000.0,
            ));
        },
    )
    .progress_chars("=> ")
}

/// `3`, `3.4`: a count of thousandths as units with one decimal (none when whole).
pub fn thousandths(count: u64) -> String {
    // Rounded down: a sample 99.9% done is not shown as done.
    let tenths = count / 100;
    if tenths.is_multiple_of(10) {
        format!("{}", tenths / 10)
    } else {
        format!("{}.{}", tenths / 10, tenths % 10)
    }
}
