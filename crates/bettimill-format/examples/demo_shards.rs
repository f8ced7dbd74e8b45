//! Writes a small dataset directory with this crate alone, so that the Python client tests
//! (`tests/python`) and `verify` can be exercised before the build pipeline exists.
//!
//! ```text
//! cargo run -p bettimill-format --example demo_shards -- OUT_DIR \
//!     [--compression none|gzip|zstd] [--samples N] [--per-shard M] [--dim D] [--seed S]
//! ```
//!
//! It writes `OUT_DIR/shards/{train,val}-NNNNNN.tar`, `OUT_DIR/index.json` and one wids
//! index per split, `OUT_DIR/shardindex-{train,val}.json`. Each sample has the members
//! `KEY.cls` (ASCII class index), `KEY.json` (labels) and `KEY.npy` (a random 0/1 uint8
//! array of rank `--dim` whose side varies from 4 to 7 between samples), with
//! `KEY = SPLIT/sNNNNNN`. The images are random noise: the Betti numbers in the labels are
//! placeholders, marked so in the `construction` field. Same arguments, same bytes.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]

use bettimill_format::{build_shard, wids_index, Index};
use bettimill_grid::npy::{self, Dtype};
use bettimill_grid::BinaryImage;
use bettimill_shard::{compress, write_atomic, Compression, Member};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

struct Options {
    out: PathBuf,
    compression: Compression,
    samples: u64,
    per_shard: u64,
    dim: usize,
    seed: u64,
}

fn usage() -> String {
    "usage: demo_shards OUT_DIR [--compression none|gzip|zstd] [--samples N] [--per-shard M] [--dim 2|3|4] [--seed S]".into()
}

fn parse(args: &[String]) -> Result<Options, String> {
    let mut options = Options {
        out: PathBuf::new(),
        compression: Compression::None,
        samples: 24,
        per_shard: 5,
        dim: 3,
        seed: 1,
    };
    let mut out = None;
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .cloned()
                .ok_or_else(|| format!("{name} needs a value\n{}", usage()))
        };
        let number = |text: String, name: &str| {
            text.parse::<u64>()
                .map_err(|_| format!("{name} {text:?} is not a number"))
        };
        match arg.as_str() {
            "--compression" => {
                let text = value("--compression")?;
                options.compression = Compression::from_name(&text)
                    .ok_or_else(|| format!("unknown compression {text:?}\n{}", usage()))?;
            }
            "--samples" => options.samples = number(value("--samples")?, "--samples")?,
            "--per-shard" => options.per_shard = number(value("--per-shard")?, "--per-shard")?,
            "--dim" => options.dim = number(value("--dim")?, "--dim")? as usize,
            "--seed" => options.seed = number(value("--seed")?, "--seed")?,
            "-h" | "--help" => return Err(usage()),
            other if other.starts_with('-') => {
                return Err(format!("unknown option {other}\n{}", usage()))
            }
            other if out.is_none() => out = Some(PathBuf::from(other)),
            other => return Err(format!("unexpected argument {other}\n{}", usage())),
        }
    }
    options.out = out.ok_or_else(usage)?;
    if options.per_shard == 0 || options.samples == 0 {
        return Err("--samples and --per-shard must be at least 1".into());
    }
    if !(2..=4).contains(&options.dim) {
        return Err("--dim must be 2, 3 or 4".into());
    }
    Ok(options)
}

