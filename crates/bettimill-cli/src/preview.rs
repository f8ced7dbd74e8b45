//! `bettimill preview`: a PNG of one sample (or a contact sheet of several) from a dataset
//! directory, one shard, or a plain `.npy` image.

use crate::commands::ExitStatus;
use anyhow::{bail, Context};
use bettimill_format::{DatasetDir, ShardStream};
use bettimill_preview::{
    caption, contact_sheet, guess_mode, label_mode, render_sample, samples_in_stream,
    short_caption, Subject,
};
use std::path::{Path, PathBuf};

/// What to draw.
pub struct Request<'a> {
    /// A dataset directory, a `.tar` shard or a `.npy` image.
    pub input: &'a Path,
    /// One sample by key.
    pub key: Option<&'a str>,
    /// A contact sheet of the first `n` samples.
    pub n: Option<usize>,
    /// The PNG to write.
    pub out: &'a Path,
    /// Say nothing on success.
    pub quiet: bool,
}

/// The shards of a dataset directory in build order, with their splits: from `index.json`
/// when the build is finished, otherwise every `shards/*.tar` by name, its split taken from
/// its completion record (`unknown` without one). Each is (split, shard name).
pub(crate) fn dataset_shards(dir: &Path) -> anyhow::Result<Vec<(String, String)>> {
    let layout = DatasetDir::new(dir);
    if layout.is_finalized() {
        let index = bettimill_shard::Index::read(&layout.index_path())?;
        return Ok(index
            .shards
            .iter()
            .map(|s| (s.split.clone(), DatasetDir::shard_stem(&s.name).to_string()))
            .collect());
    }
    let names = layout.shard_names()?;
    if names.is_empty() {
        bail!(
            "{} holds no shards: give a directory written by `bettimill build --out DIR`",
            dir.display()
        );
    }
    Ok(names
        .into_iter()
        .map(|name| {
            let split = match layout.read_record(&name) {
                Ok(Some(record)) => record.shard.split,
                _ => "unknown".to_string(),
            };
            (split, name)
        })
        .collect())
}

/// Where a shard to read is: one of a dataset directory, or a plain `.tar` file.
pub(crate) enum ShardAt<'a> {
    /// Shard `name` of the dataset directory.
    InDataset(&'a DatasetDir, &'a str),
    /// A `.tar` file given by itself.
    File(&'a Path),
}

/// Opens a shard for reading member after member (see `DatasetDir::open_tar`: a dataset's
/// shard is checked against its completion record first, so a shard inflated to gigabytes
/// or replaced by a link to a device is refused by name before anything is read).
pub(crate) fn open_shard(at: ShardAt) -> anyhow::Result<ShardStream> {
    Ok(match at {
        ShardAt::InDataset(layout, name) => {
            layout.open_tar(name, bettimill_shard::ustar::DEFAULT_MAX_MEMBER_BYTES)?
        }
        ShardAt::File(path) => bettimill_format::open_tar_file(
            path,
            None,
            bettimill_shard::ustar::DEFAULT_MAX_MEMBER_BYTES,
        )
        .with_context(|| format!("cannot read shard {}", path.display()))?,
    })
}

/// What the picture of a sample read from a shard knows: its label's mode and Betti numbers.
fn subject(sample: &bettimill_preview::SampleView) -> Subject<'_> {
    Subject {
        image: &sample.image,
        mode: label_mode(&sample.label),
        betti: &sample.label.betti,
    }
}

/// Runs `bettimill preview`.
pub fn run(request: &Request) -> anyhow::Result<ExitStatus> {
    crate::stats::refuse_inside_dataset(request.out, "--out")?;
    crate::stats::require_extension(request.out, "--out", "png")?;
    let input = request.input;
    let is_npy = crate::image::looks_like_image(input);
    let canvas = if is_npy {
        if request.key.is_some() || request.n.is_some() {
            bail!("--key and --n pick samples of a dataset or shard; a .npy file is one image");
        }
        let npy = crate::image::read_image(input, false)?;
        let topology = bettimill_homology::try_topology(&npy.image)?;
        let image = &npy.image;
        let shape: Vec<String> = image.shape().iter().map(|n| n.to_string()).collect();
        let name = input
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let lines = vec![
            name,
            format!(
                "betti {}  euler {}  (Z/2, computed now)",
                bettimill_preview::render::betti_text(&topology.betti),
                topology.euler
            ),
            format!(
                "hypervolume {} of {} voxels  shape {}",
                image.count_foreground(),
                image.len(),
                shape.join("x")
            ),
        ];
        let subject = Subject {
            image,
            mode: guess_mode(image),
            betti: &topology.betti,
        };
        render_sample(&subject, &lines)?
    } else {
        let layout = DatasetDir::new(input);
        let shards: Vec<(String, PathBuf)> = if input.is_dir() {
            dataset_shards(input)?
                .into_iter()
                .map(|(_, name)| {
                    let path = layout.tar_path(&name);
                    (name, path)
                })
                .collect()
        } else if input.extension().is_some_and(|e| e == "tar") {
            if !input.exists() {
                bail!("{} does not exist", input.display());
            }
            vec![(String::new(), input.to_path_buf())]
        } else {
            bail!(
                "{}: expected a dataset directory, a .tar shard or a .npy image",
                input.display()
            );
        };
        let want = request.n.unwrap_or(1);
        let mut found = Vec::new();
        for (name, shard) in &shards {
            let mut stream = open_shard(if input.is_dir() {
                ShardAt::InDataset(&layout, name)
            } else {
                ShardAt::File(shard)
            })?;
            let mut keep = |key: &str| match request.key {
                Some(wanted) => key == wanted,
                None => found.len() < want,
            };
            let mut samples = samples_in_stream(&mut stream, &mut keep)
                .with_context(|| format!("cannot read samples of {}", shard.display()))?;
            found.append(&mut samples);
            if found.len() >= want {
                break;
            }
        }
        found.truncate(want);
        if found.is_empty() {
            match request.key {
                Some(key) => bail!(
                    "no sample with key {key} in {}; list the keys with `tar tf SHARD`",
                    input.display()
                ),
                None => bail!("{} holds no samples", input.display()),
            }
        }
        if request.n.is_some() {
            let tiles: Vec<_> = found
                .iter()
                .map(|s| (subject(s), short_caption(&s.label)))
                .collect();
            contact_sheet(&tiles)?
        } else {
            render_sample(&subject(&found[0]), &caption(&found[0].label))?
        }
    };
    let png = canvas.to_png()?;
    std::fs::write(request.out, &png)
        .with_context(|| format!("cannot write {}", request.out.display()))?;
    if !request.quiet {
        eprintln!(
            "wrote {} ({}x{} pixels)",
            request.out.display(),
            canvas.width(),
            canvas.height()
        );
    }
    Ok(ExitStatus::Success)
}
