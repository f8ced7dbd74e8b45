//! Reliability under hostile input, full disks, signals, random kills and large samples,
//! with the real `bettimill` binary (docs/reliability.md says what each test shows and how
//! to run the longer versions).
//!
//! - Hostile files: `betti` on `.npy` files whose header lies, `verify` on datasets whose
//!   tars hold absolute, `..` and link members or giant sizes and whose index.json has wrong
//!   types or shard names outside `shards/`; a worker fed garbage on stdin. Clear one-line
//!   errors, the documented exit codes, nothing written anywhere.
//! - Disk full: a build that hits a file-size limit (always) or ENOSPC on a 2 MiB tmpfs
//!   (a system test: with BETTIMILL_SYSTEM_TESTS=1, as root; in CI it must not skip) stops
//!   with exit 2 and a clear error, leaves no visible partial shard, and resumes to the
//!   bytes of a clean build.
//! - Signals: SIGINT and SIGTERM stop the coordinator and its workers (checked in /proc);
//!   the rerun is byte-identical.
//! - Soak: random SIGKILLs of the coordinator and of workers at random (seeded) moments,
//!   rerun until the build completes; orphaned workers must exit on their own; the result
//!   is byte-identical to a clean build. `BETTIMILL_SOAK_KILLS` turns the soak test into
//!   the long run with that many kills.
//! - Resources: the coordinator's peak memory for 2000 samples is less than twice that for
//!   200; a worker's peak for a 32^4 sample stays within the documented per-voxel bound.

use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

mod common;
use bettimill_testkit::{skip_unless_ci, system_test, Xorshift};
use common::{
    alive, assert_exit, assert_same, ball_and_handle, bettimill, build, children, kill, run,
    shard_files, snapshot, spawn_build, stderr, text, wait_until, Dir,
};

fn manifest(dir: &Path, dimension: u32, side: u32, samples: u32, shard_size: u32) -> PathBuf {
    let path = dir.join(format!("r{dimension}d-{side}-{samples}-{shard_size}.toml"));
    let name = format!("r{dimension}d");
    ball_and_handle(path, &name, dimension, side, samples, shard_size, 5)
}

/// Live processes whose command line is `bettimill worker --dir <out>` (any parent).
fn workers_of(out: &Path) -> Vec<u32> {
    let needle = out.to_string_lossy().into_owned();
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(cmdline) = std::fs::read(entry.path().join("cmdline")) else {
            continue;
        };
        let args: Vec<String> = cmdline
            .split(|&b| b == 0)
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        if args.iter().any(|a| a == "worker") && args.iter().any(|a| a == &needle) && alive(pid) {
            found.push(pid);
        }
    }
    found
}

/// VmHWM (peak resident set) of a process in KiB, if it is still running.
fn peak_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

/// Every visible tar is a complete shard: `status` lists none as invalid.
fn assert_no_partial_shard_visible(out: &Path) {
    // A directory killed while it was created holds no shard at all (and `status` names
    // that state instead of reporting shards).
    if !out.join("build.json").exists() {
        assert!(!out.join("shards").exists(), "{}", out.display());
        return;
    }
    let status = run(&["status", out.to_str().unwrap(), "--json"]);
    let status: serde_json::Value = serde_json::from_slice(&status.stdout)
        .unwrap_or_else(|e| panic!("status --json: {e}: {}", text(&status.stderr)));
    for invalid in status["invalid"].as_array().unwrap() {
        // A tar renamed into place whose record was not written yet (killed between the
        // two renames) is the only acceptable kind: it is complete bytes, rebuilt anyway.
        let reason = invalid["reason"].as_str().unwrap_or("");
        assert!(reason.contains("no completion record"), "{status}");
    }
}

fn one_line_error(output: &Output) -> String {
    let stderr = text(&output.stderr);
    assert!(
        stderr.starts_with("error: "),
        "expected an error message, got: {stderr}"
    );
    assert!(
        !stderr.contains("panicked") && !stderr.contains("RUST_BACKTRACE"),
        "{stderr}"
    );
    stderr
}

// ---------------------------------------------------------------- hostile files

fn npy(header: &str, data_len: usize) -> Vec<u8> {
    let mut text = header.to_string();
    while !(10 + text.len() + 1).is_multiple_of(64) {
        text.push(' ');
    }
    text.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(text.len() as u16).to_le_bytes());
    bytes.extend_from_slice(text.as_bytes());
    bytes.extend(std::iter::repeat_n(1u8, data_len));
    bytes
}

#[test]
fn betti_refuses_npy_files_with_lying_headers() {
    let tmp = Dir::new();
    let header = |descr: &str, shape: &str| {
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}")
    };
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "huge.npy",
            npy(&header("|u1", "(1000000, 1000000, 1000000)"), 64),
            "the header promises 1000000000000000000 bytes of data, more than the 17179869184 allowed",
        ),
        (
            "overflow.npy",
            npy(&header("<u8", "(4294967296, 4294967296, 16)"), 64),
            "overflows",
        ),
        (
            "float.npy",
            npy(&header("<f4", "(4, 4)"), 64),
            "unsupported dtype",
        ),
        (
            "object.npy",
            npy(&header("|O", "(4, 4)"), 128),
            "unsupported dtype",
        ),
        (
            "truncated.npy",
            npy(&header("|u1", "(8, 8)"), 63),
            "truncated data",
        ),
        (
            "trailing.npy",
            npy(&header("|u1", "(8, 8)"), 65),
            "the data goes on past the 64 bytes the header promises",
        ),
        (
            "wide.npy",
            npy(&header("<u2", "(8, 8)"), 64),
            "truncated data: the header promises 128 bytes of data, the file has 64",
        ),
        (
            "rank5.npy",
            npy(&header("|u1", "(2, 2, 2, 2, 2)"), 32),
            "unsupported shape",
        ),
        (
            "garbage.npy",
            b"\x93NUMPY\x07\x00garbage".to_vec(),
            "not a valid .npy",
        ),
    ];
    for (name, bytes, _) in &cases {
        std::fs::write(tmp.path().join(name), bytes).unwrap();
    }
    let before = snapshot(tmp.path());
    for (name, _, expected) in &cases {
        let path = tmp.path().join(name);
        for extra in [&[][..], &["--json"][..], &["--strict"][..]] {
            let mut args = vec!["betti", path.to_str().unwrap()];
            args.extend_from_slice(extra);
            let out = run(&args);
            assert_eq!(
                out.status.code(),
                Some(2),
                "{name} {extra:?}: {}",
                text(&out.stderr)
            );
            let stderr = one_line_error(&out);
            assert!(stderr.contains(expected), "{name}: {stderr}");
            assert!(
                stderr.contains(name),
                "{name}: the error names the file: {stderr}"
            );
            assert!(out.stdout.is_empty(), "{name}: {}", text(&out.stdout));
        }
    }
    assert_eq!(snapshot(tmp.path()), before, "betti wrote or changed files");
}

/// A correctly checksummed USTAR header with any name, type and size field.
/// A valid 4.9 GB `.npy` of shape (70000, 70000) used to be read for a minute and then
/// abort `betti` (`memory allocation of 9175433216 bytes failed` in the npy placer, exit
/// 134). The shape is now checked against the memory available (here an address-space
/// limit of 8 GB, as `ulimit -v 8000000`) before anything is allocated: exit 2, one line.
#[test]
fn betti_on_an_array_larger_than_memory_is_an_error_not_an_abort() {
    let tmp = Dir::new();
    let path = tmp.path().join("big.npy");
    let header = npy(
        "{'descr': '|u1', 'fortran_order': False, 'shape': (70000, 70000), }",
        0,
    );
    let file = std::fs::File::create(&path).unwrap();
    std::io::Write::write_all(&mut &file, &header).unwrap();
    // Sparse: the data reads as zeros and takes no disk.
    file.set_len(header.len() as u64 + 70000 * 70000).unwrap();
    drop(file);
    let out = Command::new("prlimit")
        .arg("--as=8000000000")
        .arg("--")
        .arg(common::BETTIMILL)
        .arg("betti")
        .arg(&path)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "{:?}: {}",
        out.status,
        text(&out.stderr)
    );
    let error = one_line_error(&out);
    assert!(
        error.contains("big.npy")
            && error.contains("the image (2D, 4900280004 voxels) needs about")
            && error.contains("more than the"),
        "{error}"
    );
}

fn raw_header(name: &[u8], typeflag: u8, size: u64) -> [u8; 512] {
    let mut header = [0u8; 512];
    header[..name.len()].copy_from_slice(name);
    header[100..108].copy_from_slice(b"0000644\0");
    header[108..116].copy_from_slice(b"0000000\0");
    header[116..124].copy_from_slice(b"0000000\0");
    header[124..136].copy_from_slice(format!("{size:011o}\0").as_bytes());
    header[136..148].copy_from_slice(b"00000000000\0");
    header[156] = typeflag;
    if typeflag == b'2' || typeflag == b'1' {
        header[157..168].copy_from_slice(b"/etc/passwd");
    }
    header[257..265].copy_from_slice(b"ustar\x0000");
    header[148..156].fill(b' ');
    let sum: u32 = header.iter().map(|&b| b as u32).sum();
    header[148..156].copy_from_slice(format!("{sum:06o}\0 ").as_bytes());
    header
}

