//! The class table stored as `DIR/classes.json`: what every `KEY.cls` value means, and a
//! second, topology-only class index.
//!
//! `KEY.cls` is the sample's **stratum**: one cell of the manifest's balanced design
//! (class x mode x components x hypervolume bin). Two strata can share a Betti vector (a
//! ball embedded and a ball carved, or one family in two bins), so `cls` is the right target
//! for "which construction made this" and the wrong one for "which topology is this". The
//! **topology class** numbers the distinct (Betti vector, knot type) pairs, in order of first
//! appearance over the strata: train a classifier that must see holes (and knots) on it.
//!
//! The table is a pure function of the plan (`bettimill_plan::Plan::class_table`), so it is
//! equal bytes on every machine; `index.json` lists its size and blake3 like every other file
//! of the directory.

use serde::{Deserialize, Serialize};

/// Value of [`ClassTable::format`] written by this version.
pub const CLASS_TABLE_FORMAT: u32 = 1;

/// The contents of `classes.json`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassTable {
    /// Always [`CLASS_TABLE_FORMAT`] when written by this version.
    pub format: u32,
    /// Number of `cls` values (strata).
    pub classes: usize,
    /// Number of topology classes.
    pub topology_classes: usize,
    /// One entry per `cls` value, in `cls` order.
    pub strata: Vec<StratumClass>,
    /// One entry per topology class, in `topology_class` order.
    pub topology: Vec<TopologyClass>,
}

/// What one `KEY.cls` value means.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StratumClass {
    /// The value stored as `KEY.cls` (and `class_index` in `KEY.json`).
    pub cls: usize,
    /// The stratum's name, as `class_label` in `KEY.json`.
    pub name: String,
    /// The manifest class's construction family (one copy of it).
    pub family: String,
    /// `embed` (objects in empty space) or `carve` (cavities in a solid cube).
    pub mode: String,
    /// Copies of the class object in each sample.
    pub components: u32,
    /// Inclusive foreground voxel bounds `[lo, hi]` of the samples, if binned.
    pub hypervolume_bin: Option<(u64, u64)>,
    /// Betti numbers over Z/2 of every sample of the stratum.
    pub betti: Vec<u64>,
    /// Knot or link type (as `knot_type` in `KEY.json`; `"none"` when there is none).
    pub knot_type: String,
    /// The stratum's topology class (an index into [`ClassTable::topology`]).
    pub topology_class: usize,
    /// Samples of the stratum in the whole dataset.
    pub samples: u64,
}

/// One distinct topology: a Betti vector and a knot type.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TopologyClass {
    /// Position in [`ClassTable::topology`].
    pub topology_class: usize,
    /// Betti numbers over Z/2.
    pub betti: Vec<u64>,
    /// Knot or link type (`"none"` when there is none).
    pub knot_type: String,
    /// The `cls` values of this topology, ascending.
    pub strata: Vec<usize>,
    /// Samples of this topology in the whole dataset.
    pub samples: u64,
}

impl ClassTable {
    /// Builds the table from the strata in `cls` order: topology classes are numbered in
    /// order of first appearance. `strata[i].cls` must be `i`; `topology_class` of the
    /// entries is filled in here.
    pub fn new(mut strata: Vec<StratumClass>) -> ClassTable {
        let mut topology: Vec<TopologyClass> = Vec::new();
        for stratum in &mut strata {
            let found = topology
                .iter()
                .position(|t| t.betti == stratum.betti && t.knot_type == stratum.knot_type);
            let class = match found {
                Some(class) => class,
                None => {
                    topology.push(TopologyClass {
                        topology_class: topology.len(),
                        betti: stratum.betti.clone(),
                        knot_type: stratum.knot_type.clone(),
                        strata: Vec::new(),
                        samples: 0,
                    });
                    topology.len() - 1
                }
            };
            stratum.topology_class = class;
            topology[class].strata.push(stratum.cls);
            topology[class].samples += stratum.samples;
        }
        ClassTable {
            format: CLASS_TABLE_FORMAT,
            classes: strata.len(),
            topology_classes: topology.len(),
            strata,
            topology,
        }
    }

    /// The file's bytes: pretty JSON and a newline.
    pub fn to_json_bytes(&self) -> Vec<u8> {
        let mut json = serde_json::to_vec_pretty(self).expect("class tables serialise");
        json.push(b'\n');
        json
    }

    /// The topology class of a `cls` value, if it exists.
    pub fn topology_class_of(&self, cls: usize) -> Option<usize> {
        self.strata.get(cls).map(|s| s.topology_class)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stratum(cls: usize, betti: &[u64], knot: &str, samples: u64) -> StratumClass {
        StratumClass {
            cls,
            name: format!("s{cls}"),
            family: "ball".into(),
            mode: "embed".into(),
            components: 1,
            hypervolume_bin: None,
            betti: betti.to_vec(),
            knot_type: knot.into(),
            topology_class: usize::MAX,
            samples,
        }
    }

    #[test]
    fn topology_classes_merge_equal_betti_and_knot_in_order_of_first_appearance() {
        let table = ClassTable::new(vec![
            stratum(0, &[1, 1, 0], "none", 3),
            stratum(1, &[1, 0, 0], "none", 2),
            stratum(2, &[1, 1, 0], "trefoil", 4),
            stratum(3, &[1, 1, 0], "none", 5),
        ]);
        assert_eq!((table.classes, table.topology_classes), (4, 3));
        let of: Vec<usize> = table.strata.iter().map(|s| s.topology_class).collect();
        assert_eq!(of, [0, 1, 2, 0]);
        assert_eq!(table.topology[0].strata, [0, 3]);
        assert_eq!(table.topology[0].samples, 8);
        assert_eq!(table.topology[2].knot_type, "trefoil");
        assert_eq!(table.topology_class_of(3), Some(0));
        assert_eq!(table.topology_class_of(4), None);
        let back: ClassTable = serde_json::from_slice(&table.to_json_bytes()).unwrap();
        assert_eq!(back, table);
    }
}
