//! `bettimill build --out s3://BUCKET/PREFIX` against a real local S3 server (moto_server,
//! started by ci/s3-up.sh): the objects equal a local build's files byte for byte; a build
//! killed (kill -9 of the real binary) resumes against the bucket to the same bytes; a
//! build killed while its shards go by multipart uploads resumes to the same bytes and
//! leaves no temporary; a build whose server stops fails in one line (exit 2), as do array
//! tasks, finalize and status, and, once the server is back with its objects, resumes to the
//! same bytes; a second writer is refused while the first holds the
//! lease and nothing is overwritten; a bad endpoint, a missing bucket and wrong credentials
//! are one line naming the URL, exit 2; Slurm array tasks (a real Slurm, ci/slurm-up.sh)
//! upload their shards and the finalize job writes the index.
//!
//! System tests: they run only with BETTIMILL_SYSTEM_TESTS=1 (ci/test.sh sets it), because
//! they install and start the server (idempotent). When it cannot be started they fail in
//! CI (CI=true) and are skipped with a message elsewhere.

mod common;

use bettimill_shard::object::{ObjectDir, S3Config};
use bettimill_testkit::s3::S3Server;
use bettimill_testkit::system_test;
use common::{assert_exit, ball_and_handle, bettimill, stderr, Dir};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

/// The local server, and the commands and clients that reach it.
struct Server(S3Server);

impl Server {
    /// Starts the shared server (a no-op when it is up); `None` (skip) only outside CI.
    fn up() -> Option<Server> {
        S3Server::shared().map(Server)
    }

    /// A server of this test's own, in `dir`, that keeps its objects across a stop and a
    /// start.
    fn own(dir: &Dir) -> Option<Server> {
        S3Server::own(&dir.join("s3-server")).map(Server)
    }

    /// A URL under a prefix no earlier run used (the server keeps its objects while it runs).
    fn fresh_url(&self, test: &str) -> String {
        format!(
            "s3://{}/{}",
            self.0.bucket,
            self.0.fresh_prefix("cli-tests", test)
        )
    }

    /// A `bettimill` command that reaches the server through the AWS variables alone.
    fn command(&self) -> Command {
        let mut command = bettimill();
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
        command.envs(self.0.vars());
        command
    }

    fn build(&self, manifest: &Path, out: &str, extra: &[&str]) -> Output {
        self.command()
            .args(["build", manifest.to_str().unwrap(), "--out", out])
            .args(extra)
            .output()
            .unwrap()
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
}

/// A manifest of 3D balls and handles: 12 shards of 2 samples.
fn manifest(dir: &Dir) -> PathBuf {
    ball_and_handle(dir.join("m.toml"), "s3test", 3, 24, 24, 2, 11)
}

/// Every object under `url` but the build timings (`timings/`, never the same twice) is
/// byte for byte the file of the same name in the local dataset `local`, and the local
/// dataset has no other file (its lock and temporaries, names starting with a dot, aside).
/// Nothing else is left under the prefix: no lease, no temporary.
#[track_caller]
fn assert_same_as_local(server: &Server, url: &str, local: &Path) {
    let dir = server.objects(url);
    let objects: BTreeMap<String, u64> = dir
        .list()
        .unwrap()
        .into_iter()
        .map(|e| (e.name, e.bytes))
        .filter(|(name, _)| !name.starts_with("timings/"))
        .collect();
    let files: BTreeMap<String, Vec<u8>> = common::snapshot(local)
        .into_iter()
        .map(|(path, bytes)| (path.to_string_lossy().into_owned(), bytes))
        .filter(|(name, _)| {
            !Path::new(name)
                .file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with('.')
        })
        .collect();
    assert!(files.contains_key("index.json"), "{}", local.display());
    assert_eq!(
        objects.keys().collect::<Vec<_>>(),
        files.keys().collect::<Vec<_>>(),
        "{url} and {} hold different names",
        local.display()
    );
    for (name, bytes) in &files {
        let got = dir.get(name).unwrap().unwrap();
        assert!(&got == bytes, "{url}/{name} differs from the local file");
    }
}

#[test]
fn a_build_to_a_bucket_equals_a_local_build_object_for_object() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    let manifest = manifest(&dir);
    let local = dir.join("local");
    assert_exit(&common::build(&manifest, &local, 2), 0);
    let url = server.fresh_url("equal");
    let out = server
        .command()
        .args(["build", manifest.to_str().unwrap(), "--out", &url])
        .args(["--max-uploads", "2"])
        .env("RAYON_NUM_THREADS", "3")
        .output()
        .unwrap();
    assert_exit(&out, 0);
    // The summary says what made the shards: this process's threads, not worker processes.
    assert!(
        stderr(&out).contains(", 3 threads in one process, up to 2 uploads at a time), "),
        "{}",
        stderr(&out)
    );
    assert!(
        stderr(&out).contains(&format!("{url}/index.json")),
        "{}",
        stderr(&out)
    );
    // Its own progress lines (not a terminal), the last one at the last shard.
    assert!(
        stderr(&out).contains("progress: 12/12 shards made or found complete"),
        "{}",
        stderr(&out)
    );
    assert_same_as_local(&server, &url, &local);
    // `bettimill cat` streams an object as webdataset's `pipe:` URLs read it.
    let shard = "shards/s3test-000007.tar";
    let cat = server
        .command()
        .args(["cat", &format!("{url}/{shard}")])
        .output()
        .unwrap();
    assert_exit(&cat, 0);
    assert!(cat.stdout == std::fs::read(local.join(shard)).unwrap());
    // Timings are uploaded for stats, one per shard.
    let timings = server
        .objects(&url)
        .list()
        .unwrap()
        .into_iter()
        .filter(|e| e.name.starts_with("timings/"))
        .count();
    assert_eq!(timings, 12);

