//! gantry's CANopen master and the simulated drives as separate processes over vcan0:
//! `gantry run --no-rt` on the example configuration (its `[bus]` on `vcan0` at a 20 ms
//! cycle), four CiA-402 servos in two `gantry-sim --can vcan0` processes (nodes 1 to 3 in
//! one, node 4 alone in the other, so that it can disappear by itself). Through the CLI:
//! enable, set-position, PTP moves of all four axes ending on target, the statusword by
//! SDO; node 4's simulator is killed mid-move: its axis stops with a fault naming node 4
//! while the others finish; the simulator comes back, `gantry reset` restores the node
//! and the axis moves again; SIGTERM ends the service cleanly, and no node reports a lost
//! SYNC or heartbeat (EMCY) afterwards: the shutdown took both watches back.
//!
//! Needs vcan0 and the built `gantry` and `gantry-sim` binaries: deploy/test.sh runs it
//! with the other `vcan_*` tests (feature `vcan`), in the PREEMPT_RT VM of deploy/vm/ on
//! hosts whose kernel has no CAN. That VM runs in software emulation (TCG) on the build
//! machines, where everything is some ten times slower and stalls for tens of ms: the
//! simulated drives are set to ride through it as the examples' drives ride through a host
//! without real time (SYNC watchdog 10 periods instead of 1.5, following-error window 25
//! mm for 200 ms), and so is the master (`heartbeat_timeout_ms` 3000, `lost_frames_limit`
//! 20, `overrun_limit` 1000: its cycle thread there is not real time). Measured in the VM
//! (3 runs): a 20 ms cycle, round trip (SYNC to the last TPDO) p50 4.1–4.9 ms and max
//! 34–37 ms, 78–97 overruns in 610–670 cycles, no TPDO set lost but node 4's while it was
//! gone. Latency inside an emulated VM means nothing: the real-time figures are the host's.

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::canopen::heartbeat::Heartbeat;
use gantry_tests::can::{CanMaster, CanSim};
use gantry_tests::netns::{built_binary, Reaped};

const IFACE: &str = "vcan0";

/// The master's cycle and the simulated nodes' (µs).
const CYCLE_US: u32 = 20_000;

/// Generous: an emulated VM runs everything some ten times slower than the host.
const WAIT: Duration = Duration::from_secs(60);

/// How long the bus is watched after gantry's exit for a node reporting a lost SYNC or
/// heartbeat: twice the nodes' consumer time of gantry's heartbeat (`master_timeout_ms`
/// 3000 here).
const AFTER_EXIT: Duration = Duration::from_secs(6);

/// One chain file for `gantry-sim` with servos on `nodes`.
fn chain(nodes: &[u8]) -> String {
    let mut text = format!("cycle_us = {CYCLE_US}\n");
    for n in nodes {
        // The drives' SYNC watchdog (1.5 periods by default) and following-error window
        // would fault them on the emulated VM's stalls of tens of ms between SYNCs, which
        // a real bus does not have: ten periods, and 25 mm for 200 ms.
        text.push_str(&format!(
            "[[slave]]\nkind = \"servo\"\nnode = {n}\nsync_timeout_periods = 10\n\
             following_error_window = 655360\nfollowing_error_timeout_ms = 200\n"
        ));
    }
    text
}

/// Starts a simulator and waits for the boot-up messages of its `nodes`.
fn start_sim(nodes: &[u8]) -> CanSim {
    let mut listener = CanMaster::open(IFACE);
    let sim = CanSim::start(IFACE, &chain(nodes));
    let mut booted = Vec::new();
    while booted.len() < nodes.len() {
        let f = listener
            .wait_for(WAIT, |f| Heartbeat::parse(f).is_ok_and(|h| h.is_boot_up()))
            .unwrap_or_else(|| panic!("boot-ups seen: {booted:?} of nodes {nodes:?}"));
        booted.push(Heartbeat::parse(&f).unwrap().node.get());
    }
    booted.sort();
    assert_eq!(booted, nodes);
    sim
}

