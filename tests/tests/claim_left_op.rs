//! README, "The cyclic frame" and "Bus faults": a slave that leaves OP while its working
//! counter stays right — its SyncManagers stay active in SafeOp (ETG.1000.6 §6.4.1), so the
//! LRW's count does not change — is named by the AL-status summary (one BRD, read one
//! cycle in `AL_STATUS_EVERY` instead of the DC time), its states read the cycle after.
//! Drives that missed their setpoints behind lost frames (a sync error, 0x10F1:02) are
//! named in the second answered cycle after them: a lost frame makes the next cycle read
//! the summary (light, as the cycle after a host stall must be), which sends the cycle
//! after it to read every slave's state. End to end over the engine and the in-process
//! simulator, in lockstep.

use gantry::ethercat::health::AL_STATUS_EVERY;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::esc::al::AlStatusCode;
use gantry_tests::rig::Rig;

/// Cycles until `named` is the bus fault of `axis` (at most `max`).
fn cycles_until_named(rig: &mut Rig, axis: usize, named: &str, max: u32) -> u32 {
    for cycles in 1..=max {
        rig.cycle();
        if rig.bus_fault(axis).as_deref() == Some(named) {
            return cycles;
        }
    }
    panic!(
        "not named in {max} cycles: {:?}, slave state {:#x}",
        rig.bus_fault(axis),
        rig.chain.lock().unwrap().slaves()[axis].al_status()
    );
}

#[test]
fn slaves_that_left_op_are_named_after_lost_frames_and_by_the_summary() {
    let config = gantry_tests::sim_config_strict(3, 1000);
    let mut rig = Rig::new(&config);
    for axis in 0..3 {
        rig.enable_and_home(axis);
    }

    // Two frames lost: every drive misses two setpoints and leaves OP with a sync error
    // (0x10F1:02 = 4). The first answered cycle after them reads the AL-status summary,
    // which sees slaves out of OP; the next reads each state and names them — the working
    // counter is right again, the slaves exchange in SafeOp.
    rig.chain.lock().unwrap().drop_frames(2);
    let named = |i: usize| {
        format!(
            "EtherCAT: slave {i} ({:#06x}) left OP: now Safe-Operational",
            0x1000 + i
        )
    };
    assert_eq!(cycles_until_named(&mut rig, 0, &named(0), 10), 4);
    for i in 1..3 {
        assert_eq!(rig.bus_fault(i).as_deref(), Some(named(i).as_str()));
    }
    assert_eq!(rig.engine.bus.health().lost_total, 2);
    assert_eq!(rig.engine.bus.health().wkc_total, 0);
    // Reset brings each slave back to OP, the drives' sync error reset: Disabled (their
    // power went with the fault), enabled again.
    for axis in 0..3 {
        let reset = rig.ctl.reset(axis).unwrap();
        assert_eq!(rig.finish(&reset, 5000), CommandStatus::Done, "axis {axis}");
    }
    for axis in 0..3 {
        rig.enable_and_home(axis);
    }
    assert!(!rig.engine.bus.health().any_fault());
    let moving = rig.start_move(0, 50.0);
    rig.run(10);

    // Slave 1's application leaves OP on its own: its working counter stays right, so no
    // cycle reads the states one by one; the summary sees it within AL_STATUS_EVERY
    // cycles, the next cycle reads the states and names it.
    let before = rig.engine.bus.frame_stats();
    rig.chain
        .lock()
        .unwrap()
        .slave_mut(1)
        .unwrap()
        .local_error(AlStatusCode::SyncError);
    let cycles = cycles_until_named(&mut rig, 1, &named(1), AL_STATUS_EVERY + 1);
    let after = rig.engine.bus.frame_stats();
    assert_eq!(
        (
            after.summaries - before.summaries,
            after.state_reads - before.state_reads
        ),
        (1, 1),
        "one summary, then one read of the states, named in {cycles} cycles"
    );
    assert_eq!(
        rig.engine.bus.health().wkc_total,
        0,
        "the working counter stayed right"
    );
    assert!(rig.bus_fault(0).is_none() && rig.bus_fault(2).is_none());
    rig.run(5);
    assert_eq!(rig.state(1), AxisState::ErrorStop);
    // The others go on.
    assert_eq!(moving.status(), Some(CommandStatus::Active));
    assert_eq!(rig.finish(&moving, 5000), CommandStatus::Done);
    assert_eq!(rig.state(2), AxisState::Standstill);
}
