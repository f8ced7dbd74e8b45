//! `bettimill plan`'s estimates: the cost model's fields
//! in `--json`, `--pilot` building and measuring real samples, and the model's compressed
//! size against a pilot's measured bytes, the line on carved tubes for the copies, and the
//! one on the attempts `survives_dilations` adds.
//! Nothing here compares times: CPU and wall seconds depend on the machine and its load,
//! bytes do not.

use std::path::{Path, PathBuf};

mod common;
use common::{run_in, text, Dir};

fn manifest(dir: &Path, name: &str, dimension: u32, side: u32, compression: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"{name}\"\ndimension = {dimension}\nside = {side}\n\
             mode = [\"embed\", \"carve\"]\nsamples = 16\nshard_size = 8\nseed = 5\n\
             compression = \"{compression}\"\n\n[[classes]]\nfamily = [\"ball\", \"handle\"]\n"
        ),
    )
    .unwrap();
    path
}

fn plan_json(dir: &Path, args: &[&str]) -> serde_json::Value {
    let out = run_in(dir, args);
    assert!(out.status.success(), "{}", text(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn json_has_the_model_estimates() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), "tiny", 2, 24, "gzip");
    let plan = plan_json(tmp.path(), &["plan", m.to_str().unwrap(), "--json"]);
    for key in [
        "estimated_bytes",
        "estimated_compressed_bytes",
        "estimated_seconds",
        "estimated_cpu_seconds",
        "estimated_cpu_seconds_per_sample",
        "estimate_cores",
        "compression",
    ] {
        assert!(plan.get(key).is_some(), "plan --json lacks {key}: {plan}");
    }
    assert_eq!(plan["compression"], "gzip");
    assert!(
        plan["pilot"].is_null(),
        "no pilot unless asked: {}",
        plan["pilot"]
    );
    let compressed = plan["estimated_compressed_bytes"].as_u64().unwrap();
    let bound = plan["estimated_bytes"].as_u64().unwrap();
    assert!(
        compressed > 0 && compressed <= bound,
        "{compressed} vs {bound}"
    );
    assert!(plan["estimated_cpu_seconds_per_sample"].as_f64().unwrap() > 0.0);
}

#[test]
fn pilot_prints_measured_figures() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), "tiny", 2, 24, "none");
    let out = run_in(tmp.path(), &["plan", m.to_str().unwrap(), "--pilot"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    let line = stdout
        .lines()
        .find(|l| l.starts_with("pilot (measured here: "))
        .unwrap_or_else(|| panic!("no pilot line in:\n{stdout}"));
    // Four strata (ball and handle, embed and carve), each built at least once.
    assert!(line.contains(" of 4 strata built in "), "{line}");
    assert!(
        line.contains("CPU-s a sample") || line.contains("CPU-s and"),
        "{line}"
    );
    assert!(stdout.contains("estimated output: about "), "{stdout}");
    // `--pilot 1`: one stratum.
    let plan = plan_json(
        tmp.path(),
        &["plan", m.to_str().unwrap(), "--pilot", "1", "--json"],
    );
    assert_eq!(plan["pilot"]["strata"], 1);
    assert!(plan["pilot"]["samples_built"].as_u64().unwrap() >= 1);
    // Nothing was written next to the manifest.
    let entries: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().collect();
    assert_eq!(entries.len(), 1, "{entries:?}");
}

/// The model's compressed bytes are within 2x of what a pilot measures (bytes, not time).
#[test]
fn model_bytes_are_within_2x_of_a_pilot() {
    let tmp = Dir::new();
    for (name, dimension, side, compression) in [
        ("a", 2, 48, "none"),
        ("b", 2, 64, "gzip"),
        ("c", 3, 24, "gzip"),
        ("d", 3, 32, "zstd"),
    ] {
        let m = manifest(tmp.path(), name, dimension, side, compression);
        let plan = plan_json(
            tmp.path(),
            &["plan", m.to_str().unwrap(), "--pilot", "--json"],
        );
        let model = plan["estimated_compressed_bytes"].as_f64().unwrap();
        let pilot = plan["pilot"]["estimated_compressed_bytes"]
            .as_f64()
            .unwrap();
        assert!(
            model <= 2.0 * pilot && pilot <= 2.0 * model,
            "{dimension}D side {side} {compression}: model {model} bytes, pilot {pilot}"
        );
    }
}

#[test]
fn plan_says_which_carved_strata_get_tubes_for_the_copies() {
    let tmp = Dir::new();
    // 4D side 32, copies at 16: a carved ball fits with 3-voxel tubes, a carved T2xB2
    // only with the usual 2 (embed strata are not counted).
    let path = tmp.path().join("copies.toml");
    std::fs::write(
        &path,
        "schema_version = 1\nname = \"copies\"\ndimension = 4\nside = 32\n\
         mode = [\"embed\", \"carve\"]\nsamples = 4\nshard_size = 4\nseed = 5\n\
         resolutions = [16]\n\n[[classes]]\nfamily = [\"ball\", \"t2_x_b2\"]\n",
    )
    .unwrap();
    let out = run_in(tmp.path(), &["plan", path.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains(
            "copies: carved tubes at least 3.00 voxels for the 16-side copy in 1 of 2 carved strata (the others: 2)"
        ),
        "{stdout}"
    );
    // Without copies, no such line.
    std::fs::write(
        &path,
        std::fs::read_to_string(&path)
            .unwrap()
            .replace("resolutions = [16]\n", ""),
    )
    .unwrap();
    let out = run_in(tmp.path(), &["plan", path.to_str().unwrap()]);
    assert!(!text(&out.stdout).contains("carved tubes"));
}

#[test]
fn plan_says_that_survives_dilations_adds_attempts_the_model_does_not_count() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), "checked", 3, 24, "none");
    let out = run_in(tmp.path(), &["plan", m.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(!text(&out.stdout).contains("survives_dilations"));
    let body = std::fs::read_to_string(&m).unwrap();
    std::fs::write(
        &m,
        body.replace("seed = 5\n", "seed = 5\nsurvives_dilations = 1\n"),
    )
    .unwrap();
    let out = run_in(tmp.path(), &["plan", m.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains("survives_dilations = 1: the model counts one attempt a sample")
            && stdout.contains("--pilot measures it"),
        "{stdout}"
    );
}
