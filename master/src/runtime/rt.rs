//! Making the cycle thread real-time: SCHED_FIFO at the configured priority, pinned to a
//! core, all memory locked, its stack pre-faulted — and, before any of that, a check that
//! the process may do it, naming the capability that is missing. Without the rights gantry
//! refuses to start unless the user asked for `--no-rt`.

use thiserror::Error;

use crate::config::RtSection;

/// Linux capability numbers (linux/capability.h).
const CAP_NET_RAW: u32 = 13;
const CAP_IPC_LOCK: u32 = 14;
const CAP_SYS_NICE: u32 = 23;

/// Stack the cycle thread touches once so that no page fault happens in the cycle.
const STACK_PREFAULT_BYTES: usize = 256 * 1024;

/// Why the cycle cannot run in real time.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum RtError {
    /// A capability is missing.
    #[error(
        "{what} needs {capability}, which this process does not have: run as root, or \
         `setcap {setcap}+ep` on the gantry binary (or run with --no-rt, not real time)"
    )]
    MissingCapability {
        /// What needs it.
        what: &'static str,
        /// The capability.
        capability: &'static str,
        /// Its setcap name.
        setcap: &'static str,
    },
    /// A system call failed anyway.
    #[error("{what}: {reason}")]
    Failed {
        /// What was attempted.
        what: String,
        /// The error.
        reason: String,
    },
}

/// The effective capabilities of this process (from /proc/self/status).
fn effective_capabilities() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("CapEff:"))
                .and_then(|v| u64::from_str_radix(v.trim(), 16).ok())
        })
        .unwrap_or(0)
}

fn rlimit(resource: libc::__rlimit_resource_t) -> u64 {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes one rlimit into `r`.
    if unsafe { libc::getrlimit(resource, &mut r) } == 0 {
        r.rlim_cur
    } else {
        0
    }
}

/// Checks that the process may do what `rt` asks (and open a raw socket when
/// `raw_socket`), before anything starts. Reports the first thing missing.
pub fn check(rt: &RtSection, raw_socket: bool) -> Result<(), RtError> {
    let caps = effective_capabilities();
    let has = |cap: u32| caps & (1 << cap) != 0;
    if raw_socket && !has(CAP_NET_RAW) {
        return Err(RtError::MissingCapability {
            what: "the EtherCAT raw socket",
            capability: "CAP_NET_RAW",
            setcap: "cap_net_raw",
        });
    }
    // RLIMIT_RTPRIO lets an unprivileged process use SCHED_FIFO up to its value.
    if !has(CAP_SYS_NICE) && rlimit(libc::RLIMIT_RTPRIO) < u64::from(rt.priority) {
        return Err(RtError::MissingCapability {
            what: "SCHED_FIFO for the cycle thread",
            capability: "CAP_SYS_NICE",
            setcap: "cap_sys_nice",
        });
    }
    if rt.lock_memory && !has(CAP_IPC_LOCK) && rlimit(libc::RLIMIT_MEMLOCK) != libc::RLIM_INFINITY {
        return Err(RtError::MissingCapability {
            what: "locking memory (rt.lock_memory)",
            capability: "CAP_IPC_LOCK",
            setcap: "cap_ipc_lock",
        });
    }
    Ok(())
}

/// Makes the calling thread the real-time cycle thread.
pub fn enter(rt: &RtSection) -> Result<(), RtError> {
    use thread_priority::{
        set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy,
        ThreadPriority, ThreadSchedulePolicy,
    };
    let failed = |what: String, reason: String| RtError::Failed { what, reason };
    if rt.lock_memory {
        nix::sys::mman::mlockall(
            nix::sys::mman::MlockAllFlags::MCL_CURRENT | nix::sys::mman::MlockAllFlags::MCL_FUTURE,
        )
        .map_err(|e| failed("mlockall".into(), e.to_string()))?;
    }
    if let Some(cpu) = rt.cpu {
        if !core_affinity::set_for_current(core_affinity::CoreId { id: cpu }) {
            return Err(failed(
                format!("pinning the cycle thread to CPU {cpu}"),
                "not allowed or no such CPU".into(),
            ));
        }
    }
    let priority = ThreadPriority::Crossplatform(
        rt.priority
            .try_into()
            .map_err(|_| failed("priority".into(), format!("{} is not 1..99", rt.priority)))?,
    );
    set_thread_priority_and_policy(
        thread_native_id(),
        priority,
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map_err(|e| failed(format!("SCHED_FIFO {}", rt.priority), format!("{e:?}")))?;
    prefault_stack();
    hold_cpu_dma_latency();
    Ok(())
}

/// Asks the kernel to keep the CPUs out of deep idle states while gantry runs (PM QoS:
/// write 0 to /dev/cpu_dma_latency and keep it open), as cyclictest does: waking from a
/// deep C-state costs tens to hundreds of µs. Best effort: without the right to it, the
/// cycle runs anyway (rt-check reports the latency either way).
static CPU_DMA_LATENCY: std::sync::OnceLock<Option<std::fs::File>> = std::sync::OnceLock::new();

/// Whether this process holds the CPUs out of deep idle states (see [`enter`]). The
/// device is root's by default; `deploy/gantry.service` gives its group access.
pub fn holds_cpu_dma_latency() -> bool {
    CPU_DMA_LATENCY.get().is_some_and(Option::is_some)
}

fn hold_cpu_dma_latency() {
    CPU_DMA_LATENCY.get_or_init(|| {
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/cpu_dma_latency")
            .ok()?;
        f.write_all(&0i32.to_ne_bytes()).ok()?;
        Some(f)
    });
}

/// Touches the stack the cycle will use, so its pages are present (and, with mlockall,
/// stay present).
#[inline(never)]
fn prefault_stack() {
    let mut buf = [0u8; STACK_PREFAULT_BYTES];
    for chunk in buf.chunks_mut(4096) {
        if let Some(b) = chunk.first_mut() {
            // SAFETY: a valid, aligned pointer into a live local buffer.
            unsafe { std::ptr::write_volatile(b, 1) };
        }
    }
    std::hint::black_box(&buf);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn capabilities_are_read_and_named() {
        // Whatever this process may do, the check answers without panicking, and a missing
        // capability is named in words a user can act on.
        let _ = check(&RtSection::default(), true);
        let e = RtError::MissingCapability {
            what: "SCHED_FIFO for the cycle thread",
            capability: "CAP_SYS_NICE",
            setcap: "cap_sys_nice",
        };
        assert!(e.to_string().contains("setcap cap_sys_nice+ep"));
    }
}
