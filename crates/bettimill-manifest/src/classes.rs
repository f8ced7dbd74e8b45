//! Expansion of `[[classes]]` entries with parameter ranges into concrete classes.
//!
//! A class table may give an integer parameter as an inclusive range `[lo, hi]`, or a
//! string parameter as a list of strings; the entry then stands for every combination, keys taken in
//! alphabetical order (later keys vary fastest). Arrays of tables (the
//! `objects` of a scene) are never expanded.
//!
//! A class may instead give the label itself: `betti = [1, 2, 1, 0]` (b_0..b_{d-1}),
//! each entry an integer or an inclusive range `[lo, hi]`.
//!
//! What a concrete table means (which families exist, their parameters and whether they can
//! be built) is not decided here: the manifest knows syntax and ranges, and the plan turns
//! each [`ClassSpec`] into a construction, once (`bettimill_plan::Plan::new`).

use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize};
use toml::Value;

/// The most classes one entry may expand into.
const MAX_EXPANSION: usize = 10_000;

/// One concrete label class, ranges expanded, not yet resolved into a construction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassSpec {
    /// 1-based position of the `[[classes]]` entry it came from (for error messages).
    pub entry: usize,
    /// What the entry says.
    pub kind: ClassKind,
}

/// A concrete class as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ClassKind {
    /// A construction family and its parameters, e.g. `{ family = "handlebody", genus = 2 }`.
    Family(toml::Table),
    /// A Betti vector `b0..b(d-1)`.
    Betti(Vec<u64>),
}

/// Deserialises `classes`, expanding ranges and lists.
pub(crate) fn expand<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<Vec<ClassSpec>, D::Error> {
    let tables = Vec::<toml::Table>::deserialize(deserializer)?;
    let mut out = Vec::new();
    for (position, table) in tables.into_iter().enumerate() {
        let entry = position + 1;
        if table.contains_key("betti")
            || table.get("family").and_then(Value::as_str) == Some("betti")
        {
            let vectors = betti_vectors(&table)
                .map_err(|reason| D::Error::custom(format!("class {entry}: {reason}")))?;
            out.extend(vectors.into_iter().map(|betti| ClassSpec {
                entry,
                kind: ClassKind::Betti(betti),
            }));
            continue;
        }
        if !table.contains_key("family") {
            // A misspelt `family` is the likely cause: name the key written.
            if let Some(key) = table
                .keys()
                .find(|key| strsim::levenshtein(key, "family") <= 2)
            {
                return Err(D::Error::custom(format!(
                    "class {entry}: unknown field `{key}`: did you mean `family`?"
                )));
            }
            return Err(D::Error::custom(format!(
                "class {entry}: give `family = \"...\"` or `betti = [...]`"
            )));
        }
        for concrete in expand_table(table)
            .map_err(|reason| D::Error::custom(format!("class {entry}: {reason}")))?
        {
            out.push(ClassSpec {
                entry,
                kind: ClassKind::Family(concrete),
            });
        }
    }
    Ok(out)
}

