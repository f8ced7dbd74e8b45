//! The local S3 server of the object-storage tests: moto_server on loopback, installed and
//! started by `ci/s3-up.sh`, stopped by `ci/s3-down.sh` (by its PID). Every test that
//! needs one gets it here, so the start-up, the skip outside CI and the reading of the
//! script's env file are written once.
//!
//! - [`S3Server::shared`]: the one server of every test (the scripts' defaults), started
//!   when it is not up and left running (`ci/test.sh` stops it);
//! - [`S3Server::own`]: a server of the calling test's own, on a free port, that keeps its
//!   objects across [`S3Server::stop`] and [`S3Server::start`] (`S3_CI_KEEP=1`), for a
//!   test that stops the server under a build; stopped when dropped.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository's root (this crate is `crates/bettimill-testkit`).
fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The shared server's directory: ci/s3-up.sh's default `S3_CI_DIR`.
const SHARED_DIR: &str = "/tmp/bettimill-s3";

/// A running local S3 server: where it is, the key it accepts and its bucket.
#[derive(Debug)]
pub struct S3Server {
    /// Its `S3_CI_DIR`: PID file, log, env file (and recording).
    dir: PathBuf,
    /// Its port when it is the test's own; `None` for the shared server.
    own_port: Option<u16>,
    /// `AWS_ENDPOINT_URL`: `http://127.0.0.1:PORT`.
    pub endpoint: String,
    /// `AWS_ACCESS_KEY_ID`.
    pub access_key_id: String,
    /// `AWS_SECRET_ACCESS_KEY`.
    pub secret_access_key: String,
    /// `AWS_REGION`.
    pub region: String,
    /// The bucket the script made (empty at the server's first start).
    pub bucket: String,
}

/// Why running a script failed, or `None` when it exited 0.
fn run_script(name: &str, dir: &Path, port: Option<u16>) -> Option<String> {
    let script = repo_root().join("ci").join(name);
    let mut command = Command::new("bash");
    command.arg(&script).env("S3_CI_DIR", dir);
    if let Some(port) = port {
        command
            .env("S3_CI_PORT", port.to_string())
            .env("S3_CI_KEEP", "1");
    }
    match command.output() {
        Ok(out) if out.status.success() => None,
        Ok(out) => Some(format!(
            "{} exited with {}:\n{}",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        )),
        Err(err) => Some(format!("cannot run {}: {err}", script.display())),
    }
}

impl S3Server {
    /// The shared server, started when it is not up (a no-op when it is); `None` when it
    /// cannot be started, outside CI only (in CI the test fails).
    pub fn shared() -> Option<S3Server> {
        Self::up(PathBuf::from(SHARED_DIR), None)
    }

    /// A server of the calling test's own, its files in `dir` (a new directory: it starts
    /// with no object), on a free port of loopback; it keeps its objects across a stop and
    /// a start. `None` as for [`S3Server::shared`].
    pub fn own(dir: &Path) -> Option<S3Server> {
        // The port the kernel gives a listener, free again once it is dropped.
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|listener| listener.local_addr())
            .map(|addr| addr.port())
            .expect("a free port on loopback");
        Self::up(dir.to_path_buf(), Some(port))
    }

    fn up(dir: PathBuf, own_port: Option<u16>) -> Option<S3Server> {
        if let Some(reason) = run_script("s3-up.sh", &dir, own_port) {
            crate::skip_unless_ci("a local S3 server", &reason);
            return None;
        }
        let envfile = dir.join("env");
        let text = std::fs::read_to_string(&envfile)
            .unwrap_or_else(|err| panic!("ci/s3-up.sh wrote no {}: {err}", envfile.display()));
        let value = |key: &str| {
            text.lines()
                .find_map(|line| line.strip_prefix(key)?.strip_prefix('='))
                .map(str::to_string)
                .unwrap_or_else(|| panic!("no {key} in {}", envfile.display()))
        };
        Some(S3Server {
            endpoint: value("AWS_ENDPOINT_URL"),
            access_key_id: value("AWS_ACCESS_KEY_ID"),
            secret_access_key: value("AWS_SECRET_ACCESS_KEY"),
            region: value("AWS_REGION"),
            bucket: value("BETTIMILL_S3_CI_BUCKET"),
            dir,
            own_port,
        })
    }

    /// The variables that lead a client to this server with its key.
    pub fn vars(&self) -> [(&'static str, &str); 4] {
        [
            ("AWS_ENDPOINT_URL", &self.endpoint),
            ("AWS_ACCESS_KEY_ID", &self.access_key_id),
            ("AWS_SECRET_ACCESS_KEY", &self.secret_access_key),
            ("AWS_REGION", &self.region),
        ]
    }

    /// A prefix no earlier run used, under `area/` (the shared server keeps its objects
    /// while it runs).
    pub fn fresh_prefix(&self, area: &str, test: &str) -> String {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .expect("the clock is after 1970")
            .as_nanos();
        format!("{area}/{test}-{}-{nanos}", std::process::id())
    }

    /// Stops the test's own server (by its PID, ci/s3-down.sh); its objects come back at
    /// the next [`S3Server::start`].
    #[track_caller]
    pub fn stop(&self) {
        assert!(
            self.own_port.is_some(),
            "only a test's own server is stopped"
        );
        if let Some(reason) = run_script("s3-down.sh", &self.dir, None) {
            panic!("{reason}");
        }
    }

    /// Starts the test's own server again, on the same port, with the same key and the
    /// objects it held when it stopped.
    #[track_caller]
    pub fn start(&self) {
        assert!(
            self.own_port.is_some(),
            "only a test's own server is restarted"
        );
        if let Some(reason) = run_script("s3-up.sh", &self.dir, self.own_port) {
            panic!("{reason}");
        }
    }
}

impl Drop for S3Server {
    fn drop(&mut self) {
        if self.own_port.is_some() {
            let _ = run_script("s3-down.sh", &self.dir, None);
        }
    }
}
