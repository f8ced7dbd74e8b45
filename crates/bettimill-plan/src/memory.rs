//! How much memory a worker needs for a plan, and the refusal of a plan whose samples
//! cannot fit.
//!
//! The estimate is a pure function of the plan (the caller passes the limit, see
//! `--max-memory` in the CLI; only [`available`], for the checks of single images, reads
//! the machine):
//!
//! ```text
//! worker bytes = threads x (B x voxels + FIXED_BYTES)       one sample per thread
//!              + SHARD_COPIES x largest shard x sample_bytes  the shard being written
//!                (uncompressed members; with gzip or zstd members: 1 x sample_bytes)
//! ```
//!
//! `B` is the peak stage's memory per voxel of the sample's side^d grid (the image, the
//! homology's padded copy and complex, the deformation's and the targeting's buffers, the
//! serialised arrays), measured with `/usr/bin/time -v` (maximum resident set) on
//! one-sample builds of several sides (docs/reliability.md, "Memory per sample"), rounded up
//! with room to spare. In 2D and 3D it is [`PEAK_BYTES_PER_VOXEL`]. A 4D sample's image is
//! one byte a voxel and the rest grows with its topological phase (the objects in embed
//! mode, the cavities in carve mode), which targeting walks voxel by voxel: a binned carve
//! sample with 40% of its image in cavities peaks at 6-7 bytes a voxel, the 4D mixed 128
//! preset's 7% at 2.5, so `B` = [`SAMPLE_BYTES_PER_VOXEL_4D`] + [`PHASE_BYTES_4D`] x the
//! largest phase share the plan's bins allow ([`UNBINNED_PHASE_SHARE`] without bins).
//! [`PEAK_BYTES_PER_VOXEL`]'s 4D figure, the homology of an arbitrary array (a random
//! image's complex is most of the image), stays for [`image_bytes`].
//!
//! The largest shard is `shard_size` samples, or the largest split when every split is
//! smaller. `sample_bytes` is the plan's upper bound of one sample's uncompressed bytes in
//! a shard; a worker holds a shard's members once, and streams the tar from them to its
//! file, so one copy of an uncompressed shard.
//! With compressed members the shard's size depends on the data, not the plan: the estimate
//! counts the one sample being compressed, and the compressed members (a few percent of it
//! for these images) are not counted.
//!
//! Estimates are upper bounds for planning, not promises: a worker that needs more than the
//! limit is refused before it starts rather than killed by the kernel after minutes.

use crate::Plan;
use bettimill_grid::Mode;

/// Peak bytes per voxel of one sample in 2D and 3D, and of the homology of an arbitrary
/// array in 2D, 3D and 4D (see the module documentation).
pub const PEAK_BYTES_PER_VOXEL: [u64; 3] = [24, 24, 16];

/// A 4D sample's peak bytes per voxel before its phase's share (see the module
/// documentation).
pub const SAMPLE_BYTES_PER_VOXEL_4D: f64 = 4.0;

/// A 4D sample's further peak bytes per voxel of the image per unit of its phase's share.
pub const PHASE_BYTES_4D: f64 = 10.0;

/// The phase share assumed for a stratum without bins: its constructions are sized to fit,
/// not to fill, and deformation touches only their frontier.
pub const UNBINNED_PHASE_SHARE: f64 = 0.1;

/// Memory of a worker process before any sample: the binary, the plan, thread stacks,
/// allocator arenas.
pub const FIXED_BYTES: u64 = 32 << 20;

/// Copies of a shard's bytes a worker holds at once while writing it: its members, from
/// which the tar is streamed to its file.
pub const SHARD_COPIES: u64 = 1;

