//! What a user sees: `--help` snapshots, one-line errors for typical mistakes, `--json`
//! outputs, previews and statistics, shell completions, and the README's tour run as
//! written. Every test runs the real binary in a fresh temporary directory.
//!
//! Help snapshots live in `tests/snapshots/help-*.txt`; after a deliberate change to a
//! command's help, run `UPDATE_SNAPSHOTS=1 cargo test -p bettimill-cli --test cli_ux` and
//! review the diff.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

mod common;
use common::{repo_root, run_in, text, Dir, BETTIMILL};

fn check_snapshot(name: &str, actual: &str) {
    let path = repo_root().join("tests/snapshots").join(name);
    if bettimill_env::var(bettimill_env::EnvVars::UPDATE_SNAPSHOTS).is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, actual).unwrap();
        return;
    }
    let expected = std::fs::read_to_string(&path).unwrap_or_else(|_| {
        panic!(
            "no snapshot {}; create it with UPDATE_SNAPSHOTS=1 cargo test -p bettimill-cli --test cli_ux",
            path.display()
        )
    });
    assert!(
        expected == actual,
        "{name} differs from its snapshot {}.\n--- expected\n{expected}\n--- actual\n{actual}\n\
         If the change is deliberate: UPDATE_SNAPSHOTS=1 cargo test -p bettimill-cli --test cli_ux",
        path.display()
    );
}

/// The visible subcommands, read from the top-level help.
fn subcommands(tmp: &Path) -> Vec<String> {
    let help = text(&run_in(tmp, &["--help"]).stdout);
    let section = help
        .split("Commands:\n")
        .nth(1)
        .expect("the help lists commands");
    section
        .lines()
        .take_while(|line| line.starts_with("  "))
        .filter_map(|line| line.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_string)
        .collect()
}

#[test]
fn help_of_every_command_matches_its_snapshot_and_has_an_example() {
    let tmp = Dir::new();
    let top = tmp.run(&["--help"]);
    assert_eq!(top.status.code(), Some(0));
    check_snapshot("help.txt", &text(&top.stdout));
    let commands = subcommands(tmp.path());
    for expected in [
        "build",
        "verify",
        "betti",
        "plan",
        "preview",
        "stats",
        "completions",
    ] {
        assert!(commands.iter().any(|c| c == expected), "{expected} missing");
    }
    for command in &commands {
        let out = tmp.run(&[command, "--help"]);
        assert_eq!(out.status.code(), Some(0), "{command} --help");
        let help = text(&out.stdout);
        assert!(
            help.contains("Example: bettimill "),
            "`bettimill {command} --help` shows no example"
        );
        check_snapshot(&format!("help-{command}.txt"), &help);
    }
}

/// Runs a command that must fail with exit code 2 and a one-line message on stderr
/// containing every `needle`.
fn check_one_line_error(dir: &Path, args: &[&str], needles: &[&str]) {
    let out = run_in(dir, args);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert_eq!(
        stderr.trim_end().lines().count(),
        1,
        "{args:?} should fail with one line, got:\n{stderr}"
    );
    assert!(stderr.starts_with("error: "), "{stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{args:?}: {stderr} lacks {needle}");
    }
    assert!(out.stdout.is_empty(), "{args:?} printed data on failure");
}

