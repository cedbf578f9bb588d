//! A CANopen master no one here wrote — python-canopen (PyPI `canopen`, run as its own
//! process from the test venv) — against `gantry-sim --can vcan1`: NMT reset and boot-up,
//! SDO of every kind it has (expedited, segmented, block; both ways; an abort), a TPDO
//! mapped and saved its way, the CiA 402 state machine to Operation enabled through its
//! `BaseNode402`, and a small CSP move on SYNC. The simulator follows CiA 301/402, not the
//! peer: the peer script runs the cycle (RPDO then SYNC) itself, since BaseNode402 leaves
//! a synchronous RPDO for someone else to send.
//!
//! The peer is `tests/peers/canopen_master.py`; its last line on stdout is a JSON report.
//!
//! The other way round, gantry-drives' SDO client and heartbeat parsing (the master's
//! pieces) against python-canopen's `LocalNode` (`tests/peers/canopen_node.py`) on vcan0:
//! its heartbeats and boot-up, SDO expedited and segmented both ways (a 1000-byte DOMAIN
//! in 143 segments), its aborts, and what it does with block requests (it has no block
//! server).
//!
//! Needs vcan0, vcan1 and the venv deploy/test.sh makes (`GANTRY_PEER_PYTHON`, with
//! `canopen`); built with `--features vcan`, run in the VM of deploy/vm/. Fails without
//! them.

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use gantry_drives::canopen::cob_id::NodeId;
use gantry_drives::canopen::heartbeat::Heartbeat;
use gantry_drives::canopen::nmt::NmtCommand;
use gantry_drives::canopen::sdo::{AbortCode, DownloadMode, Outcome, SdoConfig, Side, UploadMode};
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

/// The python-canopen node's id on vcan0.
const PEER_NODE: u8 = 9;
/// Bytes of its DOMAIN 0x2100.
const DOMAIN_BYTES: usize = 1000;

fn heartbeat_states(master: &mut CanMaster, count: usize) -> Vec<u8> {
    let id = 0x700 + u16::from(PEER_NODE);
    (0..count)
        .map(|_| {
            let f = master
                .wait_for(Duration::from_secs(10), |f| f.id() == id)
                .expect("a heartbeat of the python-canopen node");
            Heartbeat::parse(&f).expect("a well-formed heartbeat");
            f.data()[0]
        })
        .collect()
}

