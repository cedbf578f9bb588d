//! A second, independent master: SOEM (through the `pysoem` Python package, run as its
//! own process — SOEM is GPL and never linked into gantry) brings three simulated servos
//! to OP over a veth pair, exchanges process data, reads SDOs and enables the drives.
//! The simulator must follow the ESC datasheet, not what ethercrab happens to do.
//!
//! The peer is `tests/peers/soem_bringup.py`; its last line on stdout is a JSON report.
//! Needs root (network namespaces), the `gantry-sim` binary and the pysoem venv that
//! `deploy/test.sh` makes (`GANTRY_PEER_PYTHON`); `deploy/test.sh` runs it.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};

use gantry_sim::catalog::{SERVO_PRODUCT, VENDOR_ID};
use gantry_tests::netns::{gantry_sim_binary, VethPair};
use serde::Deserialize;

const SERVOS: usize = 3;

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
    #[serde(default)]
    sdo_vendor: Vec<u32>,
    #[serde(default)]
    sdo_1c12: Vec<Vec<u16>>,
    enabled: Vec<bool>,
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

#[test]
#[ignore = "needs root, the gantry-sim binary and the pysoem venv; deploy/test.sh runs it"]
fn soem_brings_three_servos_to_op_and_enables_them() {
    let python = peer_python();
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("peers/soem_bringup.py");
    let pair = VethPair::create("soem").expect("veth pair in two namespaces");
    let dir = std::env::temp_dir().join(format!("gantry-soem-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("sim.toml");
    std::fs::write(&config, SIM_CONFIG).unwrap();
    let mut sim = Command::new("ip")
        .args(["netns", "exec", &pair.sim_ns])
        .arg(gantry_sim_binary().unwrap())
        .args(["--interface", &pair.sim_if, "--config"])
        .arg(&config)
        .args(["--seconds", "120"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start gantry-sim");
    // The simulator prints its first line once its socket is bound.
    let mut sim_out = BufReader::new(sim.stdout.take().unwrap());
    let mut first = String::new();
    sim_out.read_line(&mut first).unwrap();
    assert!(first.contains("3 slaves"), "gantry-sim started: {first:?}");

    let peer = Command::new("ip")
        .args(["netns", "exec", &pair.master_ns])
        .arg(&python)
        .arg(&script)
        .arg(&pair.master_if)
        .args(["--seconds", "1.5"])
        .output()
        .expect("run the SOEM peer");
    let _ = sim.kill();
    let _ = sim.wait();
    std::fs::remove_dir_all(&dir).unwrap();
    let stdout = String::from_utf8_lossy(&peer.stdout);
    let stderr = String::from_utf8_lossy(&peer.stderr);
    eprintln!("SOEM peer ({}):\n{stderr}{stdout}", peer.status);
    let json = stdout
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .unwrap_or_else(|| panic!("the peer printed no JSON report ({})", peer.status));
    let r: Report = serde_json::from_str(json).expect("the peer's report parses");

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
        "no working-counter error in {} cycles",
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
    assert!(r.ok, "the peer reported failures: {:?}", r.errors);
    assert!(
        peer.status.success(),
        "the peer exited with {}",
        peer.status
    );
}
