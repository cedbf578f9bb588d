//! gantry on a CANopen bus is a heartbeat producer and SYNC producer as CiA 301 asks, in
//! lockstep on simulated nodes: its heartbeat (0x700 + `[bus] master_node`, state
//! Operational) goes at `heartbeat_ms` from the cycle, the bring-up gives every node a
//! consumer for it (0x1016:01), so a drive whose master stops cycling — gantry died, the
//! cable is pulled — faults by its 0x6007 reaction (EMCY 0x8130) and stops; with
//! `[bus] sync_counter = N` every node is given 0x1019 = N (0x1006 at 0 while it is
//! written) and the SYNC counts 1..=N.

use gantry_drives::canopen::cob_id::SYNC_COB_ID;
use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::{CanFrame, NodeId};
use gantry_drives::cia402::state::State;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_sim::canopen::bus::Sender;
use gantry_tests::can_rig::{can_config, can_config_with, servos, CanRig};

/// Object `index`:`sub` of `node` as the simulated node holds it (up to 4 bytes).
fn object_u32(rig: &CanRig, node: u8, index: u16, sub: u8) -> u32 {
    let mut s = rig.sim();
    let mut out = [0u8; 4];
    let n = s
        .node_mut(node)
        .read_object(index, sub, &mut out)
        .unwrap_or_else(|e| panic!("node {node} 0x{index:04X}:{sub}: {e}"));
    assert!(n <= 4);
    u32::from_le_bytes(out)
}

/// When each frame with identifier `id` that gantry sent was on the bus, and its data.
fn sent_by_master(rig: &CanRig, id: u16) -> Vec<(u64, Vec<u8>)> {
    rig.sim()
        .bus
        .log()
        .iter()
        .filter(|d| d.from == Sender::Master && d.frame.id() == id)
        .map(|d| (d.at_ns, d.frame.data().to_vec()))
        .collect()
}

#[test]
fn gantry_produces_its_heartbeat_at_the_period_and_every_node_consumes_it() {
    let nodes = [1u8, 2];
    let config = can_config(&nodes, 2000, "csp");
    let mut rig = CanRig::new(&config, servos(&nodes));
    assert!(
        rig.log.contains(
            "CANopen: gantry is node 127: its heartbeat every 100 ms, the nodes stop 300 ms \
             without it; SYNC without counter"
        ),
        "{}",
        rig.log
    );
    let start = rig.sim().now_ns();
    rig.run(1000); // 2 s of 2 ms cycles.
    let beats = sent_by_master(&rig, 0x700 + 127);
    // The first with the first exchange, then every 100 ms: 20 in 2 s.
    assert_eq!(beats.len(), 20, "{beats:?}");
    assert!(
        beats.iter().all(|(_, d)| d == &[0x05]),
        "Operational: {beats:?}"
    );
    assert!(beats[0].0 - start < 4_000_000, "{} ns", beats[0].0 - start);
    for w in beats.windows(2) {
        let gap = w[1].0 - w[0].0;
        // Sent by the cycle every 50th exchange (100 ms of 2 ms cycles); on the wire
        // within the cycle's frames' time of that (0.5 ms at 1 Mbit/s here).
        assert!((99_500_000..=100_500_000).contains(&gap), "gap {gap} ns");
    }
    assert_eq!(rig.engine.bus.heartbeats_sent(), 20);
    for n in nodes {
        // gantry's node id 127 << 16 | 300 ms (three heartbeat times).
        assert_eq!(object_u32(&rig, n, 0x1016, 1), 127 << 16 | 300, "node {n}");
        // No node reported a heartbeat error while gantry cycled.
        let emcys = rig.sim().node(n).counters();
        assert!(!rig.sim().node(n).device().faulted(), "node {n}: {emcys:?}");
    }
}

