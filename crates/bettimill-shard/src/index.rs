//! The dataset index (`index.json`), shard records, and the wids shard index.
//!
//! # `index.json`
//!
//! A JSON object with keys in this order: `format` (always `"bettimill-index"`),
//! `format_version` ([`INDEX_FORMAT_VERSION`]), `tool_version`, `manifest_hash`,
//! `plan_hash`, `shard_count`, `samples`, `shards`, `files`. `files` ([`IndexFile`]) lists
//! every other file of the directory the build wrote (manifest, identity, class table,
//! dataset card, wids indexes) with its size and blake3, sorted by name, so that
//! [`crate::verify()`] covers every byte a build writes; it comes after `shards` so that the
//! wids indexes, written while the shards are listed, can be in it. Each entry of `shards`
//! ([`IndexShard`]) holds `name` (path relative to the dataset directory, always under
//! `shards/`), `split`, `samples`, `bytes`, `blake3` (hex of the whole tar), `first_key`,
//! `last_key` and `record_blake3` (hex of the shard's completion record file, which holds
//! the per-member records: `name`, `offset` of its first data byte in the tar, `bytes`,
//! `blake3` of its data). So the index grows with shards, not with members.
//! Written pretty-printed with two-space indentation and a trailing newline, keys in
//! declaration order, so equal indexes are equal bytes; [`IndexWriter`] writes it one shard
//! at a time and [`read_index`] reads it one shard at a time, so neither holds the list.
//!
//! Format version 1 (bettimill 0.1.0 before this change) listed every member in the index
//! instead (about 590 bytes per sample); version 2 had no `files`. Both are refused with a
//! message saying so (`bettimill finalize DIR` rewrites the index from the records).
//!
//! Invariants checked while reading (an index breaking them is refused, because
//! [`crate::verify()`] and readers join shard names onto the dataset directory): the format
//! name and version match, shard names are unique, relative, under `shards/` and free of
//! `..`, `shard_count` and `samples` add up, and `files` names at most [`MAX_INDEX_FILES`]
//! distinct plain file names of the directory itself (not `index.json`).
//!
//! # wids index
//!
//! [`wids_index`] writes the `wids-shard-index-v1` JSON that `wids.ShardListDataset` opens:
//! `{"__kind__": "wids-shard-index-v1", "wids_version": 1, "name": ..., "shardlist":
//! [{"url": ..., "nsamples": ..., "filesize": ...}]}`. URLs are the shard names relative to
//! the dataset directory, so the index file belongs in that directory.

use crate::ustar::{self, split_key, Member, BLOCK};
use crate::ShardError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::io::Write;
use std::path::Path;

/// Value of [`Index::format`].
pub const INDEX_FORMAT: &str = "bettimill-index";
/// Value of [`Index::format_version`] written by this version.
pub const INDEX_FORMAT_VERSION: u32 = 3;
/// Most entries `files` may hold (a dataset has a few files besides its shards and records:
/// one wids index per split).
pub const MAX_INDEX_FILES: usize = 4096;

/// A file of the dataset directory other than shards and records, as `index.json` lists it.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct IndexFile {
    /// File name, relative to the dataset directory (no directory part).
    pub name: String,
    /// Its size.
    pub bytes: u64,
    /// BLAKE3 of the whole file, lowercase hex.
    pub blake3: String,
}

/// Where one member's data sits in its shard, and its hash.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct MemberRecord {
    /// Name inside the tar.
    pub name: String,
    /// Offset of the member's first data byte in the tar (its header is 512 bytes before).
    pub offset: u64,
    /// Length of the member's data.
    pub bytes: u64,
    /// BLAKE3 of the member's data, lowercase hex.
    pub blake3: String,
}

/// One shard file of the dataset, with every member: the record a shard's completion record
/// holds, and what [`crate::verify()`] checks a tar against.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ShardRecord {
    /// Path relative to the dataset directory, such as `shards/train-000000.tar`.
    pub name: String,
    /// The split the shard belongs to (`train`, `val`, ...).
    pub split: String,
    /// Number of samples (runs of members sharing a key).
    pub samples: u64,
    /// Size of the tar file.
    pub bytes: u64,
    /// BLAKE3 of the whole tar file, lowercase hex.
    pub blake3: String,
    /// Key of the first sample.
    pub first_key: String,
    /// Key of the last sample.
    pub last_key: String,
    /// Every member, in tar order.
    pub members: Vec<MemberRecord>,
}

impl ShardRecord {
    /// The shard's entry in `index.json`, given the blake3 of its record file.
    pub fn index_entry(&self, record_blake3: impl Into<String>) -> IndexShard {
        IndexShard {
            name: self.name.clone(),
            split: self.split.clone(),
            samples: self.samples,
            bytes: self.bytes,
            blake3: self.blake3.clone(),
            first_key: self.first_key.clone(),
            last_key: self.last_key.clone(),
            record_blake3: record_blake3.into(),
        }
    }