    // A second build of a finished prefix builds nothing and changes nothing.
    let again = server.build(&manifest, &url, &[]);
    assert_exit(&again, 0);
    assert!(
        stderr(&again).contains("built 0 shards, skipped 12 complete"),
        "{}",
        stderr(&again)
    );
    assert_same_as_local(&server, &url, &local);
}

#[test]
fn a_killed_build_resumes_against_the_bucket_to_the_same_bytes() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    let manifest = manifest(&dir);
    let local = dir.join("local");
    assert_exit(&common::build(&manifest, &local, 2), 0);
    let url = server.fresh_url("killed");
    let objects = server.objects(&url);
    let records = || objects.list_under("records").map(|l| l.len()).unwrap_or(0);
    // Each shard waits in its staging write, so the kills land while shards are made and
    // uploaded: after the first record, then after the fifth.
    let mut killed = Vec::new();
    for records_before_kill in [1, 5] {
        let mut child = server
            .command()
            .args(["build", manifest.to_str().unwrap(), "--out", &url])
            .env("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "0.3")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        common::wait_until("records in the bucket", Duration::from_secs(120), || {
            records() >= records_before_kill
        });
        assert!(common::kill("-9", child.id()));
        child.wait().unwrap();
        killed.push(child.id());
        assert_eq!(
            objects.size("index.json").unwrap(),
            None,
            "the build was killed before its end"
        );
    }
    let staging_of = |pid: &u32| -> Vec<PathBuf> {
        let prefix = format!("bettimill-staging-{pid}-");
        std::fs::read_dir(std::env::temp_dir())
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
            .map(|e| e.path())
            .collect()
    };
    assert_eq!(
        staging_of(&killed[1]).len(),
        1,
        "kill -9 leaves its staging"
    );
    let resumed = server.build(&manifest, &url, &[]);
    assert_exit(&resumed, 0);
    // The killed builds' staging directories (their shards in flight) are gone.
    for pid in &killed {
        assert_eq!(staging_of(pid), Vec::<PathBuf>::new());
    }
    assert!(
        !stderr(&resumed).contains("skipped 0 complete"),
        "the resumed build found the killed builds' shards: {}",
        stderr(&resumed)
    );
    assert_same_as_local(&server, &url, &local);
}

