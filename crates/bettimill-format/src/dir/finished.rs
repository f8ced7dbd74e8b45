//! The finished dataset: the class table and the index entries finalize writes, and the
//! checks that read a finished directory (`verify`, the index's readability).

use super::layout::{
    BUILD_INFO_FILE, INDEX_FILE, MAX_CLASS_TABLE_BYTES, RECORDS_DIR, REQUIRED_FILES,
};
use super::{io, DatasetDir};
use crate::{FormatError, NoRecord, ShardRecord};
use bettimill_shard as shard;

impl DatasetDir {
    /// Writes `DIR/classes.json` (atomically).
    pub fn write_class_table(&self, table: &crate::ClassTable) -> Result<(), FormatError> {
        Ok(shard::write_atomic(
            &self.classes_path(),
            &table.to_json_bytes(),
        )?)
    }

    /// Reads `DIR/classes.json`, refusing a file over [`MAX_CLASS_TABLE_BYTES`] (streamed,
    /// never read whole first).
    pub fn read_class_table(&self) -> Result<crate::ClassTable, FormatError> {
        use std::io::Read;
        let path = self.classes_path();
        let file = std::fs::File::open(&path).map_err(io(&path))?;
        let mut limited = std::io::BufReader::new(file).take(MAX_CLASS_TABLE_BYTES + 1);
        let table = serde_json::from_reader(&mut limited);
        if limited.limit() == 0 {
            return Err(FormatError::Corrupt {
                path,
                reason: format!("larger than {MAX_CLASS_TABLE_BYTES} bytes"),
            });
        }
        table.map_err(|err| FormatError::Corrupt {
            path,
            reason: format!("not a class table: {err}"),
        })
    }

    /// The entry `index.json` lists for the directory's file `name` (size and a blake3
    /// streamed through a fixed buffer).
    pub fn index_file(&self, name: &str) -> Result<crate::IndexFile, FormatError> {
        let path = self.root.join(name);
        let mut file = std::fs::File::open(&path).map_err(io(&path))?;
        let mut hasher = blake3::Hasher::new();
        let bytes = std::io::copy(&mut file, &mut hasher).map_err(io(&path))?;
        Ok(crate::IndexFile {
            name: name.to_string(),
            bytes,
            blake3: hasher.finalize().to_hex().to_string(),
        })
    }

    /// Checks every shard against `index.json` and the completion records it covers (see
    /// `crate::verify`), streaming the index and each shard. `progress` gets
    /// (shards checked, shards in the index).
    pub fn verify(
        &self,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<crate::VerifyReport, FormatError> {
        if !self.index_path().exists() {
            return Err(FormatError::NotADataset {
                dir: self.root.clone(),
                found: self.describe_unfinished(),
            });
        }
        let mut records = |entry: &crate::IndexShard| -> Result<ShardRecord, NoRecord> {
            let name = DatasetDir::shard_stem(&entry.name);
            let path = self.record_path(name);
            match self.read_record_hashed(name)? {
                Some((record, hash)) if hash == entry.record_blake3 => Ok(record.shard),
                Some((_, found)) => Err(NoRecord::HashDiffers {
                    path,
                    found,
                    indexed: entry.record_blake3.clone(),
                }),
                None => Err(NoRecord::Missing { path }),
            }
        };
        let mut report =
            crate::verify_with_progress(&self.root, REQUIRED_FILES, &mut records, progress)?;
        // The index's identity must be the directory's: build.json is itself covered by the
        // index's `files`, so an edit of either is found.
        if let Some(header) = &report.header {
            let problems = super::identity_problems(header, self.read_build_info());
            report.problems.extend(problems);
        }
        Ok(report)
    }

    /// What a directory without `index.json` holds, said for a person: a build that has
    /// not finished, a dataset one level down, or the entries it has.
    fn describe_unfinished(&self) -> String {
        let root = &self.root;
        if !root.exists() {
            return "it does not exist".to_string();
        }
        if !root.is_dir() {
            return "it is a file; give the dataset's directory (the --out of `bettimill build`)"
                .to_string();
        }
        if root.join(BUILD_INFO_FILE).exists() {
            let records = std::fs::read_dir(root.join(RECORDS_DIR))
                .map(|entries| entries.filter_map(Result::ok).count())
                .unwrap_or(0);
            return format!(
                "it holds a build that has not finished ({BUILD_INFO_FILE} and {records} completed shard(s)); run the same `bettimill build MANIFEST --out {}` again to finish it",
                root.display()
            );
        }
        let mut names: Vec<String> = match std::fs::read_dir(root) {
            Ok(entries) => entries
                .filter_map(Result::ok)
                .map(|entry| entry.file_name().to_string_lossy().into_owned())
                .collect(),
            Err(err) => return format!("it cannot be listed ({err})"),
        };
        // Sorted: the message is the same on every file system.
        names.sort();
        if let Some(inner) = names
            .iter()
            .find(|name| root.join(name).join(INDEX_FILE).is_file())
        {
            return format!(
                "it holds a dataset one level down: {}",
                root.join(inner).display()
            );
        }
        if names.is_empty() {
            return "it is empty".to_string();
        }
        let shown: Vec<&str> = names.iter().take(5).map(String::as_str).collect();
        let more = names.len().saturating_sub(shown.len());
        let tail = if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        };
        format!(
            "it holds {} entr{} ({}{tail}) and none of a dataset's files",
            names.len(),
            if names.len() == 1 { "y" } else { "ies" },
            shown.join(", ")
        )
    }

    /// Reads `index.json` through once, if it exists, and says why it cannot be used (such
    /// as an index of an older format version); `Ok` when there is none yet.
    pub fn check_index(&self) -> Result<(), FormatError> {
        if !self.is_finalized() {
            return Ok(());
        }
        crate::read_index(&self.index_path(), &mut |_, _| {})?;
        Ok(())
    }
}