    /// How this record disagrees with an index entry (everything but `record_blake3`).
    pub fn disagreement(&self, entry: &IndexShard) -> Option<String> {
        let mine = self.index_entry(entry.record_blake3.clone());
        (mine != *entry).then(|| {
            format!(
                "the index says {} samples, {} bytes, blake3 {}, keys {}..{} in split {}; its record says {} samples, {} bytes, blake3 {}, keys {}..{} in split {}",
                entry.samples, entry.bytes, entry.blake3, entry.first_key, entry.last_key, entry.split,
                self.samples, self.bytes, self.blake3, self.first_key, self.last_key, self.split,
            )
        })
    }
}

/// One shard in `index.json`: its file and the hash of its record (members are in the
/// record, not here).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct IndexShard {
    /// Path relative to the dataset directory, such as `shards/train-000000.tar`.
    pub name: String,
    /// The split the shard belongs to.
    pub split: String,
    /// Number of samples.
    pub samples: u64,
    /// Size of the tar file.
    pub bytes: u64,
    /// BLAKE3 of the whole tar file, lowercase hex.
    pub blake3: String,
    /// Key of the first sample.
    pub first_key: String,
    /// Key of the last sample.
    pub last_key: String,
    /// BLAKE3 of the shard's completion record file (which lists every member), lowercase hex.
    pub record_blake3: String,
}

/// Everything in `index.json` before the list of shards.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
pub struct IndexHeader {
    /// Always [`INDEX_FORMAT`].
    pub format: String,
    /// [`INDEX_FORMAT_VERSION`] when written by this version.
    pub format_version: u32,
    /// Version of the bettimill that wrote the dataset.
    pub tool_version: String,
    /// Hash of the manifest the dataset was built from.
    pub manifest_hash: String,
    /// Hash of the build plan.
    pub plan_hash: String,
    /// Number of shards listed.
    pub shard_count: u64,
    /// Samples in all shards.
    pub samples: u64,
    /// Every other file of the directory, sorted by name (written after `shards`).
    #[serde(skip)]
    pub files: Vec<IndexFile>,
}

impl IndexHeader {
    /// A header of the current format.
    pub fn new(
        tool_version: impl Into<String>,
        manifest_hash: impl Into<String>,
        plan_hash: impl Into<String>,
        shard_count: u64,
        samples: u64,
    ) -> IndexHeader {
        IndexHeader {
            format: INDEX_FORMAT.to_string(),
            format_version: INDEX_FORMAT_VERSION,
            tool_version: tool_version.into(),
            manifest_hash: manifest_hash.into(),
            plan_hash: plan_hash.into(),
            shard_count,
            samples,
            files: Vec::new(),
        }
    }

    /// The header listing `files` (sorted here by name).
    pub fn with_files(mut self, mut files: Vec<IndexFile>) -> IndexHeader {
        files.sort_by(|a, b| a.name.cmp(&b.name));
        self.files = files;
        self
    }
}

/// The contents of `index.json`, held in memory: for tests and small datasets. Large ones
/// are written with [`IndexWriter`] and read with [`read_index`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Index {
    /// Everything but the shards.
    pub header: IndexHeader,
    /// Every shard, in the order the build wrote them.
    pub shards: Vec<IndexShard>,
}

impl Index {
    /// An index of the current format with the given shards.
    pub fn new(
        tool_version: impl Into<String>,
        manifest_hash: impl Into<String>,
        plan_hash: impl Into<String>,
        shards: Vec<IndexShard>,
    ) -> Index {
        let samples = shards.iter().map(|s| s.samples).sum();
        Index {
            header: IndexHeader::new(
                tool_version,
                manifest_hash,
                plan_hash,
                shards.len() as u64,
                samples,
            ),
            shards,
        }
    }

    /// Reads and validates an index file (see the module documentation for the checks).
    pub fn read(path: &Path) -> Result<Index, ShardError> {
        let mut shards = Vec::new();
        let header = read_index(path, &mut |_, shard| {
            shards.push(shard);
            Ok(())
        })?;
        Ok(Index { header, shards })
    }

    /// Parses and validates index bytes; `path` is only used in error messages.
    pub fn from_json_bytes(bytes: &[u8], path: &Path) -> Result<Index, ShardError> {
        let mut shards = Vec::new();
        let header = read_index_from(bytes, path, &mut |_, shard| {
            shards.push(shard);
            Ok(())
        })?;
        Ok(Index { header, shards })
    }

    /// Pretty JSON with keys in declaration order and a trailing newline (what
    /// [`IndexWriter`] writes for the same shards).
    pub fn to_json_bytes(&self) -> Vec<u8> {
        let mut writer =
            IndexWriter::new(Vec::new(), &self.header).expect("writing to memory cannot fail");
        for shard in &self.shards {
            writer.push(shard).expect("writing to memory cannot fail");
        }
        writer.finish().expect("writing to memory cannot fail")
    }

    /// The shards of one split, in index order.
    pub fn split_shards(&self, split: &str) -> Vec<IndexShard> {
        self.shards
            .iter()
            .filter(|s| s.split == split)
            .cloned()
            .collect()
    }