#[test]
fn vcan_peer_gantry_sdo_client_against_python_canopen_local_node() {
    let python = peer_python();
    let node = NodeId::new(PEER_NODE).unwrap();
    let mut master = CanMaster::open("vcan0");
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("peers/canopen_node.py");
    let mut peer = gantry_tests::netns::Reaped::new(
        Command::new(&python)
            .arg(&script)
            .arg("vcan0")
            .args(["--node", &PEER_NODE.to_string()])
            .args(["--domain-bytes", &DOMAIN_BYTES.to_string()])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{}: {e}", python.display())),
    );
    let mut stdout = BufReader::new(peer.child().stdout.take().unwrap());
    let mut line = String::new();
    stdout.read_line(&mut line).unwrap();
    assert_eq!(line.trim(), "ready", "the peer did not start");

    // Boot-up (a heartbeat with state 0), then heartbeats in Pre-operational.
    let boot = master
        .wait_for(Duration::from_secs(10), |f| {
            Heartbeat::parse(f).is_ok_and(|h| h.is_boot_up())
        })
        .expect("the python-canopen node's boot-up");
    assert_eq!(boot.id(), 0x700 + u16::from(PEER_NODE));
    assert_eq!(heartbeat_states(&mut master, 2), vec![0x7F, 0x7F]);

    // SDO, expedited and segmented uploads.
    let device_type = master.upload(node, 0x1000, 0, UploadMode::Normal).unwrap();
    assert_eq!(device_type, 0x0000_0191u32.to_le_bytes());
    let name = master.upload(node, 0x1008, 0, UploadMode::Normal).unwrap();
    assert_eq!(name, b"python-canopen LocalNode");
    let pattern: Vec<u8> = (0..DOMAIN_BYTES).map(|i| (i % 251) as u8).collect();
    let first = master.seen.len();
    assert_eq!(
        master.upload(node, 0x2100, 0, UploadMode::Normal).unwrap(),
        pattern
    );
    let segments = master.seen[first..]
        .iter()
        .filter(|r| r.frame.id() == 0x580 + u16::from(PEER_NODE) && r.frame.data()[0] & 0xE0 == 0)
        .count();
    assert_eq!(segments, DOMAIN_BYTES.div_ceil(7), "7 bytes a segment");
    // Downloads, read back.
    master
        .download(
            node,
            0x2101,
            0,
            &0xDEAD_BEEFu32.to_le_bytes(),
            DownloadMode::Expedited,
        )
        .unwrap();
    let back = master.upload(node, 0x2101, 0, UploadMode::Normal).unwrap();
    assert_eq!(back, 0xDEAD_BEEFu32.to_le_bytes());
    let written: Vec<u8> = (0..600).map(|i| (i * 7 % 256) as u8).collect();
    master
        .download(node, 0x2100, 0, &written, DownloadMode::Segmented)
        .unwrap();
    assert_eq!(
        master.upload(node, 0x2100, 0, UploadMode::Normal).unwrap(),
        written
    );
    // Its aborts reach our client with their codes.
    let missing = master.upload(node, 0x5FFF, 0, UploadMode::Normal);
    assert!(
        matches!(missing, Err(Outcome::Aborted { code, by: Side::Server, .. }) if code == AbortCode::OBJECT_DOES_NOT_EXIST),
        "{missing:?}"
    );
    let short = master.download(node, 0x2101, 0, &[1, 2, 3], DownloadMode::Expedited);
    assert!(
        matches!(short, Err(Outcome::Aborted { code, by: Side::Server, .. }) if code == AbortCode::LENGTH_MISMATCH),
        "{short:?}"
    );
    // No block server. Asked for a block upload it answers with a normal upload (CiA 301
    // §7.2.4.3.13 allows that only up to the protocol switch threshold the client
    // offered): with none offered (pst 0) our client refuses the switch, with one it takes
    // the data.
    let strict = master.upload(node, 0x1008, 0, UploadMode::Block);
    assert!(
        matches!(strict, Err(Outcome::Aborted { code, by: Side::Client, .. }) if code == AbortCode::INVALID_COMMAND_SPECIFIER),
        "{strict:?}"
    );
    let switch = SdoConfig {
        pst: 127,
        ..SdoConfig::default()
    };
    let switched = master.upload_with(switch, node, 0x1008, 0, UploadMode::Block);
    assert_eq!(switched.unwrap(), b"python-canopen LocalNode");
    // A block download is refused by the node.
    let block = master.download(node, 0x2101, 0, &[1, 2, 3, 4], DownloadMode::Block);
    assert!(
        matches!(block, Err(Outcome::Aborted { code, by: Side::Server, .. }) if code == AbortCode::INVALID_COMMAND_SPECIFIER),
        "{block:?}"
    );
    // NMT: its heartbeats follow (the one in flight may still say the old state).
    master.nmt(NmtCommand::Start, node);
    let states = heartbeat_states(&mut master, 2);
    assert_eq!(states[1], 0x05, "operational: {states:?}");

    // The node's own record of what we wrote.
    drop(peer.child().stdin.take());
    let mut rest = String::new();
    stdout.read_to_string(&mut rest).unwrap();
    let status = peer.take().wait().unwrap();
    assert!(status.success(), "peer exited {status}: {rest}");
    let report: Value = serde_json::from_str(rest.lines().last().unwrap_or(""))
        .unwrap_or_else(|e| panic!("no JSON report ({e}): {rest}"));
    let hex: String = written.iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(report["domain"], hex);
    assert_eq!(report["value"], 0xDEAD_BEEFu32);
    assert_eq!(report["nmt_state"], "OPERATIONAL");
}