#[test]
fn a_build_killed_during_streamed_uploads_resumes_to_the_same_bytes() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    // Four shards of 48 plain samples of 64^3 voxels: about 12.6 MiB each, so each tar goes
    // by a multipart upload of two parts and a create-only copy.
    let manifest = dir.join("streamed.toml");
    std::fs::write(
        &manifest,
        "schema_version = 1\nname = \"streamed\"\ndimension = 3\nside = 64\nmode = [\"embed\"]\n\
         samples = 192\nshard_size = 48\nseed = 5\n\n[[classes]]\nfamily = \"ball\"\n",
    )
    .unwrap();
    let local = dir.join("local");
    assert_exit(&common::build(&manifest, &local, 2), 0);
    let shard = std::fs::metadata(local.join("shards/streamed-000000.tar"))
        .unwrap()
        .len();
    assert!(
        shard > bettimill_shard::object::PART_BYTES as u64,
        "{shard} bytes: one part"
    );
    let url = server.fresh_url("killed-streamed");
    let objects = server.objects(&url);
    // Killed as its first tar arrives, while the next shards are made and uploaded.
    let mut child = server
        .command()
        .args(["build", manifest.to_str().unwrap(), "--out", &url])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    common::wait_until("a tar in the bucket", Duration::from_secs(300), || {
        objects.list_under("shards").is_ok_and(|l| !l.is_empty())
    });
    assert!(common::kill("-9", child.id()));
    child.wait().unwrap();
    assert_eq!(objects.size("index.json").unwrap(), None);
    // A writer killed between its upload and the copy leaves its temporary object.
    objects
        .put_new(
            &format!(
                "{}/shards/streamed-000003.tar.1-2-3",
                bettimill_shard::object::UPLOADS_DIR
            ),
            vec![7; 1000],
        )
        .unwrap();
    let resumed = server.build(&manifest, &url, &[]);
    assert_exit(&resumed, 0);
    // Every object the local file's bytes, and the temporary gone.
    assert_same_as_local(&server, &url, &local);
}

#[test]
fn a_build_whose_server_stops_fails_and_resumes_after_the_restart_to_the_same_bytes() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let dir = Dir::new();
    // A server of this test's own: stopping the shared one would fail the other tests.
    let Some(server) = Server::own(&dir) else {
        return;
    };
    let manifest = manifest(&dir);
    let local = dir.join("local");
    assert_exit(&common::build(&manifest, &local, 2), 0);
    let url = server.fresh_url("restart");
    let objects = server.objects(&url);
    let records = || {
        // Polled gently: the server records every request, to replay at its restart.
        std::thread::sleep(Duration::from_millis(200));
        objects.list_under("records").map(|l| l.len()).unwrap()
    };
    let mut child = server
        .command()
        .args(["build", manifest.to_str().unwrap(), "--out", &url])
        .env("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "0.3")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    common::wait_until("records in the bucket", Duration::from_secs(120), || {
        records() >= 3
    });
    server.0.stop();
    // The build stops by itself, in one line naming the server, rather than waiting for it.
    common::wait_until(
        "the build to stop after its server",
        Duration::from_secs(120),
        || child.try_wait().unwrap().is_some(),
    );
    let failed = child.wait_with_output().unwrap();
    assert_exit(&failed, 2);
    let text = stderr(&failed);
    let error: Vec<&str> = text.lines().filter(|l| l.starts_with("error: ")).collect();
    assert_eq!(error.len(), 1, "{text}");
    assert!(
        error[0].contains(&format!("{url}/"))
            && error[0].contains(&format!("cannot reach the server {} ", server.0.endpoint)),
        "{text}"
    );

    // Array tasks, finalize and status against the stopped server: one line each, naming
    // the URL and the server, exit 2, after a few quick retries.
    for args in [
        vec![
            "worker",
            "--dir",
            &url,
            "--task-index",
            "0",
            "--task-count",
            "2",
        ],
        vec!["finalize", &url],
        vec!["status", &url],
    ] {
        let out = server.command().args(&args).output().unwrap();
        assert_exit(&out, 2);
        let text = stderr(&out);
        assert_eq!(text.trim_end().lines().count(), 1, "{args:?}: {text}");
        assert!(
            text.starts_with(&format!("error: {url}"))
                && text.contains(&format!("cannot reach the server {} ", server.0.endpoint)),
            "{args:?}: {text}"
        );
    }

    // Restarted, the server has what it had; the build resumes from it.
    server.0.start();
    let kept = records();
    assert!((3..12).contains(&kept), "{kept} records after the restart");
    let resumed = server.build(&manifest, &url, &[]);
    assert_exit(&resumed, 0);
    assert!(
        stderr(&resumed).contains(&format!("skipped {kept} complete")),
        "{}",
        stderr(&resumed)
    );
    assert_same_as_local(&server, &url, &local);
}

