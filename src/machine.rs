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

/// The memory this process's control group may still take (cgroup v2: memory.max minus
/// memory.current; v1: limit_in_bytes minus usage_in_bytes); None without a limit.
fn cgroup_headroom() -> Option<u64> {
    let read = |p: &str| std::fs::read_to_string(p).ok().and_then(|s| s.trim().parse::<u64>().ok());
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    for line in own.lines() {
        // v2: "0::/path"; v1: "N:memory:/path" (or a list of controllers with memory).
        let mut parts = line.splitn(3, ':');
        let (_, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
        let (limit, usage) = if controllers.is_empty() {
            (format!("/sys/fs/cgroup{path}/memory.max"), format!("/sys/fs/cgroup{path}/memory.current"))
        } else if controllers.split(',').any(|c| c == "memory") {
            (format!("/sys/fs/cgroup/memory{path}/memory.limit_in_bytes"), format!("/sys/fs/cgroup/memory{path}/memory.usage_in_bytes"))
        } else {
            continue;
        };
        // "max" (v2) does not parse: no limit. v1 writes a huge number for none.
        if let (Some(limit), Some(usage)) = (read(&limit), read(&usage))
            && limit < 1 << 60
        {
            return Some(limit.saturating_sub(usage));
        }
    }
    None
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
}
