//! What `gantry reset` leaves an axis in after a bus fault — frames lost in a row stop
//! every axis — through the engine on the in-process simulator. PLCopen MC_Reset takes an
//! axis from ErrorStop to Standstill when its power is on and to Disabled when it is off
//! (Part 1, the state diagram and MC_Reset): here the drive decides — an axis whose drive
//! stayed in Operation enabled through the outage is back in Standstill, one whose drive
//! faulted (its fault is reset, CiA 402 leaves it in Switch on disabled) is Disabled until
//! enabled again — whatever the order and the timing of the resets. The bug this guards:
//! the first axis reset after the outage came back Disabled although its drive was
//! powered (the kernel saw gantry's own communication fault, which the recovery had just
//! cleared, as a drive fault), and its drive was switched off; the axes reset after it
//! came back in Standstill.

use gantry::runtime::controller::CommandHandle;
use gantry::runtime::engine::LateReply;
use gantry_drives::cia402::State;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::plant::DeviceModel;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::rig::Rig;

const AXES: usize = 3;

/// Five frames lost in a row (limit 3): every axis stops with the reason. Meanwhile a
/// frame not back within 1 ms is lost, as in a real-time cycle: the rig's usual wait (30
/// ms, for a host that is not real time) would starve the drives for 150 ms, beyond their
/// watchdog, and take them out of Op.
fn lose_frames(rig: &mut Rig) {
    rig.engine.set_late_reply(LateReply::Wait { ns: 1_000_000 });
    rig.chain.lock().unwrap().drop_frames(5);
    rig.run(10);
    rig.engine.set_late_reply(LateReply::WAIT);
    rig.run(10);
    for axis in 0..AXES {
        assert_eq!(rig.state(axis), AxisState::ErrorStop, "axis {axis}");
        assert_eq!(
            rig.bus_fault(axis).as_deref(),
            Some("EtherCAT: 3 frames lost in a row (limit 3)"),
            "axis {axis}"
        );
    }
}

/// The drive's own power state (CiA 402), in the simulator: what it is, not what gantry
/// last read of it (it reads nothing of a drive it cannot reach).
fn drive_state(rig: &Rig, axis: usize) -> State {
    match rig.chain.lock().unwrap().slaves()[axis].device() {
        DeviceModel::Servo(servo) => servo.state(),
        other => panic!("drive {axis} is no servo: {other:?}"),
    }
}

fn reset_all_at_once(rig: &mut Rig) {
    let resets: Vec<CommandHandle> = (0..AXES).map(|a| rig.ctl.reset(a).unwrap()).collect();
    for (axis, h) in resets.iter().enumerate() {
        assert_eq!(rig.finish(h, 5000), CommandStatus::Done, "axis {axis}");
    }
}

/// Every axis moves to `to` and gets there.
fn all_move_to(rig: &mut Rig, to: f64) {
    let moves: Vec<_> = (0..AXES).map(|a| rig.start_move(a, to)).collect();
    for (axis, h) in moves.iter().enumerate() {
        assert_eq!(rig.finish(h, 5000), CommandStatus::Done, "axis {axis}");
    }
}

/// One test: the bus can start once per process.
#[test]
fn a_reset_after_lost_frames_returns_each_axis_to_what_its_drive_is() {
    // Drives that ride through the missed SYNC0 periods of the outage (0x10F1:02; the
    // standard 4 takes a drive out of Op after two): this test is about what the drives
    // that stay powered and the one that faults come back to, not about when they fault.
    let config = gantry_tests::sim_config_with(AXES, 1000, "[slave.al]\nsync_error_limit = 300");
    let mut rig = Rig::new(&config);
    for axis in 0..AXES {
        rig.enable_and_home(axis);
    }

    // Lost mid-move; reset one axis after the other, each to its end. The drives never
    // noticed (5 ms is far below their 100 ms watchdog and their sync-error limit): each
    // axis is back in Standstill with its drive in Operation enabled, and moves.
    let moves: Vec<_> = (0..AXES).map(|a| rig.start_move(a, 30.0)).collect();
    rig.run(50);
    lose_frames(&mut rig);
    for h in &moves {
        assert!(matches!(h.status(), Some(CommandStatus::Error(_))));
    }
    for axis in 0..AXES {
        assert_eq!(drive_state(&rig, axis), State::OperationEnabled);
        let h = rig.ctl.reset(axis).unwrap();
        assert_eq!(rig.finish(&h, 5000), CommandStatus::Done, "axis {axis}");
        assert_eq!(
            rig.state(axis),
            AxisState::Standstill,
            "axis {axis}: its drive stayed powered"
        );
    }
    for axis in 0..AXES {
        assert_eq!(
            drive_state(&rig, axis),
            State::OperationEnabled,
            "axis {axis}: the reset left its drive powered"
        );
    }
    all_move_to(&mut rig, 0.0);

    // Lost at standstill; every axis reset in the same cycle: the same answer.
    lose_frames(&mut rig);
    reset_all_at_once(&mut rig);
    for axis in 0..AXES {
        assert_eq!(rig.state(axis), AxisState::Standstill, "axis {axis}");
    }
    all_move_to(&mut rig, 10.0);

    // Lost again; axis 0 is reset, and the others the very cycle after its slave's
    // recovery cleared the bus fault, while the kernel still holds the communication
    // fault it was given that cycle: the same answer.
    lose_frames(&mut rig);
    let first = rig.ctl.reset(0).unwrap();
    let mut cycles = 0;
    while rig.engine.bus.health().any_fault() {
        rig.cycle();
        cycles += 1;
        assert!(cycles < 1000, "the bus fault was never cleared");
    }
    let others: Vec<_> = (1..AXES).map(|a| rig.ctl.reset(a).unwrap()).collect();
    for (h, axis) in [first].iter().chain(&others).zip(0..) {
        assert_eq!(rig.finish(h, 5000), CommandStatus::Done, "axis {axis}");
        assert_eq!(rig.state(axis), AxisState::Standstill, "axis {axis}");
    }
    all_move_to(&mut rig, 5.0);

    // Lost again, and while the axes stand in ErrorStop drive 2 stops getting process data
    // for longer than its watchdog: its slave drops to SafeOp and the drive faults. Its
    // axis comes back Disabled (its power is off), the others in Standstill.
    lose_frames(&mut rig);
    rig.chain.lock().unwrap().stop_process_data(Some(2));
    rig.run(150);
    rig.chain.lock().unwrap().stop_process_data(None);
    assert_eq!(drive_state(&rig, 2), State::Fault);
    reset_all_at_once(&mut rig);
    assert_eq!(rig.state(0), AxisState::Standstill);
    assert_eq!(rig.state(1), AxisState::Standstill);
    assert_eq!(
        rig.state(2),
        AxisState::Disabled,
        "its drive faulted: power off"
    );
    assert_eq!(drive_state(&rig, 2), State::SwitchOnDisabled);
    assert_eq!(drive_state(&rig, 0), State::OperationEnabled);
    // Enabled again, it moves with the others.
    assert_eq!(
        rig.command(2, Command::Power(PowerCommand::Enable)),
        CommandStatus::Done
    );
    all_move_to(&mut rig, 20.0);

    // Lost frames fault no drive's following error, and no target that reached a drive
    // stepped further than its axis' speed allows (not real time: missed setpoints are
    // this host's, not judged).
    let drives = DriveUnderTest::of_config(&config);
    assert_drive_invariants(
        &rig.chain.lock().unwrap(),
        &drives,
        1e-3,
        TestConditions::default(),
    );
}
