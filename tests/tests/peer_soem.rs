//! A second, independent master: SOEM (through the `pysoem` Python package, run as its
//! own process — SOEM is GPL and never linked into gantry) brings three simulated servos
//! to OP over a veth pair, exchanges process data, reads SDOs, enables the drives and
//! lets the process-data watchdog trip.
//! The simulator must follow the ESC datasheet, not what ethercrab happens to do.
//!
//! The peer is `tests/peers/soem_bringup.py`; its last line on stdout is a JSON report.
//! A second case puts `tests/peers/lossy_relay.py` between master and simulator, which
//! drops every fifth mailbox answer after the slave handed it out: SOEM recovers each one
//! with the SyncManager's repeat request.
//! Needs root (network namespaces), the `gantry-sim` binary and the pysoem venv that
//! `deploy/test.sh` makes (`GANTRY_PEER_PYTHON`); `deploy/test.sh` runs it.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};
use std::sync::Mutex;

use gantry_sim::catalog::{SERVO_PRODUCT, VENDOR_ID};
use gantry_tests::netns::{start_gantry_sim, Reaped, RelayedVeth, VethPair};
use serde::Deserialize;

const SERVOS: usize = 3;

/// The two cases run one after the other: they share two cores with the simulator, the
/// peer and the relay.
static SERIAL: Mutex<()> = Mutex::new(());

const SIM_CONFIG: &str = r#"
cycle_us = 1000
[[slave]]
kind = "servo"
[[slave]]
kind = "servo"
start_position = 100000
[[slave]]
kind = "servo"
start_position = -250000
"#;

/// The Python of the pysoem venv, or a message that says how to get it.
fn peer_python() -> PathBuf {
    match std::env::var_os("GANTRY_PEER_PYTHON") {
        Some(p) if !p.is_empty() => {
            let p = PathBuf::from(p);
            assert!(
                p.exists(),
                "GANTRY_PEER_PYTHON={} does not exist: run deploy/test.sh (it creates the pysoem venv)",
                p.display()
            );
            p
        }
        _ => panic!(
            "GANTRY_PEER_PYTHON is not set: run deploy/test.sh, which creates the pysoem venv \
             under ~/.cache/gantry/venv and exports its python"
        ),
    }
}

/// The peer's JSON report (the fields the test checks).
#[derive(Debug, Deserialize)]
struct Report {
    ok: bool,
    errors: Vec<String>,
    slaves: Vec<PeerSlave>,
    reached_op: bool,
    expected_wkc: Option<u16>,
    cycles: u64,
    wkc_errors: u64,
    late_frames: u64,
    #[serde(default)]
    sdo_vendor: Vec<u32>,
    #[serde(default)]
    sdo_1c12: Vec<Vec<u16>>,
    enabled: Vec<bool>,
    dc: Option<bool>,
    refused_transition: Option<RefusedTransition>,
    watchdog: Option<Watchdog>,
}

/// 300 ms without process data in OP, then an acknowledge.
#[derive(Debug, Deserialize)]
struct Watchdog {
    /// (AL state, AL status code) of every slave after the silence.
    tripped: Vec<(String, u16)>,
    drive_faulted: Vec<bool>,
    after_ack: Vec<String>,
}

/// Slave 0 asked for PREOP -> OP (skipping SAFEOP), then acknowledged.
#[derive(Debug, Deserialize, PartialEq)]
struct RefusedTransition {
    state: String,
    al_status_code: u16,
    after_ack: String,
}

#[derive(Debug, Deserialize)]
struct PeerSlave {
    name: String,
    vendor: u32,
    product: u32,
    address: u16,
    ibytes: Option<usize>,
    obytes: Option<usize>,
    state: String,
    state_after: Option<String>,
}

