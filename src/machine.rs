//! What this machine offers a run beyond its cores: the memory a new allocation can get.
//! (The free disk space is the store's concern: [`crate::store::run::free_bytes`].)
//!
//! Why ask: an allocation the machine cannot serve aborts the process with no message a
//! physicist can act on. A run of N = 20000 disks with all D = 80000 vectors needs 150 GB
//! for its tangent vectors alone; it is refused up front with the way out (`--vectors k`).

/// Bytes a new allocation can get now: the kernel's MemAvailable, or less where a control
/// group (a batch job's allocation) limits the process. None where it cannot be found out.
pub fn available_memory() -> Option<u64> {
    if let Some(fake) = crate::store::fault::fake_available_memory() {
        return Some(fake);
    }
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let available = meminfo.lines().find_map(|l| l.strip_prefix("MemAvailable:"))?.trim().strip_suffix("kB")?.trim().parse::<u64>().ok()? * 1024;
    Some(cgroup_headroom().map_or(available, |h| h.min(available)))
}

/// The memory this process's control group may still take: the least, over the group and
/// the groups above it (a batch system puts the limit on the job, the process in a step or
/// task below it), of the limit minus what is in use. The inactive file cache a group holds
/// is not counted as in use: the kernel reclaims it before it refuses an allocation, and a
/// stage that has just written its segments would otherwise see no room at all. None
/// without a limit.
fn cgroup_headroom() -> Option<u64> {
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    headroom_in(&own, std::path::Path::new("/sys/fs/cgroup"))
}

/// [`cgroup_headroom`] from the text of /proc/self/cgroup and the cgroup file systems'
/// root (v2: ROOT/PATH/memory.max, memory.current, memory.stat; v1: ROOT/memory/PATH/
/// memory.limit_in_bytes, memory.usage_in_bytes, memory.stat).
fn headroom_in(own: &str, root: &std::path::Path) -> Option<u64> {
    let read = |p: &std::path::Path| std::fs::read_to_string(p).ok();
    let number = |p: &std::path::Path| read(p).and_then(|s| s.trim().parse::<u64>().ok());
    let stat = |p: &std::path::Path, key: &str| read(p)?.lines().find_map(|l| l.strip_prefix(key)?.strip_prefix(' ')?.trim().parse::<u64>().ok());
    let mut least: Option<u64> = None;
    for line in own.lines() {
        // v2: "0::/path"; v1: "N:memory:/path" (or a list of controllers with memory).
        let mut parts = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) = (parts.next(), parts.next(), parts.next()) else { continue };
        let (base, limit, usage, inactive) = if controllers.is_empty() {
            (root.to_path_buf(), "memory.max", "memory.current", "inactive_file")
        } else if controllers.split(',').any(|c| c == "memory") {
            (root.join("memory"), "memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file")
        } else {
            continue;
        };
        // The group and each group above it, up to the root (which has no limit file).
        let mut dir = std::path::PathBuf::from(path.trim_start_matches('/'));
        loop {
            let here = base.join(&dir);
            // "max" (v2) does not parse: no limit. v1 writes a huge number for none.
            if let (Some(limit), Some(usage)) = (number(&here.join(limit)), number(&here.join(usage)))
                && limit < 1 << 60
            {
                let cache = stat(&here.join("memory.stat"), inactive).unwrap_or(0);
                let room = limit.saturating_sub(usage.saturating_sub(cache));
                least = Some(least.map_or(room, |l| l.min(room)));
            }
            if !dir.pop() {
                break;
            }
        }
    }
    least
}

#[cfg(test)]
mod tests {
    #[test]
    fn available_memory_is_found_on_linux() {
        if cfg!(target_os = "linux") {
            let bytes = super::available_memory().expect("MemAvailable in /proc/meminfo");
            assert!(bytes > 1 << 20, "{bytes}");
        }
    }

    /// The limit of a group above the process's counts (SLURM limits the job, the process
    /// runs in a step below it), and inactive file cache is room, not use.
    #[test]
    fn the_least_headroom_of_the_group_and_those_above_it_counts() {
        let root = std::env::temp_dir().join(format!("clv-cgroup-{}", std::process::id()));
        let job = root.join("job_7");
        let task = job.join("step_0/task_0");
        std::fs::create_dir_all(&task).unwrap();
        let write = |dir: &std::path::Path, files: &[(&str, &str)]| files.iter().for_each(|(f, t)| std::fs::write(dir.join(f), t).unwrap());
        write(&task, &[("memory.max", "max\n"), ("memory.current", "100\n")]);
        write(&job, &[("memory.max", "1000000\n"), ("memory.current", "600000\n"), ("memory.stat", "anon 200000\ninactive_file 300000\nactive_file 100000\n")]);
        // v2: 1e6 - (6e5 - 3e5) at the job; the task's "max" is no limit.
        assert_eq!(super::headroom_in("0::/job_7/step_0/task_0\n", &root), Some(700_000));
        write(&task, &[("memory.max", "50000\n"), ("memory.current", "20000\n")]);
        assert_eq!(super::headroom_in("0::/job_7/step_0/task_0\n", &root), Some(30_000), "the tighter group below");
        assert_eq!(super::headroom_in("0::/elsewhere\n", &root), None);
        // v1, with the memory controller among others.
        let v1 = root.join("memory/slurm/uid_0/job_7");
        std::fs::create_dir_all(&v1).unwrap();
        write(&v1, &[("memory.limit_in_bytes", "2000000\n"), ("memory.usage_in_bytes", "1500000\n"), ("memory.stat", "cache 900000\ntotal_inactive_file 800000\n")]);
        write(&root.join("memory"), &[("memory.limit_in_bytes", "9223372036854771712\n"), ("memory.usage_in_bytes", "5\n")]);
        assert_eq!(super::headroom_in("4:cpu,cpuacct:/x\n3:memory:/slurm/uid_0/job_7\n", &root), Some(1_300_000));
        std::fs::remove_dir_all(&root).unwrap();
    }
}
