//! Tidy checks: invariants of ARCHITECTURE.md enforced as tests, not only prose.
//!
//! - Dependency directions come from `cargo metadata` (the resolved manifests, not text).
//! - "Only the CLI prints" is enforced by clippy (`print_stdout`, `print_stderr` denied in
//!   `[workspace.lints]`, `std::io::stdout`/`stderr` in clippy.toml's `disallowed-methods`);
//!   this file checks that every crate inherits those lints and that no library crate
//!   allows them anywhere in its sources.
//! - Every Rust file opens with a `//!` doc; the crates are on the code map.
//! - The environment is read in one file (`bettimill-env`'s `env.rs`), and the build is
//!   driven from one place (the executor's `build`): the CLI and the Python binding neither
//!   make build options nor read scheduler variables.
//! - One `rust-version` for the workspace, at least every resolved dependency's.

use std::path::{Path, PathBuf};

mod common;
use common::repo_root;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// One workspace member as `cargo metadata` describes it.
struct Package {
    name: String,
    /// The directory of its Cargo.toml.
    dir: PathBuf,
    /// (dependency name, kind: "normal", "build" or "dev").
    dependencies: Vec<(String, String)>,
}

impl Package {
    /// The workspace crates it depends on outside its tests (normal and build dependencies).
    fn internal_deps(&self) -> Vec<&str> {
        let mut out: Vec<&str> = self
            .dependencies
            .iter()
            .filter(|(name, kind)| name.starts_with("bettimill-") && kind != "dev")
            .map(|(name, _)| name.as_str())
            .collect();
        out.sort();
        out.dedup();
        out
    }
}

/// The workspace members, from `cargo metadata --format-version 1 --offline --no-deps`.
fn packages() -> Vec<Package> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--offline",
            "--no-deps",
        ])
        .arg("--manifest-path")
        .arg(repo_root().join("Cargo.toml"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let metadata: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut packages: Vec<Package> = metadata["packages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| Package {
            name: p["name"].as_str().unwrap().to_string(),
            dir: Path::new(p["manifest_path"].as_str().unwrap())
                .parent()
                .unwrap()
                .to_path_buf(),
            dependencies: p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| {
                    (
                        d["name"].as_str().unwrap().to_string(),
                        d["kind"].as_str().unwrap_or("normal").to_string(),
                    )
                })
                .collect(),
        })
        .collect();
    packages.sort_by(|a, b| a.name.cmp(&b.name));
    assert!(packages.len() >= 14, "only {} members", packages.len());
    packages
}

fn package<'a>(packages: &'a [Package], name: &str) -> &'a Package {
    packages
        .iter()
        .find(|p| p.name == name)
        .unwrap_or_else(|| panic!("{name} is not a workspace member"))
}