/// A plan whose worker needs more memory than allowed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "one worker of dataset {name} ({dim}D, side {side}: {voxels} voxels a sample, {shard_size} \
     samples a shard) needs about {need} (estimate: {per_voxel} bytes per voxel + {fixed} a sample, \
     + {shard} for the shard being written), more than the {limit} allowed per worker \
     ({limit_origin}); lower `side` or `shard_size` in the manifest, use fewer workers, or raise \
     --max-memory if the machine really has the memory"
)]
pub struct MemoryError {
    /// The dataset name.
    pub name: String,
    /// Number of axes.
    pub dim: usize,
    /// Voxels per axis.
    pub side: u32,
    /// Voxels of one sample.
    pub voxels: u64,
    /// Samples of the largest shard.
    pub shard_size: u64,
    /// The estimate, in words (`5.3 GiB`).
    pub need: String,
    /// The per-voxel factor used, in words (`4.7`).
    pub per_voxel: String,
    /// The fixed part, in words.
    pub fixed: String,
    /// The shard part, in words.
    pub shard: String,
    /// The limit, in words.
    pub limit: String,
    /// Where the limit came from (`--max-memory 8 GiB`, `80% of MemAvailable ...`).
    pub limit_origin: String,
    /// The estimate in bytes.
    pub need_bytes: u64,
    /// The limit in bytes.
    pub limit_bytes: u64,
}

/// One worker's estimated memory for `plan`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorkerMemory {
    /// Voxels of one sample (side^d).
    pub voxels: u64,
    /// Peak bytes per voxel of one sample ([`sample_bytes_per_voxel`]).
    pub bytes_per_voxel: f64,
    /// One sample in flight: `bytes_per_voxel x voxels + FIXED_BYTES`.
    pub sample_bytes: u64,
    /// The shard being written: `SHARD_COPIES x largest shard x sample_bytes` uncompressed,
    /// `sample_bytes` with compressed members.
    pub shard_bytes: u64,
}

impl WorkerMemory {
    /// The estimate of `plan` (saturating: a 4D side 65535 does not overflow).
    pub fn of(plan: &Plan) -> WorkerMemory {
        let d = plan.dimension.get();
        let voxels = (plan.side as u64).saturating_pow(d as u32);
        let bytes_per_voxel = sample_bytes_per_voxel(plan);
        WorkerMemory {
            voxels,
            bytes_per_voxel,
            // Saturating: `as` clamps a float above u64::MAX.
            sample_bytes: ((bytes_per_voxel * voxels as f64).ceil() as u64)
                .saturating_add(FIXED_BYTES),
            shard_bytes: if plan.compression == bettimill_shard::Compression::None {
                SHARD_COPIES
                    .saturating_mul(plan.largest_shard())
                    .saturating_mul(plan.sample_bytes)
            } else {
                plan.sample_bytes
            },
        }
    }

    /// Bytes of a worker running `threads` samples at once.
    pub fn total(&self, threads: u64) -> u64 {
        self.sample_bytes
            .saturating_mul(threads.max(1))
            .saturating_add(self.shard_bytes)
    }
}

/// Peak bytes per voxel of one of `plan`'s samples (see the module documentation).
pub fn sample_bytes_per_voxel(plan: &Plan) -> f64 {
    let d = plan.dimension.get();
    if d != 4 {
        return PEAK_BYTES_PER_VOXEL[d - 2] as f64;
    }
    let voxels = (plan.side as f64).powi(4);
    let share = plan
        .strata
        .iter()
        .map(|stratum| match stratum.hypervolume {
            None => UNBINNED_PHASE_SHARE,
            Some((low, high)) => match stratum.mode {
                Mode::Embed => high as f64 / voxels,
                Mode::Carve => (voxels - low as f64) / voxels,
            },
        })
        .fold(0.0, f64::max)
        .clamp(0.0, 1.0);
    SAMPLE_BYTES_PER_VOXEL_4D + PHASE_BYTES_4D * share
}

