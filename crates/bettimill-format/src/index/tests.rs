use super::*;
use crate::IndexError;
use bettimill_shard::blake3_hex;
use bettimill_shard::ustar::{self, Member};
use stream::ShardOrder;

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
fn a_streamed_shard_is_the_tar_of_its_members_byte_for_byte() {
    // Sizes around the block boundaries: empty, one byte, a block, a block and one.
    let sizes = [0usize, 1, 511, 512, 513, 1024, 3000];
    let samples: Vec<Vec<Member>> = sizes
        .iter()
        .enumerate()
        .map(|(i, &size)| {
            ["json", "npy"]
                .iter()
                .map(|field| Member {
                    name: format!("s{i:06}.{field}"),
                    data: (0..size).map(|b| (b * 31 + i) as u8).collect(),
                })
                .collect()
        })
        .collect();
    let name = "shards/t-000000.tar";
    let mut streamed = Vec::new();
    let record = write_shard(
        name,
        "train",
        &samples,
        &mut streamed,
        std::path::Path::new("t"),
    )
    .unwrap();
    let flat: Vec<Member> = samples.iter().flatten().cloned().collect();
    assert_eq!(streamed, ustar::tar_bytes(&flat).unwrap());
    assert_eq!(
        build_shard(name, "train", &samples).unwrap(),
        (streamed.clone(), record.clone())
    );
    assert_eq!(record.bytes, streamed.len() as u64);
    assert_eq!(record.blake3, blake3_hex(&streamed));
    // A sample that would be refused writes nothing.
    let mut out = Vec::new();
    let twice = vec![samples[0].clone(), samples[0].clone()];
    assert!(write_shard(name, "train", &twice, &mut out, std::path::Path::new("t")).is_err());
    assert!(out.is_empty());
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
    assert!(
        matches!(err, IndexRefusal::SplitNotTogether { .. }),
        "{err}"
    );
    let mut order = ShardOrder::default();
    order.next(&shard("train", "shards/d-000002.tar")).unwrap();
    let err = order
        .next(&shard("train", "shards/d-000001.tar"))
        .unwrap_err();
    assert!(matches!(err, IndexRefusal::OutOfOrder { .. }), "{err}");
    let err = order
        .next(&shard("train", "shards/d-000002.tar"))
        .unwrap_err();
    assert!(matches!(err, IndexRefusal::ListedTwice { .. }), "{err}");
    let mut order = ShardOrder::default();
    let too_many: Result<Vec<()>, IndexRefusal> = (0..=MAX_INDEX_SPLITS)
        .map(|i| {
            order.next(&shard(
                &format!("s{i}"),
                &format!("shards/d-s{i}-000000.tar"),
            ))
        })
        .collect();
    assert_eq!(too_many, Err(IndexRefusal::TooManySplits));
}

#[test]
fn index_round_trips_and_validates() {
    let (_, record) = build_shard(
        "shards/t-000000.tar",
        "train",
        &[sample("a", &["json", "npy"])],
    )
    .unwrap();
    let (_, second) = build_shard("shards/t-000001.tar", "val", &[sample("b", &["json"])]).unwrap();
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
        Err(IndexError::Json { .. })
    ));
    // An index of format version 1 (members listed) gets a message that says so.
    let old = br#"{"format": "bettimill-index", "format_version": 1, "tool_version": "0.0.7",
        "manifest_hash": "m", "plan_hash": "p", "shards": [{"name": "shards/t.tar",
        "split": "train", "samples": 1, "bytes": 1024, "blake3": "x", "first_key": "a",
        "last_key": "a", "members": []}]}"#;
    let err = Index::from_json_bytes(old, path).unwrap_err();
    assert!(matches!(err, IndexError::Format { .. }), "{err}");
    let text = err.to_string();
    assert!(
        text.contains("format_version 1") && text.contains("0.0.7"),
        "{text}"
    );
    assert!(text.contains("bettimill finalize"), "{text}");
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
