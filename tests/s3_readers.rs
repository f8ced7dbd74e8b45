//! The reading commands on a dataset in a bucket (`s3://BUCKET/PREFIX`, the local S3 server
//! of ci/s3-up.sh): `stats`, `preview` and `audit` give what they give on a local build of
//! the same manifest, find damage in the bucket as on disk, and hold memory flat whatever
//! the shard size (shards are read by ranges, member by member).
//!
//! System tests: they run only with BETTIMILL_SYSTEM_TESTS=1 (ci/test.sh sets it); when the
//! server cannot be started they fail in CI (CI=true) and are skipped elsewhere.

mod common;

use bettimill_shard::object::{ObjectDir, S3Config};
use bettimill_testkit::s3::S3Server;
use bettimill_testkit::system_test;
use common::{assert_exit, bettimill, stderr, stdout, Dir};
use std::path::PathBuf;
use std::process::{Command, Output};

/// The shared local server, with what these tests do with it.
struct Server(S3Server);

impl Server {
    fn up() -> Option<Server> {
        S3Server::shared().map(Server)
    }

    /// A URL under a prefix no earlier run used.
    fn fresh_url(&self, test: &str) -> String {
        format!(
            "s3://{}/{}",
            self.0.bucket,
            self.0.fresh_prefix("cli-tests", test)
        )
    }

    /// `command` with the server's variables in place of any AWS variable the test has.
    fn configure<'a>(&self, command: &'a mut Command) -> &'a mut Command {
        for key in [
            "AWS_ACCESS_KEY_ID",
            "AWS_SECRET_ACCESS_KEY",
            "AWS_SESSION_TOKEN",
            "AWS_REGION",
            "AWS_DEFAULT_REGION",
            "AWS_ENDPOINT_URL",
        ] {
            command.env_remove(key);
        }
        command.envs(self.0.vars())
    }

    /// A `bettimill` command that reaches the server through the AWS variables alone.
    fn command(&self) -> Command {
        let mut command = bettimill();
        self.configure(&mut command);
        command
    }

    /// The objects under `url`, opened as the tests' own client.
    fn objects(&self, url: &str) -> ObjectDir {
        let config = S3Config {
            endpoint: Some(self.0.endpoint.clone()),
            access_key_id: Some(self.0.access_key_id.clone()),
            secret_access_key: Some(self.0.secret_access_key.clone()),
            session_token: None,
            region: Some(self.0.region.clone()),
        };
        ObjectDir::open(url, &config).unwrap()
    }

    /// Replaces the object `name` under `url` by `bytes` (deleted, then put: bettimill
    /// itself never overwrites), as damage or an edit would.
    fn replace(&self, url: &str, name: &str, bytes: Vec<u8>) {
        let objects = self.objects(url);
        objects.delete(name).unwrap();
        objects.put_new(name, bytes).unwrap();
    }
}

/// A manifest of 3D balls and handles with two splits: 4 shards of 3 samples.
fn manifest(dir: &Dir) -> PathBuf {
    let path = dir.join("m.toml");
    std::fs::write(
        &path,
        "schema_version = 1\nname = \"rd\"\ndimension = 3\nside = 20\n\
         mode = [\"embed\", \"carve\"]\nsamples = 12\nshard_size = 3\nseed = 5\n\n\
         [splits]\ntrain = 9\ntest = 3\n\n[[classes]]\nfamily = \"ball\"\n\n\
         [[classes]]\nfamily = \"handle\"\n",
    )
    .unwrap();
    path
}

/// `bettimill ARGS` against the server.
fn run(server: &Server, args: &[&str]) -> Output {
    server.command().args(args).output().unwrap()
}

/// `stats --json` without its build time (from timings, never the same twice).
fn stats_json(server: &Server, dataset: &str) -> serde_json::Value {
    let out = run(server, &["stats", dataset, "--json"]);
    assert_exit(&out, 0);
    let mut stats: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let build_time = stats
        .as_object_mut()
        .unwrap()
        .remove("build_time")
        .expect("stats has a build time");
    assert!(build_time.is_object(), "{build_time}");
    stats
}

