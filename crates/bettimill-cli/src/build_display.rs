//! The progress display of `bettimill build`: one bar for samples and shards, one line per
//! worker, drawn with indicatif on stderr (hidden when stderr is not a terminal or with
//! --quiet), fed by the coordinator's [`BuildEvent`]s.

use bettimill_executor::coordinator::BuildEvent;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

/// Progress bars for a build.
pub(crate) struct Display {
    multi: MultiProgress,
    overall: Option<ProgressBar>,
    slots: Vec<ProgressBar>,
    regenerations: u64,
    failures: u64,
    quiet: bool,
    /// Worker processes (or 0 for an in-process build), for the closing summary.
    pub(crate) workers: usize,
}

impl Display {
    pub(crate) fn new(quiet: bool) -> Display {
        Display {
            multi: MultiProgress::with_draw_target(crate::progress::target(quiet)),
            overall: None,
            slots: Vec::new(),
            regenerations: 0,
            failures: 0,
            quiet,
            workers: 0,
        }
    }

    pub(crate) fn message(&self) -> String {
        format!(
            "{} regenerations, {} failed attempts",
            self.regenerations, self.failures
        )
    }

    pub(crate) fn event(&mut self, event: BuildEvent) {
        match event {
            BuildEvent::Started {
                shards,
                skipped,
                samples,
                workers,
            } => {
                self.workers = workers;
                if !self.quiet && skipped > 0 {
                    let _ = self
                        .multi
                        .println(format!("{skipped} of {shards} shards already complete"));
                }
                let overall = self.multi.add(ProgressBar::new(samples));
                overall.set_style(crate::progress::style("samples"));
                overall.set_message(self.message());
                self.overall = Some(overall);
                for slot in 0..workers {
                    let bar = self.multi.add(ProgressBar::new(0));
                    bar.set_style(
                        ProgressStyle::with_template("  worker {prefix}: {msg} {pos}/{len}")
                            .expect("the template is valid"),
                    );
                    bar.set_prefix(slot.to_string());
                    bar.set_message("starting");
                    self.slots.push(bar);
                }
            }
            BuildEvent::WorkerStarted { slot, pid } => {
                if let Some(bar) = self.slots.get(slot) {
                    bar.set_message(format!("pid {pid}"));
                }
            }
            BuildEvent::ShardStarted {
                slot,
                shard,
                samples,
            } => {
                if let Some(bar) = self.slots.get(slot) {
                    bar.set_length(samples);
                    bar.set_position(0);
                    bar.set_message(shard);
                }
            }
            BuildEvent::Sample {
                slot,
                regenerations,
            } => {
                self.regenerations += u64::from(regenerations);
                if let Some(bar) = self.slots.get(slot) {
                    bar.inc(1);
                }
                if let Some(overall) = &self.overall {
                    overall.inc(1);
                    overall.set_message(self.message());
                }
            }
            BuildEvent::ShardDone { slot, shard } => {
                if let Some(bar) = self.slots.get(slot) {
                    bar.set_message(format!("{shard} done"));
                }
            }
            BuildEvent::ShardFailed {
                shard,
                samples_lost,
                reason,
                failures,
                given_up,
                ..
            } => {
                self.failures += 1;
                if let Some(overall) = &self.overall {
                    overall.set_position(overall.position().saturating_sub(samples_lost));
                    overall.set_message(self.message());
                }
                let what = if given_up { "given up" } else { "re-queued" };
                self.note(format!(
                    "shard {shard} failed (attempt {failures}, {what}): {reason}"
                ));
            }
            BuildEvent::WorkerDied { slot, pid, status } => {
                self.note(format!(
                    "worker {slot} (pid {pid}) ended: {status}; starting a new one"
                ));
            }
        }
    }

    /// A line above the bars, or on stderr when bars are hidden (never with --quiet).
    pub(crate) fn note(&self, line: String) {
        if self.quiet {
            return;
        }
        if self.multi.is_hidden() {
            eprintln!("{line}");
        } else {
            let _ = self.multi.println(line);
        }
    }

    pub(crate) fn finish(&self) {
        for bar in &self.slots {
            bar.finish_and_clear();
        }
        if let Some(overall) = &self.overall {
            overall.finish_and_clear();
        }
    }
}
