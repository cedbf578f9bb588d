//! README, "Bus faults": with `stop_all_on_slave_loss = true` a slave that stops answering
//! stops every axis, the others with "EtherCAT: stopped with slave N". End to end over the
//! in-process simulator with the cable pulled in front of drive 2.

use gantry::runtime::cycle::COMMUNICATION_FAULT;
use gantry_kernel::axis::command::CommandError;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_tests::slave_loss::pull_the_cable_before_drive_2;

#[test]
fn a_lost_slave_stops_every_axis_when_configured() {
    let (mut rig, moves) = pull_the_cable_before_drive_2(true);
    for (axis, moved) in moves.iter().enumerate() {
        assert_eq!(
            rig.bus_fault(axis).as_deref(),
            Some("EtherCAT: stopped with slave 2 (0x1002)"),
            "axis {axis}"
        );
        assert_eq!(rig.state(axis), AxisState::ErrorStop, "axis {axis}");
        assert!(matches!(
            moved.status(),
            Some(CommandStatus::Aborted | CommandStatus::Error(_))
        ));
    }
    // While slave 2 is lost, a reset of another axis fails at once with the drive's
    // communication fault: its slave comes back (it never left OP), the fault returns with
    // slave 2 before the kernel sees the drive, and the axis stays in ErrorStop.
    let reset = rig.ctl.reset(0).unwrap();
    assert_eq!(
        rig.finish(&reset, 200),
        CommandStatus::Error(CommandError::DriveResetFailed {
            code: COMMUNICATION_FAULT
        })
    );
    assert_eq!(rig.state(0), AxisState::ErrorStop);
    assert_eq!(
        rig.bus_fault(0).as_deref(),
        Some("EtherCAT: stopped with slave 2 (0x1002)")
    );
    // Plugged back in: resets bring every axis back, the lost slave's first (its watchdog
    // took it out of Op while it was cut off; until it is back, the others would stop
    // with it again).
    rig.chain.lock().unwrap().cut_before(None);
    for axis in [2, 0, 1] {
        let reset = rig.ctl.reset(axis).unwrap();
        assert_eq!(rig.finish(&reset, 200), CommandStatus::Done, "axis {axis}");
    }
    rig.run(10);
    for axis in 0..3 {
        assert!(rig.bus_fault(axis).is_none(), "axis {axis}");
        assert_ne!(rig.state(axis), AxisState::ErrorStop, "axis {axis}");
    }
}