/// Node 1 moving under gantry at 200 mm/s, `[bus] master_node = 100`, consumer time
/// 250 ms; with `sync_watchdog` false, node 1's 0x1006 is set to 0 by another SDO client
/// (CiA 301 §7.5.2.6: 0 = not used), so that only the heartbeat consumer watches gantry.
fn moving(sync_watchdog: bool) -> CanRig {
    let nodes = [1u8];
    let config = can_config_with(
        &nodes,
        2000,
        "csp",
        "master_node = 100\nmaster_timeout_ms = 250",
    );
    let mut rig = CanRig::new(&config, servos(&nodes));
    assert_eq!(object_u32(&rig, 1, 0x1016, 1), 100 << 16 | 250);
    if !sync_watchdog {
        // Expedited download, 4 bytes (CiA 301 §7.2.4.3.3: 0x23), 0x1006:00 = 0.
        let f = CanFrame::new(0x601, &[0x23, 0x06, 0x10, 0x00, 0, 0, 0, 0]).unwrap();
        rig.sim().inject(f);
        rig.run(2);
        assert_eq!(object_u32(&rig, 1, 0x1006, 0), 0);
    }
    rig.enable_and_home(0);
    let _moving = rig.start_move(0, 200.0);
    rig.run(200);
    assert_eq!(
        rig.sim().node(1).device().drive_state(),
        Some(State::OperationEnabled)
    );
    rig
}

/// gantry stops (hangs, dies): the engine is no longer stepped, the bus' time runs on
/// 2 ms a step for 600 ms. When node 1's drive faulted (after the stop), the EMCYs it
/// sent meanwhile, and whether its shaft stands still at the end.
fn stop_cycling(rig: &mut CanRig) -> (u64, Vec<(u64, u16)>, bool) {
    let log_from = rig.sim().bus.log().len();
    let stopped_at = rig.sim().now_ns();
    let mut faulted_at = None;
    let mut positions = Vec::new();
    for k in 1..=300u64 {
        let t = stopped_at + k * 2_000_000;
        rig.sim().cycle_at(t);
        if faulted_at.is_none() && rig.sim().node(1).device().faulted() {
            faulted_at = Some(t);
        }
        positions.push(rig.sim().node(1).axis_position().unwrap());
    }
    let faulted_at = faulted_at.expect("the drive faulted");
    let emcys = rig.sim().bus.log()[log_from..]
        .iter()
        .filter(|d| d.from == Sender::Node(0) && d.frame.id() == 0x081)
        .filter_map(|d| Some((d.at_ns - stopped_at, Emergency::parse(&d.frame).ok()?)))
        .filter(|(_, e)| !e.is_reset())
        .map(|(t, e)| (t / 1_000_000, e.error_code))
        .collect();
    // Still for the last 100 ms.
    let still = positions[200..].windows(2).all(|w| w[0] == w[1]);
    // The drive was moving when gantry stopped.
    assert_ne!(positions[0], positions[299]);
    ((faulted_at - stopped_at) / 1_000_000, emcys, still)
}

#[test]
fn a_drive_watching_only_gantrys_heartbeat_faults_with_0x8130_and_stops_when_gantry_stops() {
    let mut rig = moving(false);
    let (faulted_ms, emcys, still) = stop_cycling(&mut rig);
    eprintln!("faulted {faulted_ms} ms after the stop; EMCYs (ms, code) {emcys:04X?}");
    // gantry's last heartbeat came at most 100 ms before the stop; the drive reacts at
    // the 250 ms consumer time after it (0x6007 = 1: fault), not before.
    assert!((150..=252).contains(&faulted_ms), "{faulted_ms} ms");
    let s = rig.sim();
    assert_eq!(s.node(1).device().error_code(), 0x8130);
    assert_eq!(
        emcys.first().map(|(_, code)| *code),
        Some(0x8130),
        "{emcys:?}"
    );
    assert_ne!(
        s.node(1).device().drive_state(),
        Some(State::OperationEnabled)
    );
    assert!(still, "the shaft stopped");
}

#[test]
fn a_drive_whose_master_stops_cycling_faults_on_the_sync_then_reports_the_heartbeat() {
    let mut rig = moving(true);
    let (faulted_ms, emcys, still) = stop_cycling(&mut rig);
    eprintln!("faulted {faulted_ms} ms after the stop; EMCYs (ms, code) {emcys:04X?}");
    // The SYNC watchdog (0x1006 = 2 ms, 1.5 periods) is first: 0x8100.
    assert!(faulted_ms <= 4, "{faulted_ms} ms");
    assert_eq!(rig.sim().node(1).device().error_code(), 0x8100);
    // Then gantry's heartbeat is missed within the consumer time: EMCY 0x8130 too.
    let heartbeat = emcys.iter().find(|(_, code)| *code == 0x8130);
    assert!(
        heartbeat.is_some_and(|(ms, _)| (150..=252).contains(ms)),
        "{emcys:?}"
    );
    assert!(still, "the shaft stopped");
}