/// The example `sim-canopen-4-axes.toml` with its `[bus]` on vcan0 at [`CYCLE_US`].
fn master_config() -> String {
    let example = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../deploy/examples/sim-canopen-4-axes.toml");
    let text =
        std::fs::read_to_string(&example).unwrap_or_else(|e| panic!("{}: {e}", example.display()));
    let mut out = String::new();
    let (mut simulator, mut cycle) = (false, false);
    for line in text.lines() {
        if line.starts_with("simulator =") {
            out.push_str(&format!("interface = {IFACE:?}\n"));
            simulator = true;
        } else if line.starts_with("cycle_us =") {
            out.push_str(&format!("cycle_us = {CYCLE_US}\n"));
            // The emulated VM stalls for hundreds of ms: heartbeats and TPDOs arrive
            // late there, which a real bus would not do.
            out.push_str("heartbeat_timeout_ms = 3000\n");
            // And the nodes' consumer of gantry's heartbeat (300 ms by default): a node
            // that misses it leaves Operational (0x1029:01 = 0), as one did at bring-up
            // under a loaded host.
            out.push_str("master_timeout_ms = 3000\n");
            cycle = true;
        } else if line.starts_with("lost_frames_limit =") {
            out.push_str("lost_frames_limit = 20\n");
        } else if line.starts_with("overrun_limit =") {
            out.push_str("overrun_limit = 1000\n");
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    assert!(simulator && cycle, "the example changed: {text}");
    out
}

/// The CLI against one `gantry run`.
struct Cli {
    gantry: std::path::PathBuf,
    socket: std::path::PathBuf,
}

impl Cli {
    fn run(&self, args: &[&str]) -> Output {
        Command::new(&self.gantry)
            .args(args)
            .arg("--socket")
            .arg(&self.socket)
            .output()
            .unwrap_or_else(|e| panic!("{}: {e}", self.gantry.display()))
    }

    /// Runs a command that must succeed; its output.
    fn ok(&self, args: &[&str]) -> String {
        let out = self.run(args);
        assert!(
            out.status.success(),
            "{args:?}: {}{}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
            String::from_utf8_lossy(&self.run(&["status"]).stdout)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    fn status(&self) -> serde_json::Value {
        let text = self.ok(&["status", "--json"]);
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"))
    }

    /// The statusword of `axis`' drive read by SDO.
    fn statusword(&self, axis: &str) -> u16 {
        let sw = self.ok(&["sdo", "upload", "--axis", axis, "0x6041:0", "--type", "u16"]);
        sw.trim().parse().unwrap_or_else(|e| panic!("{sw:?}: {e}"))
    }
}

const AXES: [&str; 4] = ["x", "y", "z", "c"];

#[test]
fn vcan_master_moves_four_nodes_in_two_simulators_and_restores_a_lost_one() {
    let started = Instant::now();
    let gantry = built_binary("gantry").unwrap_or_else(|e| panic!("{e}"));
    let dir = std::env::temp_dir().join(format!("gantry-vcan-master-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("gantry.toml");
    std::fs::write(&config, master_config()).unwrap();
    let socket = dir.join("gantry.sock");

    let three = start_sim(&[1, 2, 3]);
    let mut one = Some(start_sim(&[4]));

    let service = Command::new(&gantry)
        .args(["run", "--no-rt", "--config"])
        .arg(&config)
        .arg("--socket")
        .arg(&socket)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut service = Reaped::new(service);
    let cli = Cli { gantry, socket };
    // The socket opens before the cycle's first snapshot: wait for a few cycles.
    let end = Instant::now() + WAIT;
    loop {
        if let Some(status) = service.child().try_wait().unwrap() {
            let out = service.take().wait_with_output().unwrap();
            panic!(
                "gantry run ended ({status}): {}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        if std::os::unix::net::UnixStream::connect(&cli.socket).is_ok()
            && cli.status()["cycles"].as_u64().unwrap_or(0) >= 10
        {
            break;
        }
        assert!(
            Instant::now() < end,
            "gantry run: no control socket or no cycles"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let up = started.elapsed();
    let s = cli.status();
    for (i, d) in s["drives"].as_array().unwrap().iter().enumerate() {
        assert_eq!(d["canopen"]["node"], i as u64 + 1, "{d}");
        assert_eq!(d["canopen"]["nmt"], "Operational", "{d}");
    }

    // PTP moves of all four axes at once, each ending on target.
    for axis in AXES {
        assert!(cli.ok(&["enable", axis]).contains("enabled at"));
        cli.ok(&["set-position", axis, "--position", "0"]);
    }
    let targets = [("x", "100"), ("y", "-50"), ("z", "20"), ("c", "90")];
    for (axis, to) in targets {
        cli.ok(&["move", axis, "--to", to, "--no-wait"]);
    }
    for (axis, to) in targets {
        let out = cli.ok(&["move", axis, "--to", to]);
        assert!(out.contains(&format!("{axis}: done at {to}.0")), "{out}");
    }
    let sw = cli.statusword("c");
    assert_eq!(
        sw & 0x006F,
        0x0027,
        "statusword 0x{sw:04X}: Operation enabled"
    );

    // Node 4's simulator is killed while every axis moves: c stops with a fault naming
    // node 4 (its TPDOs or its heartbeat missing); the others finish.
    for (axis, to, speed) in [("x", "0", "50"), ("y", "0", "25"), ("z", "0", "10")] {
        cli.ok(&["move", axis, "--to", to, "--speed", speed, "--no-wait"]);
    }
    cli.ok(&["move", "c", "--to", "0", "--speed", "30", "--no-wait"]);
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(cli.status()["axes"][3]["state"], "DiscreteMotion");
    drop(one.take()); // SIGKILL and reaped: the node vanishes without a word.
    for (axis, _, _) in [("x", "0", "50"), ("y", "0", "25"), ("z", "0", "10")] {
        let out = cli.ok(&["move", axis, "--to", "0"]);
        assert!(out.contains(&format!("{axis}: done at 0.0")), "{out}");
    }
    let s = cli.status();
    let c = &s["axes"][3];
    // The axis' error is the communication fault; the reason, naming the node, is its
    // drive's (`gantry status` shows both).
    let error = c["error"].as_str().unwrap_or_default();
    assert!(error.contains("0x8100"), "{c}\n{s}");
    let reason = s["drives"][3]["bus_fault"].as_str().unwrap_or_default();
    assert!(
        reason.contains("CANopen node 4")
            && (reason.contains("no TPDO") || reason.contains("no heartbeat")),
        "{s}"
    );
    assert_ne!(c["state"], "DiscreteMotion", "{c}");
    let stopped_at = c["position"].as_f64().unwrap();
    assert!(
        stopped_at > 1.0 && stopped_at < 89.0,
        "c stopped mid-move, not at {stopped_at}: {c}"
    );
    for a in &s["axes"].as_array().unwrap()[..3] {
        assert!(a["error"].is_null(), "{a}");
        assert_eq!(a["state"], "Standstill", "{a}");
    }
    eprintln!("node 4 lost: {reason}, c stopped at {stopped_at:.3}");

    // It comes back (boot-up, Pre-operational, default dictionary); `gantry reset`
    // configures it again, and c moves.
    let one = start_sim(&[4]);
    let end = Instant::now() + WAIT;
    loop {
        let out = cli.run(&["reset", "c"]);
        if out.status.success() {
            break;
        }
        assert!(
            Instant::now() < end,
            "reset c: {}{}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
            cli.status()
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    let s = cli.status();
    assert!(s["drives"][3]["bus_fault"].is_null(), "{s}");
    assert_eq!(s["drives"][3]["canopen"]["nmt"], "Operational", "{s}");
    assert!(cli.ok(&["enable", "c"]).contains("enabled at"));
    // The drive restarted at its power-up position: the axis is set again.
    cli.ok(&["set-position", "c", "--position", "0"]);
    let out = cli.ok(&["move", "c", "--to", "45"]);
    assert!(out.contains("c: done at 45.0"), "{out}");
    let sw = cli.statusword("c");
    assert_eq!(
        sw & 0x006F,
        0x0027,
        "statusword 0x{sw:04X}: Operation enabled"
    );

    let s = cli.status();
    eprintln!("{}", cli.ok(&["status"]));
    eprintln!("cycle figures: {}", s["cycle"]);
    let cycles = s["cycles"].as_u64().unwrap();
    let lost: Vec<u64> = s["drives"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["canopen"]["lost_tpdos"].as_u64().unwrap())
        .collect();
    eprintln!("cycle {CYCLE_US} µs, {cycles} cycles, TPDO sets lost per node: {lost:?}");
    for a in s["axes"].as_array().unwrap() {
        assert!(a["error"].is_null(), "{a}");
        assert_eq!(a["state"], "Standstill", "{a}");
    }

    // SIGTERM: a clean end, the nodes left pre-operational and no longer watching
    // gantry's SYNC and heartbeat. A listener on the bus from before the signal to
    // AFTER_EXIT after gantry's exit (its heartbeat consumer time is 300 ms, the
    // drives' SYNC watchdog 10 periods): no node reports a loss (EMCY).
    let exited = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let listener = {
        let exited = exited.clone();
        let mut bus = CanMaster::open(IFACE);
        std::thread::spawn(move || {
            let mut frames = Vec::new();
            while !exited.load(std::sync::atomic::Ordering::Relaxed) {
                frames.extend(bus.listen(Duration::from_millis(100)));
            }
            frames.extend(bus.listen(AFTER_EXIT));
            frames
        })
    };
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(service.child().id() as i32),
        nix::sys::signal::Signal::SIGTERM,
    )
    .unwrap();
    let out = service.take().wait_with_output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "gantry run ended {}: {text}",
        out.status
    );
    exited.store(true, std::sync::atomic::Ordering::Relaxed);
    let frames = listener.join().expect("the listener");
    assert!(text.contains("CANopen: nodes pre-operational"), "{text}");
    assert!(
        text.contains("heartbeat consumer taken back on node(s) 1, 2, 3, 4 in"),
        "{text}"
    );
    let emcys: Vec<(u8, u16)> = frames
        .iter()
        .filter_map(|f| Emergency::parse(f).ok())
        .filter(|e| !e.is_reset())
        .map(|e| (e.node.get(), e.error_code))
        .collect();
    eprintln!(
        "after SIGTERM: {} frames to {} s after gantry's exit, EMCYs {emcys:04X?}",
        frames.len(),
        AFTER_EXIT.as_secs()
    );
    assert_eq!(emcys, vec![], "EMCYs (node, code) after a clean shutdown");
    for sim in [three, one] {
        let (status, summary) = sim.stop();
        assert!(status.success(), "gantry-sim ended {status}: {summary}");
        eprintln!("{summary}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
    eprintln!(
        "vcan_master: service up after {:.1} s, whole test {:.1} s",
        up.as_secs_f64(),
        started.elapsed().as_secs_f64()
    );
}
