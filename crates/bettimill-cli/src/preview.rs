//! `bettimill preview`: a PNG of one sample (or a contact sheet of several) from a dataset
//! directory, one shard, or a plain `.npy` image, and the browser viewer of one sample.

use crate::commands::ExitStatus;
use crate::printer::Printer;
use anyhow::{bail, Context};
use bettimill_format::{DatasetDir, DatasetSource, ShardStream, SourceShard};
use bettimill_preview::{
    caption, contact_sheet, guess_mode, label_mode, render_sample, samples_in_stream,
    short_caption, viewer_html, Canvas, SampleView, Subject, ViewerImage,
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
    pub out: Option<&'a Path>,
    /// The viewer page to write.
    pub html: Option<&'a Path>,
    /// Draw each sample's undeformed construction instead of its voxels.
    pub undeformed: bool,
    /// Where to say what was written.
    pub printer: Printer,
}

/// The dataset a command reads: `s3://BUCKET/PREFIX` (opened with the AWS_* variables, the
/// server and the credentials checked at once), otherwise a directory, which must exist.
pub(crate) fn open_source(dir: &Path) -> anyhow::Result<DatasetSource> {
    if let Some(url) = crate::commands::object_url(dir) {
        return Ok(DatasetSource::Bucket(
            bettimill_executor::remote::open_bucket(url, None)?,
        ));
    }
    if !dir.is_dir() {
        bail!(
            "{} is not a directory: give a dataset directory written by `bettimill build --out DIR`, or s3://BUCKET/PREFIX",
            dir.display()
        );
    }
    Ok(DatasetSource::Dir(DatasetDir::new(dir)))
}

/// The shards of a dataset in build order, with their splits (see
/// [`DatasetSource::shards`]); an error when there is none.
pub(crate) fn dataset_shards(source: &DatasetSource) -> anyhow::Result<Vec<SourceShard>> {
    let shards = source.shards()?;
    if shards.is_empty() {
        bail!(
            "{} holds no shards: give a dataset written by `bettimill build --out DIR`",
            source.location().display()
        );
    }
    Ok(shards)
}

/// Where a shard to read is: one of a dataset, or a plain `.tar` file.
pub(crate) enum ShardAt<'a> {
    /// Shard `name` of the dataset.
    InDataset(&'a DatasetSource, &'a str),
    /// A `.tar` file given by itself.
    File(&'a Path),
}