    /// The distinct split names, sorted.
    pub fn splits(&self) -> Vec<String> {
        let set: BTreeSet<&str> = self.shards.iter().map(|s| s.split.as_str()).collect();
        set.into_iter().map(str::to_string).collect()
    }
}

/// Writes a pretty JSON object whose last key is a list, one element at a time, in the
/// exact bytes of `serde_json::to_vec_pretty` plus a trailing newline.
struct StreamedObject<W: Write> {
    out: W,
    elements: u64,
}

impl<W: Write> StreamedObject<W> {
    /// Writes `{`, the fields of `head` (a struct serialising to an object) and the opening
    /// of the list `key`.
    fn new<T: Serialize>(mut out: W, head: &T, key: &str) -> std::io::Result<Self> {
        let head = serde_json::to_string_pretty(head).expect("index types serialise");
        let body = head
            .strip_suffix('}')
            .expect("a struct serialises to an object")
            .trim_end();
        out.write_all(body.as_bytes())?;
        out.write_all(format!(",\n  {}: [", serde_json::Value::from(key)).as_bytes())?;
        Ok(StreamedObject { out, elements: 0 })
    }

    fn push<T: Serialize>(&mut self, element: &T) -> std::io::Result<()> {
        let text = serde_json::to_string_pretty(element).expect("index types serialise");
        self.out
            .write_all(if self.elements == 0 { b"\n" } else { b",\n" })?;
        for (n, line) in text.lines().enumerate() {
            if n > 0 {
                self.out.write_all(b"\n")?;
            }
            self.out.write_all(b"    ")?;
            self.out.write_all(line.as_bytes())?;
        }
        self.elements += 1;
        Ok(())
    }

