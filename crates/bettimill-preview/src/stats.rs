//! Dataset statistics from labels and completion records, as data, text and a chart.
//!
//! Everything is counted in `BTreeMap`s, so the JSON and the text are in a fixed order and
//! equal datasets give equal output.

use crate::canvas::{Canvas, BAR, FRAME, INK, MUTED, PAGE};
use crate::font;
use crate::render::betti_text;
use crate::PreviewError;
use bettimill_format::{CompletionRecord, Label, Pooling};
use serde::Serialize;
use std::collections::BTreeMap;

/// Number of bins of the hypervolume histogram.
pub const HISTOGRAM_BINS: usize = 16;

/// The value of [`BuildTime::source`].
pub const BUILD_TIME_SOURCE: &str = bettimill_format::dir::TIMINGS_SOURCE;

/// How long the build took, from the timings the builds recorded (`DIR/timings/NAME.json`:
/// when each shard was started and how long it took), never from file modification times
/// (a no-op resume or a copy would move those). Shards built before timings were recorded,
/// or whose builder died between record and timing, are not counted.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BuildTime {
    /// Seconds during which at least one shard was being built (the union of the shards'
    /// intervals: pauses between resumed builds are not counted).
    pub wall_seconds: f64,
    /// The shards' seconds added up (with N workers, up to N times `wall_seconds`).
    pub worker_seconds: f64,
    /// When the first timed shard was started, in seconds since the Unix epoch.
    pub start_unix: f64,
    /// When the last timed shard was finished, in seconds since the Unix epoch.
    pub end_unix: f64,
    /// Shards with a timing.
    pub shards_timed: u64,
    /// Samples in them.
    pub samples_timed: u64,
    /// `samples_timed / wall_seconds` (`None` when `wall_seconds` is zero).
    pub samples_per_second: Option<f64>,
    /// Whether the dataset is finished (index.json written).
    pub finished: bool,
    /// Always [`BUILD_TIME_SOURCE`], so a reader of the JSON knows what the times are.
    pub source: String,
}

impl BuildTime {
    /// The build time of shards timed as (started, seconds, samples); `None` without a
    /// single usable timing.
    pub fn from_timings(timings: &[(f64, f64, u64)], finished: bool) -> Option<BuildTime> {
        let mut spans: Vec<(f64, f64)> = timings
            .iter()
            .filter(|(start, seconds, _)| {
                start.is_finite() && seconds.is_finite() && *seconds >= 0.0
            })
            .map(|&(start, seconds, _)| (start, start + seconds))
            .collect();
        if spans.is_empty() {
            return None;
        }
        spans.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let mut wall_seconds = 0.0;
        let (mut from, mut to) = spans[0];
        for &(start, end) in &spans[1..] {
            if start > to {
                wall_seconds += to - from;
                (from, to) = (start, end);
            } else {
                to = to.max(end);
            }
        }
        wall_seconds += to - from;
        let end_unix = spans.iter().map(|s| s.1).fold(f64::MIN, f64::max);
        let samples_timed: u64 = timings.iter().map(|t| t.2).sum();
        Some(BuildTime {
            wall_seconds,
            worker_seconds: timings.iter().map(|t| t.1).sum(),
            start_unix: spans[0].0,
            end_unix,
            shards_timed: timings.len() as u64,
            samples_timed,
            samples_per_second: (wall_seconds > 0.0).then(|| samples_timed as f64 / wall_seconds),
            finished,
            source: BUILD_TIME_SOURCE.to_string(),
        })
    }

    /// One line for the text report, saying where the times come from.
    pub fn to_text(&self, shards: u64) -> String {
        let rate = match self.samples_per_second {
            Some(rate) => format!("{rate:.2} samples/s"),
            None => "samples/s unknown".to_string(),
        };
        let what = if self.finished {
            "build time"
        } else {
            "build time so far (not finished)"
        };
        let untimed = shards.saturating_sub(self.shards_timed);
        let missing = if untimed == 0 {
            String::new()
        } else {
            format!(
                "; {untimed} shard{} without a timing not counted",
                if untimed == 1 { "" } else { "s" }
            )
        };
        format!(
            "{what}: {:.1} s wall, {rate} ({:.1} s of shard building in all)\n  from timings/ ({} of {shards} shards, {} samples, recorded by the builds{missing}); pauses between resumed builds are not counted\n",
            self.wall_seconds, self.worker_seconds, self.shards_timed, self.samples_timed
        )
    }
}