fn hostile_tar(name: &[u8], typeflag: u8, size: u64, data: usize) -> Vec<u8> {
    let mut bytes = raw_header(name, typeflag, size).to_vec();
    bytes.extend(vec![b'x'; data.div_ceil(512) * 512]);
    bytes.extend_from_slice(&[0; 1024]);
    bytes
}

/// A change to a parsed index.json.
type IndexMutation = Box<dyn Fn(&mut serde_json::Value)>;

#[test]
fn verify_refuses_hostile_shards_and_indexes_and_writes_nothing() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 4, 2);
    let clean = tmp.path().join("clean");
    let out = build(&m, &clean, 1);
    assert_exit(&out, 0);
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(clean.join("index.json")).unwrap()).unwrap();
    let shard_name = index["shards"][0]["name"].as_str().unwrap().to_string();

    let copy = |label: &str| -> PathBuf {
        let dir = tmp.path().join(label);
        for (rel, bytes) in snapshot(&clean) {
            let path = dir.join(rel);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, bytes).unwrap();
        }
        dir
    };

    // Shards replaced by hostile archives: verify finds differences (exit 1) or refuses
    // (exit 2), says which shard, and extracts nothing.
    let hostile_tars: Vec<(&str, Vec<u8>)> = vec![
        (
            "absolute",
            hostile_tar(b"/tmp/bettimill-escape.npy", b'0', 4, 4),
        ),
        (
            "dotdot",
            hostile_tar(b"../../bettimill-escape.npy", b'0', 4, 4),
        ),
        ("symlink", hostile_tar(b"s000000.npy", b'2', 0, 0)),
        ("hardlink", hostile_tar(b"s000000.npy", b'1', 0, 0)),
        (
            "giant",
            hostile_tar(b"s000000.npy", b'0', 0o77777777777, 512),
        ),
        (
            "random",
            (0..4096u32)
                .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
                .collect(),
        ),
    ];
    for (label, tar) in &hostile_tars {
        let dir = copy(label);
        std::fs::write(dir.join(&shard_name), tar).unwrap();
        let before = snapshot(tmp.path());
        let out = run(&["verify", dir.to_str().unwrap()]);
        let code = out.status.code();
        assert!(matches!(code, Some(1) | Some(2)), "{label}: {code:?}");
        let all = format!("{}{}", text(&out.stdout), text(&out.stderr));
        assert!(all.contains(&shard_name), "{label}: names the shard: {all}");
        assert!(!all.contains("panicked"), "{label}: {all}");
        assert_eq!(snapshot(tmp.path()), before, "{label}: verify wrote files");
        for escape in ["/tmp/bettimill-escape.npy", "/bettimill-escape.npy"] {
            assert!(!Path::new(escape).exists(), "{label}: {escape} was written");
        }
        assert!(!tmp.path().join("bettimill-escape.npy").exists());
    }

    // index.json with wrong types and names outside shards/: a bad index is refused with
    // exit 2 and a message naming index.json; no path it names is opened for writing.
    let mutations: Vec<(&str, IndexMutation)> = vec![
        (
            "bytes-string",
            Box::new(|v| v["shards"][0]["bytes"] = "many".into()),
        ),
        (
            "shards-object",
            Box::new(|v| v["shards"] = serde_json::json!({"a": 1})),
        ),
        (
            "samples-negative",
            Box::new(|v| v["shards"][0]["samples"] = (-1).into()),
        ),
        (
            "name-absolute",
            Box::new(|v| v["shards"][0]["name"] = "/etc/passwd".into()),
        ),
        (
            "name-dotdot",
            Box::new(|v| v["shards"][0]["name"] = "shards/../../outside.tar".into()),
        ),
        (
            "name-outside",
            Box::new(|v| v["shards"][0]["name"] = "elsewhere/x.tar".into()),
        ),
        ("format", Box::new(|v| v["format"] = 7.into())),
        (
            "not-an-object",
            Box::new(|v| *v = serde_json::json!([1, 2, 3])),
        ),
    ];
    for (label, mutate) in &mutations {
        let dir = copy(label);
        let mut value = index.clone();
        mutate(&mut value);
        std::fs::write(dir.join("index.json"), serde_json::to_vec(&value).unwrap()).unwrap();
        let before = snapshot(tmp.path());
        let out = run(&["verify", dir.to_str().unwrap()]);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{label}: {}{}",
            text(&out.stdout),
            text(&out.stderr)
        );
        let stderr = one_line_error(&out);
        assert!(stderr.contains("index.json"), "{label}: {stderr}");
        assert_eq!(snapshot(tmp.path()), before, "{label}: verify wrote files");
    }
}

#[test]
fn a_worker_fed_garbage_exits_with_an_error_instead_of_hanging() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 4, 2);
    let dir = tmp.path().join("ds");
    assert_eq!(build(&m, &dir, 1).status.code(), Some(0));
    let inputs: Vec<(&str, Vec<u8>)> = vec![
        ("huge length", vec![0xff, 0xff, 0xff, 0xff, 1, 2, 3]),
        ("zero length", vec![0, 0, 0, 0]),
        ("random payload", {
            let mut v = 40u32.to_le_bytes().to_vec();
            v.extend((0..40u8).map(|i| i.wrapping_mul(97)));
            v
        }),
        ("truncated frame", vec![10, 0, 0, 0, 1, 2]),
    ];
    for (label, input) in inputs {
        let mut child = bettimill()
            .args(["worker", "--dir", dir.to_str().unwrap()])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        {
            use std::io::Write;
            let mut stdin = child.stdin.take().unwrap();
            let _ = stdin.write_all(&input);
        } // stdin closed here
        let pid = child.id();
        wait_until(
            &format!("the worker fed {label} to exit"),
            Duration::from_secs(30),
            || !alive(pid),
        );
        let out = child.wait_with_output().unwrap();
        let stderr = text(&out.stderr);
        assert_ne!(out.status.code(), Some(0), "{label}: {stderr}");
        assert!(!stderr.contains("panicked"), "{label}: {stderr}");
        assert!(stderr.contains("coordinator"), "{label}: {stderr}");
    }
}

// ---------------------------------------------------------------- disk full

fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .and_then(|l| l.split_whitespace().nth(2).map(|u| u == "0"))
        })
        .unwrap_or(false)
}

/// Checks the state a failed build leaves and that resuming gives the clean bytes.
fn check_failed_then_resumed(m: &Path, out: &Path, clean: &Path, code: Option<i32>, stderr: &str) {
    assert_eq!(code, Some(2), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!out.join("index.json").exists(), "{stderr}");
    assert_no_partial_shard_visible(out);
    let resumed = build(m, out, 2);
    assert_exit(&resumed, 0);
    assert_same(clean, out);
}