    /// Closes the list, writes `key: value` (pretty, indented as a field) when given, and
    /// closes the object.
    fn finish<T: Serialize>(mut self, trailer: Option<(&str, &T)>) -> std::io::Result<W> {
        if self.elements == 0 {
            self.out.write_all(b"]")?;
        } else {
            self.out.write_all(b"\n  ]")?;
        }
        if let Some((key, value)) = trailer {
            let text = serde_json::to_string_pretty(value).expect("index types serialise");
            self.out
                .write_all(format!(",\n  {}: ", serde_json::Value::from(key)).as_bytes())?;
            for (n, line) in text.lines().enumerate() {
                if n > 0 {
                    self.out.write_all(b"\n  ")?;
                }
                self.out.write_all(line.as_bytes())?;
            }
        }
        self.out.write_all(b"\n}\n")?;
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Writes `index.json` one shard at a time (the list is never held in memory).
pub struct IndexWriter<W: Write> {
    inner: StreamedObject<W>,
    files: Vec<IndexFile>,
}

impl<W: Write> IndexWriter<W> {
    /// Writes the header; `header.shard_count` and `header.samples` must be what the pushed
    /// shards add up to (readers check).
    pub fn new(out: W, header: &IndexHeader) -> std::io::Result<Self> {
        Ok(IndexWriter {
            inner: StreamedObject::new(out, header, "shards")?,
            files: header.files.clone(),
        })
    }

    /// Sets the `files` written after the shards (sorted here by name).
    pub fn set_files(&mut self, mut files: Vec<IndexFile>) {
        files.sort_by(|a, b| a.name.cmp(&b.name));
        self.files = files;
    }

    /// Appends one shard.
    pub fn push(&mut self, shard: &IndexShard) -> std::io::Result<()> {
        self.inner.push(shard)
    }

    /// Closes the list, writes `files` and closes the object, flushes and returns the
    /// output.
    pub fn finish(self) -> std::io::Result<W> {
        self.inner.finish(Some(("files", &self.files)))
    }
}

/// Reads `index.json` one shard at a time: checks the header (format name and version
/// before any shard is read), then calls `each` with every shard in order, checking names
/// and that the shards add up to the header's counts. `each` may stop the reading with a
/// reason, returned as [`ShardError::IndexFormat`]. Holds one shard and the set of names
/// seen (to refuse duplicates), never the list.
pub fn read_index(
    path: &Path,
    each: &mut dyn FnMut(&IndexHeader, IndexShard) -> Result<(), String>,
) -> Result<IndexHeader, ShardError> {
    let file = std::fs::File::open(path).map_err(|e| ShardError::io("cannot read", path, e))?;
    read_index_from(std::io::BufReader::new(file), path, each)
}

/// [`read_index`] from any reader; `path` is only used in error messages.
pub fn read_index_from(
    reader: impl std::io::Read,
    path: &Path,
    each: &mut dyn FnMut(&IndexHeader, IndexShard) -> Result<(), String>,
) -> Result<IndexHeader, ShardError> {
    let mut refusal = None;
    let mut deserializer = serde_json::Deserializer::from_reader(reader);
    let result = serde::Deserializer::deserialize_map(
        &mut deserializer,
        IndexVisitor {
            each,
            refusal: &mut refusal,
        },
    )
    .and_then(|header| deserializer.end().map(|()| header));
    match (result, refusal) {
        (_, Some(reason)) => Err(ShardError::IndexFormat {
            path: path.to_path_buf(),
            reason,
        }),
        (Ok(header), None) => Ok(header),
        (Err(source), None) => Err(ShardError::Json {
            path: path.to_path_buf(),
            source,
        }),
    }
}

/// The header fields read so far.
#[derive(Default)]
struct PartialHeader {
    format: Option<String>,
    format_version: Option<u32>,
    tool_version: Option<String>,
    manifest_hash: Option<String>,
    plan_hash: Option<String>,
    shard_count: Option<u64>,
    samples: Option<u64>,
    files: Option<Vec<IndexFile>>,
}

impl PartialHeader {
    /// The header, or why it cannot be one; the version is judged first, so an index of
    /// another format version gets a message about that, not about a missing field.
    fn complete(&self) -> Result<IndexHeader, String> {
        let format = self.format.clone().unwrap_or_default();
        if format != INDEX_FORMAT {
            return Err(format!("format is {format:?}, expected {INDEX_FORMAT:?}"));
        }
        let tool = self
            .tool_version
            .clone()
            .unwrap_or_else(|| "unknown".into());
        match self.format_version {
            Some(INDEX_FORMAT_VERSION) => {}
            Some(1) => {
                return Err(format!(
                    "format_version 1 (written by bettimill {tool}, listing every member) is not read by this bettimill, which reads version {INDEX_FORMAT_VERSION} (shards only; member hashes are in records/NAME.json); rewrite the index with `bettimill finalize DIR`, or use bettimill {tool}"
                ))
            }
            Some(2) => {
                return Err(format!(
                    "format_version 2 (written by bettimill {tool}, without the list of the directory's other files) is not read by this bettimill, which reads version {INDEX_FORMAT_VERSION}; rewrite the index with `bettimill finalize DIR` (shards and records are unchanged), or use bettimill {tool}"
                ))
            }
            Some(other) => {
                return Err(format!(
                    "format_version {other} is not supported (this bettimill reads version {INDEX_FORMAT_VERSION}); use the bettimill version that wrote it ({tool})"
                ))
            }
            None => return Err("format_version is missing".into()),
        }
        let missing = |field: &str| format!("{field} is missing");
        Ok(IndexHeader {
            format,
            format_version: INDEX_FORMAT_VERSION,
            tool_version: self
                .tool_version
                .clone()
                .ok_or_else(|| missing("tool_version"))?,
            manifest_hash: self
                .manifest_hash
                .clone()
                .ok_or_else(|| missing("manifest_hash"))?,
            plan_hash: self.plan_hash.clone().ok_or_else(|| missing("plan_hash"))?,
            shard_count: self.shard_count.ok_or_else(|| missing("shard_count"))?,
            samples: self.samples.ok_or_else(|| missing("samples"))?,
            files: Vec::new(),
        })
    }
}

fn check_files(files: &[IndexFile]) -> Result<(), String> {
    if files.len() > MAX_INDEX_FILES {
        return Err(format!(
            "files lists {} entries, at most {MAX_INDEX_FILES} are allowed",
            files.len()
        ));
    }
    for (n, file) in files.iter().enumerate() {
        let name = file.name.as_str();
        if name.is_empty()
            || name == "."
            || name == ".."
            || name == "index.json"
            || name.contains(['/', '\\'])
            || name.chars().any(char::is_control)
        {
            return Err(format!(
                "file name {name:?} is not a plain file name of the dataset directory"
            ));
        }
        if n > 0 && files[n - 1].name.as_str() >= name {
            return Err(format!(
                "files are not sorted by name, or {name:?} is listed twice"
            ));
        }
    }
    Ok(())
}

struct IndexVisitor<'a> {
    each: &'a mut dyn FnMut(&IndexHeader, IndexShard) -> Result<(), String>,
    refusal: &'a mut Option<String>,
}

impl<'de> serde::de::Visitor<'de> for IndexVisitor<'_> {
    type Value = IndexHeader;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a bettimill index object")
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<IndexHeader, A::Error> {
        use serde::de::Error;
        let mut partial = PartialHeader::default();
        let mut header: Option<IndexHeader> = None;
        let refuse = |refusal: &mut Option<String>, reason: String| {
            *refusal = Some(reason.clone());
            A::Error::custom(reason)
        };
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "format" => partial.format = Some(map.next_value()?),
                "format_version" => partial.format_version = Some(map.next_value()?),
                "tool_version" => partial.tool_version = Some(map.next_value()?),
                "manifest_hash" => partial.manifest_hash = Some(map.next_value()?),
                "plan_hash" => partial.plan_hash = Some(map.next_value()?),
                "shard_count" => partial.shard_count = Some(map.next_value()?),
                "samples" => partial.samples = Some(map.next_value()?),
                "files" => {
                    let files = map.next_value_seed(FilesSeed)?;
                    check_files(&files).map_err(|reason| refuse(self.refusal, reason))?;
                    partial.files = Some(files);
                }
                "shards" => {
                    let complete = partial
                        .complete()
                        .map_err(|reason| refuse(self.refusal, reason))?;
                    map.next_value_seed(ShardsSeed {
                        header: &complete,
                        each: &mut *self.each,
                        refusal: &mut *self.refusal,
                    })?;
                    header = Some(complete);
                }
                other => {
                    // A version-1 index has no shard_count; say "old version", not "unknown".
                    if let Err(reason) = partial.complete() {
                        return Err(refuse(self.refusal, reason));
                    }
                    return Err(A::Error::unknown_field(other, &[]));
                }
            }
        }
        match (header, partial.files.take()) {
            (Some(mut header), Some(files)) => {
                header.files = files;
                Ok(header)
            }
            (Some(_), None) => Err(refuse(self.refusal, "files is missing".into())),
            (None, _) => Err(refuse(
                self.refusal,
                partial
                    .complete()
                    .err()
                    .unwrap_or_else(|| "shards is missing".into()),
            )),
        }
    }
}

