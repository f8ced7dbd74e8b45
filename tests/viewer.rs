//! The HTML viewer (`bettimill preview DIR --key K --html OUT.html`) in a real headless
//! browser: the page is loaded with its sliders moved (through the address's
//! `#copy=..&k=..&l=..`, which the page applies by setting each slider and firing its
//! input event), a screenshot is taken, and every voxel of the slice shown is compared
//! with the pixel drawn for it; the page's own Betti numbers of the slice are compared
//! with the slice's computed here.
//!
//! The page itself (self-contained, every slice's data embedded) is checked in every run.
//! The browser part is a system test: it runs when BETTIMILL_SYSTEM_TESTS=1 (ci/test.sh
//! sets it and installs Chromium with ci/browser.sh). Without a browser it fails in CI
//! (CI=true) and is skipped elsewhere.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use bettimill_grid::BinaryImage;
use bettimill_preview::viewer::{voxel_classes, CAVITY, OUTSIDE, SOLID};
use bettimill_testkit::skip_unless_ci;
use common::{assert_exit, run_in, text, Dir};

const WINDOW: (u32, u32) = (1300, 1000);

/// A small dataset with downscaled copies: carved and embedded handles and balls.
fn dataset(dir: &Path, dimension: u32, side: u32) -> PathBuf {
    let manifest = dir.join(format!("v{dimension}.toml"));
    std::fs::write(
        &manifest,
        format!(
            "schema_version = 1\nname = \"v{dimension}\"\ndimension = {dimension}\nside = {side}\n\
             mode = [\"carve\", \"embed\"]\nsamples = 4\nshard_size = 4\nseed = 7\n\
             resolutions = [{}]\n\n[[classes]]\nfamily = [\"handle\", \"ball\"]\n",
            side / 2
        ),
    )
    .unwrap();
    let out = dir.join(format!("d{dimension}"));
    let built = run_in(
        dir,
        &[
            "build",
            "--quiet",
            manifest.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert_exit(&built, 0);
    out
}

/// The first carved sample of a dataset: its key, image and downscaled copies.
fn carved_sample(dir: &Path) -> bettimill_preview::SampleView {
    let shards = dir.join("shards");
    let mut names: Vec<PathBuf> = std::fs::read_dir(&shards)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    for shard in names {
        let bytes = std::fs::read(&shard).unwrap();
        for sample in bettimill_preview::samples_in_tar(&bytes, &mut |_| true).unwrap() {
            if sample.label.mode == "carve" {
                return sample;
            }
        }
    }
    panic!("no carved sample in {}", dir.display());
}

/// The browser, or `None` (skipped) outside CI when there is none.
fn chromium() -> Option<String> {
    let name = bettimill_env::var(bettimill_env::EnvVars::BETTIMILL_CHROMIUM)
        .unwrap_or_else(|| "chromium".to_string());
    match Command::new(&name).arg("--version").output() {
        Ok(out) if out.status.success() => Some(name),
        Ok(out) => {
            skip_unless_ci(
                "Chromium",
                &format!("{name} --version: {}", text(&out.stderr)),
            );
            None
        }
        Err(err) => {
            skip_unless_ci(
                "Chromium",
                &format!("{name}: {err} (install it with ci/browser.sh)"),
            );
            None
        }
    }
}

/// Runs headless Chromium on `url` with `action` (`--dump-dom` or `--screenshot=FILE`) in
/// a fresh profile; returns its stdout.
fn browse(chromium: &str, url: &str, action: &str) -> String {
    let profile = Dir::new();
    let out = Command::new("timeout")
        .arg("120")
        .arg(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
            &format!("--window-size={},{}", WINDOW.0, WINDOW.1),
            &format!("--user-data-dir={}", profile.path().display()),
            action,
            url,
        ])
        .output()
        .expect("chromium runs");
    assert!(
        out.status.success(),
        "chromium {action} {url}: {}\n{}",
        out.status,
        text(&out.stderr)
    );
    text(&out.stdout)
}

/// The value of attribute `name` of the element whose start tag begins with `tag` in
/// `dom`.
fn attribute(dom: &str, tag: &str, name: &str) -> String {
    let start = dom
        .find(tag)
        .unwrap_or_else(|| panic!("no {tag} in the page"));
    let element = &dom[start..start + dom[start..].find('>').unwrap()];
    let key = format!("{name}=\"");
    let at = element
        .find(&key)
        .unwrap_or_else(|| panic!("no {name} in {element}"))
        + key.len();
    element[at..at + element[at..].find('"').unwrap()].to_string()
}

/// The text of the element with id `id` in `dom`.
fn element_text(dom: &str, id: &str) -> String {
    let start = dom.find(&format!("id=\"{id}\"")).unwrap();
    let open = start + dom[start..].find('>').unwrap() + 1;
    dom[open..open + dom[open..].find('<').unwrap()].to_string()
}

/// An RGB screenshot: width, height, pixels.
fn decode_png(path: &Path) -> (usize, usize, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let (w, h) = (info.width as usize, info.height as usize);
    let mut rgb = Vec::with_capacity(w * h * 3);
    for p in buf[..info.buffer_size()].chunks(channels) {
        rgb.extend_from_slice(&p[..3]);
    }
    (w, h, rgb)
}

/// The 2D slice `a[:, :, k, l]` (3D: `a[:, :, k]`) of `image`, as its voxel values and
/// as an image of its own.
fn slice(image: &BinaryImage, k: usize, l: usize) -> BinaryImage {
    let s = image.shape();
    let mut data = Vec::new();
    for i in 0..s[0] {
        for j in 0..s[1] {
            let x: Vec<usize> = [i, j, k, l][..s.len()].to_vec();
            data.push(image.get(&x) as u8);
        }
    }
    BinaryImage::from_vec(&[s[0], s[1]], data).unwrap()
}

/// Loads the page at `#copy=NAME&k=K&l=L`, and checks the slice drawn, pixel by voxel,
/// and the Betti numbers shown against `image`'s slice.
/// Returns how many voxels of each class (outside, foreground, cavity) the slice holds.
fn check_view(
    chromium: &str,
    page: &Path,
    work: &Path,
    name: &str,
    image: &BinaryImage,
    k: usize,
    l: usize,
) -> [usize; 3] {
    let url = format!("file://{}#copy={name}&k={k}&l={l}", page.display());
    let dom = browse(chromium, &url, "--dump-dom");
    // The sliders moved where the address asked.
    assert_eq!(
        attribute(&dom, "<body", "data-view"),
        format!("{name} {k} {l}"),
        "{url}"
    );
    let left: usize = attribute(&dom, "<canvas id=\"view\"", "data-left")
        .parse()
        .unwrap();
    let top: usize = attribute(&dom, "<canvas id=\"view\"", "data-top")
        .parse()
        .unwrap();
    let zoom: usize = attribute(&dom, "<canvas id=\"view\"", "data-zoom")
        .parse()
        .unwrap();
    let plane = slice(image, k, l);
    let betti = bettimill_homology::topology(&plane).betti;
    let shown = element_text(&dom, "slice-betti");
    assert!(
        shown.ends_with(&format!(": [{}, {}]", betti[0], betti[1])),
        "{url}: the page shows {shown}, the slice has {betti:?}"
    );

    let shot = work.join(format!("{name}-{k}-{l}.png"));
    browse(chromium, &url, &format!("--screenshot={}", shot.display()));
    let (w, h, rgb) = decode_png(&shot);
    let classes = voxel_classes(image);
    let s = image.shape();
    let (rows, cols) = (s[0], s[1]);
    assert!(
        left + cols * zoom <= w && top + rows * zoom <= h,
        "{url}: the slice is off screen"
    );
    let mut counts = [0usize; 3];
    for i in 0..rows {
        for j in 0..cols {
            let x = match s.len() {
                2 => i * s[1] + j,
                3 => (i * s[1] + j) * s[2] + k,
                _ => ((i * s[1] + j) * s[2] + k) * s[3] + l,
            };
            let class = classes[x] as usize;
            assert_eq!(
                class == 1,
                plane.get(&[i, j]),
                "classes and voxels disagree"
            );
            counts[class] += 1;
            let expected = [OUTSIDE, SOLID, CAVITY][class];
            let (px, py) = (left + j * zoom + zoom / 2, top + i * zoom + zoom / 2);
            let at = (py * w + px) * 3;
            assert_eq!(
                &rgb[at..at + 3],
                &expected,
                "{url}: voxel ({i}, {j}) of class {class} is drawn at ({px}, {py}) in the wrong colour"
            );
        }
    }
    assert!(counts[1] > 0, "{url}: the slice has no foreground");
    counts
}

#[test]
fn the_viewer_page_is_self_contained_and_a_browser_draws_every_voxel_of_its_slices() {
    let tmp = Dir::new();
    let work = tmp.path();
    let mut pages = Vec::new();
    for (dimension, side) in [(4, 16), (3, 16)] {
        let dir = dataset(work, dimension, side);
        let sample = carved_sample(&dir);
        let page = work.join(format!("{}-{dimension}d.html", sample.key));
        let out = run_in(
            work,
            &[
                "preview",
                dir.to_str().unwrap(),
                "--key",
                &sample.key,
                "--html",
                page.to_str().unwrap(),
            ],
        );
        assert_exit(&out, 0);
        let html = std::fs::read_to_string(&page).unwrap();
        for outside in ["http://", "https://", " src=", " href="] {
            assert!(
                !html.contains(outside),
                "the page refers outside itself: {outside}"
            );
        }
        assert!(html.contains(&format!("<title>{} - bettimill viewer</title>", sample.key)));
        assert_eq!(sample.copies.len(), 1, "one downscaled copy");
        pages.push((page, sample));
    }
    // Only a .html file is written as a page.
    let refused = run_in(work, &["preview", "x.npy", "--html", "v.htm"]);
    assert_exit(&refused, 2);
    assert!(
        text(&refused.stderr).contains("--html v.htm"),
        "{}",
        text(&refused.stderr)
    );

    if !bettimill_testkit::system_tests() {
        #[allow(clippy::print_stderr)]
        {
            eprintln!("SKIPPED: the browser part runs with BETTIMILL_SYSTEM_TESTS=1 (ci/test.sh)");
        }
        return;
    }
    let Some(chromium) = chromium() else {
        return;
    };
    for (page, sample) in &pages {
        let image = &sample.image;
        let s = image.shape().to_vec();
        let (k_max, l_max) = (s[2], s.get(3).copied().unwrap_or(1));
        // Two positions of the sample's sliders, one through the middle of the cavity
        // region, and one of its downscaled copy.
        let middle = check_view(&chromium, page, work, "full", image, k_max / 2, l_max / 2);
        assert!(
            middle[2] > 0,
            "{}: no cavity through the middle",
            page.display()
        );
        check_view(
            &chromium,
            page,
            work,
            "full",
            image,
            k_max / 2 - 2,
            l_max.saturating_sub(1) / 3,
        );
        let (side, copy) = &sample.copies[0];
        let c = copy.shape().to_vec();
        check_view(
            &chromium,
            page,
            work,
            &format!("r{side}"),
            copy,
            c[2] / 2,
            c.get(3).copied().unwrap_or(1) / 2,
        );
    }
}
