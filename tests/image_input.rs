//! `betti`, `deform` and `preview` read a user's image as a dataset stores it: plain
//! `.npy`, `.npy.gz` or `.npy.zst` (told by content, not by name) or `-` for standard
//! input, with the same answer for all four; a hostile stream (a gzip that expands past the
//! header's size, a truncated zstd, a header promising too much) is one clear error, exit 2.

mod common;

use bettimill_grid::npy::{write_bytes, Dtype};
use bettimill_grid::BinaryImage;
use bettimill_shard::{compress, Compression};
use common::{assert_exit, stderr, stdout, text, Dir};
use std::path::Path;
use std::process::{Output, Stdio};

/// A hollow cube (b2) beside a ring (b1): Betti numbers [2, 1, 1].
fn image() -> BinaryImage {
    let mut img = BinaryImage::zeros(&[12, 7, 7]).unwrap();
    for x in 1..=5 {
        for y in 1..=5 {
            for z in 1..=5 {
                let inner = (2..=4).contains(&x) && (2..=4).contains(&y) && (2..=4).contains(&z);
                img.set(&[x, y, z], !inner);
            }
        }
    }
    for x in 8..=10 {
        for y in 2..=4 {
            if (x, y) != (9, 3) {
                img.set(&[x, y, 3], true);
            }
        }
    }
    img
}

fn betti_of(dir: &Dir, arg: &str, stdin_file: Option<&Path>) -> Output {
    let mut command = dir.command();
    command.args(["betti", arg, "--json"]);
    if let Some(file) = stdin_file {
        command.stdin(Stdio::from(std::fs::File::open(file).unwrap()));
    }
    command.output().expect("bettimill runs")
}

fn write_all_forms(dir: &Dir, npy: &[u8]) {
    std::fs::write(dir.join("img.npy"), npy).unwrap();
    std::fs::write(
        dir.join("img.npy.gz"),
        compress(npy, Compression::Gzip).unwrap(),
    )
    .unwrap();
    std::fs::write(
        dir.join("img.npy.zst"),
        compress(npy, Compression::Zstd).unwrap(),
    )
    .unwrap();
    // Named .npy but holding gzip: the content decides.
    std::fs::write(
        dir.join("misnamed.npy"),
        compress(npy, Compression::Gzip).unwrap(),
    )
    .unwrap();
}

#[test]
fn betti_reads_plain_gzip_zstd_and_stdin_alike() {
    let dir = Dir::new();
    write_all_forms(&dir, &write_bytes(&image(), Dtype::U8));
    let mut answers = Vec::new();
    for (arg, stdin) in [
        ("img.npy", None),
        ("img.npy.gz", None),
        ("img.npy.zst", None),
        ("misnamed.npy", None),
        ("-", Some("img.npy")),
        ("-", Some("img.npy.gz")),
        ("-", Some("img.npy.zst")),
    ] {
        let out = betti_of(&dir, arg, stdin.map(|s| dir.join(s)).as_deref());
        assert_exit(&out, 0);
        let value: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
        assert_eq!(
            value["betti"],
            serde_json::json!([2, 1, 1]),
            "{arg} {stdin:?}"
        );
        answers.push(stdout(&out));
    }
    assert!(answers.iter().all(|a| a == &answers[0]), "{answers:?}");
}

#[test]
fn deform_and_preview_read_compressed_images_too() {
    let dir = Dir::new();
    write_all_forms(&dir, &write_bytes(&image(), Dtype::U8));
    for input in ["img.npy", "img.npy.zst"] {
        let out = dir.run(&[
            "deform",
            input,
            "--out",
            "moved.npy",
            "--method",
            "moves",
            "--steps",
            "20",
        ]);
        assert_exit(&out, 0);
        let moved = betti_of(&dir, "moved.npy", None);
        assert_exit(&moved, 0);
        assert!(stdout(&moved).contains("[2,1,1]"), "{}", stdout(&moved));
    }
    let mut pngs = Vec::new();
    for input in ["img.npy", "img.npy.gz", "img.npy.zst"] {
        let out = dir.run(&["preview", input, "--out", "p.png"]);
        assert_exit(&out, 0);
        pngs.push(std::fs::read(dir.join("p.png")).unwrap());
    }
    // The tile's caption names the file; the pictures are PNGs of the same size.
    for png in &pngs {
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        assert_eq!(png[16..24], pngs[0][16..24], "same width and height");
    }
}

fn check_refused(dir: &Dir, name: &str, needles: &[&str]) {
    for (arg, stdin) in [(name, None), ("-", Some(dir.join(name)))] {
        let out = betti_of(dir, arg, stdin.as_deref());
        assert_exit(&out, 2);
        let err = stderr(&out);
        assert_eq!(err.trim_end().lines().count(), 1, "{name}: {err}");
        assert!(err.starts_with("error: cannot use "), "{name}: {err}");
        for needle in needles {
            assert!(
                err.contains(needle),
                "{name} via {arg}: {err} lacks {needle}"
            );
        }
        assert!(out.stdout.is_empty(), "{}", text(&out.stdout));
    }
}

#[test]
fn hostile_streams_are_refused_with_exit_code_2() {
    let dir = Dir::new();
    let npy = write_bytes(&image(), Dtype::U8);
    // A gzip that goes on for 16 MiB past the 588 bytes its header promises: refused
    // after one byte too many, not expanded.
    let mut bomb = npy.clone();
    bomb.resize(npy.len() + (16 << 20), 0);
    std::fs::write(
        dir.join("bomb.npy.gz"),
        compress(&bomb, Compression::Gzip).unwrap(),
    )
    .unwrap();
    check_refused(&dir, "bomb.npy.gz", &["gzip", "past the 588 bytes"]);
    // A zstd cut in the middle of its frame.
    let zst = compress(&npy, Compression::Zstd).unwrap();
    std::fs::write(dir.join("cut.npy.zst"), &zst[..zst.len() / 2]).unwrap();
    check_refused(&dir, "cut.npy.zst", &["zstd", "incomplete frame"]);
    // A header promising 2^60 bytes is refused before anything is read.
    let dict = "{'descr': '|u1', 'fortran_order': False, 'shape': (1073741824, 1073741824), }";
    let mut huge = b"\x93NUMPY\x01\x00".to_vec();
    let padded = format!("{dict:<117}\n");
    huge.extend_from_slice(&(padded.len() as u16).to_le_bytes());
    huge.extend_from_slice(padded.as_bytes());
    assert_eq!(huge.len() % 64, 0);
    std::fs::write(
        dir.join("huge.npy.zst"),
        compress(&huge, Compression::Zstd).unwrap(),
    )
    .unwrap();
    check_refused(&dir, "huge.npy.zst", &["more than the 17179869184 allowed"]);
    // Not an image at all, compressed or not.
    std::fs::write(
        dir.join("junk.npy.gz"),
        compress(b"junk", Compression::Gzip).unwrap(),
    )
    .unwrap();
    check_refused(&dir, "junk.npy.gz", &["gzip", "magic"]);
    let out = dir
        .command()
        .args(["betti", "-"])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert_exit(&out, 2);
    assert!(stderr(&out).contains("standard input"), "{}", stderr(&out));
}
