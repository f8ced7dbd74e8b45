//! Tidy checks: invariants of ARCHITECTURE.md enforced as tests, not only prose.
//!
//! - Dependency directions come from `cargo metadata` (the resolved manifests, not text).
//! - "Only the CLI prints" is enforced by clippy (`print_stdout`, `print_stderr` denied in
//!   `[workspace.lints]`, `std::io::stdout`/`stderr` in clippy.toml's `disallowed-methods`);
//!   this file checks that every crate inherits those lints and that no library crate
//!   allows them anywhere in its sources.
//! - Every Rust file opens with a `//!` doc; the crates are on the code map.
//! - The environment is read in one file (`bettimill-env`'s `env.rs`), whose variables
//!   docs/environment.md names, test hooks marked internal and hidden; every variable the
//!   tests, ci/ scripts and Python files read is listed there too; and the build is
//!   driven from one place (the executor's `build`): the CLI and the Python binding neither
//!   make build options nor read scheduler variables.
//! - One `rust-version` for the workspace, at least every resolved dependency's.
//! - The CLI prints only through its `Printer`, which alone knows `--quiet`.
//! - ARCHITECTURE.md stays short (lines and line length), and its code map lists each crate
//!   below the crates it depends on, as it says; BENCHMARKS.md opens with the current
//!   figures and stays short.
//! - A check shared by several commands (a plain file, a file against its record, a tar
//!   against its record) is defined once, by the file that owns it.

