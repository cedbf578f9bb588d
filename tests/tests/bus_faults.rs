//! Bus faults, lockstep, through gantry's engine on the in-process simulator
//! (`gantry_tests::rig`: bring-up from a configuration, Controller commands and resets, the
//! chain's time stepped one cycle per cycle): lost frames are ridden through up to the
//! limit, then every axis stops with the reason; a slave that disappears mid-move stops its
//! own axis while the others finish; plugged back in, it returns to OP on a reset and its
//! axis moves again. The reasons reach the user as text.

use gantry::axis_fault::describe_fault;
use gantry::config::Config;
use gantry::runtime::bus::Restored;
use gantry::runtime::controller::CommandHandle;
use gantry::runtime::cycle::COMMUNICATION_FAULT;
use gantry::runtime::engine::{LateReply, RestoreRecord};
use gantry_kernel::axis::command::{Command, CommandError, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::rig::Rig;

const DRIVES: usize = 3;

/// Three catalog servos as the simulator makes them (their firmware takes 5 ms from
/// SafeOp to Op and waits for valid outputs, so a reset polls across cycles), without
/// distributed clocks: the drives run on the frames (SM-synchronous), so lost frames trip
/// only their 100 ms watchdog, not a SYNC0 sync error. Axes with the kernel's default
/// limits (100 mm/s, 1000 mm/s², 10 000 mm/s³) on the 5 mm ball screw.
fn config() -> Config {
    let slaves = "[[slave]]\nkind = \"servo\"\n".repeat(DRIVES);
    let axes: String = (0..DRIVES)
        .map(|i| {
            format!(
                "[[axis]]\nname = \"a{i}\"\ndrive = {i}\n\
                 scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
                 max = {{ speed = 100.0, acceleration = 1000.0, jerk = 10000.0 }}\n"
            )
        })
        .collect();
    gantry_tests::sim_config_text(1000, &slaves, "dc = false", &axes)
}

fn move_to(rig: &Rig, i: usize, to: f64) -> CommandHandle {
    let m = MovePtp::new(PositioningMode::AbsNormal, to);
    rig.ctl.command(i, Command::MovePtp(m)).expect("queued")
}

fn status(rig: &Rig, h: &CommandHandle) -> Option<CommandStatus> {
    rig.status_now(h)
}

fn actual(rig: &Rig, i: usize) -> f64 {
    rig.engine
        .cycle
        .kernel
        .axis_status(i)
        .unwrap()
        .actual_position
}

/// The health's text for drive `i`'s fault.
fn fault(rig: &Rig, i: usize) -> Option<String> {
    rig.engine.bus.health().fault(i).map(|f| f.to_string())
}

/// Cycles until the bus has finished `n` restores for resets (at most 1000 cycles); what
/// they were, in order.
fn restores(rig: &mut Rig, n: usize) -> Vec<RestoreRecord> {
    let mut seen = Vec::new();
    let mut last = rig.engine.last_restore();
    for _ in 0..1000 {
        rig.cycle();
        let now = rig.engine.last_restore();
        if now != last {
            seen.extend(now);
            last = now;
        }
        if seen.len() == n {
            return seen;
        }
    }
    panic!("{} of {n} restores in 1000 cycles: {seen:?}", seen.len());
}

fn record(axis: usize, outcome: Restored, cycles: u64) -> RestoreRecord {
    RestoreRecord {
        axis,
        outcome: Ok(outcome),
        cycles,
    }
}

#[test]
fn lost_frames_and_a_lost_slave_stop_what_they_must_and_recover_on_reset() {
    let config = config();
    let mut rig = Rig::new(&config);
    // A frame not back within the cycle is lost, as in a real-time cycle (the rig's usual
    // wait is for a host that is not real time): every cycle is 1 ms of the drives' time,
    // lost or not. Answered frames are in before the exchange looks, as ever.
    rig.engine.set_late_reply(LateReply::Wait { ns: 1_000_000 });
    for i in 0..DRIVES {
        rig.ctl
            .command(i, Command::Power(PowerCommand::Enable))
            .expect("queued");
    }
    rig.run(20);
    for i in 0..DRIVES {
        assert_eq!(rig.state(i), AxisState::Standstill);
        rig.ctl
            .command(
                i,
                Command::SetPosition {
                    position: 0.0,
                    relative: false,
                },
            )
            .expect("queued");
    }

    // Two frames lost mid-move: ridden through, the moves finish.
    let moves: Vec<_> = (0..DRIVES).map(|i| move_to(&rig, i, 30.0)).collect();
    rig.run(50);
    rig.chain.lock().unwrap().drop_frames(2);
    rig.run(600);
    for (i, h) in moves.iter().enumerate() {
        assert_eq!(status(&rig, h), Some(CommandStatus::Done), "axis {i}");
        assert!((actual(&rig, i) - 30.0).abs() < 0.01);
    }
    assert_eq!(rig.engine.bus.health().lost_total, 2);

    // Five in a row (limit 3): every axis stops, with the reason.
    let moves: Vec<_> = (0..DRIVES).map(|i| move_to(&rig, i, 0.0)).collect();
    rig.run(50);
    rig.chain.lock().unwrap().drop_frames(5);
    rig.run(10);
    assert_eq!(
        fault(&rig, 0).as_deref(),
        Some("EtherCAT: 3 frames lost in a row (limit 3)")
    );
    for (i, h) in moves.iter().enumerate() {
        assert_eq!(rig.state(i), AxisState::ErrorStop, "axis {i}");
        assert!(
            matches!(
                status(&rig, h),
                Some(CommandStatus::Error(CommandError::AxisFault { .. }))
            ),
            "axis {i}: the move ends in error"
        );
        let error = rig
            .engine
            .cycle
            .kernel
            .axis_status(i)
            .unwrap()
            .error
            .unwrap();
        assert_eq!(
            describe_fault(&error),
            format!(
                "drive fault 0x{COMMUNICATION_FAULT:04X}: communication error (the master cannot reach the drive)"
            )
        );
    }
    // Reset: the slaves never left OP (5 ms < their 100 ms watchdog), the drives stayed
    // enabled: each slave is found in OP in one cycle, the axes are back and finish the
    // move.
    let resets: Vec<_> = (0..DRIVES).map(|i| rig.ctl.reset(i).unwrap()).collect();
    assert_eq!(
        restores(&mut rig, DRIVES),
        (0..DRIVES)
            .map(|i| record(i, Restored::WasOperational, 1))
            .collect::<Vec<_>>()
    );
    for (i, h) in resets.iter().enumerate() {
        assert_eq!(rig.finish(h, 5000), CommandStatus::Done, "axis {i}");
        assert_eq!(rig.state(i), AxisState::Standstill);
    }
    let moves: Vec<_> = (0..DRIVES).map(|i| move_to(&rig, i, 0.0)).collect();
    rig.run(600);
    for h in &moves {
        assert_eq!(status(&rig, h), Some(CommandStatus::Done));
    }

    // Slave 2's cable pulled mid-move for 150 ms: its axis stops with the reason, the
    // others finish their moves.
    let moves: Vec<_> = (0..DRIVES).map(|i| move_to(&rig, i, 30.0)).collect();
    rig.run(50);
    rig.chain.lock().unwrap().cut_before(Some(2));
    rig.run(150);
    assert_eq!(
        fault(&rig, 2).as_deref(),
        Some("EtherCAT: slave 2 (0x1002) does not answer (cable, power?)")
    );
    assert_eq!(rig.state(2), AxisState::ErrorStop);
    assert!(matches!(
        status(&rig, &moves[2]),
        Some(CommandStatus::Error(CommandError::AxisFault { .. }))
    ));
    rig.chain.lock().unwrap().cut_before(None);
    rig.run(450);
    for (i, h) in moves.iter().enumerate().take(2) {
        assert_eq!(
            status(&rig, h),
            Some(CommandStatus::Done),
            "axis {i} went on"
        );
        assert!((actual(&rig, i) - 30.0).abs() < 0.01);
    }
    // Back on the wire, the slave is in SafeOp with its watchdog error, the drive faulted.
    assert_eq!(rig.chain.lock().unwrap().slaves()[2].al_status(), 0x14);
    let reset = rig.ctl.reset(2).unwrap();
    let [restore] = restores(&mut rig, 1)[..] else {
        unreachable!("one restore")
    };
    assert_eq!(
        (restore.axis, restore.outcome),
        (2, Ok(Restored::BackInOperation))
    );
    // Read, acknowledge, read, request Op, then reads through the drive's 5 ms.
    assert!(
        restore.cycles >= 8,
        "back in Op after {} cycles",
        restore.cycles
    );
    assert_eq!(rig.chain.lock().unwrap().slaves()[2].al_status(), 0x08);
    rig.run(20);
    assert_eq!(status(&rig, &reset), Some(CommandStatus::Done));
    assert_eq!(rig.state(2), AxisState::Disabled);
    rig.ctl
        .command(2, Command::Power(PowerCommand::Enable))
        .expect("queued");
    rig.run(20);
    let h = move_to(&rig, 2, 30.0);
    rig.run(600);
    assert_eq!(status(&rig, &h), Some(CommandStatus::Done));
    assert!((actual(&rig, 2) - 30.0).abs() < 0.01);
    // Lost frames and a cut cable fault drives (0x8700), not their following error; and
    // no target that reached a drive stepped further than the axis' speed allows.
    let drives = DriveUnderTest::of_config(&config);
    assert_drive_invariants(
        &rig.chain.lock().unwrap(),
        &drives,
        1e-3,
        TestConditions::default(),
    );
}