/// Reads `files`, refusing more than [`MAX_INDEX_FILES`] entries as they arrive (the list
/// is never read whole because it claims to be short).
struct FilesSeed;

impl<'de> serde::de::DeserializeSeed<'de> for FilesSeed {
    type Value = Vec<IndexFile>;

    fn deserialize<D: serde::Deserializer<'de>>(
        self,
        deserializer: D,
    ) -> Result<Self::Value, D::Error> {
        deserializer.deserialize_seq(self)
    }
}

impl<'de> serde::de::Visitor<'de> for FilesSeed {
    type Value = Vec<IndexFile>;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a list of files")
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut files = Vec::new();
        while let Some(file) = seq.next_element::<IndexFile>()? {
            if files.len() == MAX_INDEX_FILES {
                return Err(serde::de::Error::custom(format!(
                    "files lists more than {MAX_INDEX_FILES} entries"
                )));
            }
            files.push(file);
        }
        Ok(files)
    }
}

/// The most splits an index may list shards of (the plan refuses a manifest with more).
pub const MAX_INDEX_SPLITS: usize = 1024;

/// The order the index lists its shards in: the plan's, i.e. each split's shards in one
/// run, their names increasing (a shorter name first, so `NAME-999999` comes before
/// `NAME-1000000`). Checking it needs the previous name and the splits already passed,
/// not every name: a shard listed twice is found in memory that does not grow with the
/// index.
#[derive(Default)]
struct ShardOrder {
    passed: BTreeSet<String>,
    previous: Option<(String, String)>,
}

impl ShardOrder {
    fn next(&mut self, shard: &IndexShard) -> Result<(), String> {
        let name = &shard.name;
        if let Some((split, previous)) = &self.previous {
            if *split == shard.split {
                if previous == name {
                    return Err(format!("shard {name:?} is listed twice"));
                }
                if (previous.len(), previous) > (name.len(), name) {
                    return Err(format!(
                        "shard {name:?} is listed after {previous:?}: a split's shards are listed in increasing order"
                    ));
                }
            } else {
                self.passed.insert(split.clone());
                if self.passed.len() >= MAX_INDEX_SPLITS {
                    return Err(format!(
                        "shards of more than {MAX_INDEX_SPLITS} splits are listed"
                    ));
                }
                if self.passed.contains(&shard.split) {
                    return Err(format!(
                        "shard {name:?} of split {:?} is listed after another split's: each split's shards are listed together",
                        shard.split
                    ));
                }
            }
        }
        self.previous = Some((shard.split.clone(), name.clone()));
        Ok(())
    }
}

struct ShardsSeed<'a> {
    header: &'a IndexHeader,
    each: &'a mut dyn FnMut(&IndexHeader, IndexShard) -> Result<(), String>,
    refusal: &'a mut Option<String>,
}

impl<'de> serde::de::DeserializeSeed<'de> for ShardsSeed<'_> {
    type Value = ();

    fn deserialize<D: serde::Deserializer<'de>>(self, deserializer: D) -> Result<(), D::Error> {
        deserializer.deserialize_seq(self)
    }
}

impl<'de> serde::de::Visitor<'de> for ShardsSeed<'_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a list of shards")
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        use serde::de::Error;
        let mut order = ShardOrder::default();
        let (mut shards, mut samples) = (0u64, 0u64);
        let mut refuse = |reason: String| {
            *self.refusal = Some(reason.clone());
            A::Error::custom(reason)
        };
        while let Some(shard) = seq.next_element::<IndexShard>()? {
            check_shard_name(&shard.name).map_err(&mut refuse)?;
            order.next(&shard).map_err(&mut refuse)?;
            shards += 1;
            samples = samples.saturating_add(shard.samples);
            (self.each)(self.header, shard).map_err(&mut refuse)?;
        }
        if shards != self.header.shard_count || samples != self.header.samples {
            return Err(refuse(format!(
                "the index lists {shards} shards of {samples} samples, its header says {} shards of {} samples",
                self.header.shard_count, self.header.samples
            )));
        }
        Ok(())
    }
}

