//! What the CANopen bus does when a drive or its node fails, in lockstep on simulated
//! nodes: an EMCY's code and text reach the axis (ErrorStop), a node whose heartbeat
//! stays away past the consumer time, a node that resets (boot-up) and a node whose TPDOs
//! stop each stop their own axis with the reason while the others move on, and a reset
//! brings the node back — NMT reset communication, its configuration by SDO one write per
//! cycle, NMT start — after which its axis moves again.

use gantry::axis_fault::describe_fault;
use gantry::runtime::bus::CycleBus;
use gantry::runtime::cycle::COMMUNICATION_FAULT;
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::NodeId;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use gantry_sim::canopen::nmt::NmtSlaveState;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use gantry_tests::can_rig::{can_config, servos, CanRig};

const NODES: [u8; 4] = [1, 2, 3, 4];

/// The error the kernel holds for `axis`.
fn error(rig: &CanRig, axis: usize) -> Option<AxisFault> {
    rig.engine.cycle.kernel.axis_status(axis).unwrap().error
}

/// Four drives enabled at 0, moving to 200 mm (a second at full speed).
fn moving() -> (CanRig, Vec<gantry::runtime::controller::CommandHandle>) {
    let config = can_config(&NODES, 2000, "csp");
    let mut rig = CanRig::new(&config, servos(&NODES));
    for axis in 0..NODES.len() {
        rig.enable_and_home(axis);
    }
    let handles = (0..NODES.len()).map(|a| rig.start_move(a, 200.0)).collect();
    rig.run(100);
    (rig, handles)
}

/// Resets `axis` (its node brought back first), enables it and moves it to `to`.
fn reset_enable_move(rig: &mut CanRig, axis: usize, to: f64) {
    let h = rig.ctl.reset(axis).unwrap();
    assert_eq!(
        rig.finish(&h, 5000),
        CommandStatus::Done,
        "reset: {:?}",
        rig.engine.last_restore()
    );
    let restore = rig
        .engine
        .last_restore()
        .expect("the bus restored the drive");
    assert_eq!(restore.axis, axis);
    assert_eq!(
        restore.outcome,
        Ok(gantry::runtime::bus::Restored::BackInOperation)
    );
    assert!(
        restore.cycles > 30,
        "one SDO write per cycle: {} cycles",
        restore.cycles
    );
    assert!(!rig.engine.bus.any_fault());
    assert_eq!(rig.state(axis), AxisState::Disabled, "the drive is off");
    let status = rig.command(axis, Command::Power(PowerCommand::Enable));
    assert_eq!(status, CommandStatus::Done);
    let h = rig.start_move(axis, to);
    let status = rig.finish(&h, 10_000);
    assert_eq!(
        status,
        CommandStatus::Done,
        "{:?}; drive {:?}",
        rig.engine.cycle.kernel.axis_status(axis),
        rig.engine.cycle.inputs(axis)
    );
}

#[test]
fn an_emcy_stops_its_axis_with_the_drive_code_and_text() {
    // Node 2's following error window is 50 counts: a move at speed trips it (0x8611). The
    // minimal layout has no 0x603F: the code comes by EMCY alone.
    let config = can_config(&[1, 2], 1000, "csp-minimal");
    let mut tight = CanNodeConfig::servo(NodeId::new(2).unwrap());
    tight.params.following_error_window = 50;
    let nodes = vec![
        CanNode::new(CanNodeConfig::servo(NodeId::new(1).unwrap())).unwrap(),
        CanNode::new(tight).unwrap(),
    ];
    let mut rig = CanRig::new(&config, nodes);
    rig.enable_and_home(0);
    rig.enable_and_home(1);
    let a = rig.start_move(0, 50.0);
    let b = rig.start_move(1, 50.0);
    assert!(matches!(
        rig.finish(&b, 5000),
        CommandStatus::Error(_) | CommandStatus::Aborted
    ));
    assert_eq!(rig.state(1), AxisState::ErrorStop);
    let fault = error(&rig, 1).expect("an error");
    assert_eq!(fault, AxisFault::Drive { code: 0x8611 });
    assert!(
        describe_fault(&fault).starts_with("drive fault 0x8611: following error"),
        "{}",
        describe_fault(&fault)
    );
    assert_eq!(
        rig.bus_fault(1),
        None,
        "the node is reachable: a drive fault"
    );
    assert!(rig.sim().node(2).counters().emcys >= 1);
    // The other axis is not concerned.
    assert_eq!(rig.finish(&a, 10_000), CommandStatus::Done);
    // A reset clears the drive's fault (the fault reset, then the EMCY 0x0000).
    let h = rig.ctl.reset(1).unwrap();
    assert_eq!(rig.finish(&h, 1000), CommandStatus::Done);
    assert_eq!(rig.state(1), AxisState::Disabled);
    assert_eq!(error(&rig, 1), None);
    assert_eq!(
        rig.engine.bus.drive_error(1),
        None,
        "error reset EMCY taken"
    );
}

