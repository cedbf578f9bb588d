//! `gantry rt-check`: is this machine fit for a real-time cycle, and what to change. Reads
//! the kernel, capabilities, CPU isolation, frequency governor, RT throttling and the NIC's
//! interrupt coalescing; then measures the wake-up latency of a SCHED_FIFO thread at the
//! cycle time, and, when rt-tests' `cyclictest` is installed, takes the same figures with
//! it in the same run, so the two can be compared as a ratio.

use std::io::Write;
use std::process::Command;

use gantry::config::RtSection;
use gantry::runtime::clock::CycleClock;
use gantry::runtime::histogram::{Histogram, Summary};

/// One check: what was found and, if it is not right, what to do.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Finding {
    /// What was checked.
    pub check: &'static str,
    /// What this machine has.
    pub found: String,
    /// `None` when fine; otherwise the advice.
    pub advice: Option<String>,
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path)
        .ok()
        .map(|s| s.trim().to_string())
}

/// The machine's settings.
pub fn findings(rt: &RtSection, interface: Option<&str>) -> Vec<Finding> {
    let mut f = Vec::new();
    let version = read("/proc/sys/kernel/version").unwrap_or_default();
    let realtime =
        read("/sys/kernel/realtime").as_deref() == Some("1") || version.contains("PREEMPT_RT");
    f.push(Finding {
        check: "kernel",
        found: format!("{version}{}", if realtime { " (PREEMPT_RT)" } else { "" }),
        advice: (!realtime).then(|| {
            "not a PREEMPT_RT kernel: install one (Debian: linux-image-rt-amd64) for bounded latency".into()
        }),
    });
    let (found, advice) = preemption(
        &version,
        &read("/proc/cmdline").unwrap_or_default(),
        read("/sys/kernel/debug/sched/preempt").as_deref(),
    );
    f.push(Finding {
        check: "kernel preemption",
        found,
        advice,
    });
    f.push(Finding {
        check: "capabilities",
        found: match gantry::runtime::rt::check(rt, interface.is_some()) {
            Ok(()) => "SCHED_FIFO, memory locking and raw sockets allowed".into(),
            Err(e) => e.to_string(),
        },
        advice: gantry::runtime::rt::check(rt, interface.is_some())
            .err()
            .map(|_| {
                "grant the capabilities named above (deploy/gantry.service grants them to the service)".into()
            }),
    });
    let isolated = read("/sys/devices/system/cpu/isolated").unwrap_or_default();
    let nohz = read("/sys/devices/system/cpu/nohz_full").unwrap_or_default();
    let pinned = rt.cpu.map(|c| c.to_string());
    f.push(Finding {
        check: "CPU isolation",
        found: format!(
            "isolated: {}, nohz_full: {}, cycle thread pinned to: {}",
            if isolated.is_empty() { "none" } else { &isolated },
            if nohz.is_empty() || nohz == "(null)" { "none" } else { &nohz },
            pinned.as_deref().unwrap_or("no CPU (rt.cpu)")
        ),
        advice: (isolated.is_empty() || rt.cpu.is_none()).then(|| {
            "isolate a CPU for the cycle (kernel command line isolcpus=N nohz_full=N rcu_nocbs=N) and set rt.cpu = N".into()
        }),
    });
    let governors: Vec<String> = (0..num_cpus())
        .filter_map(|c| {
            read(&format!(
                "/sys/devices/system/cpu/cpu{c}/cpufreq/scaling_governor"
            ))
        })
        .collect();
    let all_performance = !governors.is_empty() && governors.iter().all(|g| g == "performance");
    f.push(Finding {
        check: "CPU frequency governor",
        found: if governors.is_empty() {
            "no cpufreq (fixed frequency or a VM)".into()
        } else {
            governors.join(", ")
        },
        advice: (!governors.is_empty() && !all_performance).then(|| {
            "set the governor to performance (cpupower frequency-set -g performance)".into()
        }),
    });
    // PM QoS: gantry holds the CPUs out of deep idle states by writing 0 here, when it may.
    let writable = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/cpu_dma_latency")
        .is_ok();
    f.push(Finding {
        check: "CPU idle states (PM QoS)",
        found: if writable {
            "/dev/cpu_dma_latency writable: gantry holds the CPUs out of deep idle".into()
        } else {
            "/dev/cpu_dma_latency not writable by this user".into()
        },
        advice: (!writable).then(|| {
            "waking from deep C-states adds tens to hundreds of µs: give gantry's group write access (chgrp gantry /dev/cpu_dma_latency; chmod g+w), as deploy/gantry.service does".into()
        }),
    });
    let runtime = read("/proc/sys/kernel/sched_rt_runtime_us").unwrap_or_default();
    f.push(Finding {
        check: "RT throttling",
        found: format!("sched_rt_runtime_us = {runtime}"),
        advice: (runtime != "-1").then(|| {
            "RT tasks are throttled to 95 % of each second: set kernel.sched_rt_runtime_us = -1 (sysctl) so a busy cycle is never paused".into()
        }),
    });
    if let Some(nic) = interface {
        let out = Command::new("ethtool").args(["-c", nic]).output();
        let (found, advice) = match out {
            Ok(o) if o.status.success() => {
                let text = String::from_utf8_lossy(&o.stdout);
                let rx = text
                    .lines()
                    .find_map(|l| l.strip_prefix("rx-usecs:"))
                    .map(|v| v.trim().to_string())
                    .unwrap_or_else(|| "n/a".into());
                let bad = rx != "0" && rx != "n/a";
                (
                    format!("{nic}: rx-usecs {rx}"),
                    bad.then(|| {
                        format!("turn interrupt coalescing off: ethtool -C {nic} rx-usecs 0")
                    }),
                )
            }
            Ok(o) => (
                format!("{nic}: {}", String::from_utf8_lossy(&o.stderr).trim()),
                None,
            ),
            Err(_) => (
                "ethtool is not installed".into(),
                Some("install ethtool to check the NIC's interrupt coalescing".into()),
            ),
        };
        f.push(Finding {
            check: "NIC interrupt coalescing",
            found,
            advice,
        });
    }
    f
}

