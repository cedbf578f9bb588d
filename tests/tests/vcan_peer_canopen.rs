//! A CANopen master no one here wrote — python-canopen (PyPI `canopen`, run as its own
//! process from the test venv) — against `gantry-sim --can vcan1`: NMT reset and boot-up,
//! SDO of every kind it has (expedited, segmented, block; both ways; an abort), a TPDO
//! mapped and saved its way, the CiA 402 state machine to Operation enabled through its
//! `BaseNode402`, and a small CSP move on SYNC. The simulator follows CiA 301/402, not the
//! peer: the peer script runs the cycle (RPDO then SYNC) itself, since BaseNode402 leaves
//! a synchronous RPDO for someone else to send.
//!
//! The peer is `tests/peers/canopen_master.py`; its last line on stdout is a JSON report.
//! Needs vcan1 and the venv deploy/test.sh makes (`GANTRY_PEER_PYTHON`, with `canopen`);
//! built with `--features vcan`, run in the VM of deploy/vm/. Fails without them.

use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use gantry_drives::canopen::cob_id::NodeId;
use gantry_drives::canopen::heartbeat::Heartbeat;
use gantry_sim::canopen::eds;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use gantry_sim::config::{SimConfig, SlaveConfig};
use gantry_tests::can::{CanMaster, CanSim};
use serde_json::Value;

const IFACE: &str = "vcan1";
const NODE: u8 = 7;
const START: i64 = 1000;
const MOVE: i64 = 20_000;

fn chain() -> String {
    format!(
        "cycle_us = 1000\n[[slave]]\nkind = \"servo\"\nnode = {NODE}\nstart_position = {START}\n"
    )
}

/// The Python of the test venv, or a message that says how to get it.
fn peer_python() -> PathBuf {
    match std::env::var_os("GANTRY_PEER_PYTHON") {
        Some(p) if !p.is_empty() => {
            let p = PathBuf::from(p);
            assert!(
                p.exists(),
                "GANTRY_PEER_PYTHON={} does not exist",
                p.display()
            );
            p
        }
        _ => panic!(
            "GANTRY_PEER_PYTHON is not set: run deploy/test.sh, which makes the venv with \
             python-canopen under ~/.cache/gantry/venv and passes its python to the VM"
        ),
    }
}

/// The EDS of the simulated node, written from the same chain description.
fn write_eds(dir: &std::path::Path) -> PathBuf {
    let config = SimConfig::parse(&chain(), "sim.toml").unwrap();
    let SlaveConfig::Servo(servo) = &config.slaves[0] else {
        unreachable!("the chain is one servo")
    };
    let mut node =
        CanNode::new(CanNodeConfig::from_servo(NodeId::new(NODE).unwrap(), servo)).unwrap();
    let path = dir.join(format!("gantry-sim-node{NODE}.eds"));
    std::fs::write(&path, eds::write(&mut node, "gantry-sim-node.eds")).unwrap();
    path
}

#[test]
fn vcan_peer_python_canopen_drives_the_simulated_servo() {
    let python = peer_python();
    let dir = std::env::temp_dir().join(format!("gantry-vcan-peer-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let eds_path = write_eds(&dir);
    let mut watch = CanMaster::open(IFACE);
    let sim = CanSim::start(IFACE, &chain());
    watch
        .wait_for(Duration::from_secs(5), |f| {
            Heartbeat::parse(f).is_ok_and(|h| h.is_boot_up())
        })
        .expect("gantry-sim's node boots");

    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("peers/canopen_master.py");
    let mut peer = Command::new(&python)
        .arg(&script)
        .arg(IFACE)
        .args(["--node", &NODE.to_string(), "--move", &MOVE.to_string()])
        .arg("--eds")
        .arg(&eds_path)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{}: {e}", python.display()));
    // Under software emulation Python is slow: 5 minutes at most.
    let t0 = Instant::now();
    let status = loop {
        if let Some(status) = peer.try_wait().unwrap() {
            break status;
        }
        if t0.elapsed() > Duration::from_secs(300) {
            let _ = peer.kill();
            let _ = peer.wait();
            panic!("the python-canopen peer did not finish in 300 s");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let (mut out, mut err) = (String::new(), String::new());
    peer.stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    peer.stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let (sim_status, sim_text) = sim.stop();
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!("peer stderr:\n{err}\ngantry-sim:\n{sim_text}");
    assert!(status.success(), "peer exited {status}: {out}{err}");
    assert!(
        sim_status.success(),
        "gantry-sim ended {sim_status}: {sim_text}"
    );
    let report: Value = serde_json::from_str(out.lines().last().unwrap_or(""))
        .unwrap_or_else(|e| panic!("no JSON report ({e}): {out}"));
    eprintln!("report: {report}");

    assert_eq!(report["bootup"], true);
    // SDO.
    assert_eq!(report["device_type"], 0x0002_0192);
    assert_eq!(report["name_segmented"], "gantry-sim CiA 402 servo");
    assert_eq!(report["name_block"], "gantry-sim CiA 402 servo");
    assert_eq!(report["downloads"]["expedited"], 1111);
    assert_eq!(report["downloads"]["segmented"], 2222);
    assert_eq!(report["downloads"]["block"], 3333);
    assert_eq!(report["abort_code"], 0x0602_0000, "object does not exist");
    assert_eq!(report["heartbeat_ms"], 100);
    // PDOs: the power-on mapping as read, TPDO2 as saved (valid, 0x280 + node).
    assert_eq!(report["rpdo1"], serde_json::json!([0x6040, 0x607A]));
    assert_eq!(report["tpdo1"], serde_json::json!([0x6041, 0x6064]));
    assert_eq!(
        report["tpdo2_cob_id"].as_u64().unwrap() & 0x8000_07FF,
        0x280 + u64::from(NODE)
    );
    assert_eq!(
        report["tpdo2"][0], START,
        "TPDO2 on SYNC: position actual value"
    );
    assert_eq!(report["op_mode"], 8, "cyclic synchronous position");
    // CiA 402: to Operation enabled, one transition at a time.
    assert_eq!(
        report["states"],
        serde_json::json!([
            "SWITCH ON DISABLED",
            "READY TO SWITCH ON",
            "SWITCHED ON",
            "OPERATION ENABLED"
        ])
    );
    // The move: from the start to the target, in Operation enabled throughout.
    assert_eq!(report["start"], START);
    assert_eq!(report["target"], START + MOVE);
    let end = report["end"].as_i64().unwrap();
    assert!(
        (end - (START + MOVE)).abs() <= 10,
        "the axis ended at {end}, target {}",
        START + MOVE
    );
    assert_eq!(report["state_after_move"], "OPERATION ENABLED");
    assert_eq!(report["state_disabled"], "SWITCH ON DISABLED");
    assert_eq!(report["emcy"], serde_json::json!([]), "no EMCY");
    assert!(
        report["cycles"].as_u64().unwrap() >= 100,
        "{}",
        report["cycles"]
    );
}