#[test]
fn a_build_over_the_file_size_limit_stops_cleanly_and_resumes_identically() {
    let tmp = Dir::new();
    // Shards of about 24 KiB; every other file is far below the 12 KiB limit.
    let m = manifest(tmp.path(), 2, 64, 12, 4);
    let clean = common::clean_build(&m, tmp.path(), 2);
    let out = tmp.path().join("limited");
    // SIGXFSZ is ignored so that writes past the limit fail with EFBIG instead of killing
    // the process (an ignored signal stays ignored across exec).
    let limited = Command::new("sh")
        .args([
            "-c",
            "trap '' XFSZ; exec prlimit --fsize=12288 -- \"$@\"",
            "sh",
        ])
        .arg(common::BETTIMILL)
        .args(["build", m.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(["--workers", "2"])
        .output()
        .unwrap();
    let stderr = text(&limited.stderr);
    assert!(
        stderr.contains("File too large") || stderr.contains("too large"),
        "the error says why: {stderr}"
    );
    check_failed_then_resumed(&m, &out, &clean, limited.status.code(), &stderr);
}

/// Unmounts a tmpfs when dropped, so a failing test leaves no mount behind.
struct Mount(PathBuf);

impl Drop for Mount {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn a_build_that_fills_the_disk_stops_cleanly_and_resumes_identically() {
    if !system_test("a tmpfs mount") {
        return;
    }
    if !is_root() {
        // CI runs as root: there the ENOSPC test must not be skipped.
        skip_unless_ci("root", "mounting a small tmpfs needs root");
        return;
    }
    let tmp = Dir::new();
    // About 3 MiB of shards (2D 128^2 samples of 16 KiB) into a 2 MiB file system.
    let m = manifest(tmp.path(), 2, 128, 192, 8);
    let clean = tmp.path().join("clean");
    let out = build(&m, &clean, 2);
    assert_exit(&out, 0);
    let mount_point = tmp.path().join("small");
    std::fs::create_dir(&mount_point).unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=2M", "tmpfs"])
        .arg(&mount_point)
        .output()
        .unwrap();
    assert!(mounted.status.success(), "mount: {}", text(&mounted.stderr));
    let _guard = Mount(mount_point.clone());
    let out = mount_point.join("ds");
    let full = build(&m, &out, 2);
    let stderr = text(&full.stderr);
    assert!(
        stderr.contains("No space left on device"),
        "the error says why: {stderr}"
    );
    // Space comes back: the same command resumes.
    let grown = Command::new("mount")
        .args(["-o", "remount,size=64M"])
        .arg(&mount_point)
        .output()
        .unwrap();
    assert!(grown.status.success(), "remount: {}", text(&grown.stderr));
    check_failed_then_resumed(&m, &out, &clean, full.status.code(), &stderr);
}

// ---------------------------------------------------------------- creation stopped half-way

/// Files to put into a directory by hand: (name, bytes).
type Files<'a> = Vec<(&'a str, Vec<u8>)>;

/// Whether any temporary (`.NAME.tmp-PID`) is left directly in `dir`.
fn temporaries_in(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp-"))
        .collect()
}

/// Every state a build killed (or out of disk) while creating its directory can leave,
/// built by hand: the same command resumes each to the bytes of a clean build, and the
/// reading commands name the state (and write nothing) instead of calling it foreign.
#[test]
fn a_creation_stopped_half_way_resumes_with_the_same_command() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 6, 2);
    let clean = common::clean_build(&m, tmp.path(), 2);
    let manifest_bytes = std::fs::read(&m).unwrap();
    let states: Vec<(&str, Files)> = vec![
        ("empty", vec![]),
        ("lock-only", vec![(".lock", vec![])]),
        (
            "manifest-temporary",
            vec![(".manifest.toml.tmp-4242", manifest_bytes[..20].to_vec())],
        ),
        (
            "manifest-and-build-json-temporary",
            vec![
                ("manifest.toml", manifest_bytes.clone()),
                (".build.json.tmp-4242", b"{\n  \"tool_ver".to_vec()),
            ],
        ),
        (
            "manifest-alone",
            vec![("manifest.toml", manifest_bytes.clone())],
        ),
        (
            "lock-manifest-and-temporaries",
            vec![
                (".lock", vec![]),
                ("manifest.toml", manifest_bytes.clone()),
                (".manifest.toml.tmp-17", b"x".to_vec()),
                (".build.json.tmp-18", vec![]),
            ],
        ),
    ];
    for (what, files) in states {
        let out = tmp.path().join(what);
        std::fs::create_dir(&out).unwrap();
        for (name, bytes) in &files {
            std::fs::write(out.join(name), bytes).unwrap();
        }
        if files.iter().any(|(name, _)| *name == "manifest.toml") {
            let before = snapshot(&out);
            for command in ["finalize", "status"] {
                let output = run(&[command, out.to_str().unwrap()]);
                assert_exit(&output, 2);
                let message = stderr(&output);
                assert!(
                    message.contains("its creation stopped before build.json was written")
                        && message.contains("rerun the same `bettimill build"),
                    "{what}, {command}: {message}"
                );
            }
            assert_eq!(snapshot(&out), before, "{what}: a reading command wrote");
        }
        let resumed = build(&m, &out, 2);
        assert_exit(&resumed, 0);
        assert_same(&clean, &out);
        assert_eq!(temporaries_in(&out), Vec::<String>::new(), "{what}");
    }
}

/// A directory is refused, untouched (not even a lock is created), only when it is really
/// not a creation of this manifest.
#[test]
fn only_a_really_foreign_directory_is_refused_and_it_is_left_untouched() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 4, 2);
    let other = manifest(tmp.path(), 2, 16, 6, 2);
    let cases: Vec<(&str, Files, &str)> = vec![
        (
            "notes",
            vec![("notes.txt", b"mine".to_vec())],
            "is not empty and holds no bettimill dataset",
        ),
        (
            "other-manifest",
            vec![("manifest.toml", std::fs::read(&other).unwrap())],
            "holds the start of a dataset of a different manifest",
        ),
        (
            "manifest-and-more",
            vec![
                ("manifest.toml", std::fs::read(&m).unwrap()),
                ("results.csv", b"1,2\n".to_vec()),
            ],
            "is not empty and holds no bettimill dataset",
        ),
        (
            "not-our-temporary",
            vec![(".manifest.toml.tmp-abc", b"x".to_vec())],
            "is not empty and holds no bettimill dataset",
        ),
    ];
    for (what, files, expected) in cases {
        let out = tmp.path().join(what);
        std::fs::create_dir(&out).unwrap();
        for (name, bytes) in &files {
            std::fs::write(out.join(name), bytes).unwrap();
        }
        let before = snapshot(&out);
        let refused = build(&m, &out, 2);
        assert_exit(&refused, 2);
        assert!(
            stderr(&refused).contains(expected),
            "{what}: {}",
            stderr(&refused)
        );
        assert_eq!(snapshot(&out), before, "{what}: something was written");
    }
}

/// Two builds started together into a fresh directory: the one that does not get the
/// directory is told another build holds its lock (not that the directory is foreign), and
/// the directory ends as a clean build.
#[test]
fn the_loser_of_two_builds_into_a_fresh_directory_is_told_about_the_lock() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 8, 2);
    let clean = common::clean_build(&m, tmp.path(), 1);
    for round in 0..4 {
        let out = tmp.path().join(format!("race{round}"));
        let first = spawn_build(&m, &out, 1, &[]);
        let second = spawn_build(&m, &out, 1, &[]);
        for child in [first, second] {
            let result = child.wait_with_output().unwrap();
            let message = text(&result.stderr);
            assert!(
                result.status.code() == Some(0)
                    || (result.status.code() == Some(2)
                        && message.contains("another bettimill build or finalize is running")),
                "{:?}: {message}",
                result.status
            );
        }
        if !out.join("index.json").exists() {
            assert_exit(&build(&m, &out, 1), 0);
        }
        assert_same(&clean, &out);
    }
}

/// `finalize` used to remove temporaries without the directory lock: of two finalizes at
/// once on a complete directory, one failed in most runs (`cannot rename into
/// DIR/shardindex-test.json: No such file or directory`), and a finalize during a build's
/// last step made the build fail. Now finalize waits for the lock, says so, and then finds
/// the work done.
#[test]
fn finalize_does_not_remove_the_temporaries_of_a_running_build_or_finalize() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 24, 2);
    let clean = common::clean_build(&m, tmp.path(), 1);
    let out = tmp.path().join("twice");
    assert_exit(&build(&m, &out, 1), 0);
    let finalize = |out: &Path| {
        bettimill()
            .arg("finalize")
            .arg(out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    for round in 0..8 {
        // Without index.json and the files written with it, both have everything to write.
        for entry in std::fs::read_dir(&out).unwrap().flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            if name == "index.json" || name.starts_with("shardindex-") {
                std::fs::remove_file(entry.path()).unwrap();
            }
        }
        let (first, second) = (finalize(&out), finalize(&out));
        for child in [first, second] {
            let result = child.wait_with_output().unwrap();
            assert_eq!(
                result.status.code(),
                Some(0),
                "round {round}: {}",
                text(&result.stderr)
            );
        }
        assert_same(&clean, &out);
    }
    // A finalize started again and again while a build runs waits for it each time; the
    // build finishes with exit 0.
    let out = tmp.path().join("during");
    // The hook holds each shard half a second before its rename, so the build is still
    // running (and holds its lock) when the first finalize starts, on any machine.
    let coordinator = spawn_build(
        &m,
        &out,
        2,
        &[("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "0.5")],
    );
    wait_until("a shard being written", Duration::from_secs(60), || {
        !shard_files(&out).is_empty()
    });
    let mut waited = false;
    while alive(coordinator.id()) {
        let result = finalize(&out).wait_with_output().unwrap();
        let message = text(&result.stderr);
        waited |= message.contains("is building or finalizing");
        assert!(
            result.status.code() == Some(0)
                || (result.status.code() == Some(2) && message.contains("not complete")),
            "{:?}: {message}",
            result.status
        );
    }
    let result = coordinator.wait_with_output().unwrap();
    assert_eq!(result.status.code(), Some(0), "{}", text(&result.stderr));
    assert!(waited, "no finalize waited for the build");
    assert_same(&clean, &out);
}

/// A build used to release the directory lock between binding the directory and starting
/// its coordinator: a `finalize` that took it in that gap made the build refuse its own
/// directory (exit 2, "another bettimill build is running") and left it unbuilt. The build
/// now holds the lock from the binding on, so the finalize waits for it and finds the work
/// done. The test hook holds the build in that gap for a second.
#[test]
fn a_finalize_during_a_builds_start_up_waits_for_the_build_instead_of_failing_it() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 16, 2);
    let clean = common::clean_build(&m, tmp.path(), 1);
    for (round, fresh) in [true, false].into_iter().enumerate() {
        let out = tmp.path().join("started");
        if fresh {
            let _ = std::fs::remove_dir_all(&out);
        } else {
            // A bound directory without shards: the build resumes it.
            let _ = std::fs::remove_dir_all(&out);
            assert_exit(
                &run(&[
                    "slurm",
                    m.to_str().unwrap(),
                    "--out",
                    out.to_str().unwrap(),
                    "--tasks",
                    "1",
                ]),
                0,
            );
            std::fs::remove_dir_all(out.join("slurm")).unwrap();
        }
        let coordinator = spawn_build(&m, &out, 1, &[("BETTIMILL_TEST_PAUSE_AT_STARTUP", "1")]);
        wait_until(
            "the build to lock its directory",
            Duration::from_secs(60),
            || holds_a_file_lock(coordinator.id()),
        );
        let finalize = bettimill()
            .arg("finalize")
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        let build = coordinator.wait_with_output().unwrap();
        assert_eq!(
            build.status.code(),
            Some(0),
            "round {round}: the build: {}",
            text(&build.stderr)
        );
        let message = text(&finalize.stderr);
        assert!(
            finalize.status.code() == Some(0) && message.contains("is building or finalizing"),
            "round {round}: the finalize did not wait for the build: {:?}: {message}",
            finalize.status
        );
        assert_same(&clean, &out);
    }
}

