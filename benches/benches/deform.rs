//! Placeholder until the kernel's benchmarks are written.
fn main() {}
