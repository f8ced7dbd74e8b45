//! Samples read back from shard bytes: the label (`KEY.json`) and the main array
//! (`KEY.npy`, `KEY.npy.gz` or `KEY.npy.zst`) of each key, in tar order, with its
//! downscaled copies (`KEY.rSIDE.npy`) for the viewer. `KEY.cls` is ignored.

use crate::PreviewError;
use bettimill_format::{Label, MemberName};
use bettimill_grid::{npy, BinaryImage};
use bettimill_shard::{decompress, TarStream};
use std::io::Read;

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
    /// The decoded downscaled copies (`KEY.rSIDE.npy`) as (side, image), in tar order.
    pub copies: Vec<(u32, BinaryImage)>,
}

/// The keys of a shard in tar order, each once.
pub fn keys_in_tar(bytes: &[u8]) -> Result<Vec<String>, PreviewError> {
    let mut stream = in_memory(bytes);
    let mut keys: Vec<String> = Vec::new();
    while let Some((name, _, _)) = stream.next_entry()? {
        if let Some(MemberName { key, .. }) = MemberName::parse(name) {
            if keys.last().map(String::as_str) != Some(key) {
                keys.push(key.to_string());
            }
        }
    }
    Ok(keys)
}

/// A stream over a whole archive held in memory (the tests, and callers that have one).
fn in_memory(bytes: &[u8]) -> TarStream<&[u8]> {
    TarStream::new(bytes, "(in memory)", u64::MAX)
}

/// Every label of a shard, in tar order (arrays are not decoded).
pub fn labels_in_tar(bytes: &[u8]) -> Result<Vec<Label>, PreviewError> {
    labels_in_stream(&mut in_memory(bytes))
}

/// [`labels_in_tar`] for a shard read member after member (one member held at a time).
pub fn labels_in_stream<R: Read>(stream: &mut TarStream<R>) -> Result<Vec<Label>, PreviewError> {
    let mut labels = Vec::new();
    while let Some((name, _, data)) = stream.next_entry()? {
        match MemberName::parse(name) {
            Some(member) if member.is_label() => labels.push(parse_label(member.key, data)?),
            _ => {}
        }
    }
    Ok(labels)
}

