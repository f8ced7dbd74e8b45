//! The plan's reach estimate against real builds: a bin that ends just past where the plan
//! says shrinking stops (or starts just short of where growth stops) plans and every one
//! of its samples is built, and a bin just beyond it is refused, for thin phases with
//! holes and voids in 2D, 3D and 4D, in both modes, and for tunnels.

use bettimill_plan::Plan;
use bettimill_sample::make_sample;
use std::path::Path;

/// Which end of the reach a case puts its bin at.
#[derive(Clone, Copy)]
enum End {
    Lowest,
    Highest,
}

/// A manifest of one class whose one bin holds the voxel counts `lo..hi` (half-open).
fn manifest(dim: u32, side: u32, mode: &str, class: &str, lo: u64, hi: u64) -> String {
    format!(
        "schema_version = 1\nname = \"reach\"\ndimension = {dim}\nside = {side}\n\
         mode = \"{mode}\"\nsamples = 6\nshard_size = 6\nseed = 11\n\n\
         [hypervolume]\nunit = \"voxels\"\nbins = [[{lo}, {hi}]]\n\n[[classes]]\n{class}\n"
    )
}

fn plan(text: &str) -> Result<Plan, String> {
    Plan::parse(text, Path::new("reach.toml")).map_err(|err| err.to_string())
}

/// Plans a bin just inside `end` of the class's reach and builds every sample, then plans
/// a bin just beyond it and expects the refusal to name the count that works.
fn check(dim: u32, side: u32, mode: &str, class: &str, end: End) {
    let inside = u64::from(side - 2).pow(dim);
    let wide = plan(&manifest(dim, side, mode, class, 1, inside + 1)).unwrap();
    let reach = wide.reach(&wide.strata[0]);
    let (lo, hi, beyond) = match end {
        // Samples stop where shrinking does, so the bin must end at or above it.
        End::Lowest => (
            reach.lowest.saturating_sub(20).max(1),
            reach.lowest + 2,
            (reach.lowest.saturating_sub(20).max(1), reach.lowest),
        ),
        End::Highest => (
            reach.highest - 1,
            inside + 1,
            (reach.highest + 1, inside + 1),
        ),
    };
    let text = manifest(dim, side, mode, class, lo, hi);
    let accepted = plan(&text).unwrap_or_else(|err| panic!("{class} {lo}-{hi}: {err}"));
    for index in 0..accepted.samples {
        let task = accepted.task(index).unwrap();
        let sample = make_sample(&accepted, &task)
            .unwrap_or_else(|err| panic!("{class} {mode} {dim}D bin {lo}-{hi}: {err}"));
        assert!((lo..hi).contains(&sample.label.hypervolume));
    }
    let refused = plan(&manifest(dim, side, mode, class, beyond.0, beyond.1)).unwrap_err();
    assert!(refused.contains("cannot reach its bin"), "{refused}");
    let works = match end {
        End::Lowest => format!("a bin must end above {} voxels", reach.lowest),
        End::Highest => format!("a bin must start at or below {} voxels", reach.highest),
    };
    assert!(refused.contains(&works), "{refused}");
}

#[test]
fn a_thin_loop_s_bin_builds_and_one_below_it_is_refused() {
    check(2, 32, "embed", "family = \"handle\"", End::Lowest);
    check(3, 24, "embed", "family = \"handle\"", End::Lowest);
    check(
        2,
        32,
        "embed",
        "family = \"scene\"\nobjects = [{ family = \"ball\" }, { family = \"handle\" }]",
        End::Lowest,
    );
}

#[test]
fn a_thin_shell_s_bin_builds_and_one_below_it_is_refused() {
    check(2, 32, "embed", "family = \"shell\"", End::Lowest);
    check(3, 24, "embed", "family = \"shell\"", End::Lowest);
    check(4, 16, "embed", "family = \"shell\"", End::Lowest);
    check(4, 16, "embed", "family = \"s2_x_b2\"", End::Lowest);
    check(3, 26, "embed", "family = \"torus_shell\"", End::Lowest);
}

#[test]
fn a_thin_cavity_s_bin_builds_and_one_above_it_is_refused() {
    check(2, 32, "carve", "family = \"shell\"", End::Highest);
    check(3, 24, "carve", "family = \"shell\"", End::Highest);
    check(4, 16, "carve", "family = \"shell\"", End::Highest);
}

#[test]
fn a_tunnel_s_bin_builds_and_one_above_it_is_refused() {
    check(
        2,
        32,
        "carve",
        "family = \"tunnel\"\nintervals = 1",
        End::Highest,
    );
    check(
        3,
        24,
        "carve",
        "family = \"tunnel\"\nintervals = 1",
        End::Highest,
    );
    check(
        4,
        16,
        "carve",
        "family = \"tunnel\"\nintervals = 2",
        End::Highest,
    );
}

#[test]
fn a_carved_handle_keeps_a_sheet_through_it() {
    check(3, 24, "carve", "family = \"handle\"", End::Lowest);
}
