//! The progress display of `bettimill build`, fed by the coordinator's [`BuildEvent`]s.
//!
//! On a terminal: one bar for the samples and one line per worker (indicatif, on stderr).
//! When stderr is not a terminal (a Slurm job's log, `nohup`, CI), bars would draw nothing,
//! so a plain line is written at a steady interval instead, from a thread of its own so that
//! it keeps coming while one big sample takes minutes: samples and shards done of the total,
//! the rate, the time left and the regenerations so far. `--quiet` silences both.
//!
//! Both advance within a sample: workers report the stage each sample reaches (generate,
//! deform, hypervolume targeting, verify, each downscaled copy, encode; a few times a second
//! at most), which counts as a fraction of a sample (`3.4/8 samples`, an estimate from the
//! stage), and each worker's line, or the plain line's end, says what it is doing.

use crate::printer::Printer;
use bettimill_executor::coordinator::BuildEvent;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// What the plain progress lines report, shared with their thread.
#[derive(Default)]
struct Counts {
    samples_done: u64,
    samples_total: u64,
    shards_done: u64,
    shards_total: u64,
    regenerations: u64,
    failures: u64,
    /// What each busy worker slot is doing.
    working: BTreeMap<usize, Activity>,
}

/// The sample a worker slot is making and the stage it last reported.
#[derive(Clone, Debug)]
struct Activity {
    key: String,
    stage: String,
    attempt: u32,
    thousandths: u16,
}

impl Activity {
    /// `s000003 verify`, `s000003 generate (attempt 2)`.
    fn describe(&self) -> String {
        if self.attempt == 0 {
            format!("{} {}", self.key, self.stage)
        } else {
            format!("{} {} (attempt {})", self.key, self.stage, self.attempt + 1)
        }
    }
}

impl Counts {
    /// Samples done, in thousandths, with the in-flight fractions.
    fn thousandths(&self) -> u64 {
        self.samples_done * 1000
            + self
                .working
                .values()
                .map(|a| u64::from(a.thousandths))
                .sum::<u64>()
    }
}

/// A thread that calls `tick` with the shared state every interval until it is dropped:
/// the plain progress lines of a build, and an array task's stage lines.
pub(crate) struct Periodic<S: Send + 'static> {
    /// The state, and whether the owner has been dropped.
    shared: Arc<(Mutex<(S, bool)>, Condvar)>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl<S: Send + 'static> Periodic<S> {
    pub(crate) fn start(
        interval: Duration,
        state: S,
        tick: impl Fn(&S) + Send + 'static,
    ) -> Periodic<S> {
        let shared = Arc::new((Mutex::new((state, false)), Condvar::new()));
        let theirs = shared.clone();
        let thread = std::thread::spawn(move || {
            let (lock, wake) = &*theirs;
            let mut guard = lock.lock().unwrap_or_else(|e| e.into_inner());
            loop {
                let (next, _) = wake
                    .wait_timeout(guard, interval)
                    .unwrap_or_else(|e| e.into_inner());
                guard = next;
                if guard.1 {
                    return;
                }
                tick(&guard.0);
            }
        });
        Periodic {
            shared,
            thread: Some(thread),
        }
    }

    /// Changes the state under the lock (what `change` prints cannot interleave a tick).
    pub(crate) fn update<R>(&self, change: impl FnOnce(&mut S) -> R) -> R {
        change(&mut self.shared.0.lock().unwrap_or_else(|e| e.into_inner()).0)
    }
}