#[test]
fn a_second_writer_is_refused_and_nothing_is_overwritten() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    let manifest = manifest(&dir);
    let url = server.fresh_url("writers");
    let objects = server.objects(&url);
    // The first build holds the lease while it waits at start-up.
    let first = server
        .command()
        .args(["build", manifest.to_str().unwrap(), "--out", &url])
        .env("BETTIMILL_TEST_PAUSE_AT_STARTUP", "4")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    common::wait_until("the first build's lease", Duration::from_secs(60), || {
        objects.list_under(".lease").is_ok_and(|l| !l.is_empty())
    });
    let second = server.build(&manifest, &url, &[]);
    assert_exit(&second, 2);
    let text = stderr(&second);
    assert!(
        text.contains("another bettimill build or finalize is running in"),
        "{text}"
    );
    assert!(text.contains(&url), "{text}");
    let first = first.wait_with_output().unwrap();
    assert_exit(&first, 0);
    let local = dir.join("local");
    assert_exit(&common::build(&manifest, &local, 1), 0);
    assert_same_as_local(&server, &url, &local);

    // An object another writer left with other bytes is never overwritten: the build
    // stops naming it, and the object keeps its bytes. (The prefix is that writer's
    // dataset of the same manifest: a prefix without build.json is refused whole.)
    let finished = objects;
    let url = server.fresh_url("other-bytes");
    let objects = server.objects(&url);
    for identity in ["manifest.toml", "build.json"] {
        let bytes = finished.get(identity).unwrap().unwrap();
        objects.put_new(identity, bytes).unwrap();
    }
    let planted = b"not the shard bettimill writes".to_vec();
    let name = "shards/s3test-000003.tar";
    objects.put_new(name, planted.clone()).unwrap();
    let refused = server.build(&manifest, &url, &[]);
    assert_exit(&refused, 2);
    let text = stderr(&refused);
    assert!(
        text.contains(&format!("{url}/{name}: exists and differs")),
        "{text}"
    );
    assert_eq!(objects.get(name).unwrap(), Some(planted));
    assert_eq!(objects.size("index.json").unwrap(), None);
}

#[test]
fn a_bad_endpoint_a_missing_bucket_and_wrong_credentials_are_one_line_exit_2() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    let manifest = manifest(&dir);
    let url = server.fresh_url("errors");
    let one_line = |out: &Output, needle: &str| {
        assert_exit(out, 2);
        let text = stderr(out);
        assert_eq!(text.trim_end().lines().count(), 1, "one line: {text}");
        assert!(text.starts_with(&format!("error: {needle}")), "{text}");
    };
    // Nothing listens on port 9 (discard) of loopback.
    let out = server.build(&manifest, &url, &["--endpoint", "http://127.0.0.1:9"]);
    one_line(&out, &format!("{url}: "));
    assert!(
        stderr(&out).contains("cannot reach the server http://127.0.0.1:9 "),
        "{}",
        stderr(&out)
    );
    let out = server.build(&manifest, "s3://no-such-bucket-here/x", &[]);
    one_line(
        &out,
        "s3://no-such-bucket-here/x: the bucket no-such-bucket-here does not exist",
    );
    let out = server
        .command()
        .env("AWS_SECRET_ACCESS_KEY", "not-the-secret")
        .args(["build", manifest.to_str().unwrap(), "--out", &url])
        .output()
        .unwrap();
    one_line(&out, &format!("{url}: the server refused the credentials"));
    // Nothing was written by any of them.
    assert_eq!(server.objects(&url).list().unwrap(), vec![]);
}