#[test]
fn stats_preview_and_audit_of_a_bucket_say_what_they_say_of_a_local_copy() {
    if !system_test("reads a dataset in a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    let manifest = manifest(&dir);
    let url = server.fresh_url("readers");
    let local = dir.join("local");
    let local = local.to_str().unwrap();
    for out in [&url, local] {
        let built = run(
            &server,
            &["build", manifest.to_str().unwrap(), "--out", out],
        );
        assert_exit(&built, 0);
    }

    let stats = stats_json(&server, &url);
    assert_eq!(stats, stats_json(&server, local));
    assert_eq!(stats["samples"], 12, "{stats}");

    // Pictures from the bucket are the local pictures, byte for byte.
    for args in [
        vec!["--n", "5", "--out"],
        vec!["--key", "s000010", "--out"],
        vec!["--undeformed", "--out"],
        vec!["--key", "s000010", "--html"],
    ] {
        let ext = if args.contains(&"--html") {
            "html"
        } else {
            "png"
        };
        let mut pictures = Vec::new();
        for (name, dataset) in [("bucket", url.as_str()), ("local", local)] {
            let path = dir.join(format!("{name}.{ext}"));
            let mut full = vec!["preview", dataset];
            full.extend(&args);
            full.push(path.to_str().unwrap());
            assert_exit(&run(&server, &full), 0);
            pictures.push(std::fs::read(&path).unwrap());
        }
        assert!(pictures[0] == pictures[1], "preview {args:?} differs");
    }

    // A full audit finds nothing, as on disk.
    for dataset in [url.as_str(), local] {
        let out = run(&server, &["audit", dataset, "--rebuild", "1", "--relabel"]);
        assert_exit(&out, 0);
        assert_eq!(
            stdout(&out),
            "ok: rebuilt 4 shard(s), relabelled 12 sample(s), 0 difference(s)\n"
        );
    }
    // Nothing was written to the bucket: the audit's copy is local and removed.
    let names: Vec<String> = server
        .objects(&url)
        .list()
        .unwrap()
        .into_iter()
        .map(|entry| entry.name)
        .collect();
    assert!(names.iter().all(|n| !n.contains(".audit")), "{names:?}");

    // An edited class table whose hash in index.json is rewritten too, as an attacker
    // would: verify of the bucket regenerates the plan's files and names the edit, as
    // verify of the directory does, in the same words.
    let objects = server.objects(&url);
    let classes = objects.get("classes.json").unwrap().unwrap();
    let index = objects.get("index.json").unwrap().unwrap();
    let forged = String::from_utf8(classes.clone())
        .unwrap()
        .replacen("\"ball", "\"bell", 1);
    let forged_index = String::from_utf8(index.clone()).unwrap().replace(
        &bettimill_shard::blake3_hex(&classes),
        &bettimill_shard::blake3_hex(forged.as_bytes()),
    );
    assert_ne!(forged_index.as_bytes(), &index[..]);
    server.replace(&url, "classes.json", forged.clone().into_bytes());
    server.replace(&url, "index.json", forged_index.clone().into_bytes());
    std::fs::write(std::path::Path::new(local).join("classes.json"), &forged).unwrap();
    std::fs::write(
        std::path::Path::new(local).join("index.json"),
        &forged_index,
    )
    .unwrap();
    let verified: Vec<Output> = [url.as_str(), local]
        .iter()
        .map(|dataset| run(&server, &["verify", dataset]))
        .collect();
    for out in &verified {
        assert_exit(out, 1);
        let report = stdout(out);
        assert!(
            report.contains(
                "classes.json: strata[0].name says \"bell/embed\", the build writes \"ball/embed\""
            ),
            "{report}"
        );
    }
    assert_eq!(stdout(&verified[0]), stdout(&verified[1]));
    server.replace(&url, "classes.json", classes);
    server.replace(&url, "index.json", index.clone());
    assert_exit(&run(&server, &["verify", &url]), 0);

    // Damage: one flipped byte in a shard's array, and an edited class table.
    let shard = "shards/rd-train-000001.tar";
    let mut bytes = objects.get(shard).unwrap().unwrap();
    bytes[3000] ^= 1;
    server.replace(&url, shard, bytes);
    let classes = objects.get("classes.json").unwrap().unwrap();
    let edited = String::from_utf8(classes)
        .unwrap()
        .replacen("\"ball", "\"bell", 1);
    server.replace(&url, "classes.json", edited.into_bytes());

    let out = run(&server, &["audit", &url, "--shards", "1", "--relabel"]);
    assert_exit(&out, 1);
    let report = stdout(&out);
    assert!(
        report.contains(
            "classes.json: strata[0].name says \"bell/embed\", the build writes \"ball/embed\""
        ),
        "{report}"
    );
    assert!(
        report.contains("rd-train-000001: rebuilt shard differs from the stored one at byte 3000 (member s000003.npy)"),
        "{report}"
    );
    // stats reads the damaged shard's members and names it by its URL.
    let out = run(&server, &["stats", &url]);
    assert_exit(&out, 2);
    assert!(
        stderr(&out).contains(&format!("{url}/{shard}")),
        "{}",
        stderr(&out)
    );
}

#[test]
fn a_prefix_without_a_dataset_and_a_missing_bucket_are_one_line_exit_2() {
    if !system_test("reads a dataset in a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let empty = server.fresh_url("empty");
    let missing = "s3://no-such-bucket-bettimill/ds";
    for command in ["stats", "preview", "audit"] {
        for (url, says) in [
            (empty.as_str(), "holds no".to_string()),
            (
                missing,
                "the bucket no-such-bucket-bettimill does not exist".to_string(),
            ),
        ] {
            let mut args = vec![command, url];
            match command {
                "preview" => args.extend(["--out", "/tmp/never-written.png"]),
                "audit" => args.push("--relabel"),
                _ => {}
            }
            let out = run(&server, &args);
            assert_exit(&out, 2);
            let err = stderr(&out);
            assert_eq!(err.lines().count(), 1, "{command} {url}: {err}");
            assert!(
                err.contains(url) && err.contains(&says),
                "{command} {url}: {err}"
            );
        }
    }
}

/// Peak resident set (KiB, GNU time's `%M`) of `bettimill ARGS` run against the server;
/// `None` (the test returns) when /usr/bin/time is missing outside CI.
fn peak_kib(server: &Server, args: &[&str]) -> Option<(Output, u64)> {
    common::run_with_peak_in(args, |command| {
        server.configure(command);
    })
}

#[test]
fn stats_preview_and_audit_of_a_bucket_hold_memory_flat_whatever_the_shard_size() {
    if !system_test("reads a dataset in a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    // One shard of 120 samples of 96^3 voxels, uncompressed: about 102 MiB.
    let manifest = dir.join("big.toml");
    std::fs::write(
        &manifest,
        "schema_version = 1\nname = \"big\"\ndimension = 3\nside = 96\nmode = [\"embed\"]\n\
         samples = 120\nshard_size = 120\nseed = 3\n\n[[classes]]\nfamily = \"ball\"\n",
    )
    .unwrap();
    let url = server.fresh_url("readers-memory");
    let built = run(
        &server,
        &[
            "build",
            manifest.to_str().unwrap(),
            "--out",
            &url,
            "--max-uploads",
            "1",
        ],
    );
    assert_exit(&built, 0);
    let shard_bytes = server
        .objects(&url)
        .size("shards/big-000000.tar")
        .unwrap()
        .unwrap();
    assert!(shard_bytes > 100 << 20, "{shard_bytes}");
    let picture = dir.join("last.png");
    // Ranges of 8 MiB, one member at a time: far below one shard whatever its size. The
    // preview's key is the shard's last sample, so every member before it is read.
    for args in [
        vec!["stats", &url],
        vec![
            "preview",
            &url,
            "--key",
            "s000119",
            "--out",
            picture.to_str().unwrap(),
        ],
        vec!["audit", &url, "--relabel"],
    ] {
        let Some((out, kib)) = peak_kib(&server, &args) else {
            return;
        };
        assert_exit(&out, 0);
        assert!(
            kib < 64 << 10,
            "bettimill {}: peak {kib} KiB for a shard of {shard_bytes} bytes",
            args[0]
        );
    }
}