/// Opens a shard for reading member after member (see `DatasetSource::open_tar`: a
/// dataset's shard is checked against its completion record first, so a shard inflated to
/// gigabytes or replaced by a link to a device is refused by name before anything is read).
pub(crate) fn open_shard(at: ShardAt<'_>) -> anyhow::Result<ShardStream<'_>> {
    Ok(match at {
        ShardAt::InDataset(source, name) => {
            source.open_tar(name, bettimill_shard::ustar::DEFAULT_MAX_MEMBER_BYTES)?
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

/// The browser viewer of a sample read from a dataset: the sample, then its downscaled
/// copies, each with its label's Betti numbers.
fn sample_page(sample: &SampleView) -> anyhow::Result<String> {
    let shape: Vec<String> = sample.image.shape().iter().map(|n| n.to_string()).collect();
    let mut images = vec![ViewerImage {
        name: "full".to_string(),
        label: format!("the sample ({})", shape.join("x")),
        image: &sample.image,
        betti: sample.label.betti.clone(),
        note: "(verified)".to_string(),
    }];
    for (side, image) in &sample.copies {
        let label = sample.label.resolutions.iter().find(|r| r.side == *side);
        images.push(ViewerImage {
            name: format!("r{side}"),
            label: format!("downscaled to side {side}"),
            image,
            betti: label.map_or_else(Vec::new, |r| r.betti.clone()),
            note: match label {
                Some(r) if r.preserved => {
                    format!("({} pooling, topology preserved)", r.pooling.name())
                }
                Some(r) => format!("({} pooling, topology NOT preserved)", r.pooling.name()),
                None => "(no label for this copy)".to_string(),
            },
        });
    }
    let title = format!("{} - bettimill viewer", sample.key);
    Ok(viewer_html(
        &title,
        &caption(&sample.label),
        label_mode(&sample.label),
        &images,
    )?)
}

/// Replaces each sample's voxels by its undeformed construction (`--undeformed`): the
/// dataset's own manifest is planned again and each construction remade at the attempt its
/// label records, so a sheet of these beside the dataset's own shows what deformation did.
/// The caption's hypervolume becomes the construction's; the downscaled copies are dropped.
fn undeform(source: &DatasetSource, found: &mut [SampleView]) -> anyhow::Result<()> {
    let (text, path) = source.read_manifest_text().with_context(|| {
        format!(
            "--undeformed needs the dataset's {}",
            bettimill_format::dir::MANIFEST_FILE
        )
    })?;
    let plan = bettimill_plan::Plan::parse(&text, &path)?;
    for sample in found {
        let task = sample
            .key
            .strip_prefix('s')
            .and_then(|n| n.parse::<u64>().ok())
            .and_then(|index| plan.task(index))
            .filter(|task| task.key == sample.key)
            .with_context(|| {
                format!(
                    "sample {} is not a sample of {}",
                    sample.key,
                    path.display()
                )
            })?;
        let built = bettimill_sample::construction(&plan, &task, sample.label.attempt)?;
        sample.label.hypervolume = built.image.count_foreground();
        sample.image = built.image;
        sample.copies.clear();
    }
    Ok(())
}

/// Writes `bytes` to `path` and says so (a note: nothing with `--quiet`).
fn write_output(path: &Path, bytes: &[u8], what: &str, printer: Printer) -> anyhow::Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
    printer.note(format_args!("wrote {} ({what})", path.display()));
    Ok(())
}

/// Runs `bettimill preview`.
pub fn run(request: &Request) -> anyhow::Result<ExitStatus> {
    if let Some(out) = request.out {
        crate::stats::refuse_inside_dataset(out, "--out")?;
        crate::stats::require_extension(out, "--out", "png")?;
    }
    if let Some(html) = request.html {
        crate::stats::refuse_inside_dataset(html, "--html")?;
        crate::stats::require_extension(html, "--html", "html")?;
    }
    let input = request.input;
    let is_npy = crate::image::looks_like_image(input);
    let dataset = input.is_dir() || crate::commands::object_url(input).is_some();
    if request.undeformed && !dataset {
        bail!(
            "--undeformed remakes samples from a dataset directory's manifest; give the directory"
        );
    }
    let (canvas, page): (Option<Canvas>, Option<String>) = if is_npy {
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
            name.clone(),
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
        let canvas = match request.out {
            Some(_) => Some(render_sample(&subject, &lines)?),
            None => None,
        };
        let page = match request.html {
            Some(_) => Some(viewer_html(
                &format!("{name} - bettimill viewer"),
                &lines,
                subject.mode,
                &[ViewerImage {
                    name: "full".to_string(),
                    label: format!("the image ({})", shape.join("x")),
                    image,
                    betti: topology.betti.clone(),
                    note: "(computed now)".to_string(),
                }],
            )?),
            None => None,
        };
        (canvas, page)
    } else {
        let source = if dataset {
            Some(open_source(input)?)
        } else if input.extension().is_some_and(|e| e == "tar") {
            if !input.exists() {
                bail!("{} does not exist", input.display());
            }
            None
        } else {
            bail!(
                "{}: expected a dataset directory, s3://BUCKET/PREFIX, a .tar shard or a .npy image",
                input.display()
            );
        };
        let shards: Vec<(String, PathBuf)> = match &source {
            Some(source) => dataset_shards(source)?
                .into_iter()
                .map(|shard| {
                    let location = source.tar_location(&shard.name);
                    (shard.name, location)
                })
                .collect(),
            None => vec![(String::new(), input.to_path_buf())],
        };
        let want = request.n.unwrap_or(1);
        let mut found = Vec::new();
        for (name, shard) in &shards {
            let mut stream = open_shard(match &source {
                Some(source) => ShardAt::InDataset(source, name),
                None => ShardAt::File(shard),
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
        if let (true, Some(source)) = (request.undeformed, &source) {
            undeform(source, &mut found)?;
        }
        if found.is_empty() {
            match request.key {
                Some(key) => bail!(
                    "no sample with key {key} in {}; list the keys with `tar tf SHARD`",
                    input.display()
                ),
                None => bail!("{} holds no samples", input.display()),
            }
        }
        let canvas = match (request.out, request.n) {
            (None, _) => None,
            (Some(_), Some(_)) => {
                let tiles: Vec<_> = found
                    .iter()
                    .map(|s| (subject(s), short_caption(&s.label)))
                    .collect();
                Some(contact_sheet(&tiles)?)
            }
            (Some(_), None) => Some(render_sample(
                &subject(&found[0]),
                &caption(&found[0].label),
            )?),
        };
        let page = match request.html {
            Some(_) => Some(sample_page(&found[0])?),
            None => None,
        };
        (canvas, page)
    };
    if let (Some(path), Some(canvas)) = (request.out, &canvas) {
        let what = format!("{}x{} pixels", canvas.width(), canvas.height());
        write_output(path, &canvas.to_png()?, &what, request.printer)?;
    }
    if let (Some(path), Some(page)) = (request.html, &page) {
        let what = format!("{} KiB, open it in a browser", page.len().div_ceil(1024));
        write_output(path, page.as_bytes(), &what, request.printer)?;
    }
    Ok(ExitStatus::Success)
}
