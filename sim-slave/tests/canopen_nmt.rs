//! NMT slave (CiA 301 §7.3.2), boot-up (§7.2.8.3.3) and heartbeat producer (§7.2.8.3.2)
//! of the simulated CANopen node, on the in-memory bus.

mod canopen_common;

use canopen_common::*;
use gantry_drives::canopen::heartbeat::NmtState;
use gantry_drives::canopen::nmt::NmtCommand;
use gantry_drives::canopen::sdo::AbortCode;
use gantry_sim::canopen::nmt::NmtSlaveState;

#[test]
fn boot_up_message_at_power_on_and_after_each_reset() {
    let mut m = Master::new(&[3, 5]);
    let got = m.step(0);
    // Both boot: one frame each, 0x700 + id, data [0x00].
    assert_eq!(on(&got, 0x703), vec![frame(0x703, &[0])]);
    assert_eq!(on(&got, 0x705), vec![frame(0x705, &[0])]);
    assert_eq!(got.len(), 2);
    assert_eq!(m.node(0).nmt_state(), NmtSlaveState::PreOperational);

    // Reset node 5 only: it boots again, node 3 does not.
    m.nmt(NmtCommand::Start, None);
    let got = m.nmt(NmtCommand::ResetNode, Some(5));
    assert_eq!(heartbeats(&got, 5), vec![(m.now, NmtState::BootUp)]);
    assert!(heartbeats(&got, 3).is_empty());
    assert_eq!(m.node(1).nmt_state(), NmtSlaveState::PreOperational);
    assert_eq!(m.node(0).nmt_state(), NmtSlaveState::Operational);

    // Reset communication of all: both boot.
    let got = m.nmt(NmtCommand::ResetCommunication, None);
    assert_eq!(heartbeats(&got, 3), vec![(m.now, NmtState::BootUp)]);
    assert_eq!(heartbeats(&got, 5), vec![(m.now, NmtState::BootUp)]);
    assert_eq!(m.node(0).nmt_state(), NmtSlaveState::PreOperational);
}

#[test]
fn each_state_allows_what_table_41_says() {
    let mut m = Master::new(&[4]);
    m.step(0);
    // Pre-operational: SDO answered; a SYNC brings no TPDO; an RPDO is not taken.
    assert_eq!(m.read_u16(4, 0x1017, 0), 100);
    let sync = m.sync_frame();
    let got = m.send(&[frame(0x204, &[0x06, 0, 0, 0, 0, 0]), sync]);
    assert!(on(&got, 0x184).is_empty(), "no TPDO in pre-operational");
    assert_eq!(m.node(0).counters().rpdos, 0, "no RPDO in pre-operational");

    // Operational: the SYNC brings TPDO1 (statusword, position actual value).
    m.nmt(NmtCommand::Start, Some(4));
    assert_eq!(m.node(0).nmt_state(), NmtSlaveState::Operational);
    let sync = m.sync_frame();
    let got = m.send(&[frame(0x204, &[0x06, 0, 0, 0, 0, 0]), sync]);
    let tpdo = on(&got, 0x184);
    assert_eq!(tpdo.len(), 1);
    assert_eq!(tpdo[0].len(), 6);
    assert_eq!(m.node(0).counters().rpdos, 1);
    assert_eq!(m.read_u16(4, 0x1017, 0), 100, "SDO in operational");

    // Stopped: no SDO answer (the client times out), no TPDO, heartbeat says 0x04.
    m.nmt(NmtCommand::Stop, Some(4));
    assert_eq!(m.node(0).nmt_state(), NmtSlaveState::Stopped);
    assert_eq!(m.read(4, 0x1017, 0), Err(AbortCode::TIMED_OUT));
    let sync = m.sync_frame();
    let got = m.send(&[sync]);
    assert!(on(&got, 0x184).is_empty());
    m.take_inbox();
    m.step(100 * MS);
    let hb = heartbeats(&m.take_inbox(), 4);
    assert!(!hb.is_empty());
    assert!(hb.iter().all(|(_, s)| *s == NmtState::Stopped), "{hb:?}");

    // A command for another node changes nothing; pre-operational from stopped.
    m.nmt(NmtCommand::Start, Some(9));
    assert_eq!(m.node(0).nmt_state(), NmtSlaveState::Stopped);
    m.nmt(NmtCommand::EnterPreOperational, None);
    assert_eq!(m.node(0).nmt_state(), NmtSlaveState::PreOperational);
    assert_eq!(m.read_u16(4, 0x1017, 0), 100);
    // Start from stopped goes straight to operational.
    m.nmt(NmtCommand::Stop, None);
    m.nmt(NmtCommand::Start, None);
    assert_eq!(m.node(0).nmt_state(), NmtSlaveState::Operational);
}

#[test]
fn heartbeat_producer_period_follows_0x1017() {
    let mut m = Master::new(&[7]);
    m.step(0);
    m.take_inbox();
    for _ in 0..1000 {
        m.step(MS);
    }
    // 1 s at 100 ms: at 100, 200, ..., 1000 ms, pre-operational.
    let hb = heartbeats(&m.take_inbox(), 7);
    let times: Vec<u64> = hb.iter().map(|(t, _)| t / MS).collect();
    assert_eq!(times, (1..=10).map(|k| k * 100).collect::<Vec<_>>());
    assert!(hb.iter().all(|(_, s)| *s == NmtState::PreOperational));

    // 20 ms from now on; then 0 stops it.
    m.write(7, 0x1017, 0, &20u16.to_le_bytes()).unwrap();
    m.take_inbox();
    let t0 = m.now;
    for _ in 0..200 {
        m.step(MS);
    }
    let hb = heartbeats(&m.take_inbox(), 7);
    assert!(
        (9..=10).contains(&hb.len()),
        "{} heartbeats in 200 ms",
        hb.len()
    );
    for w in hb.windows(2) {
        assert_eq!(w[1].0 - w[0].0, 20 * MS);
    }
    assert!(hb[0].0 > t0);
    m.write(7, 0x1017, 0, &0u16.to_le_bytes()).unwrap();
    m.take_inbox();
    for _ in 0..300 {
        m.step(MS);
    }
    assert!(heartbeats(&m.take_inbox(), 7).is_empty());

    // Reset communication restores the power-on 100 ms.
    m.nmt(NmtCommand::ResetCommunication, Some(7));
    assert_eq!(m.read_u16(7, 0x1017, 0), 100);
}

#[test]
fn reset_node_restores_application_objects_reset_communication_keeps_them() {
    let mut m = Master::new(&[2]);
    m.step(0);
    // 0x6065 following error window; 0x1017.
    m.write(2, 0x6065, 0, &1234u32.to_le_bytes()).unwrap();
    m.write(2, 0x1017, 0, &50u16.to_le_bytes()).unwrap();
    m.nmt(NmtCommand::ResetCommunication, Some(2));
    assert_eq!(m.read(2, 0x6065, 0).unwrap(), 1234u32.to_le_bytes());
    assert_eq!(m.read_u16(2, 0x1017, 0), 100);
    m.nmt(NmtCommand::ResetNode, Some(2));
    assert_ne!(m.read(2, 0x6065, 0).unwrap(), 1234u32.to_le_bytes());
    assert_eq!(m.read(2, 0x6065, 0).unwrap(), (1u32 << 15).to_le_bytes());
}
