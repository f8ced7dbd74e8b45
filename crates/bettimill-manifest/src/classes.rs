//! Expansion of `[[classes]]` entries with parameter ranges into concrete classes.
//!
//! A class table may give an integer parameter as an inclusive range `[lo, hi]`, or a
//! string parameter as a list of strings; the entry then stands for every combination, keys taken in
//! alphabetical order (later keys vary fastest). Arrays of tables (the
//! `objects` of a scene) are never expanded. Each concrete table is then read as a
//! `bettimill_shapes::Family`, so unknown fields and wrong types are still errors.
//!
//! A class may instead give the label itself: `betti = [1, 2, 1, 0]` (b_0..b_{d-1}),
//! each entry an integer or an inclusive range `[lo, hi]`; shapes realises each vector by
//! a canonical construction (`Family::Betti`).

use bettimill_shapes::Family;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer};
use toml::Value;

/// The most classes one entry may expand into.
const MAX_EXPANSION: usize = 10_000;

/// Deserialises `classes`, expanding ranges and lists.
pub(crate) fn expand<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<Family>, D::Error> {
    let tables = Vec::<toml::Table>::deserialize(deserializer)?;
    let mut out = Vec::new();
    for (position, table) in tables.into_iter().enumerate() {
        if table.contains_key("betti")
            || table.get("family").and_then(Value::as_str) == Some("betti")
        {
            let vectors = betti_vectors(&table)
                .map_err(|reason| D::Error::custom(format!("class {}: {reason}", position + 1)))?;
            out.extend(vectors.into_iter().map(|betti| Family::Betti { betti }));
            continue;
        }
        for concrete in expand_table(table)
            .map_err(|reason| D::Error::custom(format!("class {}: {reason}", position + 1)))?
        {
            let family = Family::deserialize(Value::Table(concrete.clone()))
                .map_err(|err| D::Error::custom(format!("class {}: {err}", position + 1)))?;
            // serde ignores extra keys next to a unit variant (`{ family = "ball", radius =
            // 3 }`); a misspelt or unsupported parameter must never be silently dropped, so
            // every key written must survive a round trip.
            let known = Value::try_from(&family)
                .ok()
                .and_then(|v| v.as_table().cloned())
                .unwrap_or_default();
            if let Some(extra) = concrete.keys().find(|k| !known.contains_key(*k)) {
                return Err(D::Error::custom(format!(
                    "class {}: unknown field `{extra}` for family {}",
                    position + 1,
                    family.label()
                )));
            }
            out.push(family);
        }
    }
    Ok(out)
}