fn parse_label(key: &str, data: &[u8]) -> Result<Label, PreviewError> {
    Label::from_json(data).map_err(|source| PreviewError::Label {
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
    samples_in_stream(&mut in_memory(bytes), keep)
}

/// [`samples_in_tar`] for a shard read member after member: each member is read once,
/// and only the kept samples are held.
pub fn samples_in_stream<R: Read>(
    stream: &mut TarStream<R>,
    keep: &mut dyn FnMut(&str) -> bool,
) -> Result<Vec<SampleView>, PreviewError> {
    type Parts = (
        String,
        Option<Label>,
        Option<BinaryImage>,
        Vec<(u32, BinaryImage)>,
    );
    let mut wanted: Vec<Parts> = Vec::new();
    let mut current: Option<(String, bool)> = None;
    while let Some((name, _, data)) = stream.next_entry()? {
        let Some(member) = MemberName::parse(name) else {
            continue;
        };
        let key = member.key;
        if current.as_ref().map(|(k, _)| k.as_str()) != Some(key) {
            let kept = keep(key);
            if kept {
                wanted.push((key.to_string(), None, None, Vec::new()));
            }
            current = Some((key.to_string(), kept));
        }
        if !current.as_ref().is_some_and(|(_, kept)| *kept) {
            continue;
        }
        let slot = wanted.last_mut().expect("a kept key was pushed");
        if member.is_label() {
            slot.1 = Some(parse_label(key, data)?);
        } else if member.is_image() || member.resolution().is_some() {
            let raw = decompress(data, member.compression, MAX_ARRAY_BYTES)?;
            let image = npy::read_bytes(&raw, false)
                .map_err(|source| PreviewError::Npy {
                    what: name.to_string(),
                    source,
                })?
                .image;
            match member.resolution() {
                Some(side) => slot.3.push((side, image)),
                None => slot.2 = Some(image),
            }
        }
    }
    wanted
        .into_iter()
        .map(|(key, label, image, copies)| match (label, image) {
            (Some(label), Some(image)) => Ok(SampleView {
                key,
                label,
                image,
                copies,
            }),
            (None, _) => Err(PreviewError::Missing { key, field: "json" }),
            (_, None) => Err(PreviewError::Missing { key, field: "npy" }),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use bettimill_shard::{compress, tar_bytes, Compression, Member};

    fn label_json(key: &str) -> Vec<u8> {
        serde_json::to_vec(&serde_json::json!({
            "key": key, "betti": [1, 0], "field": "Z/2", "euler": 1, "hypervolume": 1,
            "components": 1, "shape": [4, 4], "dim": 2, "mode": "embed", "family": "ball",
            "knot_type": "none", "class_index": 0, "class_label": "ball/embed", "seed": "00",
            "attempt": 0, "manifest_hash": "00", "tool_version": "0", "construction": {}
        }))
        .unwrap()
    }

    fn shard(compression: Compression, keys: &[&str]) -> Vec<u8> {
        let mut members = Vec::new();
        for (n, key) in keys.iter().enumerate() {
            let mut image = BinaryImage::zeros(&[4, 4]).unwrap();
            image.set(&[n % 4, 1], true);
            let npy = npy::write_bytes(&image, npy::Dtype::U8);
            members.push(Member::new(format!("{key}.cls"), b"0".to_vec()));
            members.push(Member::new(format!("{key}.json"), label_json(key)));
            members.push(Member::new(
                format!("{key}.npy{}", compression.suffix()),
                compress(&npy, compression).unwrap(),
            ));
            let mut copy = BinaryImage::zeros(&[2, 2]).unwrap();
            copy.set(&[1, n % 2], true);
            members.push(Member::new(
                format!("{key}.r2.npy"),
                npy::write_bytes(&copy, npy::Dtype::U8),
            ));
        }
        tar_bytes(&members).unwrap()
    }

    #[test]
    fn kept_samples_decode_with_every_compression() {
        for compression in [Compression::None, Compression::Gzip, Compression::Zstd] {
            let bytes = shard(compression, &["s0", "s1", "s2"]);
            assert_eq!(keys_in_tar(&bytes).unwrap(), vec!["s0", "s1", "s2"]);
            assert_eq!(labels_in_tar(&bytes).unwrap().len(), 3);
            let samples = samples_in_tar(&bytes, &mut |key| key != "s1").unwrap();
            let keys: Vec<&str> = samples.iter().map(|s| s.key.as_str()).collect();
            assert_eq!(keys, vec!["s0", "s2"], "{compression}");
            assert!(samples[1].image.get(&[2, 1]), "{compression}");
            assert_eq!(samples[1].image.count_foreground(), 1);
            assert_eq!(samples[1].label.key, "s2");
            assert_eq!(samples[1].copies.len(), 1);
            assert_eq!(samples[1].copies[0].0, 2);
            assert!(samples[1].copies[0].1.get(&[1, 0]));
        }
    }

    #[test]
    fn a_sample_without_its_array_or_with_a_bad_label_is_an_error() {
        let members = vec![Member::new("s0.json", label_json("s0"))];
        let bytes = tar_bytes(&members).unwrap();
        assert!(matches!(
            samples_in_tar(&bytes, &mut |_| true),
            Err(PreviewError::Missing { field: "npy", .. })
        ));
        let members = vec![Member::new("s0.json", b"{}".to_vec())];
        let bytes = tar_bytes(&members).unwrap();
        assert!(matches!(
            labels_in_tar(&bytes),
            Err(PreviewError::Label { .. })
        ));
        assert!(matches!(
            samples_in_tar(b"not a tar", &mut |_| true),
            Err(PreviewError::Shard(_))
        ));
    }
}