fn num_cpus() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Wake-up latency of a SCHED_FIFO thread at `priority` sleeping to absolute deadlines
/// every `cycle_us` for `seconds`. `None` for the priority when it could not be set.
pub fn measure(priority: u8, cycle_us: u32, seconds: f64) -> (Summary, bool) {
    let handle = std::thread::spawn(move || {
        let rt = RtSection {
            priority,
            cpu: None,
            lock_memory: true,
            overrun_limit: 1,
        };
        let real_time = gantry::runtime::rt::enter(&rt).is_ok();
        let mut h = Histogram::new(20_000);
        let n = (seconds * 1e6 / f64::from(cycle_us)).max(1.0) as u64;
        let mut clock = CycleClock::start(u64::from(cycle_us) * 1000);
        for _ in 0..n {
            h.record(clock.wait().latency_ns);
        }
        (h.summary(), real_time)
    });
    handle.join().unwrap_or_default()
}

/// The same with `cyclictest`, if installed: one thread, same priority and interval.
/// `cpu`: pinned there (`-a`), as the thread it is compared with.
pub fn cyclictest(
    priority: u8,
    cpu: Option<usize>,
    cycle_us: u32,
    seconds: f64,
) -> Result<Summary, String> {
    let loops = (seconds * 1e6 / f64::from(cycle_us)).max(1.0) as u64;
    let mut command = Command::new("cyclictest");
    if let Some(cpu) = cpu {
        command.arg(format!("-a{cpu}"));
    }
    let out = command
        .args(["-m", "-q", "-t1", "-h", "20000"])
        .arg(format!("-p{priority}"))
        .arg(format!("-i{cycle_us}"))
        .arg(format!("-l{loops}"))
        .output()
        .map_err(|e| format!("cyclictest: {e} (install rt-tests)"))?;
    if !out.status.success() {
        return Err(format!(
            "cyclictest: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let mut h = Histogram::new(20_000);
    let mut max_us = 0u64;
    for line in text.lines() {
        if let Some(m) = line.strip_prefix("# Max Latencies:") {
            max_us = m.trim().parse().unwrap_or(0);
        }
        let mut parts = line.split_whitespace();
        if let (Some(us), Some(count), None) = (parts.next(), parts.next(), parts.next()) {
            if let (Ok(us), Ok(count)) = (us.parse::<u64>(), count.parse::<u64>()) {
                for _ in 0..count {
                    // Bucket `us` holds latencies in [us, us + 1): record its middle.
                    h.record(us * 1000 + 500);
                }
            }
        }
    }
    let mut s = h.summary();
    s.max_us = s.max_us.max(max_us as f64);
    Ok(s)
}

fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else {
        f64::NAN
    }
}

/// `--can N`: the SYNC of a CANopen cycle thread on `N` simulated servos
/// ([`crate::sync_jitter`]), then cyclictest at the same priority on the same CPU (the
/// configuration's `rt.cpu`, else the last CPU: the cycle thread is pinned as in
/// production), each for `seconds`.
pub fn run_can(
    rt: &RtSection,
    drives: u8,
    cycle_us: u32,
    seconds: f64,
    out: &mut impl Write,
) -> std::io::Result<()> {
    let mut rt = *rt;
    rt.lock_memory = true;
    rt.cpu = Some(rt.cpu.unwrap_or(num_cpus() - 1));
    writeln!(
        out,
        "SYNC of the CANopen cycle thread ({drives} simulated servos at 1 Mbit/s), SCHED_FIFO {} on CPU {}, memory locked, every {cycle_us} µs for {seconds} s:",
        rt.priority,
        rt.cpu.unwrap_or(0)
    )?;
    let j = match crate::sync_jitter::measure(rt, drives, cycle_us, seconds) {
        Ok(j) => j,
        Err(e) => {
            writeln!(out, "  not measured: {e}")?;
            return Ok(());
        }
    };
    writeln!(
        out,
        "  SYNC |interval − period|  {}{}",
        j.deviation,
        if j.real_time {
            ""
        } else {
            "  (NOT real time: SCHED_FIFO, pinning or mlockall refused)"
        }
    )?;
    writeln!(out, "  SYNC sent − deadline     {}", j.lateness)?;
    writeln!(
        out,
        "  less the simulator's time in the RPDO sends before the SYNC (the thread's own):"
    )?;
    writeln!(out, "  SYNC |interval − period|  {}", j.deviation_own)?;
    writeln!(out, "  SYNC sent − deadline     {}", j.lateness_own)?;
    writeln!(
        out,
        "  {} SYNCs in {} cycles, {} TPDOs lost",
        j.syncs, j.cycles, j.lost
    )?;
    match cyclictest(rt.priority, rt.cpu, cycle_us, seconds) {
        Ok(c) => {
            writeln!(out, "  cyclictest latency       {c}")?;
            for (what, g) in [
                ("|interval − period|", j.deviation),
                ("sent − deadline", j.lateness),
                ("|interval − period| own", j.deviation_own),
                ("sent − deadline own", j.lateness_own),
            ] {
                writeln!(
                    out,
                    "  ratio SYNC {what}/cyclictest: p50 {:.2}, p99 {:.2}, p99.9 {:.2}, max {:.2}",
                    ratio(g.p50_us, c.p50_us),
                    ratio(g.p99_us, c.p99_us),
                    ratio(g.p999_us, c.p999_us),
                    ratio(g.max_us, c.max_us)
                )?;
            }
        }
        Err(e) => writeln!(out, "  cyclictest  not run: {e}")?,
    }
    Ok(())
}

/// The machine's settings, as a report.
pub fn write_findings(
    rt: &RtSection,
    interface: Option<&str>,
    out: &mut impl Write,
) -> std::io::Result<()> {
    writeln!(out, "gantry rt-check")?;
    for f in findings(rt, interface) {
        writeln!(out, "  {:<26} {}", f.check, f.found)?;
        if let Some(a) = f.advice {
            writeln!(out, "  {:<26} → {a}", "")?;
        }
    }
    Ok(())
}

/// Runs every check and the measurement; writes the report.
pub fn run(
    rt: &RtSection,
    interface: Option<&str>,
    cycle_us: u32,
    seconds: f64,
    out: &mut impl Write,
) -> std::io::Result<()> {
    write_findings(rt, interface, out)?;
    writeln!(
        out,
        "wake-up latency, SCHED_FIFO {}, every {cycle_us} µs for {seconds} s:",
        rt.priority
    )?;
    let (g, real_time) = measure(rt.priority, cycle_us, seconds);
    writeln!(
        out,
        "  gantry      {g}{}",
        if real_time {
            ""
        } else {
            "  (NOT real time: SCHED_FIFO refused)"
        }
    )?;
    match cyclictest(rt.priority, None, cycle_us, seconds) {
        Ok(c) => {
            writeln!(out, "  cyclictest  {c}")?;
            writeln!(
                out,
                "  ratio gantry/cyclictest: p50 {:.2}, p99 {:.2}, p99.9 {:.2}, max {:.2}",
                ratio(g.p50_us, c.p50_us),
                ratio(g.p99_us, c.p99_us),
                ratio(g.p999_us, c.p999_us),
                ratio(g.max_us, c.max_us)
            )?;
        }
        Err(e) => writeln!(out, "  cyclictest  not run: {e}")?,
    }
    Ok(())
}

/// How the kernel preempts its own work, from its version string (`PREEMPT_RT`,
/// `PREEMPT_DYNAMIC`, `PREEMPT`), the boot command line (`preempt=`) and, when debugfs is
/// readable, `sched/preempt` (the mode in parentheses). Without preemption of kernel code
/// a SCHED_FIFO thread waits for whatever kernel work holds its CPU — write-back, a
/// compiler's page faults, a NIC's link handling: milliseconds, measured on such VMs.
fn preemption(version: &str, cmdline: &str, debugfs: Option<&str>) -> (String, Option<String>) {
    const ADVICE: &str = "kernel code is not preempted: a real-time thread waits for it \
        (milliseconds under load); boot with preempt=full, or better a PREEMPT_RT kernel";
    if version.contains("PREEMPT_RT") {
        return ("real time (PREEMPT_RT)".into(), None);
    }
    let from_debugfs = debugfs.and_then(|s| {
        let start = s.find('(')?;
        let end = s[start..].find(')')? + start;
        s.get(start + 1..end).map(str::to_string)
    });
    let from_cmdline = cmdline
        .split_whitespace()
        .find_map(|w| w.strip_prefix("preempt="))
        .map(str::to_string);
    let (mode, source) = match (from_debugfs, from_cmdline) {
        (Some(m), _) => (m, "sched/preempt"),
        (None, Some(m)) => (m, "preempt= on the command line"),
        (None, None) if version.contains("PREEMPT_DYNAMIC") => {
            return (
                "dynamic; the mode is not readable here (debugfs sched/preempt; `dmesg | grep \
                 'Dynamic Preempt'` tells)"
                    .into(),
                Some(
                    "unless that mode is full, kernel code is not preempted: a real-time \
                     thread waits for it (milliseconds under load); boot with preempt=full, \
                     or better a PREEMPT_RT kernel"
                        .into(),
                ),
            )
        }
        (None, None) if version.contains("PREEMPT") => ("full".into(), "the kernel version"),
        (None, None) => ("none or voluntary".into(), "the kernel version"),
    };
    let advice = (mode != "full").then(|| ADVICE.to_string());
    (format!("{mode} (from {source})"), advice)
}

#[cfg(test)]
mod tests {
    use super::preemption;

    #[test]
    fn the_preemption_mode_is_read_from_where_the_kernel_says_it() {
        let rt = preemption("#1 SMP PREEMPT_RT Debian 6.1", "", None);
        assert_eq!(rt, ("real time (PREEMPT_RT)".into(), None));
        let (found, advice) = preemption(
            "#1 SMP PREEMPT_DYNAMIC",
            "",
            Some("none voluntary (full) lazy"),
        );
        assert_eq!(found, "full (from sched/preempt)");
        assert_eq!(advice, None);
        let (found, advice) = preemption("#1 SMP PREEMPT_DYNAMIC", "ro preempt=none quiet", None);
        assert_eq!(found, "none (from preempt= on the command line)");
        assert!(advice.unwrap().contains("PREEMPT_RT"));
        let (found, advice) = preemption("#1 SMP PREEMPT_DYNAMIC @0", "ro", None);
        assert!(
            found.starts_with("dynamic; the mode is not readable"),
            "{found}"
        );
        assert!(advice.is_some());
        let (found, advice) = preemption("#1 SMP", "", None);
        assert_eq!(found, "none or voluntary (from the kernel version)");
        assert!(advice.is_some());
    }
}
