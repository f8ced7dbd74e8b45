//! Checking a dataset directory against its `index.json`.
//!
//! Because [`bettimill_shard::tar_bytes`] is deterministic, the index determines every byte of every
//! shard except member data: each header can be regenerated from the member's name and
//! size, padding and the end-of-archive marker are zeros, and member data has a BLAKE3 in
//! the index. [`verify`] uses that to localise damage instead of only saying "hash
//! mismatch": a corrupted header is named by its member and the offset of the first wrong
//! byte, corrupted data by its member and data offset, a cut file by the member (and part
//! of it) where the cut falls. It also reports missing shards, files under `shards/` that
//! the index does not list (such as temporary files a crash left behind), and sample counts
//! that disagree with the members.
//!
//! The index lists shards; the member records live with each shard's record (the caller
//! resolves them, `bettimill-format` from `records/NAME.json`). Every shard is checked and
//! every problem reported; only an unreadable or invalid `index.json` is an error. The
//! index is read one shard at a time, and each shard goes through the one tar check of
//! this crate (`tar_check`, which resume, status and finalize use too): one pass through a
//! fixed buffer, never past its record's size, that hashes each part and the whole; anything
//! but a regular file (a link to `/dev/zero`) is reported unreadable without reading it.
//! Extra files under `shards/` are found by counting: the index lists each name once (in
//! plan order, checked holding one name), so if `shards/` holds as many files as the listed
//! shards that exist, none is extra; only when the counts differ are the names found there
//! kept, to say which. So memory does not grow with samples, shards or the size of a
//! damaged file.

use crate::dir::{INDEX_FILE, SHARDS_DIR};
use crate::index::{read_index, IndexShard, ShardRecord};
use crate::tar_check::{self, Depth};
use crate::IndexError;
use bettimill_shard::{file_matches, regular_len};
use serde::Serialize;
use std::collections::BTreeSet;
use std::fmt;
use std::path::{Path, PathBuf};

/// Which part of a shard's layout a cut or corruption falls in.
#[derive(Serialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Region {
    /// A member's 512-byte header block (a cut exactly at a member boundary falls at the
    /// start of the next header).
    Header,
    /// A member's data.
    Data,
    /// The zero padding after a member's data.
    Padding,
    /// The two zero blocks that end the archive.
    EndMarker,
}

impl fmt::Display for Region {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Region::Header => "header",
            Region::Data => "data",
            Region::Padding => "padding",
            Region::EndMarker => "end-of-archive marker",
        })
    }
}

