//! Unit tests of the plan: refusals that name their field, hashes, shards and dealing,
//! the class table and the analytic labels.

use super::*;
use std::path::Path;

const GOOD: &str = r#"schema_version = 1
name = "t"
dimension = 3
side = 24
mode = "embed"
samples = 10
shard_size = 4
seed = 1

[[classes]]
family = "ball"
"#;

fn plan(text: &str) -> Result<Plan, PlanError> {
    Plan::new(&Manifest::parse(text, Path::new("test.toml")).unwrap())
}

/// Asserts that planning `text` is refused at `line` of `field` with `needle` in the
/// reason.
fn check_refused(text: &str, field: &str, line: usize, needle: &str) {
    match plan(text) {
        Err(PlanError::Manifest(ManifestError::Invalid {
            line: l,
            field: f,
            reason,
            path,
        })) => {
            assert_eq!((f.as_str(), l), (field, line), "reason: {reason}");
            assert_eq!(path, Path::new("test.toml"));
            assert!(reason.contains(needle), "{reason}");
        }
        other => panic!("expected a refusal naming {field}, got {other:?}"),
    }
}

#[test]
fn auto_compression_resolves_by_array_size() {
    assert_eq!(
        plan(GOOD).unwrap().compression,
        bettimill_shard::Compression::None
    );
    let big = plan(&GOOD.replace("side = 24", "side = 128")).unwrap();
    assert_eq!(big.compression, bettimill_shard::Compression::Gzip);
    let zstd = plan(&GOOD.replace("seed = 1", "seed = 1\ncompression = \"zstd\"")).unwrap();
    assert_eq!(zstd.compression, bettimill_shard::Compression::Zstd);
}

#[test]
fn hash_ignores_comments_and_key_order() {
    let a = plan(GOOD).unwrap();
    let reordered = GOOD.replace("seed = 1\n", "").replace(
        "schema_version = 1\n",
        "schema_version = 1\nseed = 1 # the seed\n",
    );
    assert_eq!(a.manifest_hash, plan(&reordered).unwrap().manifest_hash);
    let c = plan(&GOOD.replace("seed = 1", "seed = 2")).unwrap();
    assert_ne!(a.manifest_hash, c.manifest_hash);
}

#[test]
fn a_class_that_never_fits_is_refused() {
    check_refused(
        &GOOD
            .replace("side = 24", "side = 8")
            .replace("\"ball\"", "\"handle\""),
        "classes",
        10,
        "class 1 (handle)",
    );
}

#[test]
fn more_splits_than_an_index_holds_are_refused() {
    let n = bettimill_format::MAX_INDEX_SPLITS + 1;
    let splits: String = (0..n).map(|i| format!("s{i} = 1\n")).collect();
    let text = GOOD.replace("samples = 10", &format!("samples = {n}"));
    check_refused(
        &format!("{text}\n[splits]\n{splits}"),
        "splits",
        13,
        "at most 1024",
    );
}

#[test]
fn class_errors_point_at_their_entry() {
    let two = format!("{GOOD}\n[[classes]]\nfamily = \"ball\"\nradius = 3\n");
    check_refused(&two, "classes", 13, "unknown field `radius`");
    let twice = format!("{GOOD}\n[[classes]]\nfamily = \"ball\"\n");
    check_refused(&twice, "classes", 13, "listed twice");
    let unknown = GOOD.replace("\"ball\"", "\"blob\"");
    check_refused(&unknown, "classes", 10, "unknown variant `blob`");
}

#[test]
fn a_carve_bin_below_the_solid_s_outer_layers_is_refused_by_name() {
    // A 3D side-24 ball cavity: 22^3 - 18^3 = 4816 voxels of the full cube never
    // change, 35% of the image, so a bin at 3% fails every attempt of every shard.
    let text = GOOD.replace("mode = \"embed\"", "mode = [\"embed\", \"carve\"]")
        + "\n[hypervolume]\nbins = [[0.030, 0.031], [0.4, 0.5]]\n";
    check_refused(
        &text,
        "bins",
        14,
        "stratum ball/carve/hv415-428 cannot reach",
    );
    check_refused(&text, "bins", 14, "at least 4816 foreground voxels");
    // Embed mode reaches it, and so do carved bins from the outer layers up.
    let fine = text.replace("[0.030, 0.031]", "[0.349, 0.36]");
    assert_eq!(plan(&fine).unwrap().strata.len(), 4);
    let embed = text.replace("mode = [\"embed\", \"carve\"]", "mode = \"embed\"");
    assert_eq!(plan(&embed).unwrap().strata.len(), 2);
}

