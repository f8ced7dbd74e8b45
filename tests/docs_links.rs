//! No documentation points out of the repository: every relative markdown link in
//! README.md, ARCHITECTURE.md, BENCHMARKS.md, docs/**/*.md, crates/**/README.md and the
//! manifests' comments resolves to a file or directory of the repository, and no text names
//! the development notes a user does not have (`../shared`, `/work/shared`). A failure
//! names the file and the line.

mod common;

use common::repo_root;
use std::path::{Path, PathBuf};

fn files() -> Vec<PathBuf> {
    let root = repo_root();
    let mut out: Vec<PathBuf> = ["README.md", "ARCHITECTURE.md", "BENCHMARKS.md"]
        .iter()
        .map(|f| root.join(f))
        .collect();
    fn walk(dir: &Path, keep: &dyn Fn(&Path) -> bool, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        for path in entries {
            if path.is_dir() {
                if path.file_name().is_some_and(|n| n != "target") {
                    walk(&path, keep, out);
                }
            } else if keep(&path) {
                out.push(path);
            }
        }
    }
    let is_md = |p: &Path| p.extension().is_some_and(|e| e == "md");
    walk(&root.join("docs"), &is_md, &mut out);
    walk(
        &root.join("crates"),
        &|p: &Path| p.file_name().is_some_and(|n| n == "README.md"),
        &mut out,
    );
    walk(
        &root.join("manifests"),
        &|p: &Path| p.extension().is_some_and(|e| e == "toml"),
        &mut out,
    );
    out
}

/// The targets of `[text](target)` and `![alt](target)` on one line.
fn link_targets(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(pos) = rest.find("](") {
        let after = &rest[pos + 2..];
        let Some(end) = after.find(')') else { break };
        let target = after[..end].split_whitespace().next().unwrap_or("");
        out.push(target);
        rest = &after[end..];
    }
    out
}

/// Problems of one file's text, as `path:line: what`.
fn problems(root: &Path, path: &Path, text: &str) -> Vec<String> {
    let shown = path
        .strip_prefix(root)
        .unwrap_or(path)
        .display()
        .to_string();
    let root = root.canonicalize().unwrap();
    let dir = path.parent().unwrap();
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let at = format!("{shown}:{}", n + 1);
        for outside in ["../shared", "/work/shared"] {
            if line.contains(outside) {
                out.push(format!("{at}: names {outside}, which users do not have"));
            }
        }
        for target in link_targets(line) {
            let external = target.is_empty()
                || target.starts_with('#')
                || target.contains("://")
                || target.starts_with("mailto:");
            if external {
                continue;
            }
            let file = target.split('#').next().unwrap();
            match dir.join(file).canonicalize() {
                Ok(resolved) if resolved.starts_with(&root) => {}
                Ok(_) => out.push(format!("{at}: link {target} leaves the repository")),
                Err(_) => out.push(format!("{at}: link {target} does not exist")),
            }
        }
    }
    out
}

#[test]
fn no_documentation_links_out_of_the_repository() {
    let root = repo_root();
    let files = files();
    assert!(files.iter().any(|f| f.ends_with("docs/topology.md")));
    let mut found = Vec::new();
    for path in &files {
        found.extend(problems(
            &root,
            path,
            &std::fs::read_to_string(path).unwrap(),
        ));
    }
    assert!(
        found.is_empty(),
        "links out of the repository:\n{}",
        found.join("\n")
    );
}

#[test]
fn the_check_catches_bad_links() {
    let root = repo_root();
    let readme = root.join("README.md");
    let text = "fine [a](docs/format.md#labels) and [web](https://example.org)\n\
                see `../shared/notes/labels.md`\n\
                [gone](docs/nothing-here.md) ![up](../../etc/passwd)\n";
    let found = problems(&root, &readme, text);
    assert_eq!(found.len(), 3, "{found:?}");
    assert!(
        found[0].starts_with("README.md:2: names ../shared"),
        "{found:?}"
    );
    assert!(
        found[1].starts_with("README.md:3: link docs/nothing-here.md"),
        "{found:?}"
    );
    assert!(
        found[2].contains("README.md:3: link ../../etc/passwd"),
        "{found:?}"
    );
}