/// Whether process `pid` holds an flock-style lock (the directory lock), from /proc/locks.
fn holds_a_file_lock(pid: u32) -> bool {
    std::fs::read_to_string("/proc/locks")
        .unwrap()
        .lines()
        .any(|line| {
            let fields: Vec<&str> = line.split_whitespace().collect();
            fields.get(1) == Some(&"FLOCK")
                && fields.get(3) == Some(&"WRITE")
                && fields.get(4) == Some(&pid.to_string().as_str())
        })
}

/// `bettimill worker --task-index I --task-count 2` into `out`, started in the background
/// (stderr captured), with the pause hook before each shard's rename when given.
fn array_task(out: &Path, index: u32, pause: Option<&str>) -> std::process::Child {
    let mut command = bettimill();
    command
        .arg("worker")
        .arg("--dir")
        .arg(out)
        .args([
            "--task-index",
            &index.to_string(),
            "--task-count",
            "2",
            "--threads",
            "1",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    if let Some(pause) = pause {
        command.env("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", pause);
    }
    command.spawn().unwrap()
}

/// A directory bound for 2 array tasks by `bettimill slurm` (scripts written, nothing run).
fn bound_for_tasks(m: &Path, out: &Path) {
    assert_exit(
        &run(&[
            "slurm",
            m.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--tasks",
            "2",
        ]),
        0,
    );
}

/// Array tasks hold the directory lock shared, so a `finalize` run by hand while they
/// build waits for them (saying so) instead of racing them; and no temporary a task is
/// still writing is removed. Two jobs' tasks run at once (a job resubmitted while the first
/// still runs): the first job's tasks hold each shard a second before its rename (test
/// hook), the second job's build every shard meanwhile, beside them and beside the waiting
/// finalize. A finalize without the lock used to remove the first job's temporaries, and
/// each of its tasks then failed (`cannot rename into ...: No such file or directory`).
/// Every task must exit 0, the finalize 0 after the last task, and the directory must end
/// as a local build's, every shard timed.
#[test]
fn a_manual_finalize_while_array_tasks_build_waits_for_them_and_removes_nothing() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 16, 2);
    let clean = common::clean_build(&m, tmp.path(), 1);
    let out = tmp.path().join("array");
    bound_for_tasks(&m, &out);
    let first: Vec<_> = (0..2).map(|i| array_task(&out, i, Some("1"))).collect();
    let held = || temporaries_in(&out.join("shards"));
    wait_until(
        "both tasks holding a shard",
        Duration::from_secs(60),
        || held().len() == 2,
    );
    let finalize = bettimill()
        .arg("finalize")
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The second job builds every shard, those the first job's tasks hold included.
    for index in 0..2 {
        let result = array_task(&out, index, None).wait_with_output().unwrap();
        assert_eq!(result.status.code(), Some(0), "{}", text(&result.stderr));
    }
    while first.iter().any(|t| alive(t.id())) {
        assert!(
            alive(finalize.id()),
            "finalize ended while array tasks still held the directory"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    for (index, task) in first.into_iter().enumerate() {
        let result = task.wait_with_output().unwrap();
        assert_eq!(
            result.status.code(),
            Some(0),
            "task {index} of the first job: {}",
            text(&result.stderr)
        );
    }
    let finalized = finalize.wait_with_output().unwrap();
    let message = text(&finalized.stderr);
    assert_eq!(finalized.status.code(), Some(0), "{message}");
    assert!(
        message.contains("array tasks (`bettimill worker --task-count N`) are writing into")
            && message.contains("waiting for them to finish"),
        "{message}"
    );
    assert!(held().is_empty(), "{:?}", held());
    assert_exit(&run(&["verify", out.to_str().unwrap()]), 0);
    let timings = std::fs::read_dir(out.join("timings")).unwrap().count();
    assert_eq!(timings, 8, "a shard without its timing");
    std::fs::remove_dir_all(out.join("slurm")).unwrap();
    assert_same(&clean, &out);
}

/// A local `bettimill build` into a directory that array tasks are writing (a Slurm job
/// still running) is refused before it writes anything, naming the array tasks and the
/// lock they hold; an array task started while a build runs there is refused the same
/// way, naming the build. The job and the build each finish on their own, and a build
/// afterwards completes the directory to a local build's bytes.
#[test]
fn a_build_beside_running_array_tasks_is_refused_and_a_task_beside_a_build_too() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 16, 2);
    let clean = common::clean_build(&m, tmp.path(), 1);
    let out = tmp.path().join("array");
    bound_for_tasks(&m, &out);
    let task = array_task(&out, 0, Some("1"));
    wait_until("the task holding a shard", Duration::from_secs(60), || {
        !temporaries_in(&out.join("shards")).is_empty()
    });
    for workers in [1, 2] {
        let refused = build(&m, &out, workers);
        assert_exit(&refused, 2);
        let message = one_line_error(&refused);
        assert!(
            message.contains("array tasks (`bettimill worker --task-count N`) are writing into")
                && message.contains(".lock"),
            "--workers {workers}: {message}"
        );
    }
    assert!(
        alive(task.id()),
        "the task ended before the builds were refused"
    );
    let result = task.wait_with_output().unwrap();
    assert_eq!(result.status.code(), Some(0), "{}", text(&result.stderr));
    // The other way round: a build holds the directory, a task started meanwhile is refused.
    let coordinator = spawn_build(&m, &out, 1, &[("BETTIMILL_TEST_PAUSE_AT_STARTUP", "2")]);
    wait_until(
        "the build to lock its directory",
        Duration::from_secs(60),
        || holds_a_file_lock(coordinator.id()),
    );
    let refused = array_task(&out, 1, None).wait_with_output().unwrap();
    assert_eq!(refused.status.code(), Some(2), "{}", text(&refused.stderr));
    let message = one_line_error(&refused);
    assert!(
        message.contains("a bettimill build or finalize is running in")
            && message.contains("array tasks do not write beside it"),
        "{message}"
    );
    let built = coordinator.wait_with_output().unwrap();
    assert_eq!(built.status.code(), Some(0), "{}", text(&built.stderr));
    std::fs::remove_dir_all(out.join("slurm")).unwrap();
    assert_same(&clean, &out);
}

#[test]
fn a_disk_full_while_the_directory_is_created_resumes_once_space_is_back() {
    if !system_test("a tmpfs mount") {
        return;
    }
    if !is_root() {
        // CI runs as root: there the ENOSPC test must not be skipped.
        skip_unless_ci("root", "mounting a small tmpfs needs root");
        return;
    }
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 4, 2);
    let clean = common::clean_build(&m, tmp.path(), 2);
    let mount_point = tmp.path().join("tiny");
    std::fs::create_dir(&mount_point).unwrap();
    // One page: room for manifest.toml, not for build.json too.
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=4k", "tmpfs"])
        .arg(&mount_point)
        .output()
        .unwrap();
    assert!(mounted.status.success(), "mount: {}", text(&mounted.stderr));
    let _guard = Mount(mount_point.clone());
    let out = mount_point.join("ds");
    let full = build(&m, &out, 2);
    common::assert_exit_saying(&full, 2, "No space left on device");
    assert!(!out.join("build.json").exists());
    let grown = Command::new("mount")
        .args(["-o", "remount,size=64M"])
        .arg(&mount_point)
        .output()
        .unwrap();
    assert!(grown.status.success(), "remount: {}", text(&grown.stderr));
    common::assert_rebuilds_identically(&m, &out, 2, &clean);
}