/// Refuses `plan` when one worker running `threads` samples at once needs more than
/// `limit` bytes; `limit_origin` says where the limit came from, for the message.
pub fn check(
    plan: &Plan,
    threads: u64,
    limit: u64,
    limit_origin: &str,
) -> Result<(), Box<MemoryError>> {
    let estimate = WorkerMemory::of(plan);
    let need = estimate.total(threads);
    if need <= limit {
        return Ok(());
    }
    Err(Box::new(MemoryError {
        name: plan.name.clone(),
        dim: plan.dimension.get(),
        side: plan.side,
        voxels: estimate.voxels,
        shard_size: plan.largest_shard(),
        need: human_bytes(need),
        per_voxel: format!("{:.1}", estimate.bytes_per_voxel),
        fixed: human_bytes(FIXED_BYTES),
        shard: human_bytes(estimate.shard_bytes),
        limit: human_bytes(limit),
        limit_origin: limit_origin.to_string(),
        need_bytes: need,
        limit_bytes: limit,
    }))
}

/// Peak bytes of computing one image of `voxels` voxels in `dim` dimensions (the Betti
/// numbers of a user's array, or one sample): [`PEAK_BYTES_PER_VOXEL`] per voxel plus
/// [`FIXED_BYTES`], saturating.
pub fn image_bytes(dim: usize, voxels: u64) -> u64 {
    PEAK_BYTES_PER_VOXEL[dim.clamp(2, 4) - 2]
        .saturating_mul(voxels)
        .saturating_add(FIXED_BYTES)
}

/// The memory this process can still get: the smaller of /proc/meminfo's MemAvailable and
/// the room left under its address-space limit (`ulimit -v`: its limit less its VmSize);
/// `None` when neither is known (no /proc). The one place in this module that reads the
/// machine, for the callers that must refuse an input before allocating for it.
pub fn available() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let mem_available = meminfo
        .as_deref()
        .and_then(|text| kib_field(text, "MemAvailable:"));
    let address_room = std::fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|limits| {
            let line = limits
                .lines()
                .find(|l| l.starts_with("Max address space"))?;
            // "Max address space  <soft>  <hard>  bytes": the soft limit binds.
            line["Max address space".len()..]
                .split_whitespace()
                .next()?
                .parse::<u64>()
                .ok()
        })
        .map(|limit| {
            let used = std::fs::read_to_string("/proc/self/status")
                .ok()
                .and_then(|status| kib_field(&status, "VmSize:"))
                .unwrap_or(0);
            limit.saturating_sub(used)
        });
    match (mem_available, address_room) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// A `NAME:   N kB` line of a /proc file, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let kib: u64 = text
        .lines()
        .find_map(|l| l.strip_prefix(name))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kib.saturating_mul(1024))
}

/// An image that needs more memory than is available; its message has both numbers.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ImageTooLarge(pub String);

/// Refuses an image of `voxels` voxels in `dim` dimensions when computing it needs more
/// than the memory available ([`available`]), with both numbers in words; `what` names the
/// image (`"the array"`, `"sample 0"`).
pub fn admit_image(what: &str, dim: usize, voxels: u64) -> Result<(), ImageTooLarge> {
    let need = image_bytes(dim, voxels);
    match available() {
        Some(room) if need > room => Err(ImageTooLarge(format!(
            "{what} ({dim}D, {voxels} voxels) needs about {} of memory ({} bytes per voxel + {}), \
             more than the {} available (MemAvailable, or the room under the address-space limit)",
            human_bytes(need),
            PEAK_BYTES_PER_VOXEL[dim.clamp(2, 4) - 2],
            human_bytes(FIXED_BYTES),
            human_bytes(room)
        ))),
        _ => Ok(()),
    }
}

impl Plan {
    /// Samples of the largest shard: `shard_size`, unless every split is smaller.
    pub fn largest_shard(&self) -> u64 {
        self.splits
            .iter()
            .map(|(_, size)| (*size).min(self.shard_size))
            .max()
            .unwrap_or(0)
    }
}

