//! A veth pair whose two ends live in two fresh network namespaces, for the tests that
//! run master and simulator as separate processes over a real (virtual) wire. Needs
//! root (or CAP_NET_ADMIN + CAP_SYS_ADMIN); removed again on drop.

use std::process::Command;

/// Two namespaces joined by a veth pair.
pub struct VethPair {
    /// Namespace of the master end.
    pub master_ns: String,
    /// Namespace of the simulator end.
    pub sim_ns: String,
    /// Interface name of the master end (inside `master_ns`).
    pub master_if: String,
    /// Interface name of the simulator end (inside `sim_ns`).
    pub sim_if: String,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("ip {}: {e} (is iproute2 installed?)", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// Sets the links up and waits until the kernel has them operationally up. An EtherCAT
/// wire carries no IP: IPv6 is off on it, so the kernel sends no router solicitations or
/// multicast reports into the process data and runs no address work for it. The kernel
/// turns a link up in a work item (linkwatch, within a second, holding RTNL for up to a
/// few ms measured on a non-preemptible kernel): waiting for it keeps that work out of the
/// real-time part of a test.
fn bring_up(ends: &[(&str, &str)]) -> Result<(), String> {
    // Dirty pages (the build that just wrote the binaries) are written back by kernel
    // workers that, on a kernel without preemption, hold a CPU for milliseconds (traced on
    // the CI VM: writeback work items of 10–80 ms); flush them before real time starts.
    let _ = Command::new("sync").status();
    for (ns, link) in ends {
        let sysctl = format!("net.ipv6.conf.{link}.disable_ipv6=1");
        // A kernel without IPv6 has nothing to turn off: its failure is no error.
        Command::new("ip")
            .args(["netns", "exec", ns, "sysctl", "-q", "-w", &sysctl])
            .output()
            .map_err(|e| format!("sysctl in {ns}: {e}"))?;
        ip(&["-n", ns, "link", "set", link, "up"])?;
    }
    let end = std::time::Instant::now() + std::time::Duration::from_secs(5);
    for (ns, link) in ends {
        loop {
            let out = Command::new("ip")
                .args(["-n", ns, "-o", "link", "show", link])
                .output()
                .map_err(|e| format!("ip link show {link}: {e}"))?;
            if String::from_utf8_lossy(&out.stdout).contains("state UP") {
                break;
            }
            if std::time::Instant::now() > end {
                return Err(format!("{link} in {ns} is not up after 5 s"));
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }
    Ok(())
}

impl VethPair {
    /// Creates the namespaces and the pair; names carry `tag` and the process ID so
    /// parallel runs do not collide.
    pub fn create(tag: &str) -> Result<Self, String> {
        let id = std::process::id();
        let pair = Self {
            master_ns: format!("gm-{tag}-{id}"),
            sim_ns: format!("gs-{tag}-{id}"),
            master_if: "ecat-m".into(),
            sim_if: "ecat-s".into(),
        };
        for ns in [&pair.master_ns, &pair.sim_ns] {
            ip(&["netns", "add", ns])?;
        }
        ip(&[
            "-n",
            &pair.master_ns,
            "link",
            "add",
            &pair.master_if,
            "type",
            "veth",
            "peer",
            "name",
            &pair.sim_if,
            "netns",
            &pair.sim_ns,
        ])?;
        let ends = [
            (pair.master_ns.as_str(), pair.master_if.as_str()),
            (pair.sim_ns.as_str(), pair.sim_if.as_str()),
        ];
        bring_up(&ends)?;
        Ok(pair)
    }

    /// Moves the calling thread into the master's namespace (sockets it opens afterwards
    /// live there; other threads are not affected).
    pub fn enter_master_ns(&self) -> Result<(), String> {
        let path = format!("/run/netns/{}", self.master_ns);
        let file = std::fs::File::open(&path).map_err(|e| format!("{path}: {e}"))?;
        nix::sched::setns(file, nix::sched::CloneFlags::CLONE_NEWNET)
            .map_err(|e| format!("setns {path}: {e}"))
    }
}

impl Drop for VethPair {
    fn drop(&mut self) {
        // The pair first, here: deleting a namespace leaves its devices to a kernel worker
        // (cleanup_net) that would still be tearing them down when the next test starts.
        let _ = ip(&["-n", &self.master_ns, "link", "del", &self.master_if]);
        for ns in [&self.master_ns, &self.sim_ns] {
            let _ = ip(&["netns", "del", ns]);
        }
    }
}

/// Three namespaces in a line — master, relay, simulator — joined by two veth pairs, for
/// tests that put a process between master and simulator (one that drops frames, as a
/// bad wire would). Needs root; removed again on drop.
pub struct RelayedVeth {
    /// Namespace of the master end.
    pub master_ns: String,
    /// Namespace of the relay.
    pub relay_ns: String,
    /// Namespace of the simulator end.
    pub sim_ns: String,
    /// Interface of the master (inside `master_ns`).
    pub master_if: String,
    /// Relay interface towards the master (inside `relay_ns`).
    pub relay_master_if: String,
    /// Relay interface towards the simulator (inside `relay_ns`).
    pub relay_sim_if: String,
    /// Interface of the simulator (inside `sim_ns`).
    pub sim_if: String,
}

impl RelayedVeth {
    /// Creates the namespaces and both pairs; names carry `tag` and the process ID.
    pub fn create(tag: &str) -> Result<Self, String> {
        let id = std::process::id();
        let line = Self {
            master_ns: format!("gm-{tag}-{id}"),
            relay_ns: format!("gr-{tag}-{id}"),
            sim_ns: format!("gs-{tag}-{id}"),
            master_if: "ecat-m".into(),
            relay_master_if: "relay-m".into(),
            relay_sim_if: "relay-s".into(),
            sim_if: "ecat-s".into(),
        };
        for ns in [&line.master_ns, &line.relay_ns, &line.sim_ns] {
            ip(&["netns", "add", ns])?;
        }
        for (ns, a, peer_ns, b) in [
            (
                &line.master_ns,
                &line.master_if,
                &line.relay_ns,
                &line.relay_master_if,
            ),
            (
                &line.relay_ns,
                &line.relay_sim_if,
                &line.sim_ns,
                &line.sim_if,
            ),
        ] {
            ip(&[
                "-n", ns, "link", "add", a, "type", "veth", "peer", "name", b, "netns", peer_ns,
            ])?;
        }
        bring_up(&[
            (line.master_ns.as_str(), line.master_if.as_str()),
            (line.relay_ns.as_str(), line.relay_master_if.as_str()),
            (line.relay_ns.as_str(), line.relay_sim_if.as_str()),
            (line.sim_ns.as_str(), line.sim_if.as_str()),
        ])?;
        Ok(line)
    }
}

impl Drop for RelayedVeth {
    fn drop(&mut self) {
        // The pairs first (see `VethPair`'s drop).
        let _ = ip(&["-n", &self.master_ns, "link", "del", &self.master_if]);
        let _ = ip(&["-n", &self.sim_ns, "link", "del", &self.sim_if]);
        for ns in [&self.master_ns, &self.relay_ns, &self.sim_ns] {
            let _ = ip(&["netns", "del", ns]);
        }
    }
}

/// The `gantry-sim` binary built beside the running test (target/<profile>/gantry-sim).
pub fn gantry_sim_binary() -> Result<std::path::PathBuf, String> {
    built_binary("gantry-sim")
}

/// A workspace binary built beside the running test (target/<profile>/NAME).
pub fn built_binary(name: &str) -> Result<std::path::PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .ok_or("test binary has no target directory")?;
    let bin = dir.join(name);
    if bin.exists() {
        Ok(bin)
    } else {
        Err(format!(
            "{} is missing: build it first (cargo build --release --workspace --bins; deploy/test.sh does)",
            bin.display()
        ))
    }
}

/// A child process killed and reaped when dropped, however the test ends.
pub struct Reaped(Option<std::process::Child>);

impl Reaped {
    /// Watches `child`.
    pub fn new(child: std::process::Child) -> Self {
        Self(Some(child))
    }

    /// The child, for the caller to wait for itself (it is no longer killed on drop).
    pub fn take(&mut self) -> std::process::Child {
        self.0.take().expect("taken once")
    }

    /// The child.
    pub fn child(&mut self) -> &mut std::process::Child {
        self.0.as_mut().expect("not taken")
    }
}

impl Drop for Reaped {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// A running `gantry-sim` whose summary can be read when it is stopped. Dropped without
/// [`SimProcess::stop`] (a test failed), it is stopped the same way and its summary goes to
/// stderr, so a failed run still shows the gaps the drives saw.
pub struct SimProcess {
    child: Reaped,
    stdout: Option<std::io::BufReader<std::process::ChildStdout>>,
}

impl Drop for SimProcess {
    fn drop(&mut self) {
        if self.stdout.is_some() {
            match self.finish() {
                Ok(summary) => eprintln!("{}", summary.line),
                Err(e) => eprintln!("gantry-sim: {e}"),
            }
        }
    }
}

/// What `gantry-sim` said when it stopped.
#[derive(Clone, Debug, PartialEq)]
pub struct SimSummary {
    /// Its summary line.
    pub line: String,
    /// The largest gap between two frames (µs).
    pub frame_gap_us: u64,
    /// Per slave, the largest gap between two writes of its process data (µs).
    pub write_gaps_us: Vec<u64>,
}

impl SimProcess {
    /// Stops it with SIGTERM and reads its summary (killed and reaped on drop if this is
    /// not called).
    pub fn stop(mut self) -> Result<SimSummary, String> {
        self.finish()
    }

    fn finish(&mut self) -> Result<SimSummary, String> {
        use std::io::Read;
        let mut stdout = self.stdout.take().ok_or("already stopped")?;
        let pid = self.child.child().id() as i32;
        nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(pid),
            nix::sys::signal::Signal::SIGTERM,
        )
        .map_err(|e| format!("SIGTERM to gantry-sim: {e}"))?;
        let mut rest = String::new();
        stdout
            .read_to_string(&mut rest)
            .map_err(|e| format!("gantry-sim's output: {e}"))?;
        let status = self.child.take().wait().map_err(|e| e.to_string())?;
        let line = rest
            .lines()
            .find(|l| l.contains("served"))
            .ok_or_else(|| format!("gantry-sim ended ({status}) without a summary: {rest:?}"))?
            .to_string();
        let number = |after: &str| -> Option<&str> { line.split(after).nth(1) };
        let frame_gap_us = number("largest gap between frames ")
            .and_then(|r| r.split_whitespace().next())
            .and_then(|n| n.parse().ok())
            .ok_or_else(|| format!("no frame gap in {line:?}"))?;
        let write_gaps_us = number("per slave [")
            .and_then(|r| r.split(']').next())
            .map(|list| {
                list.split(',')
                    .filter_map(|n| n.trim().parse().ok())
                    .collect()
            })
            .ok_or_else(|| format!("no process-data gaps in {line:?}"))?;
        Ok(SimSummary {
            line,
            frame_gap_us,
            write_gaps_us,
        })
    }
}

/// Starts `gantry-sim` like [`start_gantry_sim`], keeping its output for
/// [`SimProcess::stop`].
pub fn start_gantry_sim_reporting(
    ns: &str,
    iface: &str,
    config: &std::path::Path,
    slaves: usize,
) -> SimProcess {
    start_gantry_sim_recording(ns, iface, config, slaves, None)
}

/// As [`start_gantry_sim_reporting`]; with `record`, the simulator writes its drives'
/// records there when it stops (`gantry-sim --record`, for
/// [`crate::invariant::assert_record_invariants`]).
pub fn start_gantry_sim_recording(
    ns: &str,
    iface: &str,
    config: &std::path::Path,
    slaves: usize,
    record: Option<&std::path::Path>,
) -> SimProcess {
    use std::io::BufRead;
    let mut child = spawn_gantry_sim(ns, iface, config, record);
    let mut stdout = std::io::BufReader::new(child.child().stdout.take().expect("piped"));
    let mut first = String::new();
    stdout
        .read_line(&mut first)
        .expect("gantry-sim's first line");
    assert!(
        first.contains(&format!("{slaves} slaves")),
        "gantry-sim started: {first:?}"
    );
    SimProcess {
        child,
        stdout: Some(stdout),
    }
}

fn spawn_gantry_sim(
    ns: &str,
    iface: &str,
    config: &std::path::Path,
    record: Option<&std::path::Path>,
) -> Reaped {
    let mut command = Command::new("ip");
    command
        .args(["netns", "exec", ns])
        .arg(gantry_sim_binary().expect("gantry-sim is built"))
        .args(["--interface", iface, "--config"])
        .arg(config)
        .args(["--priority", "70"]);
    if let Some(path) = record {
        command.arg("--record").arg(path);
    }
    Reaped::new(
        command
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("start gantry-sim"),
    )
}

/// Starts `gantry-sim` (SCHED_FIFO 70) on `iface` in namespace `ns` with the chain in
/// `config`, and waits until it has bound its socket (its first line, which must name
/// `slaves` slaves).
pub fn start_gantry_sim(ns: &str, iface: &str, config: &std::path::Path, slaves: usize) -> Reaped {
    let mut sim = start_gantry_sim_reporting(ns, iface, config, slaves);
    // Nobody reads its summary: the simulator's last line then goes nowhere (it ignores
    // a closed pipe), and it is killed on drop.
    sim.stdout = None;
    let child = sim.child.take();
    Reaped::new(child)
}
