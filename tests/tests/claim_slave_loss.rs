//! README, "Bus faults": a slave that stops answering stops its own axes at once (with the
//! reason) and the others go on — `stop_all_on_slave_loss = false`, the default. End to
//! end over the in-process simulator with the cable pulled in front of drive 2.

use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_tests::slave_loss::pull_the_cable_before_drive_2;

#[test]
fn a_lost_slave_stops_only_its_own_axis() {
    let (mut rig, [m0, m1]) = pull_the_cable_before_drive_2(false);
    for axis in 0..2 {
        assert!(rig.bus_fault(axis).is_none(), "axis {axis}");
        assert_ne!(rig.state(axis), AxisState::ErrorStop, "axis {axis}");
    }
    // The other axes finish their moves, on target.
    assert_eq!(rig.finish(&m0, 3000), CommandStatus::Done);
    assert_eq!(rig.finish(&m1, 3000), CommandStatus::Done);
    rig.run(20);
    let snap = rig.snapshot();
    for axis in 0..2 {
        assert!((snap.axes[axis].set.p - 30.0).abs() < 1e-9, "axis {axis}");
        assert!(snap.drives[axis].bus_fault.is_none());
    }
    assert!(snap.drives[2].bus_fault.is_some());
    assert_eq!(rig.state(2), AxisState::ErrorStop);
}
