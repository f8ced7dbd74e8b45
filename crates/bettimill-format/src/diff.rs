//! Where two versions of a dataset file first differ, said the way a user can check it:
//! the JSON path and both values for JSON files, else the line. The one place outside the
//! build's writers that parses the directory's JSON to compare it.

use std::path::Path;

/// Where two versions of a finalized file first differ: a JSON path and both values for
/// JSON files, else a line and both lines.
pub fn first_difference_in(
    path: &Path,
    stored: &[u8],
    computed: &[u8],
) -> (String, String, String) {
    let shorten = |text: String| -> String {
        if text.chars().count() > 200 {
            format!("{}...", text.chars().take(200).collect::<String>())
        } else {
            text
        }
    };
    if path.extension().is_some_and(|e| e == "json") {
        let parsed: Result<serde_json::Value, _> = serde_json::from_slice(stored);
        let ours: serde_json::Value = match serde_json::from_slice(computed) {
            Ok(value) => value,
            Err(err) => return ("(file)".into(), String::new(), err.to_string()),
        };
        return match parsed {
            Err(err) => ("(file)".into(), format!("no JSON ({err})"), "JSON".into()),
            Ok(theirs) => match json_difference(&theirs, &ours, String::new()) {
                Some((field, a, b)) => (field, shorten(a), shorten(b)),
                // Same values, other bytes (spacing, key order, number spelling).
                None => (
                    "(bytes)".into(),
                    "the same values written differently".into(),
                    "the build's exact bytes".into(),
                ),
            },
        };
    }
    let (a, b) = (
        String::from_utf8_lossy(stored),
        String::from_utf8_lossy(computed),
    );
    let mut lines = a.lines().zip(b.lines()).enumerate();
    match lines.find(|(_, (x, y))| x != y) {
        Some((i, (x, y))) => (
            format!("line {}", i + 1),
            shorten(format!("{x:?}")),
            shorten(format!("{y:?}")),
        ),
        None => (
            "(length)".into(),
            format!("{} bytes", stored.len()),
            format!("{} bytes", computed.len()),
        ),
    }
}

/// The first place where two JSON values differ: its path (`classes[3].betti`) and both
/// values as JSON.
fn json_difference(
    a: &serde_json::Value,
    b: &serde_json::Value,
    path: String,
) -> Option<(String, String, String)> {
    use serde_json::Value;
    let here = || {
        Some((
            if path.is_empty() {
                "(file)".to_string()
            } else {
                path.clone()
            },
            a.to_string(),
            b.to_string(),
        ))
    };
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            for (key, value) in y {
                let inner = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                match x.get(key) {
                    Some(other) => {
                        if let Some(found) = json_difference(other, value, inner) {
                            return Some(found);
                        }
                    }
                    None => return Some((inner, "(missing)".into(), value.to_string())),
                }
            }
            x.keys().find(|k| !y.contains_key(*k)).map(|k| {
                let inner = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                (inner, x[k].to_string(), "(no such field)".into())
            })
        }
        (Value::Array(x), Value::Array(y)) => {
            for (i, (p, q)) in x.iter().zip(y).enumerate() {
                if let Some(found) = json_difference(p, q, format!("{path}[{i}]")) {
                    return Some(found);
                }
            }
            (x.len() != y.len()).then(|| {
                (
                    format!("{path} (length)"),
                    x.len().to_string(),
                    y.len().to_string(),
                )
            })
        }
        _ if a == b => None,
        _ => here(),
    }
}
