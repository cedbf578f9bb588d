//! README, "Bus faults": wrong working counters are ridden through up to
//! `bus.faults.working_counter_limit` cycles in a row (default 3), then every axis stops
//! with the reason; `gantry reset` brings them back. End to end: gantry's engine over the
//! in-process simulator, where one drive stops exchanging process data while it stays in
//! OP (its SyncManagers deactivated by its application: its part of the LRW is not
//! served and not counted), so only the working counter tells.

use gantry::runtime::cycle::COMMUNICATION_FAULT;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use gantry_tests::rig::Rig;

#[test]
fn wrong_working_counters_stop_every_axis_with_the_reason_and_reset_recovers() {
    // A DC drive whose SyncManager gets no process data misses setpoints and leaves Op
    // with a sync error after two cycles (0x10F1:02 = 4): then the lost slave, not the
    // working counter, stops the axes. These drives are set to tolerate missed setpoints
    // (0x10F1:02 is writable), so that only the working counter tells.
    let config = gantry_tests::sim_config_with(3, 1000, "[slave.al]\nsync_error_limit = 1000");
    assert_eq!(config.bus.faults.working_counter_limit, 3);
    let mut rig = Rig::new(&config);
    for axis in 0..3 {
        rig.enable_and_home(axis);
    }
    let moving = rig.start_move(0, 50.0);
    rig.run(20);
    assert_eq!(rig.snapshot().working_counter_errors, 0);

    // Two cycles short: ridden through, the move goes on. No slave's inputs from those
    // replies reach the axes (slave 1's bytes in them are stale: the frame passed it
    // unserved), and the axes standing on the other drives stand on.
    rig.chain.lock().unwrap().stop_process_data(Some(1));
    rig.run(2);
    assert!((0..3).all(|i| !rig.engine.bus.health().inputs_fresh(i)));
    rig.chain.lock().unwrap().stop_process_data(None);
    rig.run(20);
    assert_eq!(rig.engine.bus.health().wkc_total, 2);
    assert!(rig.bus_fault(0).is_none());
    assert_eq!(moving.status(), Some(CommandStatus::Active));
    for axis in 1..3 {
        assert_eq!(rig.state(axis), AxisState::Standstill, "axis {axis}");
    }

    // Three in a row: every axis stops, each with the reason.
    rig.chain.lock().unwrap().stop_process_data(Some(1));
    rig.run(3);
    // Each slave with inputs and outputs counts 3 in the LRW; slave 1 is missing.
    let reason = "EtherCAT: working counter 6 instead of 9 for 3 cycles in a row (limit 3)";
    for axis in 0..3 {
        assert_eq!(rig.bus_fault(axis).as_deref(), Some(reason), "axis {axis}");
    }
    rig.run(1);
    for axis in 0..3 {
        assert_eq!(rig.state(axis), AxisState::ErrorStop, "axis {axis}");
        let error = rig.engine.cycle.kernel.axis_status(axis).unwrap().error;
        assert_eq!(
            error,
            Some(AxisFault::Drive {
                code: COMMUNICATION_FAULT
            }),
            "axis {axis}"
        );
    }
    rig.run(10);
    assert!(
        matches!(
            moving.status(),
            Some(CommandStatus::Aborted | CommandStatus::Error(_))
        ),
        "{:?}",
        moving.status()
    );
    let snap = rig.snapshot();
    for d in &snap.drives {
        assert_eq!(d.bus_fault.map(|f| f.to_string()).as_deref(), Some(reason));
    }

    // While the drive still does not exchange, a reset does not help: the fault returns.
    let reset = rig.ctl.reset(0).unwrap();
    rig.finish(&reset, 100);
    rig.run(5);
    assert_eq!(rig.bus_fault(0).as_deref(), Some(reason));
    assert_eq!(rig.state(0), AxisState::ErrorStop);

    // The drive exchanges again. No drive faulted itself: each held its position,
    // powered, so MC_Reset takes every axis from ErrorStop to Standstill (PLCopen) —
    // axis 0 too, whose first reset went through while the fault was briefly cleared (the
    // Reset waits until the kernel has seen the drive as it is, see `Engine::reset`; it
    // used to take the communication fault for the drive's, and switch it off) — and they
    // move without a new enable.
    rig.chain.lock().unwrap().stop_process_data(None);
    for axis in 0..3 {
        let reset = rig.ctl.reset(axis).unwrap();
        assert_eq!(rig.finish(&reset, 100), CommandStatus::Done, "axis {axis}");
    }
    rig.run(5);
    for axis in 0..3 {
        assert!(rig.bus_fault(axis).is_none(), "axis {axis}");
    }
    for axis in 0..3 {
        assert_eq!(rig.state(axis), AxisState::Standstill, "axis {axis}");
        let moved = rig.start_move(axis, 10.0);
        assert_eq!(rig.finish(&moved, 3000), CommandStatus::Done, "axis {axis}");
    }
    assert_eq!(rig.engine.bus.health().lost_total, 0);
}