#[test]
fn with_sync_counter_the_sync_counts_and_every_node_has_0x1019() {
    let nodes = [1u8, 2, 3];
    let config = can_config_with(&nodes, 2000, "csp-minimal", "sync_counter = 4");
    let mut rig = CanRig::new(&config, servos(&nodes));
    assert!(rig.log.contains("SYNC with counter 1..=4"), "{}", rig.log);
    for n in nodes {
        assert_eq!(object_u32(&rig, n, 0x1019, 0) & 0xFF, 4, "node {n}");
        assert_eq!(object_u32(&rig, n, 0x1006, 0), 2000, "node {n}");
    }
    for axis in 0..nodes.len() {
        rig.enable_and_home(axis);
    }
    let h = rig.start_move(1, 20.0);
    assert_eq!(rig.finish(&h, 5000), CommandStatus::Done);
    let syncs = sent_by_master(&rig, SYNC_COB_ID);
    assert!(syncs.len() > 100, "{} SYNCs", syncs.len());
    for (k, (_, data)) in syncs.iter().enumerate() {
        assert_eq!(data, &[(k % 4) as u8 + 1], "SYNC {k}");
    }
    for n in nodes {
        let c = rig.sim().node(n).counters();
        assert!(c.last_sync_counter.is_some(), "node {n}: {c:?}");
        // No SYNC of the wrong length was reported (EMCY 0x8240).
        let wrong_length = rig
            .sim()
            .bus
            .log()
            .iter()
            .filter(|d| d.frame.id() == 0x080 + u16::from(n))
            .filter_map(|d| Emergency::parse(&d.frame).ok())
            .any(|e| e.error_code == 0x8240);
        assert!(!wrong_length, "node {n}");
    }
    // Node 2 reset by another master (0x1019 back to 0, its power-on value): gantry's
    // reset brings it back with 0x1019 = 4 again (0x1006 = 0 first), and it moves.
    let reset = NmtFrame {
        command: NmtCommand::ResetNode,
        target: NmtTarget::Node(NodeId::new(2).unwrap()),
    };
    rig.sim().inject(reset.emit());
    assert_eq!(object_u32(&rig, 2, 0x1019, 0) & 0xFF, 0);
    while rig.bus_fault(1).is_none() {
        rig.cycle();
    }
    let h = rig.ctl.reset(1).unwrap();
    assert_eq!(rig.finish(&h, 5000), CommandStatus::Done);
    assert_eq!(object_u32(&rig, 2, 0x1019, 0) & 0xFF, 4);
    assert_eq!(object_u32(&rig, 2, 0x1006, 0), 2000);
    let restored_at = rig.sim().bus.log().len();
    assert_eq!(
        rig.command(1, Command::Power(PowerCommand::Enable)),
        CommandStatus::Done
    );
    let h = rig.start_move(1, 0.0);
    assert_eq!(rig.finish(&h, 5000), CommandStatus::Done);
    assert!(rig.sim().node(2).counters().last_sync_counter.is_some());
    // Its SYNCs have the length 0x1019 says again (no EMCY 0x8240 since the restore).
    let wrong_length = rig.sim().bus.log()[restored_at..]
        .iter()
        .filter(|d| d.frame.id() == 0x082)
        .filter_map(|d| Emergency::parse(&d.frame).ok())
        .any(|e| e.error_code == 0x8240);
    assert!(!wrong_length);
    let syncs = sent_by_master(&rig, SYNC_COB_ID);
    for (k, (_, data)) in syncs.iter().enumerate() {
        assert_eq!(data, &[(k % 4) as u8 + 1], "SYNC {k}");
    }
    // Without the key, a SYNC has no data byte and 0x1019 stays 0.
    let mut plain = CanRig::new(&can_config(&[5], 2000, "csp-minimal"), servos(&[5]));
    plain.run(10);
    assert!(sent_by_master(&plain, SYNC_COB_ID)
        .iter()
        .all(|(_, d)| d.is_empty()));
    assert_eq!(object_u32(&plain, 5, 0x1019, 0) & 0xFF, 0);
}