use bettimill_env::EnvVars;
use std::collections::BTreeMap;
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
    let cargo = bettimill_env::var(EnvVars::CARGO).unwrap_or_else(|| "cargo".into());
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
    Rule::Only("bettimill-homology", &["bettimill-grid", "bettimill-types"]),
    Rule::Not("bettimill-shapes", "bettimill-homology"),
    // The manifest knows syntax and ranges; what the classes mean is the plan's to decide.
    Rule::Not("bettimill-manifest", "bettimill-shapes"),
    // A sample is made from the plan and its task alone.
    Rule::Not("bettimill-sample", "bettimill-manifest"),
    // Schema crates read plain shared types from bettimill-types, not the algorithms.
    Rule::Not("bettimill-manifest", "bettimill-deform"),
    Rule::Not("bettimill-manifest", "bettimill-homology"),
    Rule::Not("bettimill-format", "bettimill-deform"),
    Rule::Not("bettimill-plan", "bettimill-deform"),
    Rule::Only("bettimill-types", &[]),
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
fn the_testkit_anyhow_and_object_storage_stay_where_they_belong() {
    for p in packages() {
        for (dep, kind) in &p.dependencies {
            if dep == "bettimill-testkit" {
                assert_eq!(kind, "dev", "{} depends on {dep} outside its tests", p.name);
            }
            if dep == "anyhow" && kind != "dev" {
                assert_eq!(p.name, "bettimill-cli", "{} depends on anyhow", p.name);
            }
            // Object storage is storage: its client and HTTP stack stay behind one crate.
            if ["object_store", "reqwest", "rustls"].contains(&dep.as_str()) {
                assert_eq!(p.name, "bettimill-shard", "{} depends on {dep}", p.name);
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

/// The crates of ARCHITECTURE.md's code map, in the order of their `### `NAME`` headings.
fn code_map_order(architecture: &str) -> Vec<&str> {
    architecture
        .lines()
        .filter_map(|line| line.strip_prefix("### `")?.strip_suffix('`'))
        .collect()
}

/// Where `order` puts a crate after one that depends on it, given each crate's
/// dependencies: `(crate, dependency listed later or not at all)`.
fn out_of_order<'a>(
    order: &[&'a str],
    deps: &[(&'a str, Vec<&'a str>)],
) -> Vec<(&'a str, &'a str)> {
    let mut wrong = Vec::new();
    for (name, dependencies) in deps {
        let Some(at) = order.iter().position(|n| n == name) else {
            continue;
        };
        for dep in dependencies {
            if !order[..at].contains(dep) {
                wrong.push((*name, *dep));
            }
        }
    }
    wrong
}

#[test]
fn code_map_order_checker_finds_a_crate_above_its_dependency() {
    let map = "### `a`\ntext\n### `c`\n### `b`\n";
    assert_eq!(code_map_order(map), ["a", "c", "b"]);
    let deps = [("a", vec![]), ("b", vec!["a"]), ("c", vec!["a", "b"])];
    assert_eq!(out_of_order(&code_map_order(map), &deps), [("c", "b")]);
}

/// ARCHITECTURE.md says "a crate depends only on crates above it in this list": the code
/// map's order is checked against the resolved dependencies (tests may use anything).
#[test]
fn the_code_map_lists_each_crate_below_its_dependencies() {
    let architecture = std::fs::read_to_string(repo_root().join("ARCHITECTURE.md")).unwrap();
    assert!(architecture.contains("a crate depends only on crates above it in this list"));
    let order = code_map_order(&architecture);
    let packages = packages();
    let deps: Vec<(&str, Vec<&str>)> = packages
        .iter()
        .map(|p| (p.name.as_str(), p.internal_deps()))
        .collect();
    let wrong = out_of_order(&order, &deps);
    assert!(
        wrong.is_empty(),
        "ARCHITECTURE.md's code map lists a crate above a crate it depends on (crate, \
         dependency): {wrong:?}"
    );
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
    let cargo = bettimill_env::var(EnvVars::CARGO).unwrap_or_else(|| "cargo".into());
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

/// Whether `line` reads the environment itself: `std::env::var`, `var_os`, `vars` (also
/// as `env::var` after `use std::env`), not through `bettimill_env::var`, and not inside a
/// string literal (an example in a checker's own test is not a read).
fn reads_env(line: &str) -> bool {
    line.match_indices("env::var").any(|(at, _)| {
        let before = &line[..at];
        let quotes = before.matches('"').count() - before.matches("\\\"").count();
        !before.ends_with("bettimill_") && quotes.is_multiple_of(2)
    })
}

#[test]
fn env_read_checker_finds_direct_reads_only() {
    for direct in [
        "let v = std::env::var(\"SLURM_JOB_ID\");",
        "env::var_os(name)",
        "for (k, v) in std::env::vars() {",
    ] {
        assert!(reads_env(direct), "{direct}");
    }
    for through in [
        "bettimill_env::var(EnvVars::SLURM_JOB_ID)",
        "let args = std::env::args();",
        "std::env::current_exe()",
    ] {
        assert!(!reads_env(through), "{through}");
    }
}

#[test]
fn use_checker_names_file_line_and_needle_outside_comments() {
    let sources = vec![(
        PathBuf::from("src/build.rs"),
        "// BuildOptions in a comment\nlet o = BuildOptions::default();\nlet x = 1;\n\
         let id = \"SLURM_JOB_ID\";\n"
            .to_string(),
    )];
    let found = uses(&sources, &["BuildOptions", "\"SLURM_"]);
    assert_eq!(
        found,
        ["src/build.rs:2: BuildOptions", "src/build.rs:4: \"SLURM_"]
    );
}

/// The files under the repository (not `target/`, `.git/` or a virtual environment) whose
/// names end in `suffix`, sorted.
fn repo_files(suffix: &str) -> Vec<PathBuf> {
    fn walk(dir: &Path, suffix: &str, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for entry in entries {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if path.is_dir() {
                if !matches!(name.as_str(), "target" | ".git" | ".venv" | "node_modules")
                    && !name.starts_with("target-")
                {
                    walk(&path, suffix, out);
                }
            } else if name.ends_with(suffix) {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(&repo_root(), suffix, &mut out);
    out.sort();
    out
}

/// Every environment variable is read in `bettimill-env`'s `env.rs`, the one list of them
/// (docs/environment.md is its users' copy): no other Rust file of the repository reads one,
/// not a crate's sources, tests, examples or benchmarks, nor the workspace's tests.
#[test]
fn the_environment_is_read_only_in_env_rs() {
    let env_rs = Path::new("crates/bettimill-env/src/env.rs");
    let files: Vec<_> = repo_files(".rs")
        .into_iter()
        .filter(|path| !path.ends_with(env_rs))
        .collect();
    assert!(
        files.iter().any(|f| f.ends_with("tests/common/mod.rs")),
        "the workspace's tests are not scanned: {files:?}"
    );
    assert!(files.len() > 100, "only {} Rust files", files.len());
    let mut found = Vec::new();
    for path in &files {
        let text = std::fs::read_to_string(path).unwrap();
        for (number, line) in code_lines(&text) {
            if reads_env(line) {
                found.push(format!(
                    "{}:{number}: {}",
                    relative(&repo_root(), path),
                    line.trim()
                ));
            }
        }
    }
    assert!(
        found.is_empty(),
        "environment read outside bettimill-env's env.rs (add the variable to EnvVars and \
         read it with bettimill_env::var): {found:#?}"
    );
}

/// Variables a shell script may read without listing them: the shell's own.
const SHELL_VARIABLES: &[&str] = &[
    "BASH_REMATCH",
    "BASH_SOURCE",
    "EUID",
    "HOME",
    "IFS",
    "LINENO",
    "PATH",
    "PIPESTATUS",
    "PWD",
    "RANDOM",
    "SECONDS",
    "UID",
];

/// The upper-case names a shell script `text` expands (`$NAME`, `${NAME...}`, escaped
/// `\$NAME` in a script it writes included), each with whether the expansion gives a
/// default or an alternative (`${NAME:-...}`, `${NAME-...}`, `=`, `?`, `+`): that form reads
/// the environment even in a script that assigns the name.
fn shell_expansions(text: &str) -> Vec<(String, bool)> {
    let mut out = Vec::new();
    for line in text.lines().filter(|l| !l.trim_start().starts_with('#')) {
        let bytes = line.as_bytes();
        for (at, _) in line.match_indices('$') {
            let braced = bytes.get(at + 1) == Some(&b'{');
            let start = at + 1 + usize::from(braced);
            let len = line[start..]
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(line.len() - start);
            let name = &line[start..start + len];
            let upper = name.chars().all(|c| !c.is_ascii_lowercase());
            if !upper || !name.starts_with(|c: char| c.is_ascii_uppercase()) {
                continue;
            }
            let rest = &line[start + len..];
            let defaulted = braced
                && ["-", "=", "?", "+"]
                    .iter()
                    .any(|op| rest.starts_with(op) || rest.starts_with(&format!(":{op}")));
            out.push((name.to_string(), defaulted));
        }
    }
    out
}

/// Whether the shell script `text` assigns `name` itself (`NAME=`, `export NAME=`,
/// `local NAME`, `for NAME in`, `read ... NAME`).
fn shell_assigns(text: &str, name: &str) -> bool {
    text.lines().any(|line| {
        let words: Vec<&str> = line
            .split(|c: char| c.is_whitespace() || c == ';' || c == '(')
            .collect();
        words.iter().enumerate().any(|(i, w)| {
            w.strip_prefix(name).is_some_and(|r| r.starts_with('='))
                || (*w == name
                    && i > 0
                    && ["for", "local", "read", "-r", "declare", "-a", "-A"]
                        .iter()
                        .any(|k| words[..i].contains(k)))
        })
    })
}

/// The environment variables the shell script `text` reads: those it expands with a
/// default or an alternative, and those it expands without assigning them (in itself or in
/// `sourced`, the scripts it sources), but the shell's own.
fn shell_env_reads(text: &str, sourced: &[String]) -> Vec<String> {
    let mut out: Vec<String> = shell_expansions(text)
        .into_iter()
        .filter(|(name, defaulted)| {
            *defaulted
                || !(SHELL_VARIABLES.contains(&name.as_str())
                    || shell_assigns(text, name)
                    || sourced.iter().any(|s| shell_assigns(s, name)))
        })
        .map(|(name, _)| name)
        .collect();
    out.sort();
    out.dedup();
    out
}

#[test]
fn shell_env_checker_finds_defaults_and_unassigned_names() {
    let script = "#!/bin/sh\n# $COMMENTED is not code\nDIR=${SLURM_CI_DIR:-/tmp/x}\n\
                  OUT=$DIR/out\necho \"$OUT $HOME ${KEEP-0} $B\"\nfor N in 1 2; do echo $N; done\n\
                  cat <<EOF\necho \\$SLURM_ARRAY_JOB_ID ${lower} ${Version}\nEOF\n";
    assert_eq!(
        shell_env_reads(script, &[]),
        ["B", "KEEP", "SLURM_ARRAY_JOB_ID", "SLURM_CI_DIR"]
    );
    assert_eq!(
        shell_env_reads(script, &["B=/bin/true\n".to_string()]),
        ["KEEP", "SLURM_ARRAY_JOB_ID", "SLURM_CI_DIR"]
    );
}

/// The environment variables the Python source `text` reads (`os.environ.get("NAME"`,
/// `os.environ["NAME"]`, `os.getenv("NAME"`, `"NAME" in os.environ`).
fn python_env_reads(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines().filter(|l| !l.trim_start().starts_with('#')) {
        for opener in ["environ.get(", "environ[", "getenv("] {
            for (at, _) in line.match_indices(opener) {
                let rest = line[at + opener.len()..].trim_start();
                if let Some(q) = rest.chars().next().filter(|c| *c == '"' || *c == '\'') {
                    if let Some(end) = rest[1..].find(q) {
                        out.push(rest[1..1 + end].to_string());
                    }
                }
            }
        }
        for (at, _) in line.match_indices(" in os.environ") {
            let before = line[..at].trim_end();
            if let Some(q) = before.chars().last().filter(|c| *c == '"' || *c == '\'') {
                if let Some(start) = before[..before.len() - 1].rfind(q) {
                    out.push(before[start + 1..before.len() - 1].to_string());
                }
            }
        }
    }
    out.sort();
    out.dedup();
    out
}

#[test]
fn python_env_checker_finds_every_form_of_read() {
    let code = "import os\n# os.environ.get(\"COMMENT\")\na = os.environ.get(\"CI\") == \"true\"\n\
                b = os.environ['S3_CI_DIR']\nc = os.getenv(\"BETTIMILL_CLI\", \"x\")\n\
                if \"HOME\" in os.environ:\n    env = dict(os.environ, HF_HOME=\"h\")\n";
    assert_eq!(
        python_env_reads(code),
        ["BETTIMILL_CLI", "CI", "HOME", "S3_CI_DIR"]
    );
}

/// The one list covers the tests and the scripts too: every variable a script under `ci/`
/// (`.ci/run` included) or a Python file under `python/` reads is a variable of `env.rs`,
/// so a new variable anywhere fails here until it is listed (marked by who reads it).
#[test]
fn every_variable_scripts_and_python_read_is_in_env_rs() {
    let root = repo_root();
    let env_rs = std::fs::read_to_string(root.join("crates/bettimill-env/src/env.rs")).unwrap();
    let listed = env_vars(&env_rs);
    let mut reads: Vec<(String, Vec<String>)> = Vec::new();
    let mut scripts = Vec::new();
    for dir in ["ci", ".ci"] {
        for entry in std::fs::read_dir(root.join(dir)).unwrap() {
            scripts.push(entry.unwrap().path());
        }
    }
    scripts.retain(|p| {
        std::fs::read_to_string(p).is_ok_and(|t| t.starts_with("#!") && t.contains("sh"))
    });
    scripts.sort();
    assert!(
        scripts.len() > 10,
        "only {} scripts: {scripts:?}",
        scripts.len()
    );
    for script in &scripts {
        let text = std::fs::read_to_string(script).unwrap();
        let sourced: Vec<String> = text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("source "))
            .map(|s| std::fs::read_to_string(root.join(s.trim())).unwrap())
            .collect();
        reads.push((relative(&root, script), shell_env_reads(&text, &sourced)));
    }
    let python: Vec<_> = repo_files(".py")
        .into_iter()
        .filter(|p| p.starts_with(root.join("python")))
        .collect();
    assert!(python.len() > 5, "only {} Python files", python.len());
    for file in &python {
        let text = std::fs::read_to_string(file).unwrap();
        reads.push((relative(&root, file), python_env_reads(&text)));
    }
    let mut wrong = Vec::new();
    for (file, names) in &reads {
        // Who reads it, as its doc must say: a script by its place, the Python tests by name.
        let reader = if file.starts_with("python/") {
            "Python"
        } else {
            "ci/"
        };
        for name in names {
            match listed.iter().find(|v| v.name == *name) {
                None => wrong.push(format!("{file}: {name} is not in env.rs")),
                // A variable of the tool itself is documented for users; the scripts may
                // read it too.
                Some(var) if var.internal && !var.doc.contains(reader) => wrong.push(format!(
                    "{file}: {name}'s doc in env.rs does not say {reader} reads it"
                )),
                Some(_) => {}
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "environment variables read but not listed in bettimill-env's env.rs (add each to \
         EnvVars, its doc saying who reads it): {wrong:#?}"
    );
}

/// One variable of `EnvVars`: its name, whether it is hidden from the documentation, and
/// whether its doc comment says it is internal.
#[derive(Debug, PartialEq)]
struct EnvVar {
    name: String,
    hidden: bool,
    internal: bool,
    /// Its doc comment, which says who reads it.
    doc: String,
}

/// The variables `env.rs` declares (`pub const NAME: &'static str = "NAME";`, the value
/// possibly on the next line), with their doc comments and attributes.
fn env_vars(env_rs: &str) -> Vec<EnvVar> {
    let mut out = Vec::new();
    let mut docs = String::new();
    let mut hidden = false;
    for line in env_rs.lines().map(str::trim) {
        if let Some(doc) = line.strip_prefix("///") {
            docs.push_str(doc);
            docs.push(' ');
        } else if line == "#[doc(hidden)]" {
            hidden = true;
        } else if let Some(rest) = line.strip_prefix("pub const ") {
            let name = rest.split(':').next().unwrap().trim().to_string();
            out.push(EnvVar {
                name,
                hidden,
                internal: docs.trim_start().starts_with("Internal"),
                doc: docs.trim().to_string(),
            });
            docs.clear();
            hidden = false;
        } else if !line.starts_with('"') {
            docs.clear();
            hidden = false;
        }
    }
    out
}

/// What is wrong between `env.rs`'s variables and the users' list `docs`: a documented
/// variable the list does not name, a variable hidden without being marked internal (or
/// the reverse), a test hook not hidden.
fn env_docs_problems(vars: &[EnvVar], docs: &str) -> Vec<String> {
    let mut wrong = Vec::new();
    for var in vars {
        let name = &var.name;
        if !var.hidden && !docs.contains(&format!("`{name}`")) {
            wrong.push(format!(
                "{name} is documented in env.rs but not in the users' list"
            ));
        }
        if var.hidden != var.internal {
            wrong.push(format!(
                "{name}: #[doc(hidden)] goes with a doc that starts \"Internal\", and only with it"
            ));
        }
        if name.starts_with("BETTIMILL_TEST_") && !var.hidden {
            wrong.push(format!(
                "{name} is a test hook: mark it internal and hidden"
            ));
        }
        if var.hidden && docs.contains(&format!("`{name}`")) {
            wrong.push(format!("{name} is internal but the users' list names it"));
        }
    }
    wrong
}

#[test]
fn env_docs_checker_finds_undocumented_and_unmarked_variables() {
    let env_rs =
        "    /// Slurm: the index.\n    pub const SLURM_X: &'static str = \"SLURM_X\";\n\n\
                  /// Internal test hook: fails.\n    #[doc(hidden)]\n    pub const \
                  BETTIMILL_TEST_A: &'static str =\n        \"BETTIMILL_TEST_A\";\n\n\
                  /// A hook someone forgot to hide.\n    pub const BETTIMILL_TEST_B: &'static \
                  str = \"BETTIMILL_TEST_B\";\n";
    let vars = env_vars(env_rs);
    let names: Vec<(&str, bool, bool)> = vars
        .iter()
        .map(|v| (v.name.as_str(), v.hidden, v.internal))
        .collect();
    assert_eq!(
        names,
        [
            ("SLURM_X", false, false),
            ("BETTIMILL_TEST_A", true, true),
            ("BETTIMILL_TEST_B", false, false)
        ]
    );
    let wrong = env_docs_problems(&vars, "| `SLURM_X` | the index |");
    assert_eq!(wrong.len(), 2, "{wrong:?}");
    assert!(
        wrong[0].starts_with("BETTIMILL_TEST_B is documented"),
        "{wrong:?}"
    );
    assert!(
        wrong[1].starts_with("BETTIMILL_TEST_B is a test hook"),
        "{wrong:?}"
    );
    assert_eq!(env_docs_problems(&vars, "").len(), 3);
}

/// docs/environment.md is the users' copy of `EnvVars`: it names every variable that is not
/// internal, and every internal one (test hooks, the test suite's settings) is marked and
/// hidden from the documentation.
#[test]
fn the_users_list_of_environment_variables_matches_env_rs() {
    let root = repo_root();
    let env_rs = std::fs::read_to_string(root.join("crates/bettimill-env/src/env.rs")).unwrap();
    let docs = std::fs::read_to_string(root.join("docs/environment.md")).unwrap();
    let vars = env_vars(&env_rs);
    assert!(vars.len() > 10, "only {} variables: {vars:?}", vars.len());
    assert!(
        vars.iter().any(|v| v.hidden),
        "no internal variable found: {vars:?}"
    );
    let wrong = env_docs_problems(&vars, &docs);
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
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

// ------------------------------------------------------------- house rules on the text
//
// Each rule is a checker on text, unit-tested below on a synthetic bad input (so a rule
// that stops finding what it should fails), and a test that runs it on the tree. A rule
// that the tree does not meet everywhere yet names its known offenders, each with the
// count it has now: a count may only fall, and an offender that is gone must leave the
// list (the test says so), so the list only shrinks.

/// The non-test part of a Rust source: everything before the first `#[cfg(test)]`, and
/// nothing of a `tests.rs` unit-test module.
fn non_test_code(path: &Path, text: &str) -> String {
    if path.file_name().is_some_and(|n| n == "tests.rs") {
        return String::new();
    }
    match text.find("#[cfg(test)]") {
        Some(at) => text[..at].to_string(),
        None => text.to_string(),
    }
}

/// The non-test sources under `crates/*/src`, as (path relative to the repository, code),
/// for every crate but those in `except`.
fn crate_sources(except: &[&str]) -> Vec<(String, String)> {
    let root = repo_root();
    let mut out = Vec::new();
    for p in packages() {
        if except.contains(&p.name.as_str()) {
            continue;
        }
        let mut files = Vec::new();
        rust_files(&p.dir.join("src"), &mut files);
        for file in files {
            let text = std::fs::read_to_string(&file).unwrap();
            out.push((relative(&root, &file), non_test_code(&file, &text)));
        }
    }
    out.sort();
    out
}

/// `path` relative to `root`, with `/` separators.
fn relative(root: &Path, path: &Path) -> String {
    let canonical = |p: &Path| p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
    let (root, path) = (canonical(root), canonical(path));
    let rel = path.strip_prefix(&root).unwrap_or(&path);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}

/// Checks per-file counts against the known offenders: a file not listed must have none,
/// a listed one at most its count, and a listed count that is now lower (or a file now
/// clean) must be lowered in the list. Returns what is wrong.
fn ratchet(found: &BTreeMap<String, usize>, known: &[(&str, usize)]) -> Vec<String> {
    let mut wrong = Vec::new();
    for (path, &count) in found {
        match known.iter().find(|(k, _)| k == path) {
            None => wrong.push(format!("{path}: {count}")),
            Some(&(_, allowed)) if count > allowed => {
                wrong.push(format!("{path}: {count}, more than the {allowed} known"))
            }
            _ => {}
        }
    }
    for &(path, allowed) in known {
        let count = found.get(path).copied().unwrap_or(0);
        if count < allowed {
            wrong.push(format!(
                "{path}: {count} now, the list of known offenders says {allowed}: lower it"
            ));
        }
    }
    wrong
}

/// Literals that spell the dataset directory's layout, which only `bettimill-format`
/// may do: `(line, literal)` in `code`, comment lines left out.
fn layout_literals(code: &str) -> Vec<(usize, String)> {
    const LITERALS: [&str; 10] = [
        "\"shards/",
        "\"records/",
        "\"timings/",
        "\"index.json\"",
        "\"build.json\"",
        "\"classes.json\"",
        "\"manifest.toml\"",
        "join(\"shards\")",
        "join(\"records\")",
        "join(\"timings\")",
    ];
    let mut found = Vec::new();
    for (number, line) in code_lines(code) {
        for literal in LITERALS {
            if line.contains(literal) {
                found.push((number, literal.to_string()));
            }
        }
    }
    found
}

#[test]
fn layout_checker_finds_spelled_paths() {
    let bad = "// \"shards/\" in a comment is fine\nlet p = dir.join(\"shards\");\n\
               let i = \"index.json\";\nlet t = format!(\"records/{name}.json\");\n";
    let found: Vec<usize> = layout_literals(bad).iter().map(|(n, _)| *n).collect();
    assert_eq!(found, vec![2, 3, 4]);
    assert!(layout_literals("bar(total, \"shards\", \"verifying\")").is_empty());
}

#[test]
fn the_dataset_layout_is_spelled_only_in_the_format_crate() {
    let mut offences = Vec::new();
    for (path, code) in crate_sources(&["bettimill-format"]) {
        for (line, literal) in layout_literals(&code) {
            offences.push(format!("{path}:{line}: {literal}"));
        }
    }
    assert!(
        offences.is_empty(),
        "use bettimill_format::DatasetDir (or its constants) for the layout:\n{}",
        offences.join("\n")
    );
}

/// How many `Result<_, String>` types `code` spells (comment lines left out): the last
/// top-level argument of each `Result<...>` is `String`, across line breaks.
fn string_results(code: &str) -> usize {
    let code: String = code_lines(code)
        .map(|(_, line)| line)
        .collect::<Vec<_>>()
        .join("\n");
    let mut count = 0;
    let mut rest = code.as_str();
    while let Some(at) = rest.find("Result<") {
        let after = &rest[at + "Result<".len()..];
        let mut depth = 0usize;
        let mut last_arg = 0usize;
        let mut end = None;
        for (i, c) in after.char_indices() {
            match c {
                '<' | '(' | '[' => depth += 1,
                '>' if depth == 0 => {
                    end = Some(i);
                    break;
                }
                '>' | ')' | ']' => depth = depth.saturating_sub(1),
                ',' if depth == 0 => last_arg = i + 1,
                _ => {}
            }
        }
        if let Some(end) = end {
            // The last argument, a trailing comma left out.
            let args = after[..end].trim_end().trim_end_matches(',');
            let last = args.rsplit_once(',').map(|(_, last)| last);
            if last.is_some_and(|last| last.trim() == "String") && last_arg > 0 {
                count += 1;
            }
        }
        rest = after;
    }
    count
}

#[test]
fn string_result_checker_counts_across_lines() {
    let bad =
        "fn a() -> Result<(), String> {}\nfn b(\n) -> Result<\n    Vec<u8>,\n    String,\n> {}\n\
               fn c() -> Result<Vec<String>, Error> {}\nfn d() -> io::Result<String> {}\n\
               // fn e() -> Result<(), String>\ntype F = Box<dyn Fn() -> Result<u8, String>>;\n";
    assert_eq!(string_results(bad), 3);
}

#[test]
fn library_crates_return_typed_errors_not_strings() {
    let mut found = BTreeMap::new();
    for (path, code) in crate_sources(&["bettimill-cli", "bettimill-testkit"]) {
        let count = string_results(&code);
        if count > 0 {
            found.insert(path, count);
        }
    }
    let wrong: Vec<String> = found
        .iter()
        .map(|(path, count)| format!("{path}: {count}"))
        .collect();
    assert!(
        wrong.is_empty(),
        "Result<_, String> in library code: give it a thiserror enum (the CLI alone may \
         use anyhow):\n{}",
        wrong.join("\n")
    );
}

/// The most lines a source file under `crates/*/src` may have: past it, a file holds
/// more than one concept and is split.
const MAX_SOURCE_LINES: usize = 1000;

#[test]
fn ratchet_refuses_new_and_grown_offenders_and_asks_to_lower() {
    let found: BTreeMap<String, usize> = [
        ("a.rs".to_string(), 5),
        ("b.rs".to_string(), 3),
        ("c.rs".to_string(), 1),
    ]
    .into();
    let wrong = ratchet(&found, &[("a.rs", 4), ("b.rs", 3), ("d.rs", 2)]);
    assert_eq!(wrong.len(), 3, "{wrong:?}");
    assert!(wrong[0].starts_with("a.rs: 5, more than"), "{wrong:?}");
    assert!(wrong[1].starts_with("c.rs: 1"), "{wrong:?}");
    assert!(wrong[2].starts_with("d.rs: 0 now"), "{wrong:?}");
    assert!(ratchet(&found, &[("a.rs", 5), ("b.rs", 3), ("c.rs", 1)]).is_empty());
}

#[test]
fn no_source_file_is_over_a_thousand_lines() {
    let root = repo_root();
    let mut found = BTreeMap::new();
    for p in packages() {
        let mut files = Vec::new();
        rust_files(&p.dir.join("src"), &mut files);
        for file in files {
            let lines = std::fs::read_to_string(&file).unwrap().lines().count();
            if lines > MAX_SOURCE_LINES {
                found.insert(relative(&root, &file), lines);
            }
        }
    }
    let wrong: Vec<String> = found
        .iter()
        .map(|(path, lines)| format!("{path}: {lines} lines"))
        .collect();
    assert!(
        wrong.is_empty(),
        "split files over {MAX_SOURCE_LINES} lines by concept:\n{}",
        wrong.join("\n")
    );
}

/// Lines of `text` longer than `max` characters: `(line number, length)`.
fn long_lines(text: &str, max: usize) -> Vec<(usize, usize)> {
    text.lines()
        .enumerate()
        .map(|(i, line)| (i + 1, line.chars().count()))
        .filter(|&(_, len)| len > max)
        .collect()
}

#[test]
fn long_line_checker_counts_characters() {
    let text = format!("short\n{}\n{}\n", "x".repeat(101), "é".repeat(100));
    assert_eq!(long_lines(&text, 100), vec![(2, 101)]);
}

/// ARCHITECTURE.md stays readable in a terminal and a side-by-side diff.
#[test]
fn architecture_lines_fit_in_a_hundred_characters() {
    let text = std::fs::read_to_string(repo_root().join("ARCHITECTURE.md")).unwrap();
    let long = long_lines(&text, 100);
    assert!(
        long.is_empty(),
        "ARCHITECTURE.md lines over 100 characters (line, length): {long:?}"
    );
}

/// The most lines ARCHITECTURE.md may have: a map a newcomer reads in one sitting, one short
/// paragraph per crate; details live in the code's module docs.
const MAX_ARCHITECTURE_LINES: usize = 250;

#[test]
fn architecture_is_under_two_hundred_and_fifty_lines() {
    let text = std::fs::read_to_string(repo_root().join("ARCHITECTURE.md")).unwrap();
    let lines = text.lines().count();
    assert!(
        lines < MAX_ARCHITECTURE_LINES,
        "ARCHITECTURE.md has {lines} lines, at most {} allowed: say less, or move the detail \
         into the module's own docs",
        MAX_ARCHITECTURE_LINES - 1
    );
}

/// The most lines BENCHMARKS.md may have: the current figures and one section per
/// benchmark; older passes live in git history or dated files under `benches/results/`.
const MAX_BENCHMARKS_LINES: usize = 400;

/// What is wrong with the shape of a BENCHMARKS.md text: too long, or its first section is
/// not the table of current figures.
fn benchmarks_shape(text: &str) -> Vec<String> {
    let mut wrong = Vec::new();
    let lines = text.lines().count();
    if lines >= MAX_BENCHMARKS_LINES {
        wrong.push(format!(
            "{lines} lines, at most {}: move older passes to a dated file under \
             benches/results/ (or leave them to git history)",
            MAX_BENCHMARKS_LINES - 1
        ));
    }
    let mut sections = text.split("\n## ").skip(1);
    match sections.next() {
        Some(first) if first.starts_with("Current figures\n") => {
            if !first.lines().any(|line| line.starts_with("| what |")) {
                wrong.push("the current figures have no `| what |` table".to_string());
            }
        }
        other => wrong.push(format!(
            "the first section is {:?}, not \"Current figures\"",
            other.and_then(|s| s.lines().next())
        )),
    }
    wrong
}

#[test]
fn benchmarks_checker_finds_length_and_order() {
    let good = "# Benchmarks\n\nintro\n\n## Current figures\n\n| what | figure |\n\n## A\n";
    assert!(benchmarks_shape(good).is_empty());
    let late = "# Benchmarks\n\n## Old pass\n\n## Current figures\n\n| what |\n";
    assert_eq!(benchmarks_shape(late).len(), 1);
    let long = format!("{good}{}", "x\n".repeat(MAX_BENCHMARKS_LINES));
    assert_eq!(benchmarks_shape(&long).len(), 1);
}

/// BENCHMARKS.md opens with one table of current figures and stays short.
#[test]
fn benchmarks_open_with_current_figures_and_stay_short() {
    let text = std::fs::read_to_string(repo_root().join("BENCHMARKS.md")).unwrap();
    let wrong = benchmarks_shape(&text);
    assert!(wrong.is_empty(), "BENCHMARKS.md: {}", wrong.join("; "));
}

/// Where `text` points to the tracker by number (the word, an optional `#`, a number; any
/// case, plural too): users do not have it. Line numbers, from 1.
fn issue_references(text: &str) -> Vec<usize> {
    let mut found = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let lower = line.to_ascii_lowercase();
        let mut rest = lower.as_str();
        while let Some(at) = rest.find("issue") {
            let word_start = at == 0 || !rest.as_bytes()[at - 1].is_ascii_alphanumeric();
            let after = rest[at + "issue".len()..].trim_start_matches('s');
            let after = after.trim_start_matches(' ').trim_start_matches('#');
            if word_start && after.starts_with(|c: char| c.is_ascii_digit()) {
                found.push(number + 1);
                break;
            }
            rest = &rest[at + "issue".len()..];
        }
    }
    found
}

#[test]
fn issue_reference_checker_finds_tracker_numbers() {
    let text = concat!(
        "fine: an issue with 3 parts\n",
        "see iss",
        "ue 18\n",
        "(Iss",
        "ues #4, 5)\n",
        "tissue 9 is a word\n",
    );
    assert_eq!(issue_references(text), vec![2, 3]);
}

/// Files that still name tracker issues: this list only shrinks.
const KNOWN_ISSUE_REFERENCES: &[(&str, usize)] = &[];

#[test]
fn code_and_docs_name_no_tracker_issues() {
    let root = repo_root();
    let mut files = Vec::new();
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for entry in entries {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if path.is_dir() {
                if !name.starts_with('.') && name != "target" && name != "node_modules" {
                    walk(&path, out);
                }
            } else if ["rs", "md", "toml", "sh", "py", "pyi", "yml", "yaml"]
                .iter()
                .any(|ext| name.ends_with(&format!(".{ext}")))
            {
                out.push(path);
            }
        }
    }
    walk(&root, &mut files);
    assert!(files.len() > 100, "only {} files", files.len());
    let mut found = BTreeMap::new();
    for file in files {
        let Ok(text) = std::fs::read_to_string(&file) else {
            continue;
        };
        let lines = issue_references(&text);
        if !lines.is_empty() {
            found.insert(relative(&root, &file), lines.len());
        }
    }
    let wrong = ratchet(&found, KNOWN_ISSUE_REFERENCES);
    assert!(
        wrong.is_empty(),
        "say why in the text instead of pointing to a tracker users do not have:\n{}",
        wrong.join("\n")
    );
}

// ------------------------------------------------------------------ one owner per check
//
// A check written twice drifts: the copies come to refuse different files, or to say it in
// different words. Each of these has one owner, the only file that defines it; everyone
// else calls it (or, in bettimill-format, wraps its error without repeating the check).

/// Definitions that exist once, with the file that owns each.
const ONE_OWNER: &[(&str, &str)] = &[
    // The refusal of anything but a plain file (a device, a directory, a link to one).
    ("fn regular_len(", "crates/bettimill-shard/src/file.rs"),
    // Whether a file has a recorded size and blake3, streamed.
    ("fn file_matches(", "crates/bettimill-shard/src/file.rs"),
    // Whether a tar matches its record: verify, resume, status and finalize.
    (
        "fn check_tar_file(",
        "crates/bettimill-format/src/tar_check.rs",
    ),
];

/// Whether `line` asks file metadata whether it is a plain file, the test a copy of
/// `regular_len` makes (`meta.is_file()`, `metadata(path)?.is_file()`); a path's own
/// `is_file()` and a directory entry's file type are other questions.
fn asks_metadata_is_file(line: &str) -> bool {
    line.match_indices(".is_file()").any(|(at, _)| {
        let before = line[..at].trim_end_matches('?');
        before.ends_with(')') && before.contains("metadata(")
            || before
                .rsplit(|c: char| !(c.is_alphanumeric() || c == '_'))
                .next()
                .is_some_and(|name| name == "meta" || name == "metadata")
    })
}

/// The files of `sources` (path, code) with a code line that passes `test`.
fn files_with(sources: &[(String, String)], test: &dyn Fn(&str) -> bool) -> Vec<String> {
    sources
        .iter()
        .filter(|(_, code)| code_lines(code).any(|(_, line)| test(line)))
        .map(|(path, _)| path.clone())
        .collect()
}

#[test]
fn metadata_is_file_checker_finds_a_copy_of_regular_len() {
    for copy in [
        "    if !meta.is_file() {",
        "let plain = std::fs::metadata(path)?.is_file();",
        "if fs::metadata(&p).map_err(io)?.is_file() {",
        "    metadata.is_file()",
    ] {
        assert!(asks_metadata_is_file(copy), "{copy}");
    }
    for other in [
        ".find(|name| root.join(name).join(INDEX_FILE).is_file())",
        "let is_file = entry.file_type().map_err(io(dir))?.is_file();",
        "if path.is_file() {",
        "// meta.is_file() in a comment",
    ] {
        let code: Vec<_> = code_lines(other).map(|(_, line)| line).collect();
        assert!(!code.iter().any(|l| asks_metadata_is_file(l)), "{other}");
    }
}

#[test]
fn each_shared_check_is_defined_once_by_its_owner() {
    let sources = crate_sources(&[]);
    assert!(sources.len() > 50, "only {} sources", sources.len());
    let mut wrong = Vec::new();
    for &(definition, owner) in ONE_OWNER {
        let found = files_with(&sources, &|line| line.contains(definition));
        if found != [owner] {
            wrong.push(format!(
                "{definition}..) defined in {found:?}, owned by {owner}"
            ));
        }
    }
    let owner = "crates/bettimill-shard/src/file.rs";
    let found = files_with(&sources, &asks_metadata_is_file);
    if found != [owner] {
        wrong.push(format!(
            "metadata asked whether it is a plain file in {found:?}: call \
             bettimill_shard::regular_len ({owner})"
        ));
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

// ------------------------------------------------------------ the CLI's one printer

/// What prints or decides quietness in the CLI: print macros, the standard streams, and the
/// `quiet` flag read outside the printer.
const PRINTING: &[&str] = &[
    "println!(",
    "print!(",
    "eprint!(",
    "dbg!(",
    "std::io::stdout",
    "std::io::stderr",
    "io::stdout()",
    "io::stderr()",
    "quiet",
];

/// Where `code` prints or reads quietness itself: `(line, needle)`, comment lines left out.
fn printing(code: &str) -> Vec<(usize, &'static str)> {
    let mut found = Vec::new();
    for (number, line) in code_lines(code) {
        for &needle in PRINTING {
            if line.contains(needle) {
                found.push((number, needle));
                break;
            }
        }
    }
    found
}

#[test]
fn printing_checker_finds_prints_streams_and_quietness() {
    let bad = "// eprintln!(\"in a comment\")\nif !quiet {\n    eprintln!(\"x\");\n}\n\
               print!(\"{yaml}\");\nlet out = std::io::stdout().lock();\noutln!(\"data\")?;\n\
               printer.note(\"fine\");\n";
    let lines: Vec<usize> = printing(bad).iter().map(|(n, _)| *n).collect();
    assert_eq!(lines, vec![2, 3, 5, 6]);
}

/// The CLI says everything through `printer.rs`'s `Printer`, made once from `--quiet` in
/// `commands.rs`: no other file prints, takes a standard stream or reads the flag. The
/// worker's protocol stream is the one exception: bytes for the coordinator, not output
/// for a person.
#[test]
fn the_cli_prints_only_through_its_printer() {
    let root = repo_root();
    let src = root.join("crates/bettimill-cli/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    assert!(files.len() > 10, "only {} files", files.len());
    let allowed: &[(&str, &str)] = &[("commands.rs", "quiet"), ("cluster.rs", "std::io::stdout")];
    let mut found = Vec::new();
    for file in files {
        let name = relative(&src, &file);
        if name == "printer.rs" {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        for (line, needle) in printing(&non_test_code(&file, &text)) {
            if !allowed.contains(&(name.as_str(), needle)) {
                found.push(format!("crates/bettimill-cli/src/{name}:{line}: {needle}"));
            }
        }
    }
    assert!(
        found.is_empty(),
        "print through crate::printer::Printer (note, always, data, bar) instead:\n{}",
        found.join("\n")
    );
}