/// Regeneration counts of one class.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Regeneration {
    /// Samples of the class.
    pub samples: u64,
    /// Samples whose first attempt was rejected (`attempt > 0`).
    pub regenerated: u64,
    /// `regenerated / samples`.
    pub rate: f64,
    /// Rejected attempts in all (the sum of `attempt`).
    pub rejected_attempts: u64,
}

/// A histogram of foreground voxel counts: `counts[k]` samples lie in
/// `[edges[k], edges[k + 1])` (the last bin includes its upper edge).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Histogram {
    /// Bin edges, one more than bins.
    pub edges: Vec<u64>,
    /// Samples per bin.
    pub counts: Vec<u64>,
}

/// How many downscaled copies of one side length kept their topology.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Preservation {
    /// Copies of this side.
    pub copies: u64,
    /// Copies whose Betti numbers equal the full-resolution sample's.
    pub preserved: u64,
    /// `preserved / copies`.
    pub fraction: f64,
    /// Copies per pooling rule (`foreground_any`, `background_any`).
    pub pooling: BTreeMap<String, u64>,
}

/// Everything `bettimill stats` reports.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Stats {
    /// Samples counted.
    pub samples: u64,
    /// Shards read.
    pub shards: u64,
    /// Samples per split.
    pub splits: BTreeMap<String, u64>,
    /// Samples per Betti vector (`[b0, b1, ...]`).
    pub betti: BTreeMap<String, u64>,
    /// Samples per class label.
    pub classes: BTreeMap<String, u64>,
    /// Samples per construction family.
    pub families: BTreeMap<String, u64>,
    /// Samples per mode.
    pub modes: BTreeMap<String, u64>,
    /// Samples per component count.
    pub components: BTreeMap<u64, u64>,
    /// Samples per knot or link type.
    pub knot_types: BTreeMap<String, u64>,
    /// Samples per declared hypervolume bin (`[lo, hi]`), when the manifest bins.
    pub hypervolume_bins: BTreeMap<String, u64>,
    /// Smallest foreground voxel count.
    pub hypervolume_min: u64,
    /// Largest foreground voxel count.
    pub hypervolume_max: u64,
    /// Mean foreground voxel count.
    pub hypervolume_mean: f64,
    /// Histogram of foreground voxel counts.
    pub hypervolume_histogram: Histogram,
    /// Regenerations per class label, from the labels' `attempt`.
    pub regeneration: BTreeMap<String, Regeneration>,
    /// Rejected attempts per class label, from the completion records.
    pub record_regenerations: BTreeMap<String, u64>,
    /// Downscaled copies per side length: how many there are and how many kept every Betti
    /// number (`preserved` in their labels).
    pub resolutions: BTreeMap<u32, Preservation>,
    /// The build's wall-clock span from file modification times (`None` when the times
    /// are not available); set by the caller, which does the file I/O.
    pub build_time: Option<BuildTime>,
}

impl Stats {
    /// Counts `labels` (each with its split) and `records`.
    pub fn collect(labels: &[(String, Label)], records: &[CompletionRecord], shards: u64) -> Stats {
        let mut stats = Stats {
            samples: labels.len() as u64,
            shards,
            ..Stats::default()
        };
        for (split, label) in labels {
            *stats.splits.entry(split.clone()).or_default() += 1;
            *stats.betti.entry(betti_text(&label.betti)).or_default() += 1;
            *stats.classes.entry(label.class_label.clone()).or_default() += 1;
            *stats.families.entry(label.family.clone()).or_default() += 1;
            *stats.modes.entry(label.mode.clone()).or_default() += 1;
            *stats.components.entry(label.components).or_default() += 1;
            *stats.knot_types.entry(label.knot_type.clone()).or_default() += 1;
            if let Some((lo, hi)) = label.hypervolume_bin {
                *stats
                    .hypervolume_bins
                    .entry(format!("[{lo}, {hi}]"))
                    .or_default() += 1;
            }
            for copy in &label.resolutions {
                let entry = stats.resolutions.entry(copy.side).or_default();
                entry.copies += 1;
                entry.preserved += copy.preserved as u64;
                *entry.pooling.entry(pooling_name(copy.pooling)).or_default() += 1;
            }
            let regeneration = stats
                .regeneration
                .entry(label.class_label.clone())
                .or_default();
            regeneration.samples += 1;
            regeneration.regenerated += (label.attempt > 0) as u64;
            regeneration.rejected_attempts += label.attempt as u64;
        }
        for entry in stats.resolutions.values_mut() {
            entry.fraction = entry.preserved as f64 / entry.copies as f64;
        }
        for regeneration in stats.regeneration.values_mut() {
            regeneration.rate = regeneration.regenerated as f64 / regeneration.samples as f64;
        }
        for record in records {
            for (class, n) in &record.regenerations {
                *stats.record_regenerations.entry(class.clone()).or_default() += n;
            }
        }
        let volumes: Vec<u64> = labels.iter().map(|(_, l)| l.hypervolume).collect();
        if let (Some(&min), Some(&max)) = (volumes.iter().min(), volumes.iter().max()) {
            stats.hypervolume_min = min;
            stats.hypervolume_max = max;
            stats.hypervolume_mean = volumes.iter().sum::<u64>() as f64 / volumes.len() as f64;
            stats.hypervolume_histogram = histogram(&volumes, min, max);
        }
        stats
    }