/// Starts `gantry-sim` with the three servos on `iface` in `ns`; returns the process and
/// the directory of its configuration (removed by the caller).
fn start_sim(ns: &str, iface: &str, tag: &str) -> (Reaped, PathBuf) {
    let dir = std::env::temp_dir().join(format!("gantry-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("sim.toml");
    std::fs::write(&config, SIM_CONFIG).unwrap();
    (start_gantry_sim(ns, iface, &config, SERVOS), dir)
}

/// Runs the SOEM peer on `iface` in `ns`; prints its output and returns its report.
fn run_peer(python: &PathBuf, ns: &str, iface: &str, extra: &[&str]) -> (Output, Report) {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("peers/soem_bringup.py");
    let peer = Command::new("ip")
        .args(["netns", "exec", ns])
        .arg(python)
        .arg(&script)
        .arg(iface)
        .args(["--seconds", "1.5"])
        .args(extra)
        .output()
        .expect("run the SOEM peer");
    let stdout = String::from_utf8_lossy(&peer.stdout);
    let stderr = String::from_utf8_lossy(&peer.stderr);
    eprintln!("SOEM peer ({}):\n{stderr}{stdout}", peer.status);
    let json = stdout
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .unwrap_or_else(|| panic!("the peer printed no JSON report ({})", peer.status));
    let report = serde_json::from_str(json).expect("the peer's report parses");
    (peer, report)
}

/// What every bring-up must show.
fn check_bringup(peer: &Output, r: &Report) {
    assert_eq!(r.slaves.len(), SERVOS, "SOEM found every slave: {r:?}");
    for (i, s) in r.slaves.iter().enumerate() {
        assert_eq!(s.name, "SIM-SERVO", "slave {i} name");
        assert_eq!(
            (s.vendor, s.product),
            (VENDOR_ID, SERVO_PRODUCT),
            "slave {i} identity"
        );
        assert_eq!(s.address, 0x1001 + i as u16, "slave {i} configured address");
        assert_eq!(
            (s.ibytes, s.obytes),
            (Some(6), Some(6)),
            "slave {i} Ibytes/Obytes"
        );
        assert_eq!(
            s.state, "PREOP",
            "slave {i} state read back after config_init"
        );
        assert_eq!(
            s.state_after.as_deref(),
            Some("OP"),
            "slave {i} still in OP after the exchange"
        );
    }
    assert_eq!(
        r.dc,
        Some(true),
        "config_dc finds the simulated servos' distributed clocks"
    );
    assert_eq!(
        r.refused_transition,
        Some(RefusedTransition {
            state: "PREOP+ERROR".into(),
            al_status_code: 0x0011,
            after_ack: "PREOP".into(),
        }),
        "PREOP -> OP refused with 'invalid requested state change', cleared by PREOP + ACK"
    );
    assert!(r.reached_op, "all slaves reached OP: {:?}", r.errors);
    assert_eq!(
        r.expected_wkc,
        Some(3 * SERVOS as u16),
        "expected WKC of one LRW: 3 per servo"
    );
    assert!(
        r.cycles > 500,
        "process data exchanged: {} cycles",
        r.cycles
    );
    assert_eq!(
        r.wkc_errors, 0,
        "no frame came back with a wrong working counter in {} cycles",
        r.cycles
    );
    // A frame not back within 5 ms is the shared machine's doing (the peer is Python,
    // not real time); the peer itself fails above 2 %.
    assert!(
        r.late_frames * 50 <= r.cycles,
        "{} of {} frames late",
        r.late_frames,
        r.cycles
    );
    assert_eq!(r.sdo_vendor, vec![VENDOR_ID; SERVOS], "SDO 0x1018:01");
    assert_eq!(
        r.sdo_1c12,
        vec![vec![0x1600]; SERVOS],
        "SDO 0x1C12: one RxPDO, 0x1600"
    );
    assert_eq!(
        r.enabled,
        vec![true; SERVOS],
        "every servo Operation enabled"
    );
    let wd = r.watchdog.as_ref().expect("the watchdog stage ran");
    assert_eq!(
        wd.tripped,
        vec![("SAFEOP+ERROR".to_string(), 0x001B); SERVOS],
        "the process-data watchdog took every slave to SAFEOP with 0x001B"
    );
    assert_eq!(wd.drive_faulted, vec![true; SERVOS], "every drive faulted");
    assert_eq!(wd.after_ack, vec!["SAFEOP"; SERVOS], "acknowledged");
    assert!(r.ok, "the peer reported failures: {:?}", r.errors);
    assert!(
        peer.status.success(),
        "the peer exited with {}",
        peer.status
    );
}

#[test]
#[ignore = "needs root, the gantry-sim binary and the pysoem venv; deploy/test.sh runs it"]
fn soem_brings_three_servos_to_op_and_enables_them() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let python = peer_python();
    let pair = VethPair::create("soem").expect("veth pair in two namespaces");
    let (sim, dir) = start_sim(&pair.sim_ns, &pair.sim_if, "soem");
    let (peer, report) = run_peer(&python, &pair.master_ns, &pair.master_if, &[]);
    drop(sim);
    std::fs::remove_dir_all(&dir).unwrap();
    check_bringup(&peer, &report);
}

#[test]
#[ignore = "needs root, the gantry-sim binary and the pysoem venv; deploy/test.sh runs it"]
fn soem_recovers_lost_mailbox_answers_by_repeat_request() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let python = peer_python();
    let line = RelayedVeth::create("soemloss").expect("three namespaces in a line");
    let (sim, dir) = start_sim(&line.sim_ns, &line.sim_if, "soemloss");
    let relay_script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("peers/lossy_relay.py");
    let mailbox_in = format!("{:#06x}", gantry_sim::catalog::MAILBOX_IN_AT);
    let mut relay = Command::new("ip")
        .args(["netns", "exec", &line.relay_ns])
        .arg(&python)
        .arg(&relay_script)
        .args([&line.relay_master_if, &line.relay_sim_if])
        .args(["--mailbox-in", &mailbox_in, "--drop-every", "5"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start the relay");
    let mut relay_out = BufReader::new(relay.stdout.take().unwrap());
    let mut ready = String::new();
    relay_out.read_line(&mut ready).unwrap();
    assert!(ready.contains("ready"), "relay started: {ready:?}");
    let (peer, report) = run_peer(&python, &line.master_ns, &line.master_if, &[]);
    let _ = relay.kill();
    let _ = relay.wait();
    drop(sim);
    std::fs::remove_dir_all(&dir).unwrap();
    let mut drops = String::new();
    std::io::Read::read_to_string(&mut relay_out, &mut drops).unwrap();
    let dropped = drops.lines().filter(|l| l.contains("dropped")).count();
    eprintln!("relay: {dropped} mailbox answers dropped");
    // SOEM reads 16 objects per servo while mapping plus 3 in the test: 57 answers.
    assert!(dropped >= 5, "the relay dropped mailbox answers: {dropped}");
    check_bringup(&peer, &report);
}