/// One thing wrong with a dataset directory.
#[derive(Serialize, Clone, Debug, PartialEq, Eq)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Problem {
    /// A shard listed in the index does not exist.
    MissingShard {
        /// The shard's name in the index.
        shard: String,
    },
    /// A shard or directory exists but could not be read.
    Unreadable {
        /// The file or directory.
        path: String,
        /// The operating system's reason.
        error: String,
    },
    /// A shard is shorter than the index says.
    Truncated {
        /// The shard.
        shard: String,
        /// Size in the index.
        expected_bytes: u64,
        /// Size on disk.
        found_bytes: u64,
        /// The member the cut falls in (`None` for the end-of-archive marker).
        member: Option<String>,
        /// The part of the layout the cut falls in.
        region: Region,
    },
    /// A shard is longer than the index says.
    TrailingBytes {
        /// The shard.
        shard: String,
        /// Size in the index.
        expected_bytes: u64,
        /// Size on disk.
        found_bytes: u64,
    },
    /// A member's header block differs from the one its name and size determine.
    HeaderCorrupt {
        /// The shard.
        shard: String,
        /// The member whose header it is.
        member: String,
        /// Offset of the header block in the shard.
        header_offset: u64,
        /// Offset of the first byte that differs.
        offset: u64,
    },
    /// A member's data does not have the recorded hash.
    DataCorrupt {
        /// The shard.
        shard: String,
        /// The member.
        member: String,
        /// Offset of the member's first data byte in the shard.
        offset: u64,
        /// Length of the data.
        bytes: u64,
        /// BLAKE3 in the shard's record.
        expected_blake3: String,
        /// BLAKE3 of the bytes on disk.
        found_blake3: String,
    },
    /// A padding or end-marker byte that must be zero is not.
    NonZeroPadding {
        /// The shard.
        shard: String,
        /// The member the padding follows (`None` for the end-of-archive marker).
        member: Option<String>,
        /// Offset of the first non-zero byte.
        offset: u64,
    },
    /// The whole shard's hash differs although no part could be blamed (the recorded
    /// shard hash itself is probably wrong).
    HashMismatch {
        /// The shard.
        shard: String,
        /// BLAKE3 in the shard's record.
        expected_blake3: String,
        /// BLAKE3 of the file.
        found_blake3: String,
    },
    /// The recorded sample count disagrees with the keys of the recorded members.
    SampleCount {
        /// The shard.
        shard: String,
        /// Count in the shard's record.
        expected: u64,
        /// Count of samples among the members.
        found: u64,
    },
    /// A shard record contradicts itself in another way (a member record whose name
    /// cannot be written, first or last key not those of the members).
    RecordInconsistent {
        /// The shard.
        shard: String,
        /// What disagrees.
        reason: String,
    },
    /// A file of the directory (not a shard) that index.json lists differs from what it
    /// says, is missing, or is required and not listed.
    File {
        /// Path relative to the dataset directory.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// A file under `shards/` that the index does not list.
    ExtraFile {
        /// Path relative to the dataset directory.
        path: String,
    },
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Problem::MissingShard { shard } => write!(f, "{shard}: missing"),
            Problem::Unreadable { path, error } => write!(f, "{path}: cannot read: {error}"),
            Problem::Truncated {
                shard,
                expected_bytes,
                found_bytes,
                member,
                region,
            } => {
                write!(
                    f,
                    "{shard}: truncated to {found_bytes} of {expected_bytes} bytes; the cut falls in the {region}"
                )?;
                match member {
                    Some(member) => write!(f, " of member {member}"),
                    None => Ok(()),
                }
            }
            Problem::TrailingBytes {
                shard,
                expected_bytes,
                found_bytes,
            } => write!(
                f,
                "{shard}: {found_bytes} bytes, the index says {expected_bytes}; {} unexpected bytes at the end",
                found_bytes - expected_bytes
            ),
            Problem::HeaderCorrupt {
                shard,
                member,
                header_offset,
                offset,
            } => write!(
                f,
                "{shard}: header of member {member} (at byte {header_offset}) is corrupt from byte {offset}"
            ),
            Problem::DataCorrupt {
                shard,
                member,
                offset,
                bytes,
                expected_blake3,
                found_blake3,
            } => write!(
                f,
                "{shard}: data of member {member} (bytes {offset}..{}) has blake3 {found_blake3}, its record says {expected_blake3}",
                offset + bytes
            ),
            Problem::NonZeroPadding {
                shard,
                member,
                offset,
            } => match member {
                Some(member) => write!(
                    f,
                    "{shard}: non-zero padding byte at {offset} after member {member}"
                ),
                None => write!(
                    f,
                    "{shard}: non-zero byte at {offset} in the end-of-archive marker"
                ),
            },
            Problem::HashMismatch {
                shard,
                expected_blake3,
                found_blake3,
            } => write!(
                f,
                "{shard}: blake3 {found_blake3}, its record says {expected_blake3} (every member checks out: the recorded shard hash is wrong)"
            ),
            Problem::SampleCount {
                shard,
                expected,
                found,
            } => write!(
                f,
                "{shard}: its record says {expected} samples, its members form {found}"
            ),
            Problem::RecordInconsistent { shard, reason } => write!(f, "{shard}: {reason}"),
            Problem::File { path, reason } => write!(f, "{path}: {reason}"),
            Problem::ExtraFile { path } => write!(f, "{path}: not listed in index.json"),
        }
    }
}

