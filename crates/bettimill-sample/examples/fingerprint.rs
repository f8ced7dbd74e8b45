//! Makes samples of a manifest on one thread, as a DataLoader worker does, and prints a
//! fingerprint of each sample's fields (FNV-1a over every field's name and bytes) and of
//! all of them: two builds of the code make the same samples exactly when the lines agree.
//! Also a steady target for `valgrind --tool=callgrind` (nothing here but the samples).
//! Usage: `cargo run --release -p bettimill-sample --example fingerprint -- MANIFEST [N]`.

// An example for people: printing is its purpose (only library code must not print).
#![allow(clippy::print_stdout, clippy::print_stderr)]
use bettimill_plan::Plan;
use bettimill_sample::make_sample;
use std::path::Path;

/// FNV-1a, 64 bits, continued from `hash`.
fn fnv(mut hash: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
    hash
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: fingerprint MANIFEST [N]");
    let text = std::fs::read_to_string(&path).expect("read the manifest");
    let plan = Plan::parse(&text, Path::new(&path)).expect("a valid manifest");
    let n: u64 = args
        .next()
        .map_or(plan.samples, |s| s.parse().expect("N is a count"));
    // Inside a pool of one thread, as the Python package makes a worker's samples.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool of one thread");
    let mut all = 0xcbf2_9ce4_8422_2325u64;
    for index in 0..n.min(plan.samples) {
        let task = plan.task(index).expect("a planned sample");
        let sample = pool
            .install(|| make_sample(&plan, &task))
            .expect("a sample");
        let mut hash = 0xcbf2_9ce4_8422_2325u64;
        for (name, bytes) in sample.fields() {
            hash = fnv(hash, name.as_bytes());
            hash = fnv(hash, &bytes);
        }
        all = fnv(all, &hash.to_le_bytes());
        println!("{} {} {hash:016x}", task.key, sample.label.class_label);
    }
    println!("all {all:016x}");
}
