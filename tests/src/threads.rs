//! The threads of this process as the scheduler sees them: name and policy, from /proc
//! and `sched_getscheduler(2)`. The real-time tests use it to show that no thread runs at
//! SCHED_FIFO but the ones gantry documents.

/// One thread of this process.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ThreadInfo {
    /// Kernel thread id.
    pub tid: i32,
    /// Its name (`comm`, at most 15 bytes).
    pub name: String,
    /// Its scheduling policy (`libc::SCHED_*`).
    pub policy: i32,
}

impl ThreadInfo {
    /// Whether it runs at a real-time policy (SCHED_FIFO or SCHED_RR).
    pub fn real_time(&self) -> bool {
        self.policy == libc::SCHED_FIFO || self.policy == libc::SCHED_RR
    }
}

/// Every thread of this process now (those that end while being listed are skipped).
pub fn threads() -> Vec<ThreadInfo> {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return Vec::new();
    };
    dir.filter_map(|e| {
        let tid: i32 = e.ok()?.file_name().to_str()?.parse().ok()?;
        let name = std::fs::read_to_string(format!("/proc/self/task/{tid}/comm")).ok()?;
        // SAFETY: a plain system call on a thread id.
        let policy = unsafe { libc::sched_getscheduler(tid) };
        (policy >= 0).then(|| ThreadInfo {
            tid,
            name: name.trim_end().to_string(),
            policy: policy & !libc::SCHED_RESET_ON_FORK,
        })
    })
    .collect()
}
