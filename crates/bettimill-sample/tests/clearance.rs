//! A manifest's `clearance`: each sample draws its own gap width from the range, records
//! it in its label, is verified like any other, and is the same bytes on any number of
//! threads.

mod common;

use bettimill_plan::Plan;
use bettimill_sample::make_sample;
use std::collections::BTreeSet;

const MANIFEST: &str = r#"
schema_version = 1
name = "clearance"
dimension = 3
side = 32
mode = "embed"
samples = 16
shard_size = 16
seed = 5
clearance = [1, 5]

[hypervolume]
unit = "fraction"
bins = [[0.02, 0.04], [0.06, 0.1]]

[[deform]]
method = "dilate"
steps = [1, 3]

[[deform]]
method = "moves"
steps = 200

[[classes]]
family = ["handle", "shell"]

[[classes]]
family = "scene"
objects = [{ family = "ball" }, { family = "ball" }]
"#;

fn plan(text: &str) -> Plan {
    Plan::parse(text, std::path::Path::new("clearance.toml")).expect("the manifest plans")
}

#[test]
fn samples_draw_their_clearance_and_stay_verified() {
    let plan = plan(MANIFEST);
    let mut drawn = BTreeSet::new();
    for task in plan.shards().flat_map(|s| plan.shard_tasks(&s)) {
        let sample = make_sample(&plan, &task).expect("every planned sample builds");
        let stratum = &plan.strata[task.stratum];
        assert_eq!(sample.label.betti, stratum.betti, "{}", task.key);
        let clearance = sample
            .label
            .clearance
            .expect("the label records the clearance");
        assert!(clearance <= 5, "{}: {clearance}", task.key);
        drawn.insert(clearance);
    }
    assert!(drawn.len() >= 3, "one range, many widths: {drawn:?}");
}

#[test]
fn a_manifest_without_clearance_labels_none() {
    let text = MANIFEST.replace("clearance = [1, 5]\n", "");
    let plan = plan(&text);
    assert_eq!(plan.clearance, None);
    let task = plan.shard_tasks(&plan.shards().next().unwrap()).remove(0);
    assert_eq!(make_sample(&plan, &task).unwrap().label.clearance, None);
}

#[test]
fn samples_with_a_clearance_are_the_same_bytes_on_any_thread_count() {
    common::assert_same_bytes_on_any_thread_count(&plan(MANIFEST), 6);
}
