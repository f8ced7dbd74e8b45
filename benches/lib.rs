//! Shared helpers for the benchmarks in `benches/benches/` (kept empty until needed).