/// Bytes in binary units: `512 B`, `5.6 MiB`, `3.2 TiB`.
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 7] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// Why [`parse_bytes`] refuses a memory size.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MemorySizeError {
    /// No number where the size starts.
    #[error("{0:?} is not a memory size (write e.g. 8G, 512M or 1073741824)")]
    NotANumber(String),
    /// A unit other than K, M, G, T.
    #[error("{0:?} has an unknown unit (use K, M, G or T, powers of 1024)")]
    UnknownUnit(String),
    /// Less than a byte, or more than 64 bits hold.
    #[error("{0:?} is not a memory size of at least 1 byte")]
    OutOfRange(String),
}

/// Parses a memory size as written on a command line: a number of bytes, or a number with a
/// unit `K`, `M`, `G`, `T` (powers of 1024; `KiB`, `MB`, `GB` ... are read the same way).
pub fn parse_bytes(text: &str) -> Result<u64, MemorySizeError> {
    let trimmed = text.trim();
    let split = trimmed
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(trimmed.len());
    let (number, unit) = trimmed.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| MemorySizeError::NotANumber(text.to_string()))?;
    let unit = unit.trim().to_ascii_uppercase();
    let unit = unit.trim_end_matches('B').trim_end_matches('I');
    let scale: u64 = match unit {
        "" => 1,
        "K" => 1 << 10,
        "M" => 1 << 20,
        "G" => 1 << 30,
        "T" => 1 << 40,
        _ => return Err(MemorySizeError::UnknownUnit(text.to_string())),
    };
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(MemorySizeError::OutOfRange(text.to_string()));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use bettimill_manifest::Manifest;
    use std::path::Path;

    fn plan(dimension: u32, side: u32, shard_size: u64) -> Plan {
        plan_compressed(dimension, side, shard_size, "none")
    }

    fn plan_compressed(dimension: u32, side: u32, shard_size: u64, compression: &str) -> Plan {
        let text = format!(
            "schema_version = 1\nname = \"m\"\ndimension = {dimension}\nside = {side}\n\
             mode = \"embed\"\nsamples = 10\nshard_size = {shard_size}\nseed = 1\n\
             compression = \"{compression}\"\n[[classes]]\nfamily = \"ball\"\n"
        );
        Plan::new(&Manifest::parse(&text, Path::new("m.toml")).unwrap()).unwrap()
    }

    #[test]
    fn the_estimate_follows_the_documented_formula() {
        let p = plan(4, 32, 4);
        let m = WorkerMemory::of(&p);
        assert_eq!(m.voxels, 1 << 20);
        // Unbinned 4D: the assumed phase share.
        assert_eq!(
            m.sample_bytes,
            ((SAMPLE_BYTES_PER_VOXEL_4D + PHASE_BYTES_4D * UNBINNED_PHASE_SHARE)
                * (1u64 << 20) as f64) as u64
                + FIXED_BYTES
        );
        let three = WorkerMemory::of(&plan(3, 32, 4));
        assert_eq!(
            three.sample_bytes,
            PEAK_BYTES_PER_VOXEL[1] * (1 << 15) + FIXED_BYTES
        );
        assert_eq!(m.shard_bytes, SHARD_COPIES * 4 * p.sample_bytes);
        assert_eq!(m.total(2), 2 * m.sample_bytes + m.shard_bytes);
        // Compressed members: the one sample being compressed.
        let zstd = plan_compressed(4, 32, 4, "zstd");
        assert_eq!(WorkerMemory::of(&zstd).shard_bytes, zstd.sample_bytes);
        // 4D side 254 (the largest a manifest accepts) is 4.16 billion voxels: far beyond
        // any workstation.
        let huge = WorkerMemory::of(&plan(4, 254, 1));
        assert_eq!(huge.voxels, 254u64.pow(4));
        assert!(huge.total(1) > 20 << 30);
    }

    fn binned_4d(mode: &str, bin: (f64, f64)) -> Plan {
        let text = format!(
            "schema_version = 1\nname = \"m\"\ndimension = 4\nside = 32\n\
             mode = \"{mode}\"\nsamples = 10\nshard_size = 4\nseed = 1\n\
             [hypervolume]\nunit = \"fraction\"\nbins = [[{}, {}]]\n\
             [[classes]]\nfamily = \"ball\"\n",
            bin.0, bin.1
        );
        Plan::new(&Manifest::parse(&text, Path::new("m.toml")).unwrap()).unwrap()
    }

    /// A 4D sample's bytes per voxel grow with the share of the image its bins leave to
    /// the phase: the objects' upper end in embed mode, the cavities' (one less the
    /// solid's lower end) in carve mode.
    #[test]
    fn the_4d_estimate_follows_the_phase_share_the_bins_allow() {
        let per_voxel = |p: &Plan| sample_bytes_per_voxel(p);
        let close = |a: f64, b: f64| (a - b).abs() < 0.01;
        assert!(close(per_voxel(&binned_4d("embed", (0.02, 0.05))), 4.5));
        assert!(close(per_voxel(&binned_4d("carve", (0.60, 0.62))), 8.0));
        assert!(
            per_voxel(&binned_4d("carve", (0.40, 0.42)))
                > per_voxel(&binned_4d("carve", (0.60, 0.62)))
        );
    }

    #[test]
    fn a_sample_above_the_limit_is_refused_with_the_numbers() {
        let p = plan(4, 254, 1);
        let err = check(&p, 1, 8 << 30, "--max-memory 8G").unwrap_err();
        let text = err.to_string();
        for needle in [
            "side 254",
            "4162314256 voxels",
            "8.0 GiB allowed per worker (--max-memory 8G)",
            "raise --max-memory",
        ] {
            assert!(text.contains(needle), "{needle:?} not in {text}");
        }
        assert!(err.need_bytes > err.limit_bytes);
        check(&plan(3, 24, 4), 1, 8 << 30, "x").unwrap();
    }

    /// 10 samples of 3D side 128 with `shard_size = 100000` were refused as needing
    /// 392.7 GiB a worker (the estimate took 100000 samples a shard), while the same data
    /// with `shard_size = 10` needed 120 MiB: the shard part counts the largest real shard.
    #[test]
    fn the_estimate_counts_the_largest_real_shard_not_shard_size() {
        let huge = plan(3, 128, 100_000);
        let ten = plan(3, 128, 10);
        assert_eq!(huge.largest_shard(), 10);
        assert_eq!(WorkerMemory::of(&huge), WorkerMemory::of(&ten));
        check(&huge, 1, 1 << 30, "x").unwrap();
        assert_eq!(plan(3, 128, 4).largest_shard(), 4);
        let err = check(&plan(4, 254, 100_000), 1, 8 << 30, "x").unwrap_err();
        assert!(err.to_string().contains("10 samples a shard"), "{err}");
    }

    #[test]
    fn an_image_beyond_any_memory_is_refused_with_the_numbers() {
        // 10^12 voxels (a broadcast 10^6 x 10^6 array) need 22 TiB: more than any machine
        // this runs on has.
        let err = admit_image("the array", 2, 1_000_000_000_000)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("the array (2D, 1000000000000 voxels) needs about 21.8 TiB"),
            "{err}"
        );
        admit_image("the array", 3, 1000).unwrap();
        if std::path::Path::new("/proc/meminfo").exists() {
            assert!(available().is_some_and(|bytes| bytes > 0));
        }
    }

    #[test]
    fn sizes_parse_as_written() {
        assert_eq!(parse_bytes("1073741824"), Ok(1 << 30));
        assert_eq!(parse_bytes("8G"), Ok(8 << 30));
        assert_eq!(parse_bytes("8GiB"), Ok(8 << 30));
        assert_eq!(parse_bytes("512 MB"), Ok(512 << 20));
        assert_eq!(parse_bytes("1.5k"), Ok(1536));
        assert!(parse_bytes("lots").is_err());
        assert!(parse_bytes("8X").is_err());
        assert!(parse_bytes("0").is_err());
    }
}
