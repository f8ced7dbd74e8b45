//! CPU time from `/proc`, shared by the examples that time stages.

/// CPU seconds (user + system) from a `/proc/.../stat` file: `/proc/self/stat` for the
/// whole process, `/proc/thread-self/stat` for the calling thread alone.
pub fn cpu_seconds(stat_file: &str) -> f64 {
    let stat = std::fs::read_to_string(stat_file).unwrap_or_default();
    let fields: Vec<&str> = stat
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}
