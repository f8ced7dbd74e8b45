//! `cargo run --release --example betti -- IMAGE.npy [MORE.npy ...]`: prints one JSON line
//! per image, `{"path":..,"betti":[..],"euler":N,"seconds":S}`, timing only the homology
//! (not the file read). benches/compare_peers.py uses it when the `bettimill` CLI is absent.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]

use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        return Err("usage: betti IMAGE.npy [MORE.npy ...]".into());
    }
    for path in paths {
        let image = bettimill_grid::npy::read_path(Path::new(&path), false)?.image;
        let start = Instant::now();
        let topology = bettimill_homology::try_topology_owned(image)?;
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "{{\"path\":{},\"betti\":{},\"euler\":{},\"seconds\":{seconds:.6}}}",
            serde_json::to_string(&path)?,
            serde_json::to_string(&topology.betti)?,
            topology.euler
        );
    }
    Ok(())
}
