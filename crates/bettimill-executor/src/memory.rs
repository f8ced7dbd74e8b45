//! The memory one worker may use, read from the machine: `--max-memory` when given, else
//! inside a Slurm job its allocation (and the job's cgroup limit), else a share of
//! MemAvailable. The estimate it is compared with is the plan's pure model
//! (`bettimill_plan::memory`); this module is the one place that reads the machine's limit.

use bettimill_env::EnvVars;
use bettimill_plan::memory::{human_bytes, MemoryError};
use bettimill_plan::Plan;

/// The share of /proc/meminfo's MemAvailable that the default `--max-memory` hands out.
pub const DEFAULT_MEMORY_SHARE: f64 = 0.8;

/// The memory one worker may use: `--max-memory` if given, else inside a Slurm job its
/// allocation (`job_memory_limit`), else
/// [`DEFAULT_MEMORY_SHARE`] of MemAvailable divided among `workers`; `None` when neither
/// is known (no /proc/meminfo: nothing is refused). With the words saying where it came
/// from, for messages.
pub fn memory_limit(max_memory: Option<u64>, workers: u64) -> Option<(u64, String)> {
    if let Some(limit) = max_memory {
        return Some((limit, format!("--max-memory {}", human_bytes(limit))));
    }
    if let Some(job) = job_memory_limit(workers) {
        return Some(job);
    }
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let available_kib: u64 = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    let workers = workers.max(1);
    let limit = (available_kib as f64 * 1024.0 * DEFAULT_MEMORY_SHARE / workers as f64) as u64;
    Some((
        limit,
        format!(
            "the default: {:.0}% of MemAvailable {}{}; set --max-memory to change it",
            DEFAULT_MEMORY_SHARE * 100.0,
            human_bytes(available_kib * 1024),
            if workers == 1 {
                String::new()
            } else {
                format!(" / {workers} workers")
            }
        ),
    ))
}

/// Refuses `plan` when one worker running `threads` samples at once would need more than
/// the memory limit (see [`memory_limit`]).
pub fn check(
    plan: &Plan,
    max_memory: Option<u64>,
    workers: u64,
    threads: u64,
) -> Result<(), Box<MemoryError>> {
    if let Some((limit, origin)) = memory_limit(max_memory, workers) {
        bettimill_plan::memory::check(plan, threads, limit, &origin)?;
    }
    Ok(())
}

/// The memory limit of the Slurm job this process runs in, divided among `workers`, with
/// the words saying where it came from; `None` outside a Slurm job (or when the job sets
/// no memory). An array task on a shared node must stay within its allocation, not the
/// node's MemAvailable: the allocation is `SLURM_MEM_PER_NODE` (MiB), or
/// `SLURM_MEM_PER_CPU` x `SLURM_CPUS_ON_NODE`, and the job's cgroup `memory.max` when it
/// sets a lower one.
fn job_memory_limit(workers: u64) -> Option<(u64, String)> {
    job_memory_limit_from(&bettimill_env::var, cgroup_memory_max(), workers)
}