#[test]
fn heartbeat_loss_mid_move_stops_its_axis_with_the_reason_and_a_reset_brings_it_back() {
    let (mut rig, handles) = moving();
    // Node 3's heartbeats (0x703) no longer reach gantry; its TPDOs still do.
    rig.sim().drop_frames(0x703, true);
    let mut cycles = 0;
    while rig.bus_fault(2).is_none() {
        rig.cycle();
        cycles += 1;
        assert!(cycles < 300, "no heartbeat fault after {cycles} cycles");
    }
    let reason = rig.bus_fault(2).unwrap();
    let silent: u64 = reason
        .strip_prefix("CANopen node 3: no heartbeat for ")
        .and_then(|r| r.strip_suffix(" ms (limit 300 ms)"))
        .unwrap_or_else(|| panic!("{reason}"))
        .parse()
        .unwrap();
    assert!((300..=304).contains(&silent), "{reason}");
    // Within one heartbeat period past the limit (the last one came up to 100 ms before
    // the drop): 150 to 200 cycles of 2 ms.
    assert!((100..=200).contains(&cycles), "{cycles} cycles");
    rig.run(2);
    assert_eq!(rig.state(2), AxisState::ErrorStop);
    assert_eq!(
        error(&rig, 2),
        Some(AxisFault::Drive {
            code: COMMUNICATION_FAULT
        })
    );
    let snapshot = {
        rig.run(10);
        rig.snapshot()
    };
    assert_eq!(
        snapshot.drives[2].bus_fault.map(|f| f.to_string()),
        Some(reason.clone())
    );
    // The others finish their moves.
    for (axis, h) in handles.iter().enumerate() {
        if axis != 2 {
            assert_eq!(rig.finish(h, 10_000), CommandStatus::Done, "axis {axis}");
        }
    }
    // The heartbeat back, a reset: the node brought back by NMT reset communication and
    // its configuration by SDO, the axis moves again.
    rig.sim().drop_frames(0x703, false);
    reset_enable_move(&mut rig, 2, 20.0);
    assert_eq!(rig.sim().node(3).nmt_state(), NmtSlaveState::Operational);
    assert!(!rig.engine.bus.any_fault());
}

#[test]
fn a_node_that_resets_mid_move_stops_its_axis_and_comes_back_after_a_reset() {
    let (mut rig, handles) = moving();
    // Someone resets node 2 (another NMT master, its power): it boots, Pre-operational.
    let reset = NmtFrame {
        command: NmtCommand::ResetNode,
        target: NmtTarget::Node(NodeId::new(2).unwrap()),
    };
    rig.sim().inject(reset.emit());
    rig.run(2);
    assert_eq!(
        rig.bus_fault(1).as_deref(),
        Some("CANopen node 2: boot-up message: it reset and is Pre-operational")
    );
    rig.run(2);
    assert_eq!(rig.state(1), AxisState::ErrorStop);
    for (axis, h) in handles.iter().enumerate() {
        if axis != 1 {
            assert_eq!(rig.finish(h, 10_000), CommandStatus::Done, "axis {axis}");
        }
    }
    // The node's reset took the drive's power (Switch on disabled, no fault): after the
    // axis' reset it is Disabled, to be enabled again (not Standstill on a drive that
    // takes no set value).
    reset_enable_move(&mut rig, 1, -30.0);
}

