//! Expansion of `[[classes]]` entries with parameter ranges into concrete classes.
//!
//! A class table may give an integer parameter as an inclusive range `[lo, hi]`, or a
//! string parameter as a list of strings; the entry then stands for every combination, keys taken in
//! alphabetical order (later keys vary fastest). Arrays of tables (the
//! `objects` of a scene) are never expanded. Each concrete table is then read as a
//! `bettimill_shapes::Family`, so unknown fields and wrong types are still errors.

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