fn check_shard_name(name: &str) -> Result<(), String> {
    let Some(rest) = name.strip_prefix("shards/") else {
        return Err(format!("shard name {name:?} is not under shards/"));
    };
    if rest.is_empty()
        || rest
            .split('/')
            .any(|c| c.is_empty() || c == "." || c == "..")
        || name.contains('\\')
        || name.chars().any(char::is_control)
    {
        return Err(format!(
            "shard name {name:?} is not a plain relative path under shards/"
        ));
    }
    Ok(())
}

/// Lowercase hex BLAKE3 of `bytes`.
pub fn blake3_hex(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

/// Builds one shard: the tar bytes of the samples (members of each sample together, in
/// the given order) and the record describing them.
///
/// Each sample must be non-empty, its members must share one key, their fields must be in
/// strictly increasing order (sorted, no duplicates), and keys must be unique within the
/// shard, so that every WebDataset reader groups the members back into the same samples.
/// `name` must be a relative path under `shards/`.
pub fn build_shard(
    name: &str,
    split: &str,
    samples: &[Vec<Member>],
) -> Result<(Vec<u8>, ShardRecord), ShardError> {
    let bad = |sample: usize, reason: String| ShardError::BadSample {
        shard: name.to_string(),
        sample,
        reason,
    };
    check_shard_name(name).map_err(|reason| ShardError::bad_name(name, reason))?;
    if samples.is_empty() {
        return Err(bad(0, "a shard needs at least one sample".into()));
    }
    let mut keys = BTreeSet::new();
    let mut first_key = String::new();
    let mut last_key = String::new();
    for (position, sample) in samples.iter().enumerate() {
        let Some(first) = sample.first() else {
            return Err(bad(position, "sample has no members".into()));
        };
        ustar::check_member_name(&first.name)?;
        let (key, _) = split_key(&first.name).expect("checked names have a key");
        let mut previous_field: Option<&str> = None;
        for member in sample {
            ustar::check_member_name(&member.name)?;
            let (member_key, field) = split_key(&member.name).expect("checked names have a key");
            if member_key != key {
                return Err(bad(
                    position,
                    format!(
                        "member {:?} has key {member_key:?}, the sample's key is {key:?}",
                        member.name
                    ),
                ));
            }
            if let Some(previous) = previous_field {
                if field <= previous {
                    return Err(bad(
                        position,
                        format!("field {field:?} comes after {previous:?}: fields must be sorted and distinct"),
                    ));
                }
            }
            previous_field = Some(field);
        }
        if !keys.insert(key.to_string()) {
            return Err(bad(
                position,
                format!("key {key:?} appears twice in the shard"),
            ));
        }
        if position == 0 {
            first_key = key.to_string();
        }
        last_key = key.to_string();
    }
    let members: Vec<Member> = samples.iter().flatten().cloned().collect();
    let bytes = ustar::tar_bytes(&members)?;
    let mut offset = BLOCK;
    let member_records = members
        .iter()
        .map(|member| {
            let size = member.data.len() as u64;
            let record = MemberRecord {
                name: member.name.clone(),
                offset,
                bytes: size,
                blake3: blake3_hex(&member.data),
            };
            offset += size.div_ceil(BLOCK) * BLOCK + BLOCK;
            record
        })
        .collect();
    let record = ShardRecord {
        name: name.to_string(),
        split: split.to_string(),
        samples: samples.len() as u64,
        bytes: bytes.len() as u64,
        blake3: blake3_hex(&bytes),
        first_key,
        last_key,
        members: member_records,
    };
    Ok((bytes, record))
}

/// Counts samples the way WebDataset readers do: a new sample starts whenever a
/// member's key differs from the previous member's key.
pub fn count_samples<'a>(member_names: impl IntoIterator<Item = &'a str>) -> u64 {
    let mut count = 0;
    let mut previous: Option<&str> = None;
    for name in member_names {
        let key = split_key(name).map_or(name, |(key, _)| key);
        if previous != Some(key) {
            count += 1;
            previous = Some(key);
        }
    }
    count
}

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

#[cfg(test)]
mod tests {
    use super::*;

    fn to_pretty_json<T: Serialize>(value: &T) -> Vec<u8> {
        let mut out = serde_json::to_vec_pretty(value)
            .expect("index types serialise infallibly: string keys, no maps with non-string keys");
        out.push(b'\n');
        out
    }

    fn sample(key: &str, fields: &[&str]) -> Vec<Member> {
        fields
            .iter()
            .map(|f| Member::new(format!("{key}.{f}"), format!("{key}:{f}").into_bytes()))
            .collect()
    }