/// A rule on the workspace's dependency graph (normal and build dependencies only: tests
/// may use anything).
enum Rule {
    /// The crate depends on exactly these workspace crates.
    Only(&'static str, &'static [&'static str]),
    /// The crate does not depend on the other.
    Not(&'static str, &'static str),
}

const RULES: &[Rule] = &[
    // The verifier shares no code with the constructions it checks.
    Rule::Only("bettimill-homology", &["bettimill-grid"]),
    Rule::Not("bettimill-shapes", "bettimill-homology"),
    // The manifest knows syntax and ranges; what the classes mean is the plan's to decide.
    Rule::Not("bettimill-manifest", "bettimill-shapes"),
    // A sample is made from the plan and its task alone.
    Rule::Not("bettimill-sample", "bettimill-manifest"),
];

#[test]
fn dependency_directions_hold() {
    let packages = packages();
    let mut broken = Vec::new();
    for rule in RULES {
        match rule {
            Rule::Only(name, allowed) => {
                let deps = package(&packages, name).internal_deps();
                if deps != *allowed {
                    broken.push(format!(
                        "{name} must depend only on {allowed:?}, not {deps:?}"
                    ));
                }
            }
            Rule::Not(name, other) => {
                package(&packages, other);
                if package(&packages, name).internal_deps().contains(other) {
                    broken.push(format!("{name} must not depend on {other}"));
                }
            }
        }
    }
    assert!(broken.is_empty(), "{broken:#?}");
}

#[test]
fn the_testkit_is_only_a_dev_dependency_and_anyhow_only_the_clis() {
    for p in packages() {
        for (dep, kind) in &p.dependencies {
            if dep == "bettimill-testkit" {
                assert_eq!(kind, "dev", "{} depends on {dep} outside its tests", p.name);
            }
            if dep == "anyhow" && kind != "dev" {
                assert_eq!(p.name, "bettimill-cli", "{} depends on anyhow", p.name);
            }
        }
    }
}

/// Printing is a clippy error outside the CLI: the workspace denies the print lints, every
/// crate inherits the workspace lints, clippy.toml disallows `std::io::stdout`/`stderr`, and
/// no library crate allows any of them anywhere in its sources (whole files, tests
/// included). Examples and benchmarks may allow them (they print reports), and so may the
/// CLI and the test helper crate.
#[test]
fn printing_is_denied_outside_the_cli() {
    let root = repo_root();
    let read_toml = |path: &Path| -> toml::Value {
        toml::from_str(&std::fs::read_to_string(path).unwrap())
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    };
    let workspace = read_toml(&root.join("Cargo.toml"));
    let clippy = &workspace["workspace"]["lints"]["clippy"];
    for lint in ["print_stdout", "print_stderr"] {
        assert_eq!(
            clippy.get(lint).and_then(|l| l.as_str()),
            Some("deny"),
            "[workspace.lints.clippy] {lint}"
        );
    }
    let config = read_toml(&root.join("clippy.toml"));
    let disallowed: Vec<&str> = config["disallowed-methods"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|m| m.get("path").and_then(|p| p.as_str()))
        .collect();
    for method in ["std::io::stdout", "std::io::stderr"] {
        assert!(disallowed.contains(&method), "clippy.toml: {disallowed:?}");
    }
    let mut offenders = Vec::new();
    for p in packages() {
        let manifest = read_toml(&p.dir.join("Cargo.toml"));
        let inherits = manifest
            .get("lints")
            .and_then(|l| l.get("workspace"))
            .and_then(|w| w.as_bool());
        assert_eq!(inherits, Some(true), "{}: [lints] workspace = true", p.name);
        if p.name == "bettimill-cli" || p.name == "bettimill-testkit" {
            continue;
        }
        let mut files = Vec::new();
        rust_files(&p.dir.join("src"), &mut files);
        if p.dir.join("lib.rs").exists() {
            // benches/lib.rs: the library of the benchmark crate.
            files.push(p.dir.join("lib.rs"));
        }
        for file in files {
            let text = std::fs::read_to_string(&file).unwrap();
            for lint in [
                "clippy::print_stdout",
                "clippy::print_stderr",
                "clippy::disallowed_methods",
            ] {
                if text.contains(lint) {
                    offenders.push(format!("{}: {lint}", file.display()));
                }
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "library code that allows printing: {offenders:#?}"
    );
}

/// Every Rust file of the workspace (sources, tests, examples, benchmarks) opens with a
/// `//!` doc, except the `tests.rs` unit-test modules of `src/`.
#[test]
fn every_rust_file_opens_with_a_doc_comment() {
    let root = repo_root();
    let mut files = Vec::new();
    for p in packages() {
        for dir in ["src", "tests", "examples", "benches"] {
            rust_files(&p.dir.join(dir), &mut files);
        }
        if p.dir.join("lib.rs").exists() {
            files.push(p.dir.join("lib.rs"));
        }
    }
    rust_files(&root.join("tests"), &mut files);
    files.sort();
    files.dedup();
    assert!(files.len() > 80, "only {} files", files.len());
    let mut missing = Vec::new();
    for file in files {
        let unit_tests = file.file_name().is_some_and(|n| n == "tests.rs")
            && file.components().any(|c| c.as_os_str() == "src");
        let text = std::fs::read_to_string(&file).unwrap();
        if !unit_tests && !text.trim_start().starts_with("//!") {
            missing.push(file.display().to_string());
        }
    }
    assert!(missing.is_empty(), "files without a //! doc: {missing:#?}");
}

#[test]
fn every_crate_is_on_the_code_map() {
    let architecture = std::fs::read_to_string(repo_root().join("ARCHITECTURE.md")).unwrap();
    let readme = std::fs::read_to_string(repo_root().join("crates/README.md")).unwrap();
    for p in packages() {
        if p.name == "bettimill-benches" {
            continue;
        }
        assert!(
            architecture.contains(&format!("### `{}`", p.name)),
            "ARCHITECTURE.md has no code-map heading for {}",
            p.name
        );
        assert!(
            readme.contains(&format!("`{}`", p.name)),
            "crates/README.md has no line for {}",
            p.name
        );
    }
}

/// `rust-version`, version-wise: `(major, minor, patch)`, a missing part 0.
fn rust_version(text: &str) -> (u64, u64, u64) {
    let mut parts = text.split('.').map(|p| p.parse::<u64>().unwrap());
    let mut next = || parts.next().unwrap_or(0);
    (next(), next(), next())
}

/// The declared `rust-version` is one claim for the whole workspace, and it is not below
/// any package the lock file resolves to: a dependency that needs a newer Rust would make
/// the claim false for every crate above it. (Newer standard-library APIs in our own code
/// are caught by clippy's `incompatible_msrv`, which reads the same field.)
#[test]
fn the_declared_rust_version_is_the_workspaces_and_covers_every_dependency() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--offline", "--locked"])
        .arg("--manifest-path")
        .arg(repo_root().join("Cargo.toml"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let metadata: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let members: Vec<&str> = metadata["workspace_members"]
        .as_array()
        .unwrap()
        .iter()
        .map(|id| id.as_str().unwrap())
        .collect();
    let workspace = std::fs::read_to_string(repo_root().join("Cargo.toml")).unwrap();
    let declared = workspace
        .lines()
        .find_map(|line| line.strip_prefix("rust-version = "))
        .expect("the workspace declares rust-version")
        .trim_matches('"');
    let mut problems = Vec::new();
    for package in metadata["packages"].as_array().unwrap() {
        let name = package["name"].as_str().unwrap();
        let version = package["rust_version"].as_str();
        if members.contains(&package["id"].as_str().unwrap()) {
            if version != Some(declared) {
                problems.push(format!(
                    "{name} declares rust-version {version:?}, not the workspace's {declared} \
                     (use `rust-version.workspace = true`)"
                ));
            }
        } else if let Some(version) = version {
            if rust_version(version) > rust_version(declared) {
                problems.push(format!(
                    "dependency {name} {} needs Rust {version}, above the declared {declared}",
                    package["version"].as_str().unwrap()
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The lines of `text` that are code, not comments (a mention in a doc is not a use).
fn code_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .filter(|(_, line)| !line.trim_start().starts_with("//"))
        .map(|(i, line)| (i + 1, line))
}

/// Where `sources` (path, text) use any of `needles` in code, as `path:line: needle`.
fn uses(sources: &[(PathBuf, String)], needles: &[&str]) -> Vec<String> {
    let mut found = Vec::new();
    for (path, text) in sources {
        for (number, line) in code_lines(text) {
            for needle in needles {
                if line.contains(needle) {
                    found.push(format!("{}:{number}: {needle}", path.display()));
                }
            }
        }
    }
    found
}

/// The Rust sources under `src/` of every workspace member, with their text.
fn member_sources() -> Vec<(PathBuf, String)> {
    let mut files = Vec::new();
    for p in packages() {
        rust_files(&p.dir.join("src"), &mut files);
    }
    files.sort();
    files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(&f).unwrap();
            (f, text)
        })
        .collect()
}

/// Whether `line` reads the environment itself: `std::env::var`, `var_os`, `vars` (also
/// as `env::var` after `use std::env`), not through `bettimill_env::var`.
fn reads_env(line: &str) -> bool {
    line.match_indices("env::var")
        .any(|(at, _)| !line[..at].ends_with("bettimill_"))
}

/// Every environment variable is read in `bettimill-env`'s `env.rs`, the one list of them
/// (docs/environment.md is its users' copy): no other source file of a crate reads one.
#[test]
fn the_environment_is_read_only_in_env_rs() {
    let sources = member_sources();
    assert!(sources.len() > 50, "only {} sources", sources.len());
    let env_rs = Path::new("crates/bettimill-env/src/env.rs");
    let others: Vec<_> = sources
        .into_iter()
        .filter(|(path, _)| !path.ends_with(env_rs))
        .collect();
    let mut found = Vec::new();
    for (path, text) in &others {
        for (number, line) in code_lines(text) {
            if reads_env(line) {
                found.push(format!("{}:{number}: {}", path.display(), line.trim()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "environment read outside bettimill-env's env.rs (add the variable to EnvVars and \
         read it with bettimill_env::var): {found:#?}"
    );
}

/// The build is driven by `bettimill_executor::build` alone: the CLI and the Python
/// binding translate arguments and output, and neither makes the coordinator's options,
/// starts a build another way, works out a memory limit or reads a scheduler's variables.
#[test]
fn neither_the_cli_nor_python_drives_a_build_or_reads_the_scheduler() {
    let root = repo_root();
    let mut files = Vec::new();
    for krate in ["bettimill-cli", "bettimill-python"] {
        rust_files(&root.join("crates").join(krate).join("src"), &mut files);
    }
    assert!(files.len() > 10, "only {} files", files.len());
    let sources: Vec<_> = files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(&f).unwrap();
            (f, text)
        })
        .collect();
    let found = uses(
        &sources,
        &[
            // Build options and the ways around the one entry point.
            "BuildOptions",
            "coordinator::run",
            "build_in_process",
            "memory_limit",
            "MemAvailable",
            "/proc/meminfo",
            "memory.max",
            // Scheduler variables, by name or through the environment's list.
            "bettimill_env",
            "EnvVars",
            "\"SLURM_",
            "\"JOB_COMPLETION_INDEX",
            "\"PBS_",
            "\"SGE_",
            "\"LSB_",
        ],
    );
    assert!(
        found.is_empty(),
        "the CLI or the Python binding drives a build itself (use bettimill_executor::build): \
         {found:#?}"
    );
}
