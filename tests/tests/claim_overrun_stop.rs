//! README, "Real time": `rt.overrun_limit` overruns in a row stop every axis (error
//! 0x6100) until reset. End to end over the in-process simulator; the overruns are
//! injected (each wake-up marked as past its deadline), so the count is exact whatever this
//! host's timing.

use gantry::runtime::engine::OVERRUN_FAULT;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use gantry_tests::rig::Rig;

/// `n` cycles, each an overrun.
fn overruns(rig: &mut Rig, n: usize) {
    for _ in 0..n {
        let mut wake = rig.wake();
        wake.overrun = true;
        wake.latency_ns = 0;
        rig.step(wake);
    }
}

#[test]
fn overruns_in_a_row_stop_every_axis_with_0x6100_until_reset() {
    let mut config = gantry_tests::sim_config_strict(2, 1000);
    config.rt.overrun_limit = 10;
    let mut rig = Rig::new(&config);
    for axis in 0..2 {
        rig.enable_and_home(axis);
    }
    let moving = rig.start_move(0, 40.0);
    rig.run(10);

    // Nine in a row, then a cycle on time: the count starts again.
    overruns(&mut rig, 9);
    rig.run(1);
    overruns(&mut rig, 9);
    rig.run(10);
    assert!(!rig.snapshot().overrun_stop);
    assert_eq!(moving.status(), Some(CommandStatus::Active));
    assert_eq!(
        rig.snapshot().figures.worst_overrun_run,
        9,
        "the counters are in every snapshot"
    );

    // Ten in a row: every axis stops with 0x6100.
    overruns(&mut rig, 10);
    rig.run(10);
    let snap = rig.snapshot();
    assert!(snap.overrun_stop);
    for axis in 0..2 {
        assert_eq!(rig.state(axis), AxisState::ErrorStop, "axis {axis}");
        assert_eq!(
            snap.axes[axis].error,
            Some(AxisFault::Drive {
                code: OVERRUN_FAULT
            }),
            "axis {axis}"
        );
    }
    assert_eq!(OVERRUN_FAULT, 0x6100);
    assert!(matches!(
        moving.status(),
        Some(CommandStatus::Aborted | CommandStatus::Error(_))
    ));
    // It holds while nobody resets, cycles on time or not.
    rig.run(50);
    assert_eq!(rig.state(1), AxisState::ErrorStop);

    // A reset of one axis clears the stop; each axis is reset on its own.
    let reset = rig.ctl.reset(0).unwrap();
    assert_eq!(rig.finish(&reset, 100), CommandStatus::Done);
    rig.run(10);
    assert!(!rig.snapshot().overrun_stop);
    assert_ne!(rig.state(0), AxisState::ErrorStop);
    assert_eq!(rig.state(1), AxisState::ErrorStop);
    let reset = rig.ctl.reset(1).unwrap();
    assert_eq!(rig.finish(&reset, 100), CommandStatus::Done);
    rig.run(5);
    // The drives stayed powered through the stop (0x6100 is gantry's, not theirs): each
    // axis is back in Standstill, whichever was reset first (PLCopen MC_Reset with the
    // power on; see `Engine::reset`), and moves again.
    for axis in 0..2 {
        assert_eq!(rig.state(axis), AxisState::Standstill, "axis {axis}");
        let moved = rig.start_move(axis, 5.0);
        assert_eq!(rig.finish(&moved, 3000), CommandStatus::Done, "axis {axis}");
    }
}
