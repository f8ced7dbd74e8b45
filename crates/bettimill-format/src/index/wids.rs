//! The wids shard index.
//!
//! [`wids_index`] writes the `wids-shard-index-v1` JSON that `wids.ShardListDataset` opens:
//! `{"__kind__": "wids-shard-index-v1", "wids_version": 1, "name": ..., "shardlist":
//! [{"url": ..., "nsamples": ..., "filesize": ...}]}`. URLs are the shard names relative to
//! the dataset directory, so the index file belongs in that directory.

use super::stream::StreamedObject;
use super::IndexShard;
use serde::Serialize;
use std::io::Write;

#[derive(Serialize)]
struct WidsHead<'a> {
    #[serde(rename = "__kind__")]
    kind: &'static str,
    wids_version: u32,
    name: &'a str,
}

#[derive(Serialize)]
struct WidsShard<'a> {
    url: &'a str,
    nsamples: u64,
    filesize: u64,
}

/// Writes a `wids-shard-index-v1` file one shard at a time (see [`wids_index`]).
pub struct WidsWriter<W: Write> {
    inner: StreamedObject<W>,
}

impl<W: Write> WidsWriter<W> {
    /// Writes the head of the index of split `name`.
    pub fn new(out: W, name: &str) -> std::io::Result<Self> {
        let head = WidsHead {
            kind: "wids-shard-index-v1",
            wids_version: 1,
            name,
        };
        Ok(WidsWriter {
            inner: StreamedObject::new(out, &head, "shardlist")?,
        })
    }

    /// Appends a shard (`url` relative to the dataset directory).
    pub fn push(&mut self, url: &str, nsamples: u64, filesize: u64) -> std::io::Result<()> {
        self.inner.push(&WidsShard {
            url,
            nsamples,
            filesize,
        })
    }

    /// Closes the file's JSON, flushes and returns the output.
    pub fn finish(self) -> std::io::Result<W> {
        self.inner.finish::<()>(None)
    }
}

/// The `wids-shard-index-v1` JSON (pretty, trailing newline) listing `shards` in order,
/// with URLs relative to the dataset directory. Pass the shards of one split.
pub fn wids_index(name: &str, shards: &[IndexShard]) -> Vec<u8> {
    let mut writer = WidsWriter::new(Vec::new(), name).expect("writing to memory cannot fail");
    for s in shards {
        writer
            .push(&s.name, s.samples, s.bytes)
            .expect("writing to memory cannot fail");
    }
    writer.finish().expect("writing to memory cannot fail")
}