    /// A plain-text report, one table per count.
    pub fn to_text(&self) -> String {
        let mut out = format!("{} samples in {} shards\n", self.samples, self.shards);
        let mut table = |title: &str, rows: Vec<(String, String)>| {
            out.push_str(&format!("\n{title}\n"));
            let width = rows.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
            for (key, value) in rows {
                out.push_str(&format!("  {key:<width$}  {value}\n"));
            }
        };
        let counts = |map: &BTreeMap<String, u64>| -> Vec<(String, String)> {
            map.iter()
                .map(|(k, v)| (k.clone(), v.to_string()))
                .collect()
        };
        table("per split", counts(&self.splits));
        table("per betti vector", counts(&self.betti));
        table("per class", counts(&self.classes));
        table("per family", counts(&self.families));
        table("per mode", counts(&self.modes));
        table(
            "per component count",
            self.components
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
        );
        table("per knot/link type", counts(&self.knot_types));
        if !self.hypervolume_bins.is_empty() {
            table("per hypervolume bin", counts(&self.hypervolume_bins));
        }
        let h = &self.hypervolume_histogram;
        table(
            &format!(
                "hypervolume (min {}, mean {:.1}, max {})",
                self.hypervolume_min, self.hypervolume_mean, self.hypervolume_max
            ),
            h.counts
                .iter()
                .enumerate()
                .map(|(k, c)| {
                    (
                        format!("[{}, {})", h.edges[k], h.edges[k + 1]),
                        c.to_string(),
                    )
                })
                .collect(),
        );
        if !self.resolutions.is_empty() {
            table(
                "downscaled copies that keep the topology (preserved / copies, pooling)",
                self.resolutions
                    .iter()
                    .map(|(side, p)| {
                        let rules: Vec<String> =
                            p.pooling.iter().map(|(k, v)| format!("{k} {v}")).collect();
                        (
                            format!("r{side}"),
                            format!(
                                "{}/{} ({:.1}%), {}",
                                p.preserved,
                                p.copies,
                                p.fraction * 100.0,
                                rules.join(", ")
                            ),
                        )
                    })
                    .collect(),
            );
        }
        table(
            "regenerations per class (samples with attempt > 0 / samples, rejected attempts)",
            self.regeneration
                .iter()
                .map(|(k, r)| {
                    (
                        k.clone(),
                        format!(
                            "{}/{} ({:.1}%), {} rejected",
                            r.regenerated,
                            r.samples,
                            r.rate * 100.0,
                            r.rejected_attempts
                        ),
                    )
                })
                .collect(),
        );
        let total: u64 = self.record_regenerations.values().sum();
        out.push_str(&format!(
            "\nrejected attempts in completion records: {total}\n"
        ));
        match &self.build_time {
            Some(time) => out.push_str(&time.to_text(self.shards)),
            None => out.push_str(
                "build time: not available (no shard has a timing in timings/: built before \
                 timings were recorded, or the directory was copied without it)\n",
            ),
        }
        out
    }
}

/// The label spelling of a pooling rule.
fn pooling_name(pooling: Pooling) -> String {
    pooling.name().to_string()
}