// ---------------------------------------------------------------- signals

#[test]
fn sigint_and_sigterm_stop_every_worker_and_the_rerun_is_identical() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 20, 12, 3);
    let clean = common::clean_build(&m, tmp.path(), 2);
    for signal in ["-INT", "-TERM"] {
        let out = tmp.path().join(format!("signal{signal}"));
        // The hook holds each worker between its temporary file and the rename, so the
        // signal lands in the middle of the build on any machine.
        let coordinator = spawn_build(&m, &out, 2, &[("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "60")]);
        wait_until("a temporary shard file", Duration::from_secs(60), || {
            shard_files(&out).iter().any(|n| n.contains(".tmp-"))
        });
        assert_eq!(workers_of(&out).len(), 2, "two workers run");
        assert!(kill(signal, coordinator.id()));
        let result = coordinator.wait_with_output().unwrap();
        let stderr = text(&result.stderr);
        assert_eq!(result.status.code(), Some(130), "{signal}: {stderr}");
        assert!(stderr.contains("resume with: bettimill build"), "{stderr}");
        assert_eq!(
            workers_of(&out),
            Vec::<u32>::new(),
            "{signal}: workers remain"
        );
        assert_no_partial_shard_visible(&out);
        common::assert_rebuilds_identically(&m, &out, 2, &clean);
    }
}

/// The start-up of a build (planning, creating and checking the directory) runs under the
/// signal handlers: a signal there ends the build with its message, not a silent death
/// (exit 143, or death by SIGINT), and for a huge plan start-up is not short. The test hook
/// `BETTIMILL_TEST_PAUSE_AT_STARTUP` holds the build in start-up, after the directory is
/// bound and before any worker starts, so the signal lands there on any machine.
#[test]
fn a_signal_during_start_up_exits_130_with_a_message_and_the_rerun_is_identical() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 6, 2);
    let clean = common::clean_build(&m, tmp.path(), 2);
    for signal in ["-INT", "-TERM"] {
        let out = tmp.path().join(format!("startup{signal}"));
        let coordinator = spawn_build(&m, &out, 2, &[("BETTIMILL_TEST_PAUSE_AT_STARTUP", "120")]);
        wait_until("build.json", Duration::from_secs(60), || {
            out.join("build.json").exists()
        });
        assert!(kill(signal, coordinator.id()));
        let start = Instant::now();
        let result = coordinator.wait_with_output().unwrap();
        let message = text(&result.stderr);
        assert!(start.elapsed() < Duration::from_secs(60), "{message}");
        assert_eq!(result.status.code(), Some(130), "{signal}: {message}");
        assert!(
            message.contains("interrupted while no worker was running")
                && message.contains("resume with: bettimill build"),
            "{message}"
        );
        assert!(workers_of(&out).is_empty());
        common::assert_rebuilds_identically(&m, &out, 2, &clean);
    }
}

/// Signals from the first milliseconds of a build on: each ends it with 130 (or, sent
/// before `main` has run its first line, kills it by that signal with nothing written),
/// and the rerun ends byte-identical. Counts are printed; no outcome is left to luck but
/// which of the two allowed ones is seen.
#[test]
#[allow(clippy::print_stderr)]
fn signals_in_the_first_milliseconds_exit_130_and_resume() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 6, 2);
    let clean = common::clean_build(&m, tmp.path(), 2);
    let (mut handled, mut before_main) = (0, 0);
    for step in 0..16u64 {
        let signal = if step % 2 == 0 { "-INT" } else { "-TERM" };
        let out = tmp.path().join(format!("early{step}"));
        let coordinator = spawn_build(&m, &out, 2, &[]);
        std::thread::sleep(Duration::from_micros(step * 1500));
        kill(signal, coordinator.id());
        let result = coordinator.wait_with_output().unwrap();
        match (result.status.code(), result.status.signal()) {
            (Some(130), _) => handled += 1,
            (None, Some(2 | 15)) => {
                before_main += 1;
                assert!(!out.join("manifest.toml").exists(), "{}", out.display());
            }
            (Some(0), _) => {}
            other => panic!("{signal} after {step}: {other:?}: {}", text(&result.stderr)),
        }
        assert!(workers_of(&out).is_empty());
        common::assert_rebuilds_identically(&m, &out, 2, &clean);
    }
    eprintln!("early signals: {handled} handled (exit 130), {before_main} before main");
    assert!(handled > 0);
}

/// The signal handlers used to be installed on a thread that first built a tokio runtime:
/// for up to ~23 ms after spawn on a busy machine, SIGINT or SIGTERM killed a build by the
/// signal, with no message and no exit 130. Now they are registered on `main`'s own thread
/// before any other thread exists. Watched in /proc: the moment a second thread appears,
/// SIGINT and SIGTERM must already be caught, and a SIGTERM then gives exit 130 and the
/// documented message.
#[test]
fn signal_handlers_are_in_place_before_the_first_thread_starts() {
    fn status(pid: u32) -> Option<(u32, u64)> {
        let text = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
        let field = |name: &str| {
            text.lines()
                .find_map(|l| l.strip_prefix(name))
                .map(|v| v.trim().to_string())
        };
        let threads = field("Threads:")?.parse().ok()?;
        let caught = u64::from_str_radix(&field("SigCgt:")?, 16).ok()?;
        Some((threads, caught))
    }
    const INT_AND_TERM: u64 = (1 << (2 - 1)) | (1 << (15 - 1));
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 6, 2);
    for round in 0..20 {
        let out = tmp.path().join(format!("early{round}"));
        let coordinator = spawn_build(&m, &out, 2, &[]);
        let pid = coordinator.id();
        let seen = loop {
            match status(pid) {
                Some((threads, caught)) if threads >= 2 => break Some(caught),
                Some(_) => {}
                None => break None,
            }
        };
        let Some(caught) = seen else {
            panic!("round {round}: the build ended before it started a thread");
        };
        assert_eq!(
            caught & INT_AND_TERM,
            INT_AND_TERM,
            "round {round}: a second thread runs before SIGINT and SIGTERM are caught (SigCgt {caught:x})"
        );
        assert!(kill("-TERM", pid));
        let result = coordinator.wait_with_output().unwrap();
        let message = text(&result.stderr);
        // A build that finished before the signal arrived exits 0.
        if result.status.code() != Some(0) {
            assert_eq!(result.status.code(), Some(130), "round {round}: {message}");
            // Before the workers start (nearly always), or while they run.
            assert!(
                message.contains(
                    "interrupted while no worker was running; nothing partial is visible; resume with: "
                ) || message.contains("resume with: bettimill build"),
                "round {round}: {message}"
            );
        }
    }
}

// ---------------------------------------------------------------- inflated shards

/// The readers' peak resident set allowed on a damaged shard: far below the 6 GiB the
/// shard claims, which a reader that holds a whole shard would need.
const READER_PEAK_KIB: u64 = 200 * 1024;

/// `verify`, `status`, `stats`, `preview` and `audit` on a shard sparse-truncated to 3 GB or
/// a link to /dev/zero: each checks the file against its completion record before reading
/// and streams through a fixed buffer, so each finishes with a finding that names the
/// shard, in small memory.
#[test]
fn an_inflated_shard_or_a_link_to_dev_zero_is_a_finding_of_every_reader_in_small_memory() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 8, 4);
    for case in ["sparse", "dev-zero"] {
        let out = tmp.path().join(case);
        assert_exit(&build(&m, &out, 1), 0);
        let shard = out.join("shards").join("r2d-000000.tar");
        match case {
            "sparse" => std::fs::OpenOptions::new()
                .write(true)
                .open(&shard)
                .unwrap()
                .set_len(6 << 30)
                .unwrap(),
            _ => {
                std::fs::remove_file(&shard).unwrap();
                std::os::unix::fs::symlink("/dev/zero", &shard).unwrap();
            }
        }
        let dir = out.to_str().unwrap();
        let png = tmp.path().join(format!("{case}.png"));
        let commands: [(&[&str], Option<i32>); 6] = [
            (&["verify", dir], Some(1)),
            (&["status", dir], Some(0)),
            (&["stats", dir], Some(2)),
            (&["preview", dir, "--out", png.to_str().unwrap()], Some(2)),
            (&["audit", dir, "--relabel"], None),
            (&["audit", dir, "--shards", "0"], None),
        ];
        for (args, code) in commands {
            let Some((output, peak_kib)) = common::run_with_peak(args) else {
                return;
            };
            let said = format!("{}{}", text(&output.stdout), text(&output.stderr));
            eprintln!(
                "{case}: {args:?}: exit {:?}, peak {peak_kib} KiB",
                output.status.code()
            );
            match code {
                Some(code) => assert_exit(&output, code),
                // audit: 1 for "differs" (a finding), never 0.
                None => assert!(
                    matches!(output.status.code(), Some(c) if c != 0),
                    "{case} {args:?}: {said}"
                ),
            }
            assert!(said.contains("r2d-000000"), "{case} {args:?}: {said}");
            assert!(
                !said.contains("panicked") && !said.contains("memory allocation"),
                "{case} {args:?}: {said}"
            );
            assert!(
                peak_kib < READER_PEAK_KIB,
                "{case} {args:?}: peak {peak_kib} KiB"
            );
        }
    }
}

