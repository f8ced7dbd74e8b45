//! `index.json` written and read one shard at a time, validated while it is read.

use super::{
    IndexError, IndexFile, IndexHeader, IndexRefusal, IndexShard, INDEX_FORMAT,
    INDEX_FORMAT_VERSION, MAX_INDEX_FILES,
};
use crate::dir::{INDEX_FILE, SHARDS_DIR};
use serde::Serialize;
use std::collections::BTreeSet;
use std::io::Write;
use std::path::Path;

/// Writes a pretty JSON object whose last key is a list, one element at a time, in the
/// exact bytes of `serde_json::to_vec_pretty` plus a trailing newline.
pub(super) struct StreamedObject<W: Write> {
    out: W,
    elements: u64,
}

impl<W: Write> StreamedObject<W> {
    /// Writes `{`, the fields of `head` (a struct serialising to an object) and the opening
    /// of the list `key`.
    pub(super) fn new<T: Serialize>(mut out: W, head: &T, key: &str) -> std::io::Result<Self> {
        let head = serde_json::to_string_pretty(head).expect("index types serialise");
        let body = head
            .strip_suffix('}')
            .expect("a struct serialises to an object")
            .trim_end();
        out.write_all(body.as_bytes())?;
        out.write_all(format!(",\n  {}: [", serde_json::Value::from(key)).as_bytes())?;
        Ok(StreamedObject { out, elements: 0 })
    }

    pub(super) fn push<T: Serialize>(&mut self, element: &T) -> std::io::Result<()> {
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
    pub(super) fn finish<T: Serialize>(
        mut self,
        trailer: Option<(&str, &T)>,
    ) -> std::io::Result<W> {
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
/// and that the shards add up to the header's counts. Holds one shard and the set of names
/// seen (to refuse duplicates), never the list.
pub fn read_index(
    path: &Path,
    each: &mut dyn FnMut(&IndexHeader, IndexShard),
) -> Result<IndexHeader, IndexError> {
    let file = std::fs::File::open(path).map_err(|source| IndexError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_index_from(std::io::BufReader::new(file), path, each)
}

/// [`read_index`] from any reader; `path` is only used in error messages.
pub fn read_index_from(
    reader: impl std::io::Read,
    path: &Path,
    each: &mut dyn FnMut(&IndexHeader, IndexShard),
) -> Result<IndexHeader, IndexError> {
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
        (_, Some(reason)) => Err(IndexError::Format {
            path: path.to_path_buf(),
            reason,
        }),
        (Ok(header), None) => Ok(header),
        (Err(source), None) => Err(IndexError::Json {
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
    fn complete(&self) -> Result<IndexHeader, IndexRefusal> {
        let format = self.format.clone().unwrap_or_default();
        if format != INDEX_FORMAT {
            return Err(IndexRefusal::OtherFormat { found: format });
        }
        let tool = self
            .tool_version
            .clone()
            .unwrap_or_else(|| "unknown".into());
        match self.format_version {
            Some(INDEX_FORMAT_VERSION) => {}
            Some(1) => return Err(IndexRefusal::Version1 { tool }),
            Some(2) => return Err(IndexRefusal::Version2 { tool }),
            Some(version) => return Err(IndexRefusal::UnknownVersion { version, tool }),
            None => {
                return Err(IndexRefusal::Missing {
                    field: "format_version",
                })
            }
        }
        let missing = |field: &'static str| IndexRefusal::Missing { field };
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

fn check_files(files: &[IndexFile]) -> Result<(), IndexRefusal> {
    if files.len() > MAX_INDEX_FILES {
        return Err(IndexRefusal::TooManyFiles { count: files.len() });
    }
    for (n, file) in files.iter().enumerate() {
        let name = file.name.as_str();
        if name.is_empty()
            || name == "."
            || name == ".."
            || name == INDEX_FILE
            || name.contains(['/', '\\'])
            || name.chars().any(char::is_control)
        {
            return Err(IndexRefusal::BadFileName { name: name.into() });
        }
        if n > 0 && files[n - 1].name.as_str() >= name {
            return Err(IndexRefusal::FilesUnsorted { name: name.into() });
        }
    }
    Ok(())
}

struct IndexVisitor<'a> {
    each: &'a mut dyn FnMut(&IndexHeader, IndexShard),
    refusal: &'a mut Option<IndexRefusal>,
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
        let refuse = |refusal: &mut Option<IndexRefusal>, reason: IndexRefusal| {
            let error = A::Error::custom(&reason);
            *refusal = Some(reason);
            error
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
            (Some(_), None) => Err(refuse(
                self.refusal,
                IndexRefusal::Missing { field: "files" },
            )),
            (None, _) => Err(refuse(
                self.refusal,
                partial
                    .complete()
                    .err()
                    .unwrap_or(IndexRefusal::Missing { field: "shards" }),
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
pub(super) struct ShardOrder {
    passed: BTreeSet<String>,
    previous: Option<(String, String)>,
}

impl ShardOrder {
    pub(super) fn next(&mut self, shard: &IndexShard) -> Result<(), IndexRefusal> {
        let name = &shard.name;
        if let Some((split, previous)) = &self.previous {
            if *split == shard.split {
                if previous == name {
                    return Err(IndexRefusal::ListedTwice { name: name.clone() });
                }
                if (previous.len(), previous) > (name.len(), name) {
                    return Err(IndexRefusal::OutOfOrder {
                        name: name.clone(),
                        previous: previous.clone(),
                    });
                }
            } else {
                self.passed.insert(split.clone());
                if self.passed.len() >= MAX_INDEX_SPLITS {
                    return Err(IndexRefusal::TooManySplits);
                }
                if self.passed.contains(&shard.split) {
                    return Err(IndexRefusal::SplitNotTogether {
                        name: name.clone(),
                        split: shard.split.clone(),
                    });
                }
            }
        }
        self.previous = Some((shard.split.clone(), name.clone()));
        Ok(())
    }
}

struct ShardsSeed<'a> {
    header: &'a IndexHeader,
    each: &'a mut dyn FnMut(&IndexHeader, IndexShard),
    refusal: &'a mut Option<IndexRefusal>,
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
        let mut refuse = |reason: IndexRefusal| {
            let error = A::Error::custom(&reason);
            *self.refusal = Some(reason);
            error
        };
        while let Some(shard) = seq.next_element::<IndexShard>()? {
            check_shard_name(&shard.name).map_err(&mut refuse)?;
            order.next(&shard).map_err(&mut refuse)?;
            shards += 1;
            samples = samples.saturating_add(shard.samples);
            (self.each)(self.header, shard);
        }
        if shards != self.header.shard_count || samples != self.header.samples {
            return Err(refuse(IndexRefusal::Counts {
                shards,
                samples,
                header_shards: self.header.shard_count,
                header_samples: self.header.samples,
            }));
        }
        Ok(())
    }
}

pub(super) fn check_shard_name(name: &str) -> Result<(), IndexRefusal> {
    let Some(rest) = name
        .strip_prefix(SHARDS_DIR)
        .and_then(|rest| rest.strip_prefix('/'))
    else {
        return Err(IndexRefusal::NotUnderShards { name: name.into() });
    };
    if rest.is_empty()
        || rest
            .split('/')
            .any(|c| c.is_empty() || c == "." || c == "..")
        || name.contains('\\')
        || name.chars().any(char::is_control)
    {
        return Err(IndexRefusal::NotAPlainPath { name: name.into() });
    }
    Ok(())
}