/// The Betti vectors of a `betti = [...]` class: entries are integers or `[lo, hi]`.
fn betti_vectors(table: &toml::Table) -> Result<Vec<Vec<u64>>, String> {
    if let Some(extra) = table.keys().find(|k| *k != "betti" && *k != "family") {
        return Err(format!(
            "unknown field `{extra}` next to `betti` (a class is either a Betti vector or a family)"
        ));
    }
    if let Some(family) = table.get("family") {
        if family.as_str() != Some("betti") {
            return Err(format!(
                "`betti` and `family = {family}` together: a class is either a Betti vector or a family"
            ));
        }
    }
    let Some(Value::Array(entries)) = table.get("betti") else {
        return Err("`betti` must be a list of b0..b(d-1), e.g. betti = [1, 2, 1, 0]".into());
    };
    if entries.is_empty() || entries.len() > 4 {
        return Err(format!(
            "`betti` has {} entries; give b0..b(d-1): 2 to 4 entries",
            entries.len()
        ));
    }
    let mut vectors = vec![Vec::new()];
    for (k, entry) in entries.iter().enumerate() {
        let (lo, hi) = match entry {
            Value::Integer(n) => (*n, *n),
            Value::Array(pair) => match pair.as_slice() {
                [Value::Integer(lo), Value::Integer(hi)] => (*lo, *hi),
                _ => return Err(format!("betti entry b{k}: a range is [lo, hi] of integers")),
            },
            other => {
                return Err(format!(
                    "betti entry b{k}: expected an integer or [lo, hi], found {}",
                    other.type_str()
                ))
            }
        };
        if lo < 0 || hi > 64 || lo > hi {
            return Err(format!(
                "betti entry b{k}: [{lo}, {hi}] must be a non-empty range within 0..=64"
            ));
        }
        if vectors.len().saturating_mul((hi - lo + 1) as usize) > MAX_EXPANSION {
            return Err(format!("expands into more than {MAX_EXPANSION} classes"));
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
fn alternatives(value: &Value) -> Result<Vec<Value>, String> {
    let Value::Array(items) = value else {
        return Ok(vec![value.clone()]);
    };
    if items.iter().all(|v| v.is_str()) && !items.is_empty() {
        return Ok(items.clone());
    }
    if let [Value::Integer(lo), Value::Integer(hi)] = items.as_slice() {
        if lo > hi {
            return Err(format!("range [{lo}, {hi}] is empty"));
        }
        if hi - lo >= MAX_EXPANSION as i64 {
            return Err(format!("range [{lo}, {hi}] is too long"));
        }
        return Ok((*lo..=*hi).map(Value::Integer).collect());
    }
    Ok(vec![value.clone()])
}

fn expand_table(table: toml::Table) -> Result<Vec<toml::Table>, String> {
    let mut combos = vec![toml::Table::new()];
    for (key, value) in table {
        let options = alternatives(&value)?;
        if combos.len().saturating_mul(options.len()) > MAX_EXPANSION {
            return Err(format!("expands into more than {MAX_EXPANSION} classes"));
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

    fn expanded(text: &str) -> Vec<Family> {
        #[derive(Deserialize)]
        struct Wrapper {
            #[serde(deserialize_with = "expand")]
            classes: Vec<Family>,
        }
        toml::from_str::<Wrapper>(text).unwrap().classes
    }

    #[test]
    fn extra_keys_on_unit_families_are_refused() {
        #[derive(Deserialize, Debug)]
        #[allow(dead_code)]
        struct Wrapper {
            #[serde(deserialize_with = "expand")]
            classes: Vec<Family>,
        }
        let err =
            toml::from_str::<Wrapper>("[[classes]]\nfamily = \"ball\"\nradius = 3\n").unwrap_err();
        assert!(err.message().contains("unknown field `radius`"), "{err}");
    }

    #[test]
    fn betti_vectors_expand_their_ranges() {
        let betti = |v: &[u64]| Family::Betti { betti: v.to_vec() };
        assert_eq!(
            expanded("[[classes]]\nbetti = [1, 2, 1, 0]\n"),
            vec![betti(&[1, 2, 1, 0])]
        );
        // Two integers are a vector, not a range: b0 = 1, b1 = 2.
        assert_eq!(
            expanded("[[classes]]\nbetti = [1, 2]\n"),
            vec![betti(&[1, 2])]
        );
        assert_eq!(
            expanded("[[classes]]\nfamily = \"betti\"\nbetti = [1, [0, 2], 0]\n"),
            vec![betti(&[1, 0, 0]), betti(&[1, 1, 0]), betti(&[1, 2, 0])]
        );
        #[derive(Deserialize, Debug)]
        #[allow(dead_code)]
        struct Wrapper {
            #[serde(deserialize_with = "expand")]
            classes: Vec<Family>,
        }
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
        ] {
            let err = toml::from_str::<Wrapper>(&format!("[[classes]]\n{text}\n")).unwrap_err();
            assert!(err.message().contains(needle), "{text}: {err}");
        }
    }

    #[test]
    fn ranges_and_lists_expand() {
        let classes =
            expanded("[[classes]]\nfamily = \"connected_sum\"\ng = [0, 2]\nh = 1\ni = 0\nj = 0\n");
        assert_eq!(classes.len(), 3);
        assert_eq!(
            classes[2],
            Family::ConnectedSum {
                g: 2,
                h: 1,
                i: 0,
                j: 0
            }
        );
        let classes =
            expanded("[[classes]]\nfamily = \"knot\"\nknot = [\"trefoil\", \"figure_eight\"]\n");
        assert_eq!(classes.len(), 2);
        let classes = expanded("[[classes]]\nfamily = [\"ball\", \"handle\"]\n");
        assert_eq!(classes, vec![Family::Ball, Family::Handle]);
    }
}