fn histogram(values: &[u64], min: u64, max: u64) -> Histogram {
    let span = max - min + 1;
    let bins = (HISTOGRAM_BINS as u64).min(span);
    let width = span.div_ceil(bins);
    let edges: Vec<u64> = (0..=bins).map(|k| min + k * width).collect();
    let mut counts = vec![0u64; bins as usize];
    for &v in values {
        counts[((v - min) / width) as usize] += 1;
    }
    Histogram { edges, counts }
}

/// The chart's width in pixels.
const CHART_WIDTH: u32 = 960;
/// Height of one bar's row, in pixels.
const BAR_ROW: u32 = 24;
/// Pixels around a panel's bars: its title, its axis and their labels.
const PANEL_EXTRA: u32 = 84;
/// The font family name the chart's text is drawn in (the bundled font, registered with
/// plotters under this name).
const FAMILY: &str = "bettimill-mono";

fn colour(rgb: [u8; 3]) -> plotters::style::RGBColor {
    plotters::style::RGBColor(rgb[0], rgb[1], rgb[2])
}

fn chart_error<E: std::fmt::Display>(err: E) -> PreviewError {
    PreviewError::Chart(err.to_string())
}

/// One panel of horizontal bars, one per (label, count), under `title`.
fn bar_panel<DB: plotters::prelude::DrawingBackend>(
    area: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    rows: &[(String, u64)],
) -> Result<(), PreviewError>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    let max = rows.iter().map(|r| r.1).max().unwrap_or(0).max(1);
    let label_w = rows
        .iter()
        .map(|(l, _)| font::text_width(l, font::BODY))
        .max()
        .unwrap_or(0) as u32;
    let n = rows.len().max(1);
    // Room right of the longest bar for its count.
    let top = max + max.div_ceil(6);
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FAMILY, 17).into_font().color(&colour(INK)))
        .margin(8)
        .x_label_area_size(28)
        .y_label_area_size(label_w + 14)
        .build_cartesian_2d(0u64..top, (0..n).into_segmented())
        .map_err(chart_error)?;
    chart
        .configure_mesh()
        .disable_y_mesh()
        .light_line_style(colour(PAGE))
        .bold_line_style(colour([220, 222, 230]))
        .axis_style(colour(FRAME))
        .label_style((FAMILY, 13).into_font().color(&colour(MUTED)))
        .y_labels(n)
        .y_label_formatter(&|v| match v {
            SegmentValue::CenterOf(i) => rows.get(*i).map_or_else(String::new, |r| r.0.clone()),
            _ => String::new(),
        })
        .x_desc("samples")
        .draw()
        .map_err(chart_error)?;
    chart
        .draw_series(rows.iter().enumerate().map(|(i, (_, count))| {
            let mut bar = Rectangle::new(
                [
                    (0, SegmentValue::Exact(i)),
                    (*count, SegmentValue::Exact(i + 1)),
                ],
                colour(BAR).filled(),
            );
            bar.set_margin(3, 3, 0, 0);
            bar
        }))
        .map_err(chart_error)?;
    chart
        .draw_series(rows.iter().enumerate().map(|(i, (_, count))| {
            Text::new(
                format!(" {count}"),
                (*count, SegmentValue::CenterOf(i)),
                (FAMILY, 13).into_font().color(&colour(INK)).pos(
                    plotters::style::text_anchor::Pos::new(
                        plotters::style::text_anchor::HPos::Left,
                        plotters::style::text_anchor::VPos::Center,
                    ),
                ),
            )
        }))
        .map_err(chart_error)?;
    Ok(())
}

/// The hypervolume histogram: one bar per bin over its range of voxel counts.
fn histogram_panel<DB: plotters::prelude::DrawingBackend>(
    area: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    h: &Histogram,
) -> Result<(), PreviewError>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    let (Some(&lo), Some(&hi)) = (h.edges.first(), h.edges.last()) else {
        return Ok(());
    };
    let max = h.counts.iter().copied().max().unwrap_or(0).max(1);
    let mut chart = ChartBuilder::on(area)
        .caption(
            "hypervolume histogram (foreground voxels)",
            (FAMILY, 17).into_font().color(&colour(INK)),
        )
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(lo..hi.max(lo + 1), 0u64..max + max.div_ceil(8))
        .map_err(chart_error)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .light_line_style(colour(PAGE))
        .bold_line_style(colour([220, 222, 230]))
        .axis_style(colour(FRAME))
        .label_style((FAMILY, 13).into_font().color(&colour(MUTED)))
        .x_labels(8)
        .x_desc("foreground voxels")
        .y_desc("samples")
        .draw()
        .map_err(chart_error)?;
    chart
        .draw_series(h.counts.iter().enumerate().map(|(k, &count)| {
            let mut bar = Rectangle::new(
                [(h.edges[k], 0), (h.edges[k + 1], count)],
                colour(BAR).filled(),
            );
            bar.set_margin(0, 0, 1, 1);
            bar
        }))
        .map_err(chart_error)?;
    Ok(())
}