/// Why a class entry does not expand; the caller names the entry.
#[derive(Debug, thiserror::Error)]
enum ClassError {
    #[error("unknown field `{0}` next to `betti` (a class is either a Betti vector or a family)")]
    BesideBetti(String),
    #[error("`betti` and `family = {0}` together: a class is either a Betti vector or a family")]
    BettiAndFamily(Value),
    #[error("`betti` must be a list of b0..b(d-1), e.g. betti = [1, 2, 1, 0]")]
    BettiNotAList,
    #[error("`betti` has {0} entries; give b0..b(d-1): 2 to 4 entries")]
    BettiLength(usize),
    #[error("betti entry b{0}: a range is [lo, hi] of integers")]
    BettiPair(usize),
    #[error("betti entry b{entry}: expected an integer or [lo, hi], found {found}")]
    BettiType { entry: usize, found: &'static str },
    #[error("betti entry b{entry}: [{lo}, {hi}] must be a non-empty range within 0..=64")]
    BettiRange { entry: usize, lo: i64, hi: i64 },
    #[error("expands into more than {MAX_EXPANSION} classes")]
    TooMany,
    #[error("range [{0}, {1}] is empty")]
    EmptyRange(i64, i64),
    #[error("range [{0}, {1}] is too long")]
    LongRange(i64, i64),
}

/// The Betti vectors of a `betti = [...]` class: entries are integers or `[lo, hi]`.
fn betti_vectors(table: &toml::Table) -> Result<Vec<Vec<u64>>, ClassError> {
    if let Some(extra) = table.keys().find(|k| *k != "betti" && *k != "family") {
        return Err(ClassError::BesideBetti(extra.clone()));
    }
    if let Some(family) = table.get("family") {
        if family.as_str() != Some("betti") {
            return Err(ClassError::BettiAndFamily(family.clone()));
        }
    }
    let Some(Value::Array(entries)) = table.get("betti") else {
        return Err(ClassError::BettiNotAList);
    };
    if entries.is_empty() || entries.len() > 4 {
        return Err(ClassError::BettiLength(entries.len()));
    }
    let mut vectors = vec![Vec::new()];
    for (k, entry) in entries.iter().enumerate() {
        let (lo, hi) = match entry {
            Value::Integer(n) => (*n, *n),
            Value::Array(pair) => match pair.as_slice() {
                [Value::Integer(lo), Value::Integer(hi)] => (*lo, *hi),
                _ => return Err(ClassError::BettiPair(k)),
            },
            other => {
                return Err(ClassError::BettiType {
                    entry: k,
                    found: other.type_str(),
                })
            }
        };
        if lo < 0 || hi > 64 || lo > hi {
            return Err(ClassError::BettiRange { entry: k, lo, hi });
        }
        if vectors.len().saturating_mul((hi - lo + 1) as usize) > MAX_EXPANSION {
            return Err(ClassError::TooMany);
        }
        vectors = vectors
            .into_iter()
            .flat_map(|base| {
                (lo..=hi).map(move |b| {
                    let mut next = base.clone();
                    next.push(b as u64);
                    next
                })
            })
            .collect();
    }
    Ok(vectors)
}

/// The alternatives a value stands for.
fn alternatives(value: &Value) -> Result<Vec<Value>, ClassError> {
    let Value::Array(items) = value else {
        return Ok(vec![value.clone()]);
    };
    if items.iter().all(|v| v.is_str()) && !items.is_empty() {
        return Ok(items.clone());
    }
    if let [Value::Integer(lo), Value::Integer(hi)] = items.as_slice() {
        if lo > hi {
            return Err(ClassError::EmptyRange(*lo, *hi));
        }
        if hi - lo >= MAX_EXPANSION as i64 {
            return Err(ClassError::LongRange(*lo, *hi));
        }
        return Ok((*lo..=*hi).map(Value::Integer).collect());
    }
    Ok(vec![value.clone()])
}

fn expand_table(table: toml::Table) -> Result<Vec<toml::Table>, ClassError> {
    let mut combos = vec![toml::Table::new()];
    for (key, value) in table {
        let options = alternatives(&value)?;
        if combos.len().saturating_mul(options.len()) > MAX_EXPANSION {
            return Err(ClassError::TooMany);
        }
        combos = combos
            .into_iter()
            .flat_map(|base| {
                let key = &key;
                options.iter().map(move |option| {
                    let mut next = base.clone();
                    next.insert(key.clone(), option.clone());
                    next
                })
            })
            .collect();
    }
    Ok(combos)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn expanded(text: &str) -> Result<Vec<ClassKind>, String> {
        #[derive(Deserialize)]
        struct Wrapper {
            #[serde(deserialize_with = "expand")]
            classes: Vec<ClassSpec>,
        }
        toml::from_str::<Wrapper>(text)
            .map(|w| w.classes.into_iter().map(|c| c.kind).collect())
            .map_err(|e| e.message().to_string())
    }

    fn table(text: &str) -> ClassKind {
        ClassKind::Family(toml::from_str(text).unwrap())
    }

    #[test]
    fn betti_vectors_expand_their_ranges() {
        let betti = |v: &[u64]| ClassKind::Betti(v.to_vec());
        assert_eq!(
            expanded("[[classes]]\nbetti = [1, 2, 1, 0]\n").unwrap(),
            vec![betti(&[1, 2, 1, 0])]
        );
        // Two integers are a vector, not a range: b0 = 1, b1 = 2.
        assert_eq!(
            expanded("[[classes]]\nbetti = [1, 2]\n").unwrap(),
            vec![betti(&[1, 2])]
        );
        assert_eq!(
            expanded("[[classes]]\nfamily = \"betti\"\nbetti = [1, [0, 2], 0]\n").unwrap(),
            vec![betti(&[1, 0, 0]), betti(&[1, 1, 0]), betti(&[1, 2, 0])]
        );
        for (text, needle) in [
            ("betti = [1, 0]\ngenus = 2", "unknown field `genus`"),
            (
                "betti = [1, 0]\nfamily = \"ball\"",
                "either a Betti vector or a family",
            ),
            ("betti = 3", "must be a list"),
            ("betti = [1, -1]", "within 0..=64"),
            ("betti = [1, [2, 1]]", "non-empty range"),
            ("betti = [1, 0.5]", "found float"),
            ("betti = [1, 0, 0, 0, 0]", "5 entries"),
            ("family = \"betti\"", "must be a list"),
            ("genus = 2", "give `family"),
        ] {
            let err = expanded(&format!("[[classes]]\n{text}\n")).unwrap_err();
            assert!(err.contains(needle), "{text}: {err}");
        }
    }

    #[test]
    fn ranges_and_lists_expand() {
        let classes =
            expanded("[[classes]]\nfamily = \"connected_sum\"\ng = [0, 2]\nh = 1\ni = 0\nj = 0\n")
                .unwrap();
        assert_eq!(classes.len(), 3);
        assert_eq!(
            classes[2],
            table("family = \"connected_sum\"\ng = 2\nh = 1\ni = 0\nj = 0")
        );
        let classes =
            expanded("[[classes]]\nfamily = \"knot\"\nknot = [\"trefoil\", \"figure_eight\"]\n")
                .unwrap();
        assert_eq!(classes.len(), 2);
        let classes = expanded("[[classes]]\nfamily = [\"ball\", \"handle\"]\n").unwrap();
        assert_eq!(
            classes,
            vec![table("family = \"ball\""), table("family = \"handle\"")]
        );
    }
}