// ---------------------------------------------------------------- records, links, no-op builds

/// Flips one character of the second member's blake3 in `record` (the JSON text stays
/// valid; the file's blake3 changes).
fn flip_member_hash(record: &Path) {
    let text = std::fs::read_to_string(record).unwrap();
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let hash = value["shard"]["members"][1]["blake3"]
        .as_str()
        .unwrap()
        .to_string();
    let flipped = format!(
        "{}{}",
        if hash.starts_with('0') { '1' } else { '0' },
        &hash[1..]
    );
    assert_eq!(text.matches(&hash).count(), 1);
    std::fs::write(record, text.replace(&hash, &flipped)).unwrap();
}

/// A record with one member hash flipped fails `status` (the whole record is checked, not
/// only the shard's own size and hash), so `finalize` and `build` never copy it into
/// index.json, where `verify` would call the intact shard damaged forever.
#[test]
fn a_flipped_member_hash_in_a_record_makes_the_shard_incomplete_and_build_repairs_it() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 6, 2);
    let clean = common::clean_build(&m, tmp.path(), 2);
    let out = tmp.path().join("flipped");
    assert_exit(&build(&m, &out, 2), 0);
    let record = out.join("records").join("r2d-000001.json");
    flip_member_hash(&record);
    let status = run(&["status", out.to_str().unwrap()]);
    let report = text(&status.stdout);
    assert!(
        report.contains("1 invalid") && report.contains("its record says"),
        "{report}"
    );
    // Without index.json: finalize refuses to write one from the bad record.
    std::fs::remove_file(out.join("index.json")).unwrap();
    let finalize = run(&["finalize", out.to_str().unwrap()]);
    common::assert_exit_saying(&finalize, 2, "r2d-000001");
    assert!(!out.join("index.json").exists());
    // build regenerates the shard and its record, then writes the clean index.
    common::assert_rebuilds_identically(&m, &out, 2, &clean);
    assert_exit(&run(&["verify", out.to_str().unwrap()]), 0);
    // With index.json in place: build repairs the record and leaves the index as it was.
    let index = std::fs::read(out.join("index.json")).unwrap();
    flip_member_hash(&record);
    assert_exit(&build(&m, &out, 2), 0);
    assert_eq!(std::fs::read(out.join("index.json")).unwrap(), index);
    assert_same(&clean, &out);
}

/// A symlinked `shards/` or `records/` is refused: following it would write tars outside
/// the dataset directory.
#[test]
fn a_symlinked_shards_or_records_directory_is_refused_and_nothing_is_written_through_it() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 6, 2);
    for inner in ["shards", "records"] {
        let out = tmp.path().join(format!("linked-{inner}"));
        assert_exit(&build(&m, &out, 2), 0);
        let elsewhere = tmp.path().join(format!("elsewhere-{inner}"));
        std::fs::rename(out.join(inner), &elsewhere).unwrap();
        std::os::unix::fs::symlink(&elsewhere, out.join(inner)).unwrap();
        // Work to do: one shard and its record gone, the index too.
        std::fs::remove_file(elsewhere.join(if inner == "shards" {
            "r2d-000000.tar"
        } else {
            "r2d-000000.json"
        }))
        .unwrap();
        std::fs::remove_file(out.join("index.json")).unwrap();
        let before = snapshot(&elsewhere);
        let refused = build(&m, &out, 2);
        assert_exit(&refused, 2);
        assert!(
            stderr(&refused).contains("is a symbolic link"),
            "{}",
            stderr(&refused)
        );
        assert_eq!(snapshot(&elsewhere), before, "written through the link");
        assert!(!out.join("index.json").exists());
    }
}

/// `preview DIR --out DIR/index.json` and `stats --plot DIR/shards/X.tar` would overwrite
/// dataset files: they are refused.
#[test]
fn output_files_inside_a_dataset_directory_are_refused() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 4, 2);
    let out = tmp.path().join("ds");
    assert_exit(&build(&m, &out, 2), 0);
    let dir = out.to_str().unwrap();
    let link = tmp.path().join("card-link.png");
    std::os::unix::fs::symlink(out.join("README.md"), &link).unwrap();
    let npy = tmp.path().join("square.npy");
    std::fs::write(&npy, bettimill_grid_npy_square()).unwrap();
    let before = snapshot(&out);
    let index = format!("{dir}/index.json");
    let tar = format!("{dir}/shards/r2d-000000.tar");
    let new_file = format!("{dir}/records/new.png");
    let attempts: Vec<Vec<&str>> = vec![
        vec!["preview", dir, "--out", &index],
        vec!["preview", dir, "--out", &new_file],
        vec!["preview", dir, "--out", link.to_str().unwrap()],
        vec!["stats", dir, "--plot", &tar],
        vec![
            "deform",
            npy.to_str().unwrap(),
            "--out",
            &index,
            "--method",
            "moves",
            "--steps",
            "1",
        ],
    ];
    for args in attempts {
        let refused = run(&args);
        assert_exit(&refused, 2);
        assert!(
            stderr(&refused).contains("inside the dataset directory"),
            "{args:?}: {}",
            stderr(&refused)
        );
    }
    assert_eq!(snapshot(&out), before);
    // Outside the dataset the same commands write.
    let outside = tmp.path().join("preview.png");
    assert_exit(
        &run(&["preview", dir, "--out", outside.to_str().unwrap()]),
        0,
    );
    assert!(outside.exists());
}

/// A 5x5 uint8 .npy holding a 3x3 square.
fn bettimill_grid_npy_square() -> Vec<u8> {
    let header = "{'descr': '|u1', 'fortran_order': False, 'shape': (5, 5), }";
    let mut header = header.to_string();
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for y in 0..5 {
        for x in 0..5 {
            bytes.push(u8::from((1..4).contains(&x) && (1..4).contains(&y)));
        }
    }
    bytes
}

/// (inode, mtime, ctime, size) of every file and directory under `dir`, `dir` included.
fn file_identities(
    dir: &Path,
) -> std::collections::BTreeMap<PathBuf, (u64, i64, i64, i64, i64, u64)> {
    use std::os::unix::fs::MetadataExt;
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(path) = stack.pop() {
        let meta = std::fs::symlink_metadata(&path).unwrap();
        out.insert(
            path.clone(),
            (
                meta.ino(),
                meta.mtime(),
                meta.mtime_nsec(),
                meta.ctime(),
                meta.ctime_nsec(),
                meta.len(),
            ),
        );
        if meta.is_dir() {
            stack.extend(
                std::fs::read_dir(&path)
                    .unwrap()
                    .flatten()
                    .map(|e| e.path()),
            );
        }
    }
    out
}

/// The tour's no-op `build --out demo-out`: a build or finalize that changes nothing writes
/// nothing (not even index.json, the wids indexes or the card), and `stats` reports the
/// build time from the timings the build recorded, never from file modification times.
#[test]
fn a_no_op_build_writes_nothing_and_stats_keeps_the_recorded_build_time() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 6, 2);
    let out = tmp.path().join("ds");
    assert_exit(&build(&m, &out, 2), 0);
    let stats = |out: &Path| -> serde_json::Value {
        let output = run(&["stats", out.to_str().unwrap(), "--json"]);
        assert_exit(&output, 0);
        serde_json::from_slice(&output.stdout).unwrap()
    };
    let time = stats(&out)["build_time"].clone();
    assert_eq!(time["shards_timed"], 3, "{time}");
    assert_eq!(time["samples_timed"], 6, "{time}");
    let before = file_identities(&out);
    std::thread::sleep(Duration::from_millis(50));
    assert_exit(&build(&m, &out, 2), 0);
    let finalize = run(&["finalize", out.to_str().unwrap()]);
    assert_exit(&finalize, 0);
    // It does not claim "wrote index.json" when it wrote nothing.
    assert!(
        stderr(&finalize).contains("nothing changed") && !stderr(&finalize).contains("wrote"),
        "{}",
        stderr(&finalize)
    );
    assert_eq!(
        file_identities(&out),
        before,
        "a no-op build or finalize wrote"
    );
    assert_eq!(stats(&out)["build_time"], time);
    // A damaged dataset card is rewritten (and only what differs changes).
    std::fs::write(out.join("README.md"), b"edited\n").unwrap();
    assert_exit(&build(&m, &out, 2), 0);
    assert_ne!(std::fs::read(out.join("README.md")).unwrap(), b"edited\n");
    // A finalize that does rewrite says so.
    std::fs::write(out.join("README.md"), b"edited\n").unwrap();
    let finalize = run(&["finalize", out.to_str().unwrap()]);
    common::assert_exit_saying(&finalize, 0, "wrote");
    assert!(
        !stderr(&finalize).contains("nothing changed"),
        "{}",
        stderr(&finalize)
    );
    assert_ne!(std::fs::read(out.join("README.md")).unwrap(), b"edited\n");
}