/// What [`verify`] found.
#[derive(Serialize, Clone, Debug, Default, PartialEq, Eq)]
pub struct VerifyReport {
    /// Shards listed in the index.
    pub shards_checked: u64,
    /// Samples listed in the index.
    pub samples_checked: u64,
    /// Bytes of shard files read.
    pub bytes_checked: u64,
    /// Other files of the directory checked against the index's `files`.
    pub files_checked: u64,
    /// Every problem, in index order, then extra files in path order.
    pub problems: Vec<Problem>,
    /// The index's header, for checks of the caller's own (not in the JSON report).
    #[serde(skip)]
    pub header: Option<crate::IndexHeader>,
}

impl VerifyReport {
    /// True when no problem was found.
    pub fn is_ok(&self) -> bool {
        self.problems.is_empty()
    }
}

/// Finds the member records of an index entry (the shard's [`ShardRecord`]), or says why
/// there are none.
pub type RecordSource<'a> = dyn FnMut(&IndexShard) -> Result<ShardRecord, NoRecord> + 'a;

/// Why an index entry has no usable record.
#[derive(Debug, thiserror::Error)]
pub enum NoRecord {
    /// The record is not the one the index covers.
    #[error("{path} has blake3 {found}, index.json says {indexed}")]
    HashDiffers {
        /// The record file.
        path: PathBuf,
        /// Its blake3.
        found: String,
        /// The blake3 in the index.
        indexed: String,
    },
    /// There is no record.
    #[error("{path} is missing (it lists the shard's members)")]
    Missing {
        /// The record file.
        path: PathBuf,
    },
    /// The record cannot be read or parsed.
    #[error(transparent)]
    Unreadable(#[from] crate::FormatError),
}

/// Checks every shard of `dir` against `dir/index.json` and the records `records` gives
/// (see the module documentation). Returns `Err` only when the index itself cannot be read
/// or is invalid.
pub fn verify(dir: &Path, records: &mut RecordSource) -> Result<VerifyReport, IndexError> {
    verify_with_progress(dir, &[], records, &mut |_, _| {})
}

/// [`verify`], calling `progress` with (shards checked, shards in the index): once with
/// zero checked when the index's header is read, then after each shard; every name in
/// `required` must be among the index's `files` (the dataset format's own files).
pub fn verify_with_progress(
    dir: &Path,
    required: &[&str],
    records: &mut RecordSource,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<VerifyReport, IndexError> {
    let mut report = VerifyReport::default();
    // Listed shards that are files: if `shards/` holds as many files, none is extra (the
    // index lists every name once), so no list of names is kept.
    let mut listed_files = 0u64;
    let mut started = false;
    let header = read_index(&dir.join(INDEX_FILE), &mut |header, entry| {
        if !started {
            progress(0, header.shard_count);
            started = true;
        }
        report.shards_checked += 1;
        report.samples_checked += entry.samples;
        check_entry(dir, &entry, records, &mut report);
        listed_files += u64::from(dir.join(&entry.name).is_file());
        progress(report.shards_checked, header.shard_count);
    })?;
    if !started {
        progress(0, header.shard_count);
    }
    for name in required {
        if !header.files.iter().any(|f| f.name == *name) {
            report.problems.push(Problem::File {
                path: name.to_string(),
                reason: "not listed in index.json's files".into(),
            });
        }
    }
    for file in &header.files {
        report.files_checked += 1;
        if let Err(reason) = file_matches(&dir.join(&file.name), file.bytes, &file.blake3) {
            report.problems.push(Problem::File {
                path: file.name.clone(),
                reason: reason
                    .to_string()
                    .replace("its record says", "index.json says"),
            });
        }
    }
    report.header = Some(header);
    let mut on_disk = 0u64;
    walk_files(
        dir,
        Path::new(SHARDS_DIR),
        &mut |_| on_disk += 1,
        &mut report.problems,
    );
    if on_disk != listed_files {
        // Something is extra: only now are names kept, those of the files found (the
        // index is read a second time to strike out the listed ones).
        let mut found = BTreeSet::new();
        walk_files(
            dir,
            Path::new(SHARDS_DIR),
            &mut |name| {
                found.insert(name);
            },
            &mut Vec::new(),
        );
        read_index(&dir.join(INDEX_FILE), &mut |_, entry| {
            found.remove(&entry.name);
        })?;
        for path in found {
            report.problems.push(Problem::ExtraFile { path });
        }
    }
    Ok(report)
}

/// Checks one index entry: its record, then its file.
fn check_entry(
    dir: &Path,
    entry: &IndexShard,
    records: &mut RecordSource,
    report: &mut VerifyReport,
) {
    let path = dir.join(&entry.name);
    let problems = &mut report.problems;
    let record = match records(entry) {
        Ok(record) => record,
        Err(reason) => {
            problems.push(Problem::RecordInconsistent {
                shard: entry.name.clone(),
                reason: reason.to_string(),
            });
            // Without member records the file can still be checked as a whole.
            match std::fs::metadata(&path) {
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    problems.push(Problem::MissingShard {
                        shard: entry.name.clone(),
                    })
                }
                _ => {
                    if let Err(reason) = file_matches(&path, entry.bytes, &entry.blake3) {
                        problems.push(Problem::RecordInconsistent {
                            shard: entry.name.clone(),
                            reason: reason.to_string(),
                        });
                    } else {
                        report.bytes_checked += entry.bytes;
                    }
                }
            }
            return;
        }
    };
    if let Some(reason) = record.disagreement(entry) {
        problems.push(Problem::RecordInconsistent {
            shard: entry.name.clone(),
            reason,
        });
    }
    let consistent = tar_check::record_problems(&record, problems);
    match std::fs::metadata(&path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            problems.push(Problem::MissingShard {
                shard: record.name.clone(),
            });
            return;
        }
        Err(e) => {
            problems.push(Problem::Unreadable {
                path: path.display().to_string(),
                error: e.to_string(),
            });
            return;
        }
        Ok(_) => {}
    }
    let len = match regular_len(&path) {
        Ok(len) => len,
        Err(error) => {
            problems.push(Problem::Unreadable {
                path: path.display().to_string(),
                error: error.to_string(),
            });
            return;
        }
    };
    if !consistent {
        // Without a layout to follow, the file can still be checked as a whole.
        match file_matches(&path, record.bytes, &record.blake3) {
            Ok(()) => report.bytes_checked += record.bytes,
            Err(reason) => problems.push(Problem::RecordInconsistent {
                shard: entry.name.clone(),
                reason: reason.to_string(),
            }),
        }
        return;
    }
    let checked = std::fs::File::open(&path).and_then(|mut file| {
        tar_check::file_problems(&record, &mut file, len, Depth::All, problems)
    });
    match checked {
        Ok(read) => report.bytes_checked += read,
        Err(e) => problems.push(Problem::Unreadable {
            path: path.display().to_string(),
            error: e.to_string(),
        }),
    }
}

/// Calls `found` with every file under `dir/relative`, as a `/`-separated path relative to
/// `dir`, in directory order (nothing is collected).
fn walk_files(
    dir: &Path,
    relative: &Path,
    found: &mut dyn FnMut(String),
    problems: &mut Vec<Problem>,
) {
    let full: PathBuf = dir.join(relative);
    let entries = match std::fs::read_dir(&full) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return,
        Err(e) => {
            problems.push(Problem::Unreadable {
                path: full.display().to_string(),
                error: e.to_string(),
            });
            return;
        }
    };
    for entry in entries {
        let entry = match entry {
            Ok(entry) => entry,
            Err(e) => {
                problems.push(Problem::Unreadable {
                    path: full.display().to_string(),
                    error: e.to_string(),
                });
                continue;
            }
        };
        let child = relative.join(entry.file_name());
        let is_dir = entry.file_type().map(|t| t.is_dir()).unwrap_or(false);
        if is_dir {
            walk_files(dir, &child, found, problems);
        } else {
            let text: Vec<String> = child
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            found(text.join("/"));
        }
    }
}
