//! A clean shutdown of gantry on a CANopen bus leaves the nodes quiet, in lockstep on
//! simulated nodes. The bring-up had every node watch gantry's SYNC (0x1006) and
//! heartbeat (0x1016:01); after the drives are disabled the bus sends NMT pre-operational
//! and writes both to 0 by SDO on every node at once (CiA 301 §7.5.2.6, §7.5.2.16: 0 =
//! not used), keeping its SYNC and heartbeat going until each node confirmed, so no node
//! reports a lost SYNC (EMCY 0x8100) or heartbeat (EMCY 0x8130) afterwards — before, each
//! did about `master_timeout_ms` later. A node that does not confirm is named and the
//! shutdown still ends within `RELEASE_TIMEOUT_NS`; that node does report the loss, which
//! shows what the first test's silence is worth.

use gantry::canopen::bus::RELEASE_TIMEOUT_NS;
use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::cia402::state::State;
use gantry_sim::canopen::bus::Sender;
use gantry_sim::canopen::nmt::NmtSlaveState;
use gantry_tests::can_rig::{can_config, lock, servos, CanRig, SharedBus};

const NODES: [u8; 3] = [1, 2, 3];

/// Object `index`:`sub` of `node` (up to 4 bytes).
fn object_u32(bus: &SharedBus, node: u8, index: u16, sub: u8) -> u32 {
    let mut out = [0u8; 4];
    lock(bus)
        .node_mut(node)
        .read_object(index, sub, &mut out)
        .unwrap_or_else(|e| panic!("node {node} 0x{index:04X}:{sub}: {e}"));
    u32::from_le_bytes(out)
}

/// Three drives enabled, the first moving, the bus' log position and time before the
/// shutdown is asked for.
fn moving_rig() -> (CanRig, usize, u64) {
    let config = can_config(&NODES, 2000, "csp");
    let mut rig = CanRig::new(&config, servos(&NODES));
    for axis in 0..NODES.len() {
        rig.enable_and_home(axis);
    }
    let _moving = rig.start_move(0, 200.0);
    rig.run(100);
    assert_eq!(
        rig.sim().node(1).device().drive_state(),
        Some(State::OperationEnabled)
    );
    let from = rig.sim().bus.log().len();
    let at = rig.sim().now_ns();
    (rig, from, at)
}

/// Lets the bus' time run on by `ms` (the nodes alone: gantry has stopped).
fn run_on(bus: &SharedBus, ms: u64) {
    let start = lock(bus).now_ns();
    for k in 1..=ms {
        lock(bus).cycle_at(start + k * 1_000_000);
    }
}

/// EMCYs (ms after `at`, node, error code) the nodes sent after log entry `from`, resets
/// (code 0) left out.
fn emcys(bus: &SharedBus, from: usize, at: u64) -> Vec<(u64, u8, u16)> {
    lock(bus).bus.log()[from..]
        .iter()
        .filter(|d| matches!(d.from, Sender::Node(_)))
        .filter_map(|d| Some((d.at_ns, Emergency::parse(&d.frame).ok()?)))
        .filter(|(_, e)| !e.is_reset())
        .map(|(t, e)| ((t - at) / 1_000_000, e.node.get(), e.error_code))
        .collect()
}

/// The "in N ms" of the shutdown's summary line.
fn took_ms(log: &str) -> u64 {
    let line = log
        .lines()
        .find(|l| l.starts_with("CANopen: nodes pre-operational"))
        .unwrap_or_else(|| panic!("no summary: {log}"));
    line.rsplit(" in ")
        .next()
        .and_then(|t| t.strip_suffix(" ms"))
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{line}"))
}

#[test]
fn after_a_clean_shutdown_no_node_reports_a_lost_sync_or_heartbeat() {
    let (rig, from, at) = moving_rig();
    let (log, bus) = rig.shut_down(5000);
    eprintln!("{log}");
    assert!(log.contains("taken back on node(s) 1, 2, 3 in"), "{log}");
    let took = took_ms(&log);
    // Two expedited SDO exchanges per node, the three nodes at once, at 1 Mbit/s.
    assert!(took <= 10, "{took} ms");
    let end = lock(&bus).now_ns();
    // Well past gantry's SYNC watchdog (3 ms) and heartbeat consumer time (300 ms).
    run_on(&bus, 1000);
    let quiet = emcys(&bus, from, at);
    assert_eq!(quiet, vec![], "EMCYs after the shutdown (ms, node, code)");
    for n in NODES {
        let b = lock(&bus);
        let node = b.node(n);
        assert_eq!(node.nmt_state(), NmtSlaveState::PreOperational, "node {n}");
        assert!(!node.device().faulted(), "node {n}");
        assert_ne!(
            node.device().drive_state(),
            Some(State::OperationEnabled),
            "node {n}"
        );
        drop(b);
        assert_eq!(object_u32(&bus, n, 0x1006, 0), 0, "node {n}: SYNC watchdog");
        assert_eq!(
            object_u32(&bus, n, 0x1016, 1),
            0,
            "node {n}: heartbeat consumer"
        );
    }
    // gantry sent nothing after its shutdown returned (its heartbeat stopped).
    let b = lock(&bus);
    let late = b
        .bus
        .log()
        .iter()
        .filter(|d| d.from == Sender::Master && d.at_ns > end)
        .count();
    assert_eq!(late, 0);
}

#[test]
fn a_node_that_does_not_confirm_is_named_within_the_bound_and_reports_the_loss() {
    let (rig, from, at) = moving_rig();
    // Node 2's SDO answers no longer reach gantry (its requests still reach node 2).
    rig.sim().drop_frames(0x582, true);
    let (log, bus) = rig.shut_down(5000);
    eprintln!("{log}");
    assert!(
        log.contains(
            "CANopen node 2: the SYNC watchdog (0x1006) not taken back (no answer in time): \
             it may still watch"
        ),
        "{log}"
    );
    assert!(log.contains("taken back on node(s) 1, 3 in"), "{log}");
    let took = took_ms(&log);
    assert!(
        took * 1_000_000 <= RELEASE_TIMEOUT_NS,
        "{took} ms, bound {} ms",
        RELEASE_TIMEOUT_NS / 1_000_000
    );
    run_on(&bus, 1000);
    let all = emcys(&bus, from, at);
    eprintln!("EMCYs (ms, node, code): {all:04X?}");
    // Node 2 still watches gantry's heartbeat: it reports the loss; 1 and 3 are quiet.
    assert!(
        all.iter().any(|&(_, n, code)| n == 2 && code == 0x8130),
        "{all:04X?}"
    );
    assert!(all.iter().all(|&(_, n, _)| n == 2), "{all:04X?}");
}