/// SplitMix64: a tiny deterministic generator, enough for demo noise.
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn sample(split: &str, index: u64, options: &Options) -> Result<Vec<Member>, String> {
    let key = format!("{split}/s{index:06}");
    let sample_seed = options.seed.wrapping_mul(1_000_003).wrapping_add(index) ^ split.len() as u64;
    let mut state = sample_seed;
    let side = 4 + (splitmix(&mut state) % 4) as usize;
    let shape = vec![side; options.dim];
    let voxels = side.pow(options.dim as u32);
    let data: Vec<u8> = (0..voxels)
        .map(|_| splitmix(&mut state).is_multiple_of(3) as u8)
        .collect();
    let image = BinaryImage::from_vec(&shape, data).map_err(|e| e.to_string())?;
    let hypervolume = image.count_foreground();
    let mut betti = vec![0u64; options.dim];
    betti[0] = 1 + splitmix(&mut state) % 3;
    betti[1] = splitmix(&mut state) % 4;
    let euler: i64 = betti
        .iter()
        .enumerate()
        .map(|(k, &b)| if k % 2 == 0 { b as i64 } else { -(b as i64) })
        .sum();
    let class_index = betti[1];
    let labels = serde_json::json!({
        "key": key,
        "betti": betti,
        "euler": euler,
        "hypervolume": hypervolume,
        "shape": shape,
        "dim": options.dim,
        "seed": sample_seed,
        "family": "demo-noise",
        "mode": "demo",
        "tool_version": env!("CARGO_PKG_VERSION"),
        "construction": "demo_shards example: random voxels; betti/euler are placeholders, not computed",
    });
    let mut json = serde_json::to_vec(&labels).map_err(|e| e.to_string())?;
    json.push(b'\n');
    let npy_bytes = npy::write_bytes(&image, Dtype::U8);
    let npy_bytes = compress(&npy_bytes, options.compression).map_err(|e| e.to_string())?;
    Ok(vec![
        Member::new(format!("{key}.cls"), class_index.to_string().into_bytes()),
        Member::new(format!("{key}.json"), json),
        Member::new(
            format!("{key}.npy{}", options.compression.suffix()),
            npy_bytes,
        ),
    ])
}

fn run(options: &Options) -> Result<(), String> {
    let shards_dir = options.out.join("shards");
    std::fs::create_dir_all(&shards_dir)
        .map_err(|e| format!("cannot create {}: {e}", shards_dir.display()))?;
    let val_samples = (options.samples / 4).max(1);
    let mut records = Vec::new();
    let mut member_count = 0;
    for (split, count) in [("train", options.samples), ("val", val_samples)] {
        let mut split_records = Vec::new();
        let mut index = 0;
        while index < count {
            let end = (index + options.per_shard).min(count);
            let samples = (index..end)
                .map(|i| sample(split, i, options))
                .collect::<Result<Vec<_>, _>>()?;
            let name = format!("shards/{split}-{:06}.tar", split_records.len());
            let (bytes, record) = build_shard(&name, split, &samples).map_err(|e| e.to_string())?;
            write_atomic(&options.out.join(&name), &bytes).map_err(|e| e.to_string())?;
            // The member records go beside the index (which lists shards only), covered by
            // the hash the index keeps of them.
            let record_name = format!("records/{split}-{:06}.json", split_records.len());
            // Shaped like bettimill's completion records: {"shard": ..., "regenerations": []}.
            let record_json = serde_json::to_vec_pretty(
                &serde_json::json!({"shard": &record, "regenerations": []}),
            )
            .map_err(|e| e.to_string())?;
            std::fs::create_dir_all(options.out.join("records")).map_err(|e| e.to_string())?;
            write_atomic(&options.out.join(&record_name), &record_json)
                .map_err(|e| e.to_string())?;
            member_count += record.members.len();
            split_records.push(record.index_entry(bettimill_shard::blake3_hex(&record_json)));
            index = end;
        }
        let wids = wids_index(split, &split_records);
        write_atomic(&options.out.join(format!("shardindex-{split}.json")), &wids)
            .map_err(|e| e.to_string())?;
        records.extend(split_records);
    }
    let index = Index::new(
        env!("CARGO_PKG_VERSION"),
        "demo-manifest",
        "demo-plan",
        records,
    );
    write_atomic(&options.out.join("index.json"), &index.to_json_bytes())
        .map_err(|e| e.to_string())?;
    let shards = index.shards.len();
    eprintln!(
        "wrote {shards} shards ({} train + {val_samples} val samples, {member_count} members, compression {}) to {}",
        options.samples,
        options.compression,
        display(&options.out)
    );
    Ok(())
}

fn display(path: &Path) -> String {
    path.display().to_string()
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match parse(&args).and_then(|options| run(&options)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("demo_shards: {message}");
            ExitCode::FAILURE
        }
    }
}
