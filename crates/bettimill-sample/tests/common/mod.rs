//! Helpers shared by this crate's integration tests.

use bettimill_plan::Plan;
use bettimill_sample::make_sample;

/// The stored fields of the plan's first `count` samples, made on a pool of `threads`.
pub fn fields_on_threads(plan: &Plan, count: usize, threads: usize) -> Vec<Vec<(String, Vec<u8>)>> {
    let tasks: Vec<_> = plan
        .shards()
        .flat_map(|s| plan.shard_tasks(&s))
        .take(count)
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        tasks
            .iter()
            .map(|task| make_sample(plan, task).unwrap().fields())
            .collect()
    })
}

/// Asserts that the plan's first `count` samples are the same bytes on 1, 2 and 4 threads.
pub fn assert_same_bytes_on_any_thread_count(plan: &Plan, count: usize) {
    let one = fields_on_threads(plan, count, 1);
    assert_eq!(one, fields_on_threads(plan, count, 2), "1 vs 2 threads");
    assert_eq!(one, fields_on_threads(plan, count, 4), "1 vs 4 threads");
}