#[test]
fn every_unreachable_stratum_of_a_4d_carve_manifest_is_named() {
    // The audit's 4D side-24 manifest: its lowest bin (1-3%) sat in every shard.
    let text = "schema_version = 1\nname = \"c4\"\ndimension = 4\nside = 24\n\
                mode = \"carve\"\nsamples = 8\nshard_size = 1\nseed = 5\n\
                components = [1, 2]\n\n[hypervolume]\n\
                bins = [[0.01, 0.03], [0.5, 0.6]]\n\n[[classes]]\nfamily = \"ball\"\n";
    check_refused(text, "bins", 12, "ball/carve/x1/hv3318-9953");
    check_refused(text, "bins", 12, "ball/carve/x2/hv3318-9953");
    let reachable = text.replace("[0.01, 0.03], ", "");
    assert_eq!(plan(&reachable).unwrap().strata.len(), 2);
}

#[test]
fn reach_bounds_every_preset_bin_and_stays_cheap() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../manifests");
    let manifest = Manifest::from_path(&dir.join("4d-mixed-128.toml")).unwrap();
    let plan = Plan::new(&manifest).unwrap();
    for stratum in &plan.strata {
        let (lo, hi) = stratum.hypervolume.unwrap();
        let r = stratum_reach(&manifest, stratum);
        assert!(r.lowest < lo && hi < r.highest, "{}: {r:?}", stratum.label);
    }
}

#[test]
fn shard_bytes_too_small_for_a_sample_is_refused() {
    let text = GOOD.replace("shard_size = 4", "shard_bytes = 1000");
    check_refused(&text, "shard_bytes", 7, "cannot hold one sample");
    let fits = plan(&GOOD.replace("shard_size = 4", "shard_bytes = 100000")).unwrap();
    assert_eq!(fits.shard_size, 100000 / fits.sample_bytes);
}

fn manifest(samples: u64, shard_size: u64) -> Manifest {
    let text = bettimill_manifest::DEMO_MANIFEST
        .replace("samples = 240", &format!("samples = {samples}"))
        .replace("shard_size = 40", &format!("shard_size = {shard_size}"));
    Manifest::parse(&text, Path::new("t")).unwrap()
}

#[test]
fn plans_are_reproducible() {
    let a = Plan::new(&manifest(100, 7)).unwrap();
    let b = Plan::new(&manifest(100, 7)).unwrap();
    assert_eq!(a.hash(), b.hash());
    assert_eq!(a.shard_tasks(&a.shard(3)), b.shard_tasks(&b.shard(3)));
    assert_ne!(a.hash(), Plan::new(&manifest(101, 7)).unwrap().hash());
}

#[test]
fn shards_cover_every_sample_once() {
    let plan = Plan::new(&manifest(103, 10)).unwrap();
    assert_eq!(plan.shard_count(), 11);
    let mut all: Vec<u64> = plan
        .shards()
        .flat_map(|s| plan.shard_tasks(&s))
        .map(|t| t.index)
        .collect();
    all.sort();
    assert_eq!(all, (0..103).collect::<Vec<_>>());
    assert_eq!(plan.shard(10).samples, 3);
}

#[test]
fn task_of_an_index_is_its_shard_task() {
    // Named splits of sizes that are not multiples of the shard size, so shards start
    // at split boundaries as well as every shard_size samples.
    let text = format!("{GOOD}\n[splits]\ntrain = 5\nval = 2\ntest = 3\n");
    let plan = plan(&text).unwrap();
    let mut seen = 0;
    for shard in plan.shards() {
        for task in plan.shard_tasks(&shard) {
            assert_eq!(plan.task(task.index).as_ref(), Some(&task), "{}", task.key);
            seen += 1;
        }
    }
    assert_eq!(seen, 10);
    assert_eq!(plan.task(10), None);
}