#[test]
fn verify_and_status_read_a_bucket_and_verify_finds_a_flipped_byte() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    let manifest = manifest(&dir);
    let url = server.fresh_url("verify");
    let objects = server.objects(&url);
    let run = |args: &[&str]| server.command().args(args).output().unwrap();

    // Half-way: status names what is done and what is missing.
    let mut child = server
        .command()
        .args(["build", manifest.to_str().unwrap(), "--out", &url])
        .env("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "0.3")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    common::wait_until("records in the bucket", Duration::from_secs(120), || {
        objects.list_under("records").is_ok_and(|l| l.len() >= 2)
    });
    assert!(common::kill("-9", child.id()));
    child.wait().unwrap();
    let status = run(&["status", &url, "--json"]);
    assert_exit(&status, 0);
    let report: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    let complete = report["complete_count"].as_u64().unwrap();
    assert!((2..12).contains(&complete), "{report}");
    assert_eq!(report["missing_count"].as_u64().unwrap(), 12 - complete);
    assert_eq!(report["finalized"], false);
    let unfinished = run(&["verify", &url]);
    assert_exit(&unfinished, 2);
    assert!(stderr(&unfinished).contains("not a finished bettimill dataset"));

    assert_exit(&server.build(&manifest, &url, &[]), 0);
    let ok = run(&["verify", &url]);
    assert_exit(&ok, 0);
    assert_eq!(
        common::stdout(&ok),
        format!("ok: 12 shards and 5 other files match {url}/index.json\n")
    );
    let status = run(&["status", &url]);
    assert_exit(&status, 0);
    assert!(
        common::stdout(&status).starts_with(&format!(
            "{url}: 12 of 12 shards complete, 0 missing, 0 invalid; index.json written"
        )),
        "{}",
        common::stdout(&status)
    );

    // One flipped bit in the last byte of a shard's first array: verify names the member.
    let name = "shards/s3test-000004.tar";
    let mut bytes = objects.get(name).unwrap().unwrap();
    let record = objects.get("records/s3test-000004.json").unwrap().unwrap();
    let record: serde_json::Value = serde_json::from_slice(&record).unwrap();
    let member = record["shard"]["members"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"].as_str().unwrap().ends_with(".npy"))
        .unwrap();
    let at = (member["offset"].as_u64().unwrap() + member["bytes"].as_u64().unwrap() - 1) as usize;
    bytes[at] ^= 1;
    objects.delete(name).unwrap();
    objects.put_new(name, bytes).unwrap();
    let bad = run(&["verify", &url, "--json"]);
    assert_exit(&bad, 1);
    let report: serde_json::Value = serde_json::from_slice(&bad.stdout).unwrap();
    let problems = report["problems"].as_array().unwrap();
    assert_eq!(problems.len(), 1, "{report}");
    assert_eq!(problems[0]["kind"], "data_corrupt");
    assert_eq!(problems[0]["shard"], name);
    assert_eq!(problems[0]["member"], member["name"]);
}

#[test]
fn array_tasks_upload_their_shards_and_finalize_writes_the_index() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    let manifest = manifest(&dir);
    let url = server.fresh_url("tasks");
    let run = |args: &[&str]| server.command().args(args).output().unwrap();
    // `k8s` binds the prefix and prints a Job with no volume, its pods' credentials from
    // a Secret.
    let job = run(&[
        "k8s",
        manifest.to_str().unwrap(),
        "--out",
        &url,
        "--tasks",
        "3",
    ]);
    assert_exit(&job, 0);
    let yaml = common::stdout(&job);
    assert!(yaml.contains(&format!("\"--dir\", \"{url}\"")), "{yaml}");
    assert!(
        yaml.contains("secretRef:\n                name: \"bettimill-s3\""),
        "{yaml}"
    );
    assert!(!yaml.contains("persistentVolumeClaim"), "{yaml}");

    let task = |index: &str| {
        let out = run(&[
            "worker",
            "--dir",
            &url,
            "--task-index",
            index,
            "--task-count",
            "3",
        ]);
        assert_exit(&out, 0);
    };
    task("0");
    task("2");
    // Task 1 has not run: finalize refuses, and writes no index.
    let early = run(&["finalize", &url]);
    assert_exit(&early, 2);
    assert!(
        stderr(&early).contains("4 of 12 shards are not complete"),
        "{}",
        stderr(&early)
    );
    assert_eq!(server.objects(&url).size("index.json").unwrap(), None);
    task("1");
    assert_exit(&run(&["finalize", &url]), 0);
    let local = dir.join("local");
    assert_exit(&common::build(&manifest, &local, 2), 0);
    assert_same_as_local(&server, &url, &local);
    assert_exit(&run(&["verify", &url]), 0);
}

