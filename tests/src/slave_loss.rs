//! The scenario behind README's "a slave that leaves OP or stops answering stops its own
//! axes at once … and the others go on unless `stop_all_on_slave_loss`", run by two test
//! files (one bus per process), one per setting.

use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;

use crate::rig::Rig;

/// Three axes moving; the cable in front of drive 2 is pulled. Returns the rig with the
/// cable still pulled, after the faults settled, and the handles of the moves of axes 0
/// and 1.
pub fn pull_the_cable_before_drive_2(
    stop_all: bool,
) -> (Rig, [gantry::runtime::controller::CommandHandle; 2]) {
    let mut config = crate::sim_config_strict(3, 1000);
    config.bus.faults.stop_all_on_slave_loss = stop_all;
    let mut rig = Rig::new(&config);
    for axis in 0..3 {
        rig.enable_and_home(axis);
    }
    let moves = [rig.start_move(0, 30.0), rig.start_move(1, 30.0)];
    let third = rig.start_move(2, 30.0);
    rig.run(20);
    for h in moves.iter().chain([&third]) {
        assert_eq!(h.status(), Some(CommandStatus::Active));
    }
    rig.chain.lock().unwrap().cut_before(Some(2));
    rig.run(3);
    assert_eq!(
        rig.bus_fault(2).as_deref(),
        Some("EtherCAT: slave 2 (0x1002) does not answer (cable, power?)")
    );
    assert_eq!(rig.state(2), AxisState::ErrorStop);
    rig.run(10);
    assert!(matches!(
        third.status(),
        Some(CommandStatus::Aborted | CommandStatus::Error(_))
    ));
    (rig, moves)
}
