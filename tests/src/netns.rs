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
        for (ns, link) in [
            (&pair.master_ns, &pair.master_if),
            (&pair.sim_ns, &pair.sim_if),
        ] {
            ip(&["-n", ns, "link", "set", link, "up"])?;
        }
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
        // Deleting a namespace deletes the veth end in it, and with it the peer.
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
        for (ns, link) in [
            (&line.master_ns, &line.master_if),
            (&line.relay_ns, &line.relay_master_if),
            (&line.relay_ns, &line.relay_sim_if),
            (&line.sim_ns, &line.sim_if),
        ] {
            ip(&["-n", ns, "link", "set", link, "up"])?;
        }
        Ok(line)
    }
}

impl Drop for RelayedVeth {
    fn drop(&mut self) {
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

/// Starts `gantry-sim` (SCHED_FIFO 70) on `iface` in namespace `ns` with the chain in
/// `config`, and waits until it has bound its socket (its first line, which must name
/// `slaves` slaves).
pub fn start_gantry_sim(ns: &str, iface: &str, config: &std::path::Path, slaves: usize) -> Reaped {
    use std::io::BufRead;
    let mut sim = Reaped::new(
        Command::new("ip")
            .args(["netns", "exec", ns])
            .arg(gantry_sim_binary().expect("gantry-sim is built"))
            .args(["--interface", iface, "--config"])
            .arg(config)
            .args(["--priority", "70"])
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("start gantry-sim"),
    );
    let mut first = String::new();
    std::io::BufReader::new(sim.child().stdout.take().expect("piped"))
        .read_line(&mut first)
        .expect("gantry-sim's first line");
    assert!(
        first.contains(&format!("{slaves} slaves")),
        "gantry-sim started: {first:?}"
    );
    sim
}