#[test]
fn slurm_array_tasks_upload_to_the_bucket_and_finalize_writes_the_index() {
    if !system_test("a real Slurm (ci/slurm-up.sh) and a local S3 server") || !common::slurm_up() {
        return;
    }
    let Some(server) = Server::up() else { return };
    // On /tmp, as the Slurm test's: the jobs run the binary and write their logs there.
    let dir = Dir::new_in("/tmp", "bettimill-s3-slurm-");
    let manifest = manifest(&dir);
    let m = manifest.to_str().unwrap();
    let url = server.fresh_url("slurm");
    let scripts = dir.join("scripts");
    let s = scripts.to_str().unwrap();
    let run = |args: &[&str]| server.command().args(args).output().unwrap();

    // A bucket has no directory for the scripts and logs: --scripts names one.
    let out = run(&["slurm", m, "--out", &url, "--tasks", "3"]);
    assert_exit(&out, 2);
    assert!(
        stderr(&out).contains("give --scripts DIR"),
        "{}",
        stderr(&out)
    );
    assert_eq!(server.objects(&url).list().unwrap(), vec![]);

    // Bound, with every task in the array; the script names the bucket, not the key.
    let out = run(&["slurm", m, "--out", &url, "--tasks", "3", "--scripts", s]);
    assert_exit(&out, 0);
    let body = std::fs::read_to_string(scripts.join("build.sbatch")).unwrap();
    assert!(body.contains("#SBATCH --array=0,1,2\n"), "{body}");
    assert!(
        body.contains(&format!(
            "worker --dir '{url}' --task-index-from-env --task-count 3"
        )),
        "{body}"
    );
    assert!(!body.contains(&server.0.secret_access_key), "{body}");
    // Task 0 ran already (an earlier submission that did only it).
    let task = run(&[
        "worker",
        "--dir",
        &url,
        "--task-index",
        "0",
        "--task-count",
        "3",
    ]);
    assert_exit(&task, 0);

    // The submission runs the tasks that still have work, then finalize (afterok), and
    // waits for it; sbatch passes the AWS variables on to the jobs.
    let out = run(&[
        "slurm",
        m,
        "--out",
        &url,
        "--tasks",
        "3",
        "--scripts",
        s,
        "--submit",
        "--wait",
    ]);
    let stdout = common::stdout(&out);
    assert_eq!(out.status.code(), Some(0), "{stdout}{}", stderr(&out));
    assert!(
        stdout.contains("build job ") && stdout.contains("finalize job "),
        "{stdout}"
    );
    let body = std::fs::read_to_string(scripts.join("build.sbatch")).unwrap();
    assert!(body.contains("#SBATCH --array=1,2\n"), "{body}");
    let logs: Vec<String> = std::fs::read_dir(scripts.join("logs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(logs.len(), 3, "two array tasks and finalize: {logs:?}");

    let local = dir.join("local");
    assert_exit(&common::build(&manifest, &local, 2), 0);
    assert_same_as_local(&server, &url, &local);
    assert_exit(&run(&["verify", &url]), 0);
}

/// Peak resident set (KiB, GNU time's `%M`) of `bettimill ARGS` run against the server;
/// `None` (the test returns) when /usr/bin/time is missing outside CI.
fn peak_kib(server: &Server, args: &[&str]) -> Option<(Output, u64)> {
    common::run_with_peak_in(args, |command| {
        command.envs(server.0.vars());
    })
}

#[test]
fn verify_and_cat_of_a_bucket_hold_memory_flat_whatever_the_shard_size() {
    if !system_test("builds to a local S3 server") {
        return;
    }
    let Some(server) = Server::up() else { return };
    let dir = Dir::new();
    // Two shards of 120 samples of 96^3 voxels, uncompressed: about 102 MiB each.
    let manifest = dir.join("big.toml");
    std::fs::write(
        &manifest,
        "schema_version = 1\nname = \"big\"\ndimension = 3\nside = 96\nmode = [\"embed\"]\n\
         samples = 240\nshard_size = 120\nseed = 3\n\n[[classes]]\nfamily = \"ball\"\n",
    )
    .unwrap();
    let url = server.fresh_url("memory");
    assert_exit(&server.build(&manifest, &url, &["--max-uploads", "1"]), 0);
    let shard_bytes = server
        .objects(&url)
        .size("shards/big-000000.tar")
        .unwrap()
        .unwrap();
    assert!(shard_bytes > 100 << 20, "{shard_bytes}");
    // Ranges of 8 MiB, one at a time: far below one shard whatever its size.
    for args in [
        vec!["verify".to_string(), url.clone()],
        vec!["cat".to_string(), format!("{url}/shards/big-000000.tar")],
    ] {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let Some((out, kib)) = peak_kib(&server, &args) else {
            return;
        };
        assert_exit(&out, 0);
        assert!(
            kib < 64 << 10,
            "bettimill {}: peak {kib} KiB for shards of {shard_bytes} bytes",
            args[0]
        );
    }
}