fn counts(plan: &Plan, tasks: &[SampleTask]) -> Vec<u64> {
    let mut c = vec![0u64; plan.strata.len()];
    for t in tasks {
        c[t.stratum] += 1;
    }
    c
}

#[test]
fn counting_agrees_with_the_tasks() {
    let plan = Plan::new(&manifest(97, 11)).unwrap();
    for shard in plan.shards() {
        assert_eq!(
            plan.shard_counts(&shard),
            counts(&plan, &plan.shard_tasks(&shard))
        );
    }
    assert_eq!(plan.total_counts().iter().sum::<u64>(), 97);
}

fn random_manifest(
    samples: u64,
    shard_size: u64,
    classes: usize,
    copies: u32,
    val: u64,
) -> Manifest {
    let families = ["ball", "handle", "shell", "curve"];
    let mut text = format!(
            "schema_version = 1\nname = \"r\"\ndimension = 3\nside = 64\nmode = [\"embed\", \"carve\"]\n\
             samples = {samples}\nshard_size = {shard_size}\nseed = 9\ncomponents = {:?}\n",
            (1..=copies).collect::<Vec<_>>()
        );
    if val > 0 && val < samples {
        text.push_str(&format!(
            "[splits]\ntrain = {}\nval = {val}\n",
            samples - val
        ));
    }
    for family in families.iter().take(classes) {
        text.push_str(&format!("[[classes]]\nfamily = \"{family}\"\n"));
    }
    Manifest::parse(&text, Path::new("random")).unwrap()
}

fn spread(c: &[u64]) -> u64 {
    c.iter().max().unwrap() - c.iter().min().unwrap()
}

#[test]
fn class_table_names_every_stratum_and_merges_equal_topologies() {
    let text = GOOD
            .replace("mode = \"embed\"", "mode = [\"embed\", \"carve\"]")
            .replace("seed = 1\n", "seed = 1\ncomponents = [1, 2]\n")
            + "\n[[classes]]\nfamily = \"handle\"\n\n[[classes]]\nfamily = \"knot\"\nknot = \"trefoil\"\n";
    let text = text
        .replace("side = 24", "side = 64")
        .replace("samples = 10", "samples = 50");
    let plan = plan(&text).unwrap();
    let table = plan.class_table();
    assert_eq!(table.classes, plan.strata.len());
    let total: u64 = table.strata.iter().map(|s| s.samples).sum();
    assert_eq!(total, plan.samples);
    for (entry, stratum) in table.strata.iter().zip(&plan.strata) {
        assert_eq!(entry.cls, stratum.index);
        assert_eq!(entry.betti, stratum.betti);
        assert_eq!(entry.name, stratum.label);
        let topology = &table.topology[entry.topology_class];
        assert_eq!(
            (&topology.betti, &topology.knot_type),
            (&entry.betti, &entry.knot_type)
        );
        assert!(topology.strata.contains(&entry.cls));
        // One copy of the stratum's object, whatever the component count.
        let family = &plan.strata[entry.cls].family;
        assert_eq!(
            class_with_copies(&one_copy(family, entry.components), entry.components),
            *family
        );
    }
    // A trefoil and a handle have the same Betti numbers but are different topologies.
    let knots: Vec<_> = table
        .strata
        .iter()
        .filter(|s| s.family.starts_with("knot"))
        .collect();
    assert!(!knots.is_empty());
    assert!(
        knots.iter().all(|s| s.knot_type.contains("trefoil")),
        "{knots:?}"
    );
    let handle = table
        .strata
        .iter()
        .find(|s| s.family == "handle" && s.components == 1 && s.mode == "embed")
        .unwrap();
    let knot = knots
        .iter()
        .find(|s| s.components == 1 && s.mode == "embed")
        .unwrap();
    assert_eq!(handle.betti, knot.betti);
    assert_ne!(handle.topology_class, knot.topology_class);
    // Distinct topologies are fewer than strata here (embed and carve balls differ, but
    // copies of handles in two modes repeat Betti vectors only within a mode).
    let distinct: std::collections::BTreeSet<_> = table
        .strata
        .iter()
        .map(|s| (s.betti.clone(), s.knot_type.clone()))
        .collect();
    assert_eq!(table.topology_classes, distinct.len());
}