/// A build killed between a shard's record and its timing leaves a complete shard with no
/// `timings/NAME.json` (8 of 180 killed builds). Nothing but `stats`' build time reads
/// timings: `verify`, a resumed build and `stats` all succeed, and `stats` says how many
/// shards it could not time.
#[test]
fn a_complete_shard_without_its_timing_changes_nothing_but_the_stats_line() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 8, 2);
    let out = tmp.path().join("untimed");
    assert_exit(&build(&m, &out, 1), 0);
    std::fs::remove_file(out.join("timings").join("r2d-000001.json")).unwrap();
    assert_exit(&run(&["verify", out.to_str().unwrap()]), 0);
    assert_exit(&build(&m, &out, 1), 0);
    let stats = run(&["stats", out.to_str().unwrap()]);
    assert_exit(&stats, 0);
    assert!(
        text(&stats.stdout).contains("(3 of 4 shards")
            && text(&stats.stdout).contains("1 shard without a timing not counted"),
        "{}",
        text(&stats.stdout)
    );
}

/// `stats` used to read every file in `records/`: a stray file there stopped it (exit 2,
/// `not a completion record`) and a copy of a record counted its shard twice (`11 of 10
/// shards`), although records no shard names are never data (docs/format.md). It now
/// reads the records of the dataset's shards only.
#[test]
fn a_stray_or_copied_file_in_records_neither_stops_nor_skews_stats() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 8, 2);
    let out = tmp.path().join("strays");
    assert_exit(&build(&m, &out, 1), 0);
    let stats = || {
        let result = run(&["stats", "--json", out.to_str().unwrap()]);
        assert_exit(&result, 0);
        let value: serde_json::Value = serde_json::from_slice(&result.stdout).unwrap();
        (value, text(&result.stdout))
    };
    let (before, before_text) = stats();
    let records = out.join("records");
    std::fs::write(records.join("notes.json"), "not a record\n").unwrap();
    std::fs::copy(
        records.join("r2d-000000.json"),
        records.join("old-copy.json"),
    )
    .unwrap();
    std::fs::copy(
        out.join("timings").join("r2d-000000.json"),
        out.join("timings").join("old-copy.json"),
    )
    .unwrap();
    let (after, after_text) = stats();
    assert_eq!(before, after, "{before_text}\n{after_text}");
    assert_eq!(after["build_time"]["shards_timed"], 4, "{after_text}");
    assert_exit(&run(&["verify", out.to_str().unwrap()]), 0);
}

// ---------------------------------------------------------------- soak

struct SoakReport {
    coordinator_kills: u32,
    worker_kills: u32,
    runs: u32,
    rounds: u32,
}

/// Soak rounds: each builds `m` into a fresh `out` again and again, killing the coordinator
/// or a worker with SIGKILL at a random moment of each run, until a run completes; the
/// result must then equal `clean`. Rounds repeat until `kills` kills have landed. After
/// every coordinator kill its workers must exit on their own and no partial shard may be
/// visible.
fn soak(
    m: &Path,
    clean: &Path,
    out: &Path,
    kills: u32,
    clean_time: Duration,
    seed: u64,
) -> SoakReport {
    // Kill times and targets come from a seeded generator.
    let mut rng = Xorshift(seed | 1);
    let mut report = SoakReport {
        coordinator_kills: 0,
        worker_kills: 0,
        runs: 0,
        rounds: 0,
    };
    let max_runs = 30 * kills + 30;
    while report.coordinator_kills + report.worker_kills < kills {
        report.rounds += 1;
        let _ = std::fs::remove_dir_all(out);
        loop {
            assert!(
                report.runs < max_runs,
                "no progress after {} runs",
                report.runs
            );
            report.runs += 1;
            let coordinator = spawn_build(m, out, 2, &[]);
            let pid = coordinator.id();
            let delay = clean_time.mul_f64((rng.next_u64() % 1000) as f64 / 1000.0);
            let kill_coordinator = rng.next_u64().is_multiple_of(3);
            let start = Instant::now();
            while start.elapsed() < delay && alive(pid) {
                std::thread::sleep(Duration::from_millis(2));
            }
            // Workers start a moment after the coordinator; wait for them unless it is done.
            let mut workers = children(pid);
            let start = Instant::now();
            while workers.is_empty() && alive(pid) && start.elapsed() < Duration::from_secs(30) {
                std::thread::sleep(Duration::from_millis(2));
                workers = children(pid);
            }
            let completed;
            if kill_coordinator {
                kill("-KILL", pid);
                let result = coordinator.wait_with_output().unwrap();
                // A kill that reached a finished (zombie) coordinator does not count.
                if result.status.signal() == Some(9) {
                    report.coordinator_kills += 1;
                    completed = false;
                } else {
                    assert_exit(&result, 0);
                    completed = true;
                }
                for worker in workers {
                    wait_until(
                        "an orphaned worker to exit",
                        Duration::from_secs(30),
                        || !alive(worker),
                    );
                }
            } else {
                if !workers.is_empty() {
                    let worker = workers[(rng.next_u64() % workers.len() as u64) as usize];
                    kill("-KILL", worker);
                }
                let result = coordinator.wait_with_output().unwrap();
                let stderr = text(&result.stderr);
                // Exit 2: random kills hit one shard three times and it was given up, or
                // killed a worker before any worker of the run had shaken hands (which the
                // coordinator cannot tell from a broken binary, so it stops).
                let stopped = stderr.contains("failed 3 times")
                    || stderr.contains("exited before its handshake");
                assert!(
                    result.status.code() == Some(0) || (result.status.code() == Some(2) && stopped),
                    "{:?}: {stderr}",
                    result.status
                );
                // Counted only when the coordinator saw the death (an idle worker killed at
                // the very end of a build is not).
                if stderr.contains("killed by signal 9") || stderr.contains("signal: 9") {
                    report.worker_kills += 1;
                }
                completed = result.status.code() == Some(0);
            }
            assert!(workers_of(out).is_empty(), "workers outlived the run");
            assert_no_partial_shard_visible(out);
            if completed {
                assert_same(clean, out);
                break;
            }
        }
    }
    report
}

/// Builds cleanly, soaks, and reports the kills survived on the test's stderr.
#[allow(clippy::print_stderr)]
fn soak_test(dimension: u32, side: u32, samples: u32, shard_size: u32, kills: u32, seed: u64) {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), dimension, side, samples, shard_size);
    let clean = tmp.path().join("clean");
    let start = Instant::now();
    let out = build(&m, &clean, 2);
    assert_exit(&out, 0);
    let clean_time = start.elapsed();
    let soaked = tmp.path().join("soaked");
    let report = soak(&m, &clean, &soaked, kills, clean_time, seed);
    eprintln!(
        "soak: {samples} samples, {} coordinator and {} worker SIGKILLs survived in {} runs, {} complete rebuilds, each byte-identical",
        report.coordinator_kills, report.worker_kills, report.runs, report.rounds
    );
    assert!(report.coordinator_kills + report.worker_kills >= kills);
}

/// With `BETTIMILL_SOAK_KILLS=N` set this is the long soak (2000 samples in 100 shards, N
/// kills; about 3 minutes per 120 kills on 2 cores): `BETTIMILL_SOAK_KILLS=200
/// CARGO_TARGET_DIR=/tmp/target-rel cargo test -p bettimill-cli --release --test reliability
/// -- random_kills --nocapture`. Without it, 8 kills over 300 samples.
#[test]
fn random_kills_of_coordinator_and_workers_end_byte_identical() {
    match bettimill_env::var(bettimill_env::EnvVars::BETTIMILL_SOAK_KILLS) {
        Some(kills) => {
            let kills = kills
                .parse()
                .unwrap_or_else(|e| panic!("BETTIMILL_SOAK_KILLS={kills:?}: {e}"));
            soak_test(2, 32, 2000, 20, kills, 7);
        }
        None => soak_test(2, 32, 300, 10, 8, 2026),
    }
}

// ---------------------------------------------------------------- resources