    #[test]
    fn record_matches_the_tar() {
        let samples = vec![
            sample("train/s1", &["cls", "json", "npy"]),
            sample("train/s2", &["cls", "json", "npy"]),
        ];
        let (bytes, record) = build_shard("shards/train-000000.tar", "train", &samples).unwrap();
        assert_eq!(record.samples, 2);
        assert_eq!(record.bytes, bytes.len() as u64);
        assert_eq!(record.first_key, "train/s1");
        assert_eq!(record.last_key, "train/s2");
        assert_eq!(record.blake3, blake3_hex(&bytes));
        let entries = ustar::tar_entries(&bytes, u64::MAX).unwrap();
        assert_eq!(entries.len(), record.members.len());
        for (entry, member) in entries.iter().zip(&record.members) {
            assert_eq!(entry.name, member.name);
            assert_eq!(entry.data_offset(), member.offset);
            assert_eq!(blake3_hex(entry.data), member.blake3);
        }
        assert_eq!(
            count_samples(record.members.iter().map(|m| m.name.as_str())),
            2
        );
    }

    #[test]
    fn badly_grouped_samples_are_refused() {
        let name = "shards/x-000000.tar";
        let check = |samples: Vec<Vec<Member>>| build_shard(name, "train", &samples);
        assert!(check(vec![]).is_err());
        assert!(check(vec![vec![]]).is_err());
        assert!(
            check(vec![sample("a", &["npy", "json"])]).is_err(),
            "unsorted"
        );
        assert!(
            check(vec![sample("a", &["json", "json"])]).is_err(),
            "duplicate"
        );
        let mut mixed = sample("a", &["json"]);
        mixed.extend(sample("b", &["npy"]));
        assert!(check(vec![mixed]).is_err(), "two keys");
        assert!(check(vec![sample("a", &["json"]), sample("a", &["npy"])]).is_err());
        assert!(build_shard("../x.tar", "t", &[sample("a", &["json"])]).is_err());
        assert!(build_shard("x.tar", "t", &[sample("a", &["json"])]).is_err());
        assert!(check(vec![sample("a", &["json"])]).is_ok());
    }

    #[test]
    fn shards_are_checked_in_plan_order_holding_one_name() {
        let shard = |split: &str, name: &str| IndexShard {
            name: name.into(),
            split: split.into(),
            samples: 1,
            bytes: 0,
            blake3: String::new(),
            first_key: String::new(),
            last_key: String::new(),
            record_blake3: String::new(),
        };
        let mut order = ShardOrder::default();
        for (split, name) in [
            ("train", "shards/d-train-999999.tar"),
            ("train", "shards/d-train-1000000.tar"),
            ("val", "shards/d-val-000000.tar"),
            ("test", "shards/d-test-000000.tar"),
        ] {
            order.next(&shard(split, name)).unwrap();
        }
        let err = order
            .next(&shard("val", "shards/d-val-000001.tar"))
            .unwrap_err();
        assert!(err.contains("listed together"), "{err}");
        let mut order = ShardOrder::default();
        order.next(&shard("train", "shards/d-000002.tar")).unwrap();
        let err = order
            .next(&shard("train", "shards/d-000001.tar"))
            .unwrap_err();
        assert!(err.contains("increasing order"), "{err}");
        let err = order
            .next(&shard("train", "shards/d-000002.tar"))
            .unwrap_err();
        assert!(err.contains("listed twice"), "{err}");
        let mut order = ShardOrder::default();
        let too_many: Result<Vec<()>, String> = (0..=MAX_INDEX_SPLITS)
            .map(|i| {
                order.next(&shard(
                    &format!("s{i}"),
                    &format!("shards/d-s{i}-000000.tar"),
                ))
            })
            .collect();
        assert!(too_many.unwrap_err().contains("splits"));
    }

    #[test]
    fn index_round_trips_and_validates() {
        let (_, record) = build_shard(
            "shards/t-000000.tar",
            "train",
            &[sample("a", &["json", "npy"])],
        )
        .unwrap();
        let (_, second) =
            build_shard("shards/t-000001.tar", "val", &[sample("b", &["json"])]).unwrap();
        let entry = record.index_entry("ab".repeat(32));
        let mut index = Index::new(
            "0.1.0",
            "m",
            "p",
            vec![entry.clone(), second.index_entry("cd".repeat(32))],
        );
        let file = |name: &str| IndexFile {
            name: name.into(),
            bytes: 7,
            blake3: "ef".repeat(32),
        };
        index.header = index
            .header
            .with_files(vec![file("manifest.toml"), file("README.md")]);
        assert_eq!(index.header.files[0].name, "README.md", "sorted by name");
        let bytes = index.to_json_bytes();
        // The streamed writer gives exactly serde_json's pretty bytes.
        #[derive(Serialize)]
        struct Whole<'a> {
            #[serde(flatten)]
            header: &'a IndexHeader,
            shards: &'a [IndexShard],
            files: &'a [IndexFile],
        }
        let whole = to_pretty_json(&Whole {
            header: &index.header,
            shards: &index.shards,
            files: &index.header.files,
        });
        assert_eq!(
            String::from_utf8(bytes.clone()).unwrap(),
            String::from_utf8(whole).unwrap()
        );
        let empty = Index::new("0.1.0", "m", "p", vec![]);
        assert!(String::from_utf8(empty.to_json_bytes())
            .unwrap()
            .ends_with("\"shards\": [],\n  \"files\": []\n}\n"));
        let text = String::from_utf8(bytes.clone()).unwrap();
        let format_at = text.find("\"format\"").unwrap();
        let shards_at = text.find("\"shards\"").unwrap();
        assert!(format_at < shards_at, "declaration order");
        assert!(
            !text.contains("members"),
            "the index lists shards, not members"
        );
        let path = Path::new("index.json");
        assert_eq!(Index::from_json_bytes(&bytes, path).unwrap(), index);
        assert_eq!(record.disagreement(&entry), None);
        assert!(second.disagreement(&entry).is_some());