impl<S: Send + 'static> Drop for Periodic<S> {
    fn drop(&mut self) {
        self.shared.0.lock().unwrap_or_else(|e| e.into_inner()).1 = true;
        self.shared.1.notify_all();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// `progress: 120.4/9600 samples, 3/1371 shards, 1.2 samples/s, about 2.2 h left, 0
/// regenerations, 0 failed attempts, 1 min 40 s elapsed; worker 0: s000120 verify`.
fn progress_line(c: &Counts, elapsed: Duration) -> String {
    let seconds = elapsed.as_secs_f64();
    let done = c.thousandths() as f64 / 1000.0;
    let left = if done > 0.0 && (c.samples_total as f64) > done {
        let per_sample = seconds / done;
        format!(
            ", about {} left",
            human_seconds(per_sample * (c.samples_total as f64 - done))
        )
    } else {
        String::new()
    };
    let working: String = c
        .working
        .iter()
        .map(|(slot, activity)| format!("; worker {slot}: {}", activity.describe()))
        .collect();
    format!(
        "progress: {}/{} samples, {}/{} shards, {}{left}, {} regenerations, {} failed attempts, {} elapsed{working}",
        crate::progress::thousandths(c.thousandths()),
        c.samples_total,
        c.shards_done,
        c.shards_total,
        rate(c.samples_done, seconds),
        c.regenerations,
        c.failures,
        human_seconds(seconds),
    )
}

/// `1 shard`, `6 shards`.
pub(crate) fn count(n: u64, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// A sample rate a person can read: `31.4 samples/s`, `0.52 samples/s`, `77 s per sample`,
/// or `no sample built yet`.
pub(crate) fn rate(samples: u64, seconds: f64) -> String {
    if samples == 0 || seconds <= 0.0 {
        return "no sample built yet".to_string();
    }
    rate_per_second(samples as f64 / seconds)
}

/// [`rate`] from samples per second (`no sample built yet` when not positive).
pub(crate) fn rate_per_second(per_second: f64) -> String {
    if !(per_second.is_finite() && per_second > 0.0) {
        return "no sample built yet".to_string();
    }
    if per_second >= 100.0 {
        format!("{per_second:.0} samples/s")
    } else if per_second >= 1.0 {
        format!("{per_second:.1} samples/s")
    } else if per_second >= 0.1 {
        format!("{per_second:.2} samples/s")
    } else {
        format!("{:.0} s per sample", 1.0 / per_second)
    }
}

/// `42 s`, `3 min 5 s`, `2.2 h`.
pub(crate) fn human_seconds(seconds: f64) -> String {
    if seconds < 9.95 {
        format!("{seconds:.1} s")
    } else if seconds < 60.0 {
        format!("{seconds:.0} s")
    } else if seconds < 3600.0 {
        format!(
            "{} min {} s",
            (seconds / 60.0) as u64,
            (seconds % 60.0) as u64
        )
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

/// Progress bars for a build.
pub(crate) struct Display {
    multi: MultiProgress,
    /// Counts thousandths of samples.
    overall: Option<ProgressBar>,
    slots: Vec<ProgressBar>,
    /// Each slot's current shard, and what it is doing in it.
    shards: Vec<String>,
    working: Vec<Option<Activity>>,
    samples_done: u64,
    regenerations: u64,
    failures: u64,
    printer: Printer,
    /// Worker processes (or 0 for an in-process build), for the closing summary.
    pub(crate) workers: usize,
    /// The plain progress lines (when stderr is not a terminal and not `--quiet`), written
    /// by their own thread every interval.
    plain: Option<Periodic<Counts>>,
}

impl Display {
    /// A display; `interval` is the time between plain progress lines (used when stderr is
    /// not a terminal).
    pub(crate) fn new(printer: Printer, interval: Duration) -> Display {
        let plain = printer.plain_progress().then(|| {
            let started = Instant::now();
            Periodic::start(interval, Counts::default(), move |counts| {
                printer.note(progress_line(counts, started.elapsed()));
            })
        });
        Display {
            multi: MultiProgress::with_draw_target(printer.draw_target()),
            overall: None,
            slots: Vec::new(),
            shards: Vec::new(),
            working: Vec::new(),
            samples_done: 0,
            regenerations: 0,
            failures: 0,
            printer,
            workers: 0,
            plain,
        }
    }

    fn count(&self, change: impl FnOnce(&mut Counts)) {
        if let Some(plain) = &self.plain {
            plain.update(change);
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
                samples,
                workers,
            } => {
                self.workers = workers;
                self.count(|c| {
                    c.samples_total = samples;
                    c.shards_total = shards;
                });
                let overall = self.multi.add(ProgressBar::new(samples * 1000));
                overall.set_style(crate::progress::thousandths_style("samples"));
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
                    self.shards.push(String::new());
                    self.working.push(None);
                }
            }
            BuildEvent::ShardSkipped { samples, .. } => {
                // The totals are of what this run builds: a shard found complete leaves them.
                self.count(|c| {
                    c.samples_total = c.samples_total.saturating_sub(samples);
                    c.shards_total = c.shards_total.saturating_sub(1);
                });
                if let Some(overall) = &self.overall {
                    overall
                        .set_length(overall.length().unwrap_or(0).saturating_sub(samples * 1000));
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
                    bar.set_message(shard.clone());
                }
                if let Some(current) = self.shards.get_mut(slot) {
                    *current = shard;
                }
            }
            BuildEvent::Stage {
                slot,
                key,
                attempt,
                stage,
                thousandths,
            } => {
                let activity = Activity {
                    key,
                    stage: stage.to_string(),
                    attempt,
                    thousandths,
                };
                if let Some(bar) = self.slots.get(slot) {
                    bar.set_message(format!(
                        "{} {}",
                        self.shards.get(slot).map_or("", String::as_str),
                        activity.describe()
                    ));
                }
                self.count(|c| {
                    c.working.insert(slot, activity.clone());
                });
                if let Some(working) = self.working.get_mut(slot) {
                    *working = Some(activity);
                }
                self.advance();
            }
            BuildEvent::Sample {
                slot,
                regenerations,
            } => {
                self.regenerations += u64::from(regenerations);
                self.samples_done += 1;
                self.count(|c| {
                    c.samples_done += 1;
                    c.regenerations += u64::from(regenerations);
                    c.working.remove(&slot);
                });
                if let Some(working) = self.working.get_mut(slot) {
                    *working = None;
                }
                if let Some(bar) = self.slots.get(slot) {
                    bar.inc(1);
                    bar.set_message(self.shards.get(slot).cloned().unwrap_or_default());
                }
                self.advance();
                if let Some(overall) = &self.overall {
                    overall.set_message(self.message());
                }
            }
            BuildEvent::ShardDone { slot, shard } => {
                self.count(|c| c.shards_done += 1);
                if let Some(bar) = self.slots.get(slot) {
                    bar.set_message(format!("{shard} done"));
                }
            }
            BuildEvent::ShardFailed {
                slot,
                shard,
                samples_lost,
                reason,
                failures,
                given_up,
            } => {
                self.failures += 1;
                self.samples_done = self.samples_done.saturating_sub(samples_lost);
                self.count(|c| {
                    c.failures += 1;
                    c.samples_done = c.samples_done.saturating_sub(samples_lost);
                    c.working.remove(&slot);
                });
                if let Some(working) = self.working.get_mut(slot) {
                    *working = None;
                }
                self.advance();
                if let Some(overall) = &self.overall {
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

    /// Puts the overall bar at the samples done and the in-flight fractions.
    fn advance(&self) {
        if let Some(overall) = &self.overall {
            let in_flight: u64 = self
                .working
                .iter()
                .flatten()
                .map(|a| u64::from(a.thousandths))
                .sum();
            overall.set_position(self.samples_done * 1000 + in_flight);
        }
    }

    /// A line above the bars, or on stderr when bars are hidden (never with --quiet).
    pub(crate) fn note(&self, line: String) {
        // With --quiet the bars are hidden too, and the note says nothing.
        if self.multi.is_hidden() {
            self.printer.note(line);
        } else {
            let _ = self.multi.println(line);
        }
    }

    pub(crate) fn finish(&mut self) {
        // Stops the plain lines' thread before the summary is printed.
        self.plain = None;
        for bar in &self.slots {
            bar.finish_and_clear();
        }
        if let Some(overall) = &self.overall {
            overall.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_and_durations_read_sensibly() {
        assert_eq!(rate(0, 0.2), "no sample built yet");
        assert_eq!(rate(314, 10.0), "31.4 samples/s");
        assert_eq!(rate(52, 100.0), "0.52 samples/s");
        assert_eq!(rate(4, 308.0), "77 s per sample");
        assert_eq!(rate(5000, 10.0), "500 samples/s");
        assert_eq!(human_seconds(42.4), "42 s");
        assert_eq!(human_seconds(0.33), "0.3 s");
        assert_eq!(human_seconds(9.96), "10 s");
        assert_eq!(human_seconds(185.0), "3 min 5 s");
        let line = progress_line(
            &Counts {
                samples_done: 10,
                samples_total: 40,
                shards_done: 1,
                shards_total: 4,
                ..Counts::default()
            },
            Duration::from_secs(20),
        );
        assert_eq!(
            line,
            "progress: 10/40 samples, 1/4 shards, 0.50 samples/s, about 1 min 0 s left, 0 regenerations, 0 failed attempts, 20 s elapsed"
        );
    }

    #[test]
    fn in_flight_samples_count_as_fractions_and_say_their_stage() {
        let activity = |key: &str, stage: &str, attempt, thousandths| Activity {
            key: key.to_string(),
            stage: stage.to_string(),
            attempt,
            thousandths,
        };
        let counts = Counts {
            samples_done: 3,
            samples_total: 8,
            working: BTreeMap::from([
                (0, activity("s000003", "verify", 0, 300)),
                (1, activity("s000004", "generate", 2, 150)),
            ]),
            ..Counts::default()
        };
        assert_eq!(counts.thousandths(), 3450);
        let line = progress_line(&counts, Duration::from_secs(30));
        assert!(
            line.starts_with(
                "progress: 3.4/8 samples, 0/0 shards, 0.10 samples/s, about 40 s left, "
            ),
            "{line}"
        );
        assert!(
            line.ends_with(
                " elapsed; worker 0: s000003 verify; worker 1: s000004 generate (attempt 3)"
            ),
            "{line}"
        );
        // A sample 99.9% done is not shown as done.
        assert_eq!(crate::progress::thousandths(999), "0.9");
        assert_eq!(crate::progress::thousandths(1000), "1");
        assert_eq!(crate::progress::thousandths(12_340), "12.3");
    }

    /// A quiet display of a one-worker build that has started.
    fn started(shards: u64, samples: u64) -> Display {
        let mut display = Display::new(Printer::new(true), Duration::from_secs(60));
        display.event(BuildEvent::Started {
            shards,
            samples,
            workers: 1,
        });
        display
    }

    #[test]
    fn the_bar_advances_within_a_sample() {
        use bettimill_executor::protocol::Stage;
        let mut display = started(1, 2);
        let position = |d: &Display| d.overall.as_ref().unwrap().position();
        assert_eq!(position(&display), 0);
        display.event(BuildEvent::Stage {
            slot: 0,
            key: "s000000".into(),
            attempt: 0,
            stage: Stage::Verify,
            thousandths: 300,
        });
        assert_eq!(position(&display), 300);
        display.event(BuildEvent::Sample {
            slot: 0,
            regenerations: 0,
        });
        assert_eq!(position(&display), 1000);
        display.event(BuildEvent::Stage {
            slot: 0,
            key: "s000001".into(),
            attempt: 0,
            stage: Stage::Encode,
            thousandths: 900,
        });
        assert_eq!(position(&display), 1900);
        // A failed attempt takes back its samples and its in-flight fraction.
        display.event(BuildEvent::ShardFailed {
            slot: 0,
            shard: "x-000000".into(),
            samples_lost: 1,
            reason: "test".into(),
            failures: 1,
            given_up: false,
        });
        assert_eq!(position(&display), 0);
    }

    #[test]
    fn shards_found_complete_leave_the_totals() {
        let mut display = started(3, 6);
        let length = |d: &Display| d.overall.as_ref().unwrap().length();
        assert_eq!(length(&display), Some(6000));
        display.event(BuildEvent::ShardSkipped {
            shard: "x-000000".into(),
            samples: 2,
        });
        assert_eq!(length(&display), Some(4000));
    }
}