/// Runs a build, polling the peak resident set of the coordinator and of its workers.
fn build_peaks(m: &Path, out: &Path, workers: u32) -> (u64, u64) {
    build_peaks_with(m, out, workers, &[])
}

fn build_peaks_with(m: &Path, out: &Path, workers: u32, env: &[(&str, &str)]) -> (u64, u64) {
    let coordinator = spawn_build(m, out, workers, env);
    let pid = coordinator.id();
    let (mut coordinator_peak, mut worker_peak) = (0, 0);
    while alive(pid) {
        if let Some(kib) = peak_kib(pid) {
            coordinator_peak = coordinator_peak.max(kib);
        }
        for worker in children(pid) {
            worker_peak = worker_peak.max(peak_kib(worker).unwrap_or(0));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let result = coordinator.wait_with_output().unwrap();
    assert_exit(&result, 0);
    (coordinator_peak, worker_peak)
}

#[test]
fn the_coordinators_memory_does_not_grow_with_the_number_of_samples() {
    let tmp = Dir::new();
    let small = manifest(tmp.path(), 2, 16, 200, 10);
    let large = manifest(tmp.path(), 2, 16, 2000, 10);
    let (small_peak, _) = build_peaks(&small, &tmp.path().join("small"), 2);
    let (large_peak, _) = build_peaks(&large, &tmp.path().join("large"), 2);
    eprintln!("coordinator VmHWM: 200 samples {small_peak} KiB, 2000 samples {large_peak} KiB");
    assert!(small_peak > 0 && large_peak > 0, "no measurement");
    assert!(
        large_peak < 2 * small_peak,
        "200 samples: {small_peak} KiB, 2000 samples: {large_peak} KiB"
    );
}

#[test]
fn a_workers_memory_for_a_32_4_sample_is_within_the_documented_bound() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 4, 32, 2, 1);
    let (_, worker_peak) = build_peaks(&m, &tmp.path().join("out"), 1);
    // docs/reliability.md: at most 100 bytes per voxel plus 64 MiB of fixed cost.
    let bound_kib = (100 * 32u64.pow(4) + (64 << 20)) / 1024;
    eprintln!("worker VmHWM for 4D 32^4: {worker_peak} KiB (bound {bound_kib} KiB)");
    assert!(worker_peak > 0, "no measurement");
    assert!(worker_peak < bound_kib, "{worker_peak} KiB");
}

/// A manifest of `samples` balls in one shard, written to DIR/NAME{samples}.toml.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn one_shard_of_balls(
    dir: &Path,
    name: &str,
    dimension: u32,
    side: u32,
    mode: &str,
    compression: &str,
    samples: u32,
) -> PathBuf {
    let path = dir.join(format!("{name}{samples}.toml"));
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"{name}\"\ndimension = {dimension}\nside = {side}\n\
             mode = \"{mode}\"\nsamples = {samples}\nshard_size = {samples}\nseed = 5\n\
             compression = \"{compression}\"\n\n[[classes]]\nfamily = \"ball\"\n"
        ),
    )
    .unwrap();
    path
}

/// glibc only: its dynamic mmap threshold otherwise keeps freed image-sized blocks in the
/// heap, which grows by about one image per sample whatever the program holds (see
/// docs/reliability.md); a fixed threshold takes the allocator out of the measurement.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn a_worker_holds_compressed_members_not_the_images_of_a_shard() {
    // Carved 4D 32^4 samples are 1 MiB each uncompressed (every page touched) and a few
    // KiB compressed: a worker that held a shard's images until the tar was written needed
    // ~58 MiB more for 64 samples than for 4; keeping only compressed members, <1 MiB.
    let tmp = Dir::new();
    let write = |samples| one_shard_of_balls(tmp.path(), "z", 4, 32, "carve", "zstd", samples);
    let env = [("MALLOC_MMAP_THRESHOLD_", "262144")];
    let (_, small) = build_peaks_with(&write(4), &tmp.path().join("small"), 1, &env);
    let (_, large) = build_peaks_with(&write(64), &tmp.path().join("large"), 1, &env);
    eprintln!("worker VmHWM: shard of 4 {small} KiB, shard of 64 {large} KiB");
    assert!(small > 0 && large > 0, "no measurement");
    assert!(large < small + 8 * 1024, "4: {small} KiB, 64: {large} KiB");
}

/// glibc only, for the reason above.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn a_worker_holds_an_uncompressed_shard_once_while_writing_it() {
    // Plain 3D 128^3 samples are 2 MiB members: 20 more of them in a shard cost their 40 MiB
    // once, since the tar is streamed from the members to its file. Holding the members, a
    // flattened copy and the tar as well cost three times that (166 MiB for a 48 MiB shard
    // against 72 MiB streamed).
    let tmp = Dir::new();
    let write = |samples| one_shard_of_balls(tmp.path(), "p", 3, 128, "embed", "none", samples);
    let env = [("MALLOC_MMAP_THRESHOLD_", "262144")];
    let (_, small) = build_peaks_with(&write(4), &tmp.path().join("small"), 1, &env);
    let (_, large) = build_peaks_with(&write(24), &tmp.path().join("large"), 1, &env);
    let tar = std::fs::metadata(tmp.path().join("large/shards/p-000000.tar"))
        .unwrap()
        .len();
    assert!(tar > 48 << 20, "{tar}");
    eprintln!("worker VmHWM: shard of 4 {small} KiB, shard of 24 ({tar} bytes) {large} KiB");
    assert!(small > 0 && large > 0, "no measurement");
    // 20 samples of 2 MiB: 40 MiB once, with room for the allocator; not 80 or 120.
    assert!(large < small + 60 * 1024, "4: {small} KiB, 24: {large} KiB");
}

/// `status` on a plan of 10^7 one-sample shards took 96-122 s: it opened every planned
/// shard's record and tar. Now it lists `shards/` and `records/` once and opens only what
/// is there: on a bound directory of 100,000 planned shards and none built, strace sees
/// no open or stat of a shard's or record's path.
#[test]
fn status_opens_only_the_shards_on_disk_not_every_planned_one() {
    if Command::new("strace").arg("-V").output().is_err() {
        skip_unless_ci("strace", "strace is not installed");
        return;
    }
    let tmp = Dir::new();
    let m = common::ball_and_handle(tmp.path().join("many.toml"), "many", 2, 16, 100_000, 1, 5);
    let out = tmp.path().join("many");
    // Bound (manifest.toml, build.json), nothing built: stopped during start-up.
    let coordinator = spawn_build(&m, &out, 1, &[("BETTIMILL_TEST_PAUSE_AT_STARTUP", "120")]);
    wait_until("build.json", Duration::from_secs(60), || {
        out.join("build.json").exists()
    });
    assert!(kill("-INT", coordinator.id()));
    assert_eq!(
        coordinator.wait_with_output().unwrap().status.code(),
        Some(130)
    );
    let trace = tmp.path().join("trace");
    let result = Command::new("strace")
        .args([
            "-f",
            "-e",
            "trace=open,openat,stat,newfstatat,statx,access",
            "-o",
        ])
        .arg(&trace)
        .arg(common::BETTIMILL)
        .args(["status", "--json"])
        .arg(&out)
        .output()
        .unwrap();
    let report: serde_json::Value = serde_json::from_slice(&result.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", text(&result.stderr)));
    assert_eq!(report["shards"], 100_000);
    assert_eq!(report["missing_count"], 100_000);
    let calls = std::fs::read_to_string(&trace).unwrap();
    let per_shard = calls
        .lines()
        .filter(|l| l.contains("/records/many-") || l.contains("/shards/many-"))
        .count();
    assert_eq!(per_shard, 0, "status looked at planned shards one by one");
}

/// A dataset whose manifest.toml was edited after the build (another seed): `verify` names
/// manifest.toml against build.json, and `audit` says the manifest was changed (it used to
/// give build's advice, "use another --out directory").
#[test]
fn an_edited_manifest_is_named_by_verify_and_audit_gives_its_own_advice() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 4, 2);
    let out = tmp.path().join("edited");
    assert_exit(&build(&m, &out, 1), 0);
    let path = out.join("manifest.toml");
    let original = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, original.replace("seed = 5", "seed = 6")).unwrap();
    let verified = run(&["verify", out.to_str().unwrap()]);
    assert_exit(&verified, 1);
    assert!(
        text_of(&verified).contains("manifest.toml")
            && text_of(&verified).contains("build.json's manifest_hash"),
        "{}",
        text_of(&verified)
    );
    let audited = run(&["audit", out.to_str().unwrap(), "--relabel"]);
    assert_exit(&audited, 2);
    let message = text(&audited.stderr);
    assert!(
        message.contains("the manifest was changed after the build")
            && !message.contains("another --out"),
        "{message}"
    );
}

fn text_of(out: &Output) -> String {
    format!("{}{}", text(&out.stdout), text(&out.stderr))
}