#[test]
fn typical_mistakes_fail_with_exit_code_2_and_one_line() {
    let tmp = Dir::new();
    let dir = tmp.path();
    check_one_line_error(
        dir,
        &["build", "missing.toml", "--out", "out"],
        &["missing.toml", "cannot read manifest"],
    );
    assert!(!dir.join("out").exists(), "a failed build wrote its output");

    std::fs::write(
        dir.join("typo.toml"),
        "schema_version = 1\nname = \"x\"\ndimenson = 3\n",
    )
    .unwrap();
    check_one_line_error(
        dir,
        &["build", "typo.toml", "--out", "out"],
        &["typo.toml:3", "dimenson"],
    );
    check_one_line_error(dir, &["plan", "typo.toml"], &["typo.toml:3", "dimenson"]);

    std::fs::create_dir(dir.join("thesis")).unwrap();
    std::fs::write(dir.join("thesis/chapter1.tex"), "precious").unwrap();
    check_one_line_error(dir, &["build", "--out", "thesis"], &["thesis", "not empty"]);
    let left: Vec<_> = std::fs::read_dir(dir.join("thesis")).unwrap().collect();
    assert_eq!(
        left.len(),
        1,
        "a refused build wrote into a foreign directory"
    );

    check_one_line_error(dir, &["verify", "nowhere"], &["nowhere"]);
    check_one_line_error(dir, &["betti", "nothing.npy"], &["nothing.npy"]);
    std::fs::write(dir.join("junk.npy"), b"not an array").unwrap();
    check_one_line_error(dir, &["betti", "junk.npy"], &["junk.npy", ".npy"]);
    check_one_line_error(
        dir,
        &["preview", "junk.npy", "--out", "x.png"],
        &["junk.npy"],
    );
    check_one_line_error(
        dir,
        &["preview", "thesis/chapter1.tex", "--out", "x.png"],
        &["expected a dataset directory, s3://BUCKET/PREFIX, a .tar shard or a .npy image"],
    );
    check_one_line_error(dir, &["stats", "nowhere"], &["nowhere", "not a directory"]);
    check_one_line_error(dir, &["stats", "thesis"], &["holds no shards"]);
    assert!(!dir.join("x.png").exists());

    // Usage errors are clap's (several lines with a usage hint) but exit with 2 too.
    let out = run_in(dir, &["bulid"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("unrecognized subcommand"));
}

#[test]
fn shards_that_could_pass_5_gib_are_refused_for_s3_by_plan_build_and_k8s_before_any_work() {
    let tmp = Dir::new();
    let dir = tmp.path();
    // 16 MiB samples, 400 to a shard: up to 6.3 GiB, more than one create-only copy on S3.
    std::fs::write(
        dir.join("big.toml"),
        "schema_version = 1\nname = \"big\"\ndimension = 3\nside = 256\nmode = \"embed\"\n\
         samples = 800\nshard_size = 400\nseed = 1\n\n[[classes]]\nfamily = \"ball\"\n",
    )
    .unwrap();
    let needles = [
        "big.toml:7",
        "shard_size",
        "5 GiB",
        "use at most shard_size = 3",
    ];
    let url = "s3://no-such-bucket-bettimill/big";
    check_one_line_error(dir, &["plan", "big.toml", "--out", url], &needles);
    // The server (a closed port) is never asked: the manifest is refused first.
    let endpoint = "http://127.0.0.1:1";
    check_one_line_error(
        dir,
        &["build", "big.toml", "--out", url, "--endpoint", endpoint],
        &needles,
    );
    check_one_line_error(
        dir,
        &[
            "k8s", "big.toml", "--out", url, "--image", "x", "--tasks", "2",
        ],
        &needles,
    );
    // To a directory the same manifest plans: the limit is object storage's.
    let out = run_in(dir, &["plan", "big.toml", "--out", "local", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(!dir.join("local").exists(), "plan wrote its --out");
}

/// A fast manifest in `dir`.
fn small_manifest(dir: &Path, dimension: u32, side: u32) -> PathBuf {
    let path = dir.join(format!("small-{dimension}d.toml"));
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"small{dimension}d\"\ndimension = {dimension}\n\
             side = {side}\nmode = [\"embed\", \"carve\"]\nsamples = 8\nshard_size = 4\n\
             seed = 5\ncompression = \"{}\"\n\n[splits]\ntrain = 4\nval = 4\n\n\
             [[classes]]\nfamily = \"ball\"\n\n[[classes]]\nfamily = \"handle\"\n",
            if dimension == 4 { "zstd" } else { "none" }
        ),
    )
    .unwrap();
    path
}

fn build_small(dir: &Path, dimension: u32, side: u32) -> PathBuf {
    let manifest = small_manifest(dir, dimension, side);
    let out_dir = dir.join(format!("out{dimension}"));
    let out = run_in(
        dir,
        &[
            "build",
            "--quiet",
            manifest.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    out_dir
}

fn json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", text(&out.stderr));
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", text(&out.stdout)))
}

fn check_keys(value: &serde_json::Value, keys: &[&str]) {
    for key in keys {
        assert!(value.get(key).is_some(), "no {key} in {value}");
    }
}

#[test]
fn json_outputs_parse_and_carry_their_keys() {
    let tmp = Dir::new();
    let dir = tmp.path();
    let manifest = small_manifest(dir, 3, 18);
    let plan = json(&run_in(
        dir,
        &["plan", manifest.to_str().unwrap(), "--json"],
    ));
    check_keys(
        &plan,
        &[
            "name",
            "dimension",
            "side",
            "manifest_hash",
            "plan_hash",
            "samples",
            "strata",
            "shards",
        ],
    );
    assert_eq!(plan["samples"], 8);

    let out_dir = build_small(dir, 3, 18);
    let out_str = out_dir.to_str().unwrap();
    let verify = json(&run_in(dir, &["verify", out_str, "--json"]));
    check_keys(&verify, &["shards_checked", "samples_checked", "problems"]);
    assert_eq!(verify["samples_checked"], 8);
    assert_eq!(verify["problems"].as_array().unwrap().len(), 0);

    let status = json(&run_in(dir, &["status", out_str, "--json"]));
    assert!(status.is_object());

    let stats = json(&run_in(dir, &["stats", out_str, "--json"]));
    check_keys(
        &stats,
        &[
            "samples",
            "shards",
            "splits",
            "betti",
            "classes",
            "components",
            "knot_types",
            "hypervolume_histogram",
            "regeneration",
            "record_regenerations",
            "build_time",
        ],
    );
    // The build time comes from the timings the build recorded, never from the dataset's
    // bytes or file modification times.
    let build_time = &stats["build_time"];
    check_keys(
        build_time,
        &[
            "wall_seconds",
            "worker_seconds",
            "start_unix",
            "end_unix",
            "shards_timed",
            "samples_timed",
            "samples_per_second",
            "finished",
            "source",
        ],
    );
    assert!(build_time["wall_seconds"].as_f64().unwrap() >= 0.0);
    assert!(build_time["start_unix"].as_f64().unwrap() > 0.0);
    assert_eq!(build_time["finished"], true);
    assert_eq!(build_time["shards_timed"], 2);
    assert_eq!(build_time["samples_timed"], 8);
    assert_eq!(build_time["source"], "timings/ (recorded by the builds)");
    assert_eq!(stats["samples"], 8);
    assert_eq!(stats["splits"]["train"], 4);
    assert_eq!(stats["splits"]["val"], 4);
    let per_betti: u64 = stats["betti"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(per_betti, 8);
    let histogram: u64 = stats["hypervolume_histogram"]["counts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(histogram, 8);
    assert_eq!(stats["classes"].as_object().unwrap().len(), 4);

    // betti --json on a member extracted from a shard agrees with its label.
    let shard = std::fs::read(out_dir.join("shards/small3d-train-000000.tar")).unwrap();
    let members = bettimill_shard::read_tar(&shard).unwrap();
    let npy = members.iter().find(|m| m.name.ends_with(".npy")).unwrap();
    let key = npy.name.trim_end_matches(".npy");
    let label = members
        .iter()
        .find(|m| m.name == format!("{key}.json"))
        .unwrap();
    std::fs::write(dir.join("one.npy"), &npy.data).unwrap();
    let betti = json(&run_in(dir, &["betti", "one.npy", "--json"]));
    check_keys(&betti, &["betti", "euler", "shape", "hypervolume", "field"]);
    let label: serde_json::Value = serde_json::from_slice(&label.data).unwrap();
    assert_eq!(betti["betti"], label["betti"]);
    assert_eq!(betti["hypervolume"], label["hypervolume"]);
}

/// Width and height from a PNG's IHDR, after checking the signature.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
    assert_eq!(&bytes[12..16], b"IHDR");
    (
        u32::from_be_bytes(bytes[16..20].try_into().unwrap()),
        u32::from_be_bytes(bytes[20..24].try_into().unwrap()),
    )
}

#[test]
fn previews_of_2d_3d_4d_samples_shards_and_images_are_deterministic_pngs() {
    let tmp = Dir::new();
    let dir = tmp.path();
    for (dimension, side) in [(2, 16), (3, 18), (4, 18)] {
        let out_dir = build_small(dir, dimension, side);
        let out_str = out_dir.to_str().unwrap();
        let run = |args: &[&str], png: &str| -> Vec<u8> {
            let mut all = args.to_vec();
            all.extend(["--out", png]);
            let out = run_in(dir, &all);
            assert!(out.status.success(), "{all:?}: {}", text(&out.stderr));
            std::fs::read(dir.join(png)).unwrap()
        };
        let first = run(&["preview", out_str], "a.png");
        let again = run(&["preview", out_str], "b.png");
        assert_eq!(first, again, "{dimension}D preview is not deterministic");
        let (width, height) = png_size(&first);
        assert!(
            width >= 200 && height >= 100,
            "{dimension}D: {width}x{height}"
        );

        // Every key of a shard can be drawn, from the directory and from the shard.
        let shard = out_dir.join(format!("shards/small{dimension}d-val-000000.tar"));
        let members = bettimill_shard::read_tar(&std::fs::read(&shard).unwrap()).unwrap();
        let key = members[0].name.split('.').next().unwrap().to_string();
        let by_dir = run(&["preview", out_str, "--key", &key], "c.png");
        let by_shard = run(
            &["preview", shard.to_str().unwrap(), "--key", &key],
            "d.png",
        );
        assert_eq!(by_dir, by_shard);
        assert_ne!(
            by_dir, first,
            "a val sample drew like the first train sample"
        );

        let sheet = run(&["preview", out_str, "--n", "6"], "e.png");
        assert_ne!(sheet, first);
        png_size(&sheet);
        // Without deformation a sample is its construction.
        let undeformed = run(&["preview", out_str, "--n", "6", "--undeformed"], "u.png");
        assert_eq!(
            undeformed, sheet,
            "{dimension}D: an undeformed sample drew differently"
        );

        // A plain image.
        let npy = members.iter().find(|m| m.name.contains(".npy")).unwrap();
        if npy.name.ends_with(".npy") {
            std::fs::write(dir.join("plain.npy"), &npy.data).unwrap();
            png_size(&run(&["preview", "plain.npy"], "f.png"));
        }
    }
}

#[test]
fn undeformed_previews_draw_the_constructions_of_a_deformed_dataset() {
    let tmp = Dir::new();
    let dir = tmp.path();
    let demo = repo_root().join("manifests/demo-2d.toml");
    let out = run_in(
        dir,
        &["build", "--quiet", demo.to_str().unwrap(), "--out", "demo"],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let draw = |extra: &[&str], png: &str| {
        let mut args = vec!["preview", "demo", "--n", "4", "--out", png];
        args.extend(extra);
        let out = run_in(dir, &args);
        assert!(out.status.success(), "{args:?}: {}", text(&out.stderr));
        std::fs::read(dir.join(png)).unwrap()
    };
    let built = draw(&[], "built.png");
    let before = draw(&["--undeformed"], "before.png");
    png_size(&before);
    assert_ne!(
        before, built,
        "the demo deforms, so its constructions look different"
    );
    assert_eq!(before, draw(&["--undeformed"], "again.png"));
    // A shard or an image has no manifest to remake constructions from.
    let shard = std::fs::read_dir(dir.join("demo/shards"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "tar"))
        .unwrap();
    let out = run_in(
        dir,
        &[
            "preview",
            shard.to_str().unwrap(),
            "--undeformed",
            "--out",
            "x.png",
        ],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("--undeformed remakes samples from a dataset directory"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn stats_plot_is_a_png_and_text_names_every_section() {
    let tmp = Dir::new();
    let dir = tmp.path();
    let out_dir = build_small(dir, 2, 16);
    let out = run_in(
        dir,
        &["stats", out_dir.to_str().unwrap(), "--plot", "plot.png"],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report = text(&out.stdout);
    for section in [
        "8 samples in 2 shards",
        "per split",
        "per betti vector",
        "per class",
        "per component count",
        "per knot/link type",
        "hypervolume",
        "regenerations per class",
        "build time: ",
        "from timings/ (2 of 2 shards, 8 samples, recorded by the builds)",
    ] {
        assert!(report.contains(section), "no {section:?} in\n{report}");
    }
    png_size(&std::fs::read(dir.join("plot.png")).unwrap());

    // An extension the picture cannot have is refused by name, and nothing is written.
    let out_str = out_dir.to_str().unwrap();
    for args in [
        vec!["stats", out_str, "--plot", "plot.jpg"],
        vec!["preview", out_str, "--out", "x.jpg"],
        vec!["preview", out_str, "--out", "x"],
    ] {
        let out = run_in(dir, &args);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        let file = args[3];
        assert!(
            err.contains(&format!("{} {file}", args[2]))
                && err.contains("supported extension is .png"),
            "{args:?}: {err}"
        );
        assert!(!dir.join(file).exists(), "{args:?} wrote {file}");
    }

    // An unfinished build (no index.json yet) still has statistics, splits from its
    // completion records.
    std::fs::remove_file(out_dir.join("index.json")).unwrap();
    let out = run_in(dir, &["stats", out_dir.to_str().unwrap(), "--json"]);
    let stats = json(&out);
    assert_eq!(stats["samples"], 8);
    assert_eq!(stats["splits"]["train"], 4);
    assert_eq!(stats["splits"]["val"], 4);
    // Its build time so far is that of the shards built.
    assert_eq!(stats["build_time"]["finished"], false);
    assert!(stats["build_time"]["wall_seconds"].as_f64().unwrap() >= 0.0);
    let out = run_in(dir, &["stats", out_dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("build time so far (not finished)"));

    // Without timings (a copy that left them out) the field is null and the text says so.
    std::fs::remove_dir_all(out_dir.join("timings")).unwrap();
    let stats = json(&run_in(
        dir,
        &["stats", out_dir.to_str().unwrap(), "--json"],
    ));
    assert!(stats["build_time"].is_null(), "{}", stats["build_time"]);
    let out = run_in(dir, &["stats", out_dir.to_str().unwrap()]);
    assert!(text(&out.stdout).contains("build time: not available"));
}

/// stderr of a command whose stderr is a pipe: indicatif must draw nothing there, so no
/// bar, no carriage return and no escape sequence.
fn check_no_progress(args: &[&str], stderr: &str) {
    for garbage in ["\r", "\x1b", "[=", "=>", "ETA", "/s "] {
        assert!(
            !stderr.contains(garbage),
            "{args:?} drew progress ({garbage:?}) on a stderr that is not a terminal:\n{stderr:?}"
        );
    }
}

#[test]
fn verify_and_audit_draw_no_progress_when_stderr_is_not_a_terminal() {
    let tmp = Dir::new();
    let dir = tmp.path();
    let out_dir = build_small(dir, 2, 16);
    let out_str = out_dir.to_str().unwrap();
    let runs: [&[&str]; 6] = [
        &["verify", out_str],
        &["verify", out_str, "--json"],
        &["audit", out_str, "--rebuild", "1", "--relabel"],
        &["audit", out_str, "--rebuild", "1", "--relabel", "--json"],
        &["audit", out_str, "--shards", "0", "--quiet"],
        &["stats", out_str, "--json"],
    ];
    for args in runs {
        let out = run_in(dir, args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {stderr}");
        check_no_progress(args, &stderr);
        assert!(stderr.is_empty(), "{args:?} wrote to stderr: {stderr:?}");
        if args.contains(&"--json") {
            json(&out);
        }
    }
    let audit = json(&run_in(
        dir,
        &["audit", out_str, "--rebuild", "1", "--relabel", "--json"],
    ));
    assert_eq!(audit["relabelled_samples"], 8);
    assert_eq!(audit["rebuilt"].as_array().unwrap().len(), 2);
    assert_eq!(audit["findings"].as_array().unwrap().len(), 0);
    let verify = text(&run_in(dir, &["verify", out_str]).stdout);
    assert!(
        verify.starts_with("ok: 2 shards and 6 other files match"),
        "{verify}"
    );
}

#[test]
fn completions_exist_for_every_shell() {
    let tmp = Dir::new();
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let out = tmp.run(&["completions", shell]);
        assert!(out.status.success(), "{shell}: {}", text(&out.stderr));
        let script = text(&out.stdout);
        assert!(script.contains("bettimill"), "{shell}");
        assert!(
            script.contains("preview"),
            "{shell} completion lacks preview"
        );
    }
    let out = tmp.run(&["completions", "tcsh"]);
    assert_eq!(out.status.code(), Some(2));
}

/// The lines of the first ```sh block after the tour heading of README.md.
fn tour_commands() -> Vec<String> {
    let readme = std::fs::read_to_string(repo_root().join("README.md")).unwrap();
    let tour = readme
        .split("## A five-minute tour")
        .nth(1)
        .expect("README.md has a five-minute tour");
    let block = tour
        .split("```sh\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("the tour has a ```sh block");
    block
        .lines()
        .map(|line| match line.find(" #") {
            Some(comment) => line[..comment].trim().to_string(),
            None => line.trim().to_string(),
        })
        .filter(|line| !line.is_empty())
        .collect()
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, to.join(path.file_name().unwrap())).unwrap();
    }
}

#[test]
fn the_readme_tour_runs_as_written() {
    let tmp = Dir::new();
    let dir = tmp.path();
    // The tour runs from the repository root, where manifests/ is.
    copy_dir(&repo_root().join("manifests"), &dir.join("manifests"));
    let commands = tour_commands();
    assert!(commands.len() >= 6, "{commands:?}");
    for line in &commands {
        // Words split on spaces; `> FILE` redirects stdout, the only shell syntax allowed.
        let words: Vec<&str> = line.split_whitespace().collect();
        let (words, redirect) = match words.iter().position(|w| *w == ">") {
            Some(at) => (&words[..at], Some(words[at + 1])),
            None => (&words[..], None),
        };
        assert!(
            words
                .iter()
                .all(|w| !w.contains(['|', '&', ';', '$', '"', '\''])),
            "the tour line {line:?} needs a shell; keep the tour to plain commands"
        );
        let program = match words[0] {
            "bettimill" => BETTIMILL,
            other => other,
        };
        let mut command = Command::new(program);
        command.args(&words[1..]).current_dir(dir);
        if let Some(file) = redirect {
            command.stdout(Stdio::from(std::fs::File::create(dir.join(file)).unwrap()));
        }
        let out = command.output().unwrap();
        assert!(
            out.status.success(),
            "README tour line {line:?} failed: {}",
            text(&out.stderr)
        );
    }
    let mentioned: Vec<&str> = commands
        .iter()
        .flat_map(|l| l.split_whitespace())
        .filter(|w| w.ends_with(".png"))
        .collect();
    assert!(!mentioned.is_empty());
    for png in mentioned {
        png_size(&std::fs::read(dir.join(png)).unwrap());
    }
}

#[test]
fn the_committed_preview_figures_are_pngs() {
    let figures = repo_root().join("docs/figures/previews");
    for name in [
        "demo-2d-s000000.png",
        "demo-3d-s000006.png",
        "demo-4d-s000004.png",
        "demo-3d-sheet.png",
        "demo-3d-stats.png",
    ] {
        let bytes = std::fs::read(figures.join(name)).unwrap();
        let (width, height) = png_size(&bytes);
        assert!(width > 100 && height > 100, "{name}");
    }
    let readme = std::fs::read_to_string(repo_root().join("README.md")).unwrap();
    for link in readme.split("](docs/figures/previews/").skip(1) {
        let file = link.split(')').next().unwrap();
        assert!(figures.join(file).exists(), "README links a missing {file}");
    }
}

#[test]
fn a_reader_that_stops_early_is_not_a_crash() {
    // `bettimill completions bash | head -1`: the pipe closes before the script is written.
    let tmp = Dir::new();
    let mut child = tmp
        .command()
        .args(["completions", "bash"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = text(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(0), "{stderr}");
}

/// A manifest with the given lines after the usual head (schema ... seed) and one class.
fn manifest_with(dir: &Path, name: &str, head: &str, tail: &str) -> String {
    std::fs::write(
        dir.join(name),
        format!(
            "schema_version = 1\nname = \"x\"\ndimension = 2\nside = 24\n{head}samples = 4\n\
             shard_size = 2\n{tail}"
        ),
    )
    .unwrap();
    name.to_string()
}

#[test]
fn manifest_mistakes_are_named_as_written() {
    let tmp = Dir::new();
    let dir = tmp.path();
    let class = "[[classes]]\nfamily = \"ball\"\n";
    // A missing field is named itself, not after the first line of the file.
    let m = manifest_with(dir, "no_classes.toml", "mode = \"embed\"\n", "seed = 1\n");
    check_one_line_error(
        dir,
        &["plan", &m],
        &["field `classes`: missing field `classes`"],
    );
    std::fs::write(dir.join("empty.toml"), "").unwrap();
    check_one_line_error(
        dir,
        &["plan", "empty.toml"],
        &["empty.toml: field `schema_version`: missing field `schema_version`"],
    );
    // A TOML date-time is called one.
    let m = manifest_with(
        dir,
        "datetime.toml",
        "mode = \"embed\"\n",
        &format!("seed = 1979-05-27T07:32:00Z\n{class}"),
    );
    check_one_line_error(
        dir,
        &["plan", &m],
        &["datetime.toml:8: field `seed`: invalid type: date-time"],
    );
    // A bad mode lists the valid ones and leaks no type name.
    let m = manifest_with(
        dir,
        "mode.toml",
        "mode = \"sideways\"\n",
        &format!("seed = 1\n{class}"),
    );
    check_one_line_error(
        dir,
        &["plan", &m],
        &["field `mode`: \"sideways\" is not a mode: write \"embed\", \"carve\""],
    );
    let out = run_in(dir, &["plan", &m]);
    assert!(
        !text(&out.stderr).contains("untagged"),
        "{}",
        text(&out.stderr)
    );
    // A 100,000-key table gives a short line that says how much it left out.
    let keys: String = (0..100_000).map(|i| format!("k{i}=1,")).collect();
    let m = manifest_with(
        dir,
        "wide.toml",
        &format!("mode = {{ {}}}\n", keys.trim_end_matches(',')),
        &format!("seed = 1\n{class}"),
    );
    let out = run_in(dir, &["plan", &m]);
    assert_eq!(out.status.code(), Some(2));
    let err = text(&out.stderr);
    assert!(err.len() < 1000, "{} bytes of error", err.len());
    assert!(err.contains("more characters)"), "{err}");
    // A family refused in carve mode is refused in carve mode.
    let m = manifest_with(
        dir,
        "carve.toml",
        "mode = \"carve\"\n",
        "seed = 1\n[[classes]]\nfamily = \"s2_x_b2\"\n",
    );
    check_one_line_error(dir, &["plan", &m], &["not available in 2D carve mode"]);
}

#[cfg(unix)]
#[test]
fn a_dangling_symlink_as_out_is_named_as_such() {
    let tmp = Dir::new();
    let dir = tmp.path();
    std::os::unix::fs::symlink(dir.join("gone"), dir.join("link")).unwrap();
    for command in ["build", "slurm"] {
        check_one_line_error(
            dir,
            &[command, "--out", "link"],
            &[
                "--out link is a symbolic link to",
                "gone",
                "which does not exist",
            ],
        );
    }
    assert!(!dir.join("gone").exists());
}

#[test]
fn audit_of_a_non_binary_array_does_not_suggest_a_betti_flag() {
    let tmp = Dir::new();
    let dir = tmp.path();
    let out_dir = build_small(dir, 2, 16);
    // Make one voxel of a stored (uncompressed) array a 2, re-indexed as an attacker would
    // not even need to: relabel reads the arrays whatever the hashes say.
    let shards = out_dir.join("shards");
    let tar = std::fs::read_dir(&shards)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "tar"))
        .unwrap();
    let mut bytes = std::fs::read(&tar).unwrap();
    let magic = b"\x93NUMPY";
    let at = bytes.windows(magic.len()).position(|w| w == magic).unwrap();
    let header_len = u16::from_le_bytes([bytes[at + 8], bytes[at + 9]]) as usize;
    bytes[at + 10 + header_len] = 2;
    std::fs::write(&tar, &bytes).unwrap();
    let out = run_in(dir, &["audit", out_dir.to_str().unwrap(), "--relabel"]);
    let report = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{report}{}", text(&out.stderr));
    assert!(
        report.contains("has value 2; a dataset array holds only 0 and 1"),
        "{report}"
    );
    assert!(!report.contains("--strict"), "{report}");
}
