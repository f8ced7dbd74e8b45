//! Samples read back from shard bytes: the label (`KEY.json`) and the main array
//! (`KEY.npy`, `KEY.npy.gz` or `KEY.npy.zst`) of each key, in tar order. Downscaled copies
//! (`KEY.rSIDE.npy`) and `KEY.cls` are ignored.

use crate::PreviewError;
use bettimill_grid::{npy, BinaryImage};
use bettimill_sample::Label;
use bettimill_shard::{decompress, split_key, tar_entries, Compression};

/// The largest decompressed array accepted: a 1024^3 image plus its header, with room.
const MAX_ARRAY_BYTES: u64 = 1 << 31;

/// One sample of a shard.
#[derive(Clone, Debug)]
pub struct SampleView {
    /// The WebDataset key.
    pub key: String,
    /// The parsed `KEY.json`.
    pub label: Label,
    /// The decoded `KEY.npy`.
    pub image: BinaryImage,
}

fn array_compression(field: &str) -> Option<Compression> {
    match field {
        "npy" => Some(Compression::None),
        "npy.gz" => Some(Compression::Gzip),
        "npy.zst" => Some(Compression::Zstd),
        _ => None,
    }
}

/// The keys of a shard in tar order, each once.
pub fn keys_in_tar(bytes: &[u8]) -> Result<Vec<String>, PreviewError> {
    let mut keys: Vec<String> = Vec::new();
    for entry in tar_entries(bytes, u64::MAX)? {
        if let Some((key, _)) = split_key(&entry.name) {
            if keys.last().map(String::as_str) != Some(key) {
                keys.push(key.to_string());
            }
        }
    }
    Ok(keys)
}

/// Every label of a shard, in tar order (arrays are not decoded).
pub fn labels_in_tar(bytes: &[u8]) -> Result<Vec<Label>, PreviewError> {
    let mut labels = Vec::new();
    for entry in tar_entries(bytes, u64::MAX)? {
        if let Some((key, "json")) = split_key(&entry.name) {
            labels.push(parse_label(key, entry.data)?);
        }
    }
    Ok(labels)
}

fn parse_label(key: &str, data: &[u8]) -> Result<Label, PreviewError> {
    serde_json::from_slice(data).map_err(|source| PreviewError::Label {
        key: key.to_string(),
        source,
    })
}

/// The samples of a shard whose keys `keep` accepts, in tar order. Only their arrays are
/// decompressed and decoded.
pub fn samples_in_tar(
    bytes: &[u8],
    keep: &mut dyn FnMut(&str) -> bool,
) -> Result<Vec<SampleView>, PreviewError> {
    let mut wanted: Vec<(String, Option<Label>, Option<BinaryImage>)> = Vec::new();
    let mut current: Option<(String, bool)> = None;
    for entry in tar_entries(bytes, u64::MAX)? {
        let Some((key, field)) = split_key(&entry.name) else {
            continue;
        };
        if current.as_ref().map(|(k, _)| k.as_str()) != Some(key) {
            let kept = keep(key);
            if kept {
                wanted.push((key.to_string(), None, None));
            }
            current = Some((key.to_string(), kept));
        }
        if !current.as_ref().is_some_and(|(_, kept)| *kept) {
            continue;
        }
        let slot = wanted.last_mut().expect("a kept key was pushed");
        if field == "json" {
            slot.1 = Some(parse_label(key, entry.data)?);
        } else if let Some(compression) = array_compression(field) {
            let raw = decompress(entry.data, compression, MAX_ARRAY_BYTES)?;
            let image = npy::read_bytes(&raw, false)
                .map_err(|source| PreviewError::Npy {
                    what: entry.name.clone(),
                    source,
                })?
                .image;
            slot.2 = Some(image);
        }
    }
    wanted
        .into_iter()
        .map(|(key, label, image)| match (label, image) {
            (Some(label), Some(image)) => Ok(SampleView { key, label, image }),
            (None, _) => Err(PreviewError::Missing { key, field: "json" }),
            (_, None) => Err(PreviewError::Missing { key, field: "npy" }),
        })
        .collect()
}
