//! What the build writes per shard: its completion record ([`CompletionRecord`], the
//! proof that the shard is finished) and its timing ([`ShardTiming`], statistics outside
//! the hashed data).

use super::layout::{ensure_real_dir, TIMINGS_DIR};
use super::DatasetDir;
use crate::{FormatError, ShardRecord};
use bettimill_shard as shard;
use serde::{Deserialize, Serialize};

/// When and how long a shard took to build, written by the process that built it to
/// `DIR/timings/NAME.json` after its record. Outside the hashed data on purpose (times are
/// never the same twice); `bettimill stats` reports the build time from these files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardTiming {
    /// When the shard's first sample was started, in seconds since the Unix epoch.
    pub started_unix: f64,
    /// Seconds from then until its record was written.
    pub seconds: f64,
    /// Samples in the shard.
    pub samples: u64,
}

/// A shard's completion record (`DIR/records/NAME.json`): its storage record (with every
/// member's offset, size and hash) plus build statistics.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompletionRecord {
    /// The shard's storage record.
    pub shard: ShardRecord,
    /// Rejected attempts (regenerations) per stratum label, sorted by label.
    pub regenerations: Vec<(String, u64)>,
}

impl ShardTiming {
    /// A timing file's bytes read, `None` when they are not a timing with finite times.
    pub fn from_json(bytes: &[u8]) -> Option<ShardTiming> {
        let timing: ShardTiming = serde_json::from_slice(bytes).ok()?;
        (timing.started_unix.is_finite() && timing.seconds.is_finite() && timing.seconds >= 0.0)
            .then_some(timing)
    }
}

impl CompletionRecord {
    /// The record's file bytes: pretty JSON and a newline.
    pub fn to_json_bytes(&self) -> Vec<u8> {
        let mut json = serde_json::to_vec_pretty(self).expect("records serialise");
        json.push(b'\n');
        json
    }
}

impl DatasetDir {
    /// Reads a shard's completion record; `Ok(None)` when there is none.
    pub fn read_record(&self, shard: &str) -> Result<Option<CompletionRecord>, FormatError> {
        let path = self.record_path(shard);
        let bytes = match std::fs::read(&path) {
            Ok(bytes) => bytes,
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(FormatError::Io { path, source }),
        };
        serde_json::from_slice(&bytes)
            .map(Some)
            .map_err(|err| FormatError::Corrupt {
                path,
                reason: format!("not a completion record: {err}"),
            })
    }

    /// Reads a shard's completion record with the blake3 of its file (what `index.json`
    /// keeps as `record_blake3`); `Ok(None)` when there is none.
    pub fn read_record_hashed(
        &self,
        shard: &str,
    ) -> Result<Option<(CompletionRecord, String)>, FormatError> {
        let path = self.record_path(shard);
        let bytes = match std::fs::read(&path) {
            Ok(bytes) => bytes,
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(FormatError::Io { path, source }),
        };
        let record = serde_json::from_slice(&bytes).map_err(|err| FormatError::Corrupt {
            path,
            reason: format!("not a completion record: {err}"),
        })?;
        Ok(Some((record, shard::blake3_hex(&bytes))))
    }

    /// Writes a shard's completion record (atomically). Write it only after its tar.
    pub fn write_record(&self, shard: &str, record: &CompletionRecord) -> Result<(), FormatError> {
        Ok(shard::write_atomic(
            &self.record_path(shard),
            &record.to_json_bytes(),
        )?)
    }

    /// Writes a shard's timing (atomically; creates `timings/`, refusing a link there).
    /// Write it after the shard's record.
    pub fn write_timing(&self, shard: &str, timing: &ShardTiming) -> Result<(), FormatError> {
        ensure_real_dir(&self.root.join(TIMINGS_DIR))?;
        let mut bytes = serde_json::to_vec_pretty(timing).expect("timings serialise");
        bytes.push(b'\n');
        Ok(shard::write_atomic(&self.timing_path(shard), &bytes)?)
    }

    /// A shard's timing, `None` when it has none or it cannot be read (a timing is
    /// statistics, never data: a shard built before timings existed, or whose builder was
    /// killed between its record and its timing, simply has none).
    pub fn read_timing(&self, shard: &str) -> Option<ShardTiming> {
        ShardTiming::from_json(&std::fs::read(self.timing_path(shard)).ok()?)
    }
}