        let mut evil = index.clone();
        evil.shards[0].name = "shards/../../etc/passwd".into();
        assert!(Index::from_json_bytes(&evil.to_json_bytes(), path).is_err());
        // A shard listed twice is caught next to itself, or as out of plan order.
        let mut twice = index.clone();
        twice.shards.insert(1, twice.shards[0].clone());
        twice.header.shard_count += 1;
        twice.header.samples += twice.shards[0].samples;
        let err = Index::from_json_bytes(&twice.to_json_bytes(), path).unwrap_err();
        assert!(err.to_string().contains("listed twice"), "{err}");
        let mut later = index.clone();
        later.shards.push(entry.clone());
        later.header.shard_count += 1;
        later.header.samples += 1;
        let err = Index::from_json_bytes(&later.to_json_bytes(), path).unwrap_err();
        assert!(err.to_string().contains("listed together"), "{err}");
        let mut lying = index.clone();
        lying.header.samples += 1;
        let err = Index::from_json_bytes(&lying.to_json_bytes(), path).unwrap_err();
        assert!(err.to_string().contains("header says"), "{err}");
        let mut future = index.clone();
        future.header.format_version = 4;
        let err = Index::from_json_bytes(&future.to_json_bytes(), path).unwrap_err();
        assert!(err.to_string().contains("format_version 4"), "{err}");
        // Version 2 had no files; a version-3 index without them, or with a file name that
        // leaves the directory or is listed twice, is refused.
        let text = String::from_utf8(bytes.clone()).unwrap();
        let v2 = text.replace("\"format_version\": 3", "\"format_version\": 2");
        let err = Index::from_json_bytes(v2.as_bytes(), path).unwrap_err();
        assert!(err.to_string().contains("format_version 2"), "{err}");
        assert!(err.to_string().contains("bettimill finalize"), "{err}");
        let cut = &text[..text.find(",\n  \"files\"").unwrap()];
        let err = Index::from_json_bytes(format!("{cut}\n}}").as_bytes(), path).unwrap_err();
        assert!(err.to_string().contains("files is missing"), "{err}");
        for bad in ["../x", "shards/a.tar", "index.json", ""] {
            let mut evil = index.clone();
            evil.header.files[0].name = bad.into();
            let err = Index::from_json_bytes(&evil.to_json_bytes(), path).unwrap_err();
            assert!(err.to_string().contains("plain file name"), "{bad}: {err}");
        }
        let mut twice = index.clone();
        twice.header.files[1].name = "README.md".into();
        let err = Index::from_json_bytes(&twice.to_json_bytes(), path).unwrap_err();
        assert!(err.to_string().contains("listed twice"), "{err}");
        assert!(matches!(
            Index::from_json_bytes(b"{", path),
            Err(ShardError::Json { .. })
        ));
        // An index of format version 1 (members listed) gets a message that says so.
        let old = br#"{"format": "bettimill-index", "format_version": 1, "tool_version": "0.0.7",
            "manifest_hash": "m", "plan_hash": "p", "shards": [{"name": "shards/t.tar",
            "split": "train", "samples": 1, "bytes": 1024, "blake3": "x", "first_key": "a",
            "last_key": "a", "members": []}]}"#;
        let err = Index::from_json_bytes(old, path).unwrap_err();
        assert!(matches!(err, ShardError::IndexFormat { .. }), "{err}");
        let text = err.to_string();
        assert!(
            text.contains("format_version 1") && text.contains("0.0.7"),
            "{text}"
        );
        assert!(text.contains("bettimill finalize"), "{text}");
        // A reader can stop at any shard with a reason.
        let err = read_index_from(&bytes[..], path, &mut |_, _| Err("stop".into())).unwrap_err();
        assert!(err.to_string().contains("stop"), "{err}");
    }

    #[test]
    fn wids_index_has_the_documented_shape() {
        let (_, record) =
            build_shard("shards/t-000000.tar", "train", &[sample("a", &["json"])]).unwrap();
        let json: serde_json::Value =
            serde_json::from_slice(&wids_index("train", &[record.index_entry("")])).unwrap();
        assert_eq!(json["__kind__"], "wids-shard-index-v1");
        assert_eq!(json["wids_version"], 1);
        assert_eq!(json["shardlist"][0]["url"], "shards/t-000000.tar");
        assert_eq!(json["shardlist"][0]["nsamples"], 1);
    }
}