/// A 4D side-32 manifest in both modes, four samples, with `extra` top-level lines and
/// one class of `families` (a TOML list).
fn both_modes_4d_32(extra: &str, families: &str) -> String {
    format!(
        "schema_version = 1\nname = \"t4\"\ndimension = 4\nside = 32\n\
             mode = [\"embed\", \"carve\"]\nsamples = 4\nshard_size = 4\nseed = 1\n{extra}\n\
             [[classes]]\nfamily = {families}\n"
    )
}

#[test]
fn carve_strata_with_copies_get_tubes_the_largest_copy_keeps_where_they_fit() {
    let text = &both_modes_4d_32("resolutions = [16, 8]\n", r#"["ball", "t2_x_b2"]"#);
    let floors = |text: &str| -> Vec<(String, f64)> {
        plan(text)
            .unwrap()
            .strata
            .iter()
            .map(|s| (s.label.clone(), s.tube_floor.radius()))
            .collect()
    };
    // Pooled by 2 (the largest copy, 16): (2 * 2 - 1) * sqrt(4) / 2 = 3 voxels. A
    // carved T2xB2 does not fit a 32^4 cube with 3-voxel tubes (it does with 2), so it
    // keeps the usual floor; embed mode always does.
    let s = |label: &str, floor: f64| (label.to_string(), floor);
    assert_eq!(
        floors(text),
        [
            s("ball/embed", 2.0),
            s("ball/carve", 3.0),
            s("t2_x_b2/embed", 2.0),
            s("t2_x_b2/carve", 2.0),
        ]
    );
    let without_copies = text.replace("resolutions = [16, 8]\n", "");
    assert!(floors(&without_copies).iter().all(|(_, f)| *f == 2.0));
}

#[test]
fn the_plan_decides_every_analytic_label_field_once() {
    let plan = plan(&both_modes_4d_32("", r#"["klein_bottle", "handle"]"#)).unwrap();
    let labels: Vec<_> = plan
        .strata
        .iter()
        .map(|s| {
            (
                s.label.as_str(),
                s.betti_rational.clone(),
                s.knot_type.as_str(),
            )
        })
        .collect();
    assert_eq!(
        labels,
        [
            ("klein_bottle/embed", Some(vec![1, 1, 0, 0]), "none"),
            ("klein_bottle/carve", Some(vec![1, 0, 1, 1]), "none"),
            ("handle/embed", None, "none"),
            ("handle/carve", None, "none"),
        ]
    );
    // Derived from what the hash covers, so not in it: the serialised plan has neither.
    let json = serde_json::to_string(&plan).unwrap();
    assert!(!json.contains("betti_rational") && !json.contains("knot_type"));
}

proptest::proptest! {
    #[test]
    fn balance_holds_for_random_manifests(
        samples in 1u64..300, shard_size in 1u64..40, classes in 1usize..=4,
        copies in 1u32..=3, val in 0u64..50,
    ) {
        let plan = Plan::new(&random_manifest(samples, shard_size, classes, copies, val)).unwrap();
        let mut all = Vec::new();
        for split in &plan.splits {
            let tasks: Vec<SampleTask> = plan.split_shards(&split.0)
                .flat_map(|s| plan.shard_tasks(&s)).collect();
            proptest::prop_assert!(spread(&counts(&plan, &tasks)) <= 1);
            all.extend(tasks);
        }
        for shard in plan.shards() {
            proptest::prop_assert!(spread(&plan.shard_counts(&shard)) <= 1);
        }
        proptest::prop_assert!(spread(&counts(&plan, &all)) <= 1);
        proptest::prop_assert_eq!(all.len() as u64, samples);
    }

    #[test]
    fn balance_is_exact_per_dataset_and_per_shard(samples in 1u64..400, shard_size in 1u64..60) {
        let plan = Plan::new(&manifest(samples, shard_size)).unwrap();
        let mut all = Vec::new();
        for shard in plan.shards() {
            let tasks = plan.shard_tasks(&shard);
            let c = counts(&plan, &tasks);
            proptest::prop_assert!(c.iter().max().unwrap() - c.iter().min().unwrap() <= 1);
            all.extend(tasks);
        }
        let c = counts(&plan, &all);
        proptest::prop_assert!(c.iter().max().unwrap() - c.iter().min().unwrap() <= 1);
    }
}

/// GOOD at side 256 (16 MiB a sample) with `shard` in place of `shard_size = 4` and
/// `compression`.
fn big(shard: &str, compression: &str) -> Manifest {
    let text = GOOD
        .replace("side = 24", "side = 256")
        .replace("samples = 10", "samples = 1000")
        .replace(
            "shard_size = 4",
            &format!("{shard}\ncompression = \"{compression}\""),
        );
    Manifest::parse(&text, Path::new("test.toml")).unwrap()
}

fn object_storage_refusal(manifest: &Manifest) -> Option<(String, usize, String)> {
    match Plan::new(manifest).unwrap().check_object_storage(manifest) {
        Ok(()) => None,
        Err(PlanError::Manifest(ManifestError::Invalid {
            line,
            field,
            reason,
            path,
        })) => {
            assert_eq!(path, Path::new("test.toml"));
            Some((field, line, reason))
        }
        Err(other) => panic!("expected a refusal naming the field, got {other:?}"),
    }
}

#[test]
fn shards_that_can_pass_5_gib_are_refused_for_object_storage_naming_the_largest_that_fits() {
    use bettimill_shard::object::MAX_STREAMED_OBJECT_BYTES as LIMIT;
    for compression in ["none", "gzip", "zstd"] {
        let manifest = big("shard_size = 400", compression);
        let plan = Plan::new(&manifest).unwrap();
        assert!(plan.shard_bytes_bound() > LIMIT, "{compression}");
        let (field, line, reason) = object_storage_refusal(&manifest).expect(compression);
        assert_eq!((field.as_str(), line), ("shard_size", 7), "{reason}");
        assert!(
            reason.contains("5 GiB") && reason.contains("s3://"),
            "{reason}"
        );
        // The value the message offers is the largest that fits: it passes, one more not.
        let fits: u64 = reason
            .rsplit("shard_size = ")
            .next()
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no shard_size offered: {reason}"));
        assert!((300..400).contains(&fits), "{compression}: {fits}");
        let at = big(&format!("shard_size = {fits}"), compression);
        assert_eq!(object_storage_refusal(&at), None, "{compression}");
        assert!(Plan::new(&at).unwrap().shard_bytes_bound() <= LIMIT);
        let over = big(&format!("shard_size = {}", fits + 1), compression);
        assert!(object_storage_refusal(&over).is_some(), "{compression}");
    }
    // Compressed members can outgrow their input, so the bound of a compressed shard is
    // the larger one.
    let none = Plan::new(&big("shard_size = 300", "none")).unwrap();
    let zstd = Plan::new(&big("shard_size = 300", "zstd")).unwrap();
    assert!(zstd.shard_bytes_bound() > none.shard_bytes_bound());
}

#[test]
fn shard_bytes_over_5_gib_are_refused_for_object_storage_and_the_offer_fits() {
    let manifest = big("shard_bytes = 6442450944", "none");
    let (field, line, reason) = object_storage_refusal(&manifest).unwrap();
    assert_eq!((field.as_str(), line), ("shard_bytes", 7), "{reason}");
    let offered = reason.rsplit("shard_bytes = ").next().unwrap();
    let at = big(&format!("shard_bytes = {offered}"), "none");
    assert_eq!(object_storage_refusal(&at), None, "{reason}");
    // A split smaller than the shard size makes the shards: 10 samples of 16 MiB fit.
    let small = GOOD
        .replace("side = 24", "side = 256")
        .replace("shard_size = 4", "shard_size = 100000");
    let small = Manifest::parse(&small, Path::new("test.toml")).unwrap();
    assert_eq!(object_storage_refusal(&small), None);
    // A local build has no such limit: planning alone accepts them all.
    assert!(Plan::new(&manifest).is_ok());
}

#[test]
fn the_shipped_manifests_fit_object_storage() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../manifests");
    for name in [
        "4d-mixed-128",
        "demo-2d",
        "demo-3d",
        "demo-4d",
        "paper-figures",
    ] {
        let manifest = Manifest::from_path(&dir.join(format!("{name}.toml"))).unwrap();
        let plan = Plan::new(&manifest).unwrap();
        plan.check_object_storage(&manifest)
            .unwrap_or_else(|err| panic!("{name}: {err}"));
    }
}