/// [`job_memory_limit`] from an environment and a cgroup limit (bytes, and the file).
fn job_memory_limit_from(
    env: &dyn Fn(&str) -> Option<String>,
    cgroup: Option<(u64, String)>,
    workers: u64,
) -> Option<(u64, String)> {
    let mebibytes = |name: &str| -> Option<u64> {
        let text = env(name)?;
        let text = text.trim();
        text.strip_suffix('M')
            .unwrap_or(text)
            .parse::<u64>()
            .ok()
            .filter(|&n| n > 0)
    };
    let slurm = if let Some(per_node) = mebibytes(EnvVars::SLURM_MEM_PER_NODE) {
        let bytes = per_node.saturating_mul(1 << 20);
        Some((bytes, format!("SLURM_MEM_PER_NODE {}", human_bytes(bytes))))
    } else if let Some(per_cpu) = mebibytes(EnvVars::SLURM_MEM_PER_CPU) {
        let cpus = env(EnvVars::SLURM_CPUS_ON_NODE)
            .and_then(|c| c.trim().parse::<u64>().ok())
            .filter(|&c| c > 0)
            .unwrap_or(1);
        let bytes = per_cpu.saturating_mul(1 << 20).saturating_mul(cpus);
        Some((
            bytes,
            format!(
                "SLURM_MEM_PER_CPU {} x SLURM_CPUS_ON_NODE {cpus}",
                human_bytes(per_cpu << 20)
            ),
        ))
    } else {
        None
    };
    let in_job = slurm.is_some() || env(EnvVars::SLURM_JOB_ID).is_some();
    if !in_job {
        return None;
    }
    let cgroup = cgroup.map(|(bytes, file)| {
        (
            bytes,
            format!("the job's cgroup limit {file} {}", human_bytes(bytes)),
        )
    });
    let (limit, source) = match (slurm, cgroup) {
        (Some(s), Some(c)) => {
            if c.0 < s.0 {
                c
            } else {
                s
            }
        }
        (Some(s), None) => s,
        (None, Some(c)) => c,
        (None, None) => return None,
    };
    let workers = workers.max(1);
    Some((
        limit / workers,
        format!(
            "the Slurm job's memory: {source}{}; set --max-memory to change it",
            if workers == 1 {
                String::new()
            } else {
                format!(" / {workers} workers")
            }
        ),
    ))
}

/// The cgroup v2 `memory.max` of this process, when it sets one (not `max`).
fn cgroup_memory_max() -> Option<(u64, String)> {
    let cgroups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let relative = cgroups.lines().find_map(|l| l.strip_prefix("0::"))?;
    let file = format!(
        "/sys/fs/cgroup{}/memory.max",
        relative.trim_end_matches('/')
    );
    let text = std::fs::read_to_string(&file).ok()?;
    let bytes = text.trim().parse::<u64>().ok()?;
    Some((bytes, file))
}

#[cfg(test)]
mod tests {
    use super::job_memory_limit_from;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |name| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn outside_slurm_there_is_no_job_limit_even_with_a_cgroup() {
        assert_eq!(
            job_memory_limit_from(&env(&[]), Some((1 << 30, "f".into())), 1),
            None
        );
    }

    #[test]
    fn slurm_mem_per_node_is_the_limit_and_is_named() {
        let (limit, source) =
            job_memory_limit_from(&env(&[("SLURM_MEM_PER_NODE", "4096")]), None, 1).unwrap();
        assert_eq!(limit, 4096 << 20);
        assert!(source.contains("SLURM_MEM_PER_NODE 4.0 GiB"), "{source}");
        let (limit, source) =
            job_memory_limit_from(&env(&[("SLURM_MEM_PER_NODE", "4096")]), None, 4).unwrap();
        assert_eq!(limit, 1024 << 20);
        assert!(source.contains("/ 4 workers"), "{source}");
    }

    #[test]
    fn slurm_mem_per_cpu_is_multiplied_by_the_cpus_on_the_node() {
        let vars = [("SLURM_MEM_PER_CPU", "1000"), ("SLURM_CPUS_ON_NODE", "3")];
        let (limit, source) = job_memory_limit_from(&env(&vars), None, 1).unwrap();
        assert_eq!(limit, 3000 << 20);
        assert!(
            source.contains("SLURM_MEM_PER_CPU") && source.contains("x SLURM_CPUS_ON_NODE 3"),
            "{source}"
        );
    }

    #[test]
    fn a_lower_cgroup_limit_wins_inside_a_job() {
        let vars = [("SLURM_JOB_ID", "7"), ("SLURM_MEM_PER_NODE", "4096")];
        let cgroup = Some((1 << 30, "/sys/fs/cgroup/job/memory.max".to_string()));
        let (limit, source) = job_memory_limit_from(&env(&vars), cgroup.clone(), 1).unwrap();
        assert_eq!(limit, 1 << 30);
        assert!(source.contains("/sys/fs/cgroup/job/memory.max"), "{source}");
        let (limit, _) = job_memory_limit_from(&env(&[("SLURM_JOB_ID", "7")]), cgroup, 1).unwrap();
        assert_eq!(limit, 1 << 30);
        // A job without a memory setting or cgroup limit has none.
        assert_eq!(
            job_memory_limit_from(&env(&[("SLURM_JOB_ID", "7")]), None, 1),
            None
        );
    }
}
