//! Tidy checks: invariants of ARCHITECTURE.md enforced as tests, not only prose.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn crates() -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(root().join("crates"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("Cargo.toml").exists())
        .collect();
    out.sort();
    out
}

#[test]
fn every_module_opens_with_a_doc_comment() {
    let mut missing = Vec::new();
    for krate in crates() {
        let mut files = Vec::new();
        rust_files(&krate.join("src"), &mut files);
        for file in files {
            let text = std::fs::read_to_string(&file).unwrap();
            let is_test_module = file.file_name().is_some_and(|n| n == "tests.rs");
            if !is_test_module && !text.trim_start().starts_with("//!") {
                missing.push(file.display().to_string());
            }
        }
    }
    assert!(
        missing.is_empty(),
        "modules without a //! doc: {missing:#?}"
    );
}

#[test]
fn only_the_cli_prints() {
    let mut offenders = Vec::new();
    for krate in crates() {
        if krate.ends_with("bettimill-cli") {
            continue;
        }
        let mut files = Vec::new();
        rust_files(&krate.join("src"), &mut files);
        for file in files {
            if file.file_name().is_some_and(|n| n == "tests.rs") {
                continue;
            }
            let text = std::fs::read_to_string(&file).unwrap();
            // Unit tests may print; library code may not.
            let code = text.split("#[cfg(test)]").next().unwrap_or("");
            for needle in ["println!(", "eprintln!(", "print!(", "eprint!("] {
                if code.contains(needle) {
                    offenders.push(format!("{}: {needle}", file.display()));
                }
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "library code that prints: {offenders:#?}"
    );
}

#[test]
fn the_verifier_depends_only_on_the_grid() {
    let text =
        std::fs::read_to_string(root().join("crates/bettimill-homology/Cargo.toml")).unwrap();
    let deps = text
        .split("[dependencies]")
        .nth(1)
        .unwrap()
        .split("\n[")
        .next()
        .unwrap();
    let internal: Vec<&str> = deps
        .lines()
        .filter(|l| l.trim_start().starts_with("bettimill-"))
        .collect();
    assert_eq!(internal, vec!["bettimill-grid.workspace = true"]);
}

#[test]
fn every_crate_is_on_the_code_map() {
    let architecture = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let readme = std::fs::read_to_string(root().join("crates/README.md")).unwrap();
    for krate in crates() {
        let name = krate.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            architecture.contains(&format!("### `{name}`")),
            "ARCHITECTURE.md has no code-map heading for {name}"
        );
        assert!(
            readme.contains(&format!("`{name}`")),
            "crates/README.md has no line for {name}"
        );
    }
}