#[test]
fn tpdos_lost_past_the_limit_stop_their_axis_naming_the_node() {
    let (mut rig, _) = moving();
    // Node 4's TPDOs (0x184, 0x284) no longer reach gantry: three cycles in a row lost
    // ([bus.faults] lost_frames_limit = 3) fault it.
    rig.sim().drop_frames(0x184, true);
    let before = rig.engine.bus.counters().lost;
    rig.run(2);
    assert_eq!(rig.bus_fault(3), None, "two lost: ridden through");
    rig.cycle();
    assert_eq!(
        rig.bus_fault(3).as_deref(),
        Some("CANopen node 4: no TPDO for 3 cycles in a row")
    );
    assert_eq!(rig.engine.bus.counters().lost - before, 3);
    assert_eq!(rig.engine.bus.counters().incomplete, 3, "TPDO2 still came");
    rig.run(2);
    assert_eq!(rig.state(3), AxisState::ErrorStop);
    rig.sim().drop_frames(0x184, false);
    reset_enable_move(&mut rig, 3, 10.0);
}

#[test]
fn a_reset_fails_naming_the_node_when_it_does_not_come_back() {
    let (mut rig, _) = moving();
    // Node 3 silent for gantry (its heartbeats and boot-ups, 0x703, lost) through the
    // reset: no boot-up after NMT reset communication, the reset fails with the reason.
    rig.sim().drop_frames(0x703, true);
    while rig.bus_fault(2).is_none() {
        rig.cycle();
    }
    let h = rig.ctl.reset(2).unwrap();
    let status = rig.finish(&h, 5000);
    let CommandStatus::Error(e) = status else {
        panic!("{status:?}");
    };
    assert_eq!(
        e.to_string(),
        "Reset: the drive at bus position 2 (CANopen node 3) is not back in operation: no \
         boot-up after NMT reset communication (power, cable?)"
    );
    let restore = rig.engine.last_restore().unwrap();
    // 5 s of 2 ms cycles.
    assert!((2500..=2502).contains(&restore.cycles), "{restore:?}");
    assert_eq!(rig.state(2), AxisState::ErrorStop);
    assert!(rig.bus_fault(2).is_some());
}

/// An expedited SDO download request from another client on the bus (CiA 301 §7.2.4.3.3:
/// 0x23 four bytes, 0x2F one byte).
fn sdo_write(
    node: u8,
    index: u16,
    sub: u8,
    value: u32,
    len: usize,
) -> gantry_drives::canopen::CanFrame {
    let cs = if len == 4 { 0x23 } else { 0x2F };
    let [i0, i1] = index.to_le_bytes();
    let v = value.to_le_bytes();
    gantry_drives::canopen::CanFrame::new(
        0x600 + u32::from(node),
        &[cs, i0, i1, sub, v[0], v[1], v[2], v[3]],
    )
    .unwrap()
}

#[test]
fn a_tpdo_shorter_than_its_mapping_is_never_decoded_and_stops_its_axis() {
    let (mut rig, _) = moving();
    // Another tool remaps node 1's TPDO1 to the statusword alone (2 bytes where gantry
    // mapped 8), by the CiA 301 procedure.
    for f in [
        sdo_write(1, 0x1800, 1, 0x8000_0181, 4),
        sdo_write(1, 0x1A00, 0, 0, 1),
        sdo_write(1, 0x1A00, 1, 0x6041_0010, 4),
        sdo_write(1, 0x1A00, 0, 1, 1),
        sdo_write(1, 0x1800, 1, 0x181, 4),
    ] {
        rig.sim().inject(f);
    }
    let before = rig.engine.bus.malformed();
    // The cycle decodes at its start what the last exchange brought (still whole).
    rig.cycle();
    let position = rig.engine.cycle.inputs(0).unwrap().position;
    rig.run(2);
    assert_eq!(
        rig.engine.bus.malformed() - before,
        3,
        "one short TPDO1 a cycle"
    );
    assert_eq!(
        rig.bus_fault(0).as_deref(),
        Some("CANopen node 1: no TPDO for 3 cycles in a row")
    );
    rig.run(2);
    assert_eq!(
        rig.engine.cycle.inputs(0).unwrap().position,
        position,
        "nothing of the short TPDOs decoded"
    );
    assert_eq!(rig.state(0), AxisState::ErrorStop);
    // A reset maps it again.
    reset_enable_move(&mut rig, 0, 5.0);
}