/// The `--plot` chart, drawn with plotters in the bundled font: bars per Betti vector, per
/// class, per split and per knot or link type, then the hypervolume histogram.
pub fn plot(stats: &Stats) -> Result<Canvas, PreviewError> {
    use plotters::prelude::*;
    plotters::style::register_font(FAMILY, FontStyle::Normal, font::FONT_BYTES)
        .map_err(|_| PreviewError::Chart("the bundled font does not load".to_string()))?;
    let to_rows = |map: &BTreeMap<String, u64>| map.iter().map(|(k, v)| (k.clone(), *v)).collect();
    let sections: Vec<(String, Vec<(String, u64)>)> = vec![
        (
            format!("{} samples per betti vector", stats.samples),
            to_rows(&stats.betti),
        ),
        ("per class".to_string(), to_rows(&stats.classes)),
        ("per split".to_string(), to_rows(&stats.splits)),
        ("per knot/link type".to_string(), to_rows(&stats.knot_types)),
    ];
    let heights: Vec<u32> = sections
        .iter()
        .map(|(_, rows)| rows.len().max(1) as u32 * BAR_ROW + PANEL_EXTRA)
        .chain([320])
        .collect();
    let height: u32 = heights.iter().sum();
    let pixels = CHART_WIDTH as usize * height as usize;
    if pixels > crate::canvas::MAX_PIXELS {
        return Err(PreviewError::TooLarge {
            width: CHART_WIDTH as usize,
            height: height as usize,
        });
    }
    let mut buffer = vec![0u8; pixels * 3];
    {
        let root =
            BitMapBackend::with_buffer(&mut buffer, (CHART_WIDTH, height)).into_drawing_area();
        root.fill(&colour(PAGE)).map_err(chart_error)?;
        let mut rest = root.clone();
        for (k, (title, rows)) in sections.iter().enumerate() {
            let (panel, below) = rest.split_vertically(heights[k]);
            bar_panel(&panel, title, rows)?;
            rest = below;
        }
        histogram_panel(&rest, &stats.hypervolume_histogram)?;
        root.present().map_err(chart_error)?;
    }
    Canvas::from_rgb(CHART_WIDTH as usize, height as usize, buffer).ok_or(PreviewError::TooLarge {
        width: CHART_WIDTH as usize,
        height: height as usize,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn label(class: &str, betti: Vec<u64>, hypervolume: u64, attempt: u32) -> Label {
        serde_json::from_value(serde_json::json!({
            "key": "k", "betti": betti, "field": "Z/2", "euler": 1, "hypervolume": hypervolume,
            "components": 1, "shape": [8, 8], "dim": 2, "mode": "embed", "family": class,
            "knot_type": "none", "class_index": 0, "class_label": class, "seed": "00",
            "attempt": attempt, "manifest_hash": "00", "tool_version": "0", "construction": {}
        }))
        .unwrap()
    }

    fn copy(side: u32, preserved: bool, pooling: &str) -> bettimill_format::ResolutionLabel {
        serde_json::from_value(serde_json::json!({
            "side": side, "pooling": pooling, "betti": [1, 0], "euler": 1, "hypervolume": 3,
            "preserved": preserved
        }))
        .unwrap()
    }

    #[test]
    fn counts_rates_and_histogram_add_up() {
        let labels = vec![
            ("train".to_string(), label("ball", vec![1, 0], 10, 0)),
            ("train".to_string(), label("ball", vec![1, 0], 20, 2)),
            ("val".to_string(), label("handle", vec![1, 1], 41, 0)),
        ];
        let records = vec![CompletionRecord {
            shard: bettimill_format::ShardRecord {
                name: "shards/t-000000.tar".into(),
                split: "train".into(),
                samples: 2,
                bytes: 1024,
                blake3: String::new(),
                first_key: "k".into(),
                last_key: "k".into(),
                members: Vec::new(),
            },
            regenerations: vec![("ball".to_string(), 2)],
        }];
        let mut labels = labels;
        labels[0].1.resolutions = vec![
            copy(4, true, "background_any"),
            copy(2, false, "background_any"),
        ];
        labels[1].1.resolutions = vec![
            copy(4, false, "background_any"),
            copy(2, false, "background_any"),
        ];
        // A label written before pooling was recorded reads as max pooling.
        labels[2].1.resolutions = vec![serde_json::from_value(serde_json::json!({
            "side": 4, "betti": [1, 1], "euler": 0, "hypervolume": 3, "preserved": true
        }))
        .unwrap()];
        let stats = Stats::collect(&labels, &records, 1);
        assert_eq!(stats.resolutions[&4].copies, 3);
        assert_eq!(stats.resolutions[&4].preserved, 2);
        assert!((stats.resolutions[&4].fraction - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(stats.resolutions[&4].pooling["background_any"], 2);
        assert_eq!(stats.resolutions[&4].pooling["foreground_any"], 1);
        assert_eq!(stats.resolutions[&2].preserved, 0);
        assert_eq!(stats.resolutions[&2].fraction, 0.0);
        let text = stats.to_text();
        assert!(
            text.contains("r4  2/3 (66.7%), background_any 2, foreground_any 1"),
            "{text}"
        );
        assert!(text.contains("r2  0/2 (0.0%), background_any 2"), "{text}");
        assert_eq!(stats.samples, 3);
        assert_eq!(stats.splits["train"], 2);
        assert_eq!(stats.betti["[1, 0]"], 2);
        assert_eq!(stats.regeneration["ball"].regenerated, 1);
        assert_eq!(stats.regeneration["ball"].rejected_attempts, 2);
        assert_eq!(stats.regeneration["ball"].rate, 0.5);
        assert_eq!(stats.record_regenerations["ball"], 2);
        assert_eq!(stats.build_time, None);
        assert!(stats.to_text().contains("build time: not available"));
        let h = &stats.hypervolume_histogram;
        assert_eq!(h.counts.iter().sum::<u64>(), 3);
        assert_eq!(h.edges[0], 10);
        assert!(*h.edges.last().unwrap() > 41);
        assert_eq!(*h.counts.last().unwrap(), 1);
        assert!(stats.to_text().contains("1/2 (50.0%), 2 rejected"));
        let png = plot(&stats).unwrap().to_png().unwrap();
        assert_eq!(png, plot(&stats).unwrap().to_png().unwrap());
    }

    #[test]
    fn build_time_from_timings_counts_overlaps_once_and_pauses_not_at_all() {
        // Two workers overlapping on [100, 104] and [102, 106], then a pause, then [200, 202].
        let timings = [(100.0, 4.0, 4), (102.0, 4.0, 4), (200.0, 2.0, 2)];
        let time = BuildTime::from_timings(&timings, true).unwrap();
        assert_eq!(time.wall_seconds, 8.0);
        assert_eq!(time.worker_seconds, 10.0);
        assert_eq!(time.samples_timed, 10);
        assert_eq!(time.samples_per_second, Some(1.25));
        assert_eq!((time.start_unix, time.end_unix), (100.0, 202.0));
        assert_eq!(time.source, BUILD_TIME_SOURCE);
        let text = time.to_text(3);
        assert!(
            text.starts_with("build time: 8.0 s wall, 1.25 samples/s"),
            "{text}"
        );
        assert!(text.contains("from timings/ (3 of 3 shards"), "{text}");
        assert!(time.to_text(5).contains("2 shards without a timing"));
        let unfinished = BuildTime::from_timings(&[(100.0, 0.0, 1)], false).unwrap();
        assert_eq!(unfinished.samples_per_second, None);
        assert!(unfinished.to_text(1).contains("not finished"));
        assert_eq!(BuildTime::from_timings(&[], true), None);
        assert_eq!(BuildTime::from_timings(&[(f64::NAN, 1.0, 1)], true), None);
    }

    #[test]
    fn histogram_of_one_value_has_one_bin() {
        let h = histogram(&[5, 5], 5, 5);
        assert_eq!(h.edges, vec![5, 6]);
        assert_eq!(h.counts, vec![2]);
    }
}
