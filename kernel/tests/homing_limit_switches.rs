//! Hardware limit switches outside homing (issue 13 §1): an axis moving into an active
//! limit switch stops with its quick-stop deceleration and goes to ErrorStop naming the
//! switch; after Reset it may only move away from it until it has left it.

mod homing_model;

use gantry_kernel::axis::command::{
    Command, CommandError, Jog, MoveDirection, MovePtp, MoveVelocity, PositioningMode,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::{AxisFault, FaultSummary};
use gantry_kernel::homing::LimitSide;
use homing_model::*;

/// Runs positive at 20 into the positive limit switch at 100 from 80.
fn into_the_positive_limit() -> (Rig, Vec<Sample>, gantry_kernel::axis::handle::HandleId) {
    let mut rig = Rig::new(axis_config(), Layout::STANDARD, 80.0);
    // Homed where it stands, so absolute moves are taken.
    rig.k.command(0, Command::SetReference(80.0)).unwrap();
    let h = rig
        .k
        .command(
            0,
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 20.0)),
        )
        .unwrap();
    let mut out = Vec::new();
    rig.run_until_final(h, 10_000, &mut out);
    rig.run(2000, &mut out);
    (rig, out, h)
}

#[test]
fn running_into_a_limit_switch_quick_stops_into_error_stop_naming_it() {
    let (rig, out, h) = into_the_positive_limit();
    let CommandStatus::Error(e) = rig.k.command_status(h) else {
        panic!("{:?}", rig.k.command_status(h))
    };
    assert_eq!(
        e.to_string(),
        "MoveVelocity: stopped by the positive limit switch"
    );
    let s = rig.k.axis_status(0).unwrap();
    assert_eq!(s.state, AxisState::ErrorStop);
    assert_eq!(
        s.error,
        Some(AxisFault::LimitSwitch {
            side: LimitSide::Positive
        })
    );
    assert_eq!(s.error.unwrap().to_string(), "positive limit switch");
    assert_eq!(s.set.v, 0.0);
    // The stop: from the first cycle the switch was seen, braking at most with the
    // quick-stop deceleration (400), and reaching it (not the axis' 1000).
    let first = out
        .iter()
        .position(|x| x.status.switches.positive_limit)
        .expect("switch seen");
    let braking = &out[first..];
    let peak = braking
        .iter()
        .map(|x| x.status.set.a.abs())
        .fold(0.0, f64::max);
    assert!(peak <= 400.0 * (1.0 + 1e-9), "{peak}");
    assert!(
        peak >= 399.0,
        "brakes with the quick-stop deceleration: {peak}"
    );
    // It set the error in the cycle it first saw the switch.
    assert_eq!(braking[0].status.state, AxisState::ErrorStop);
    assert!(out[..first]
        .iter()
        .all(|x| x.status.state != AxisState::ErrorStop));
}

#[test]
fn after_reset_only_moves_away_from_the_switch_are_taken_until_it_is_left() {
    let (mut rig, mut out, _) = into_the_positive_limit();
    let r = rig.k.command(0, Command::Reset).unwrap();
    assert_eq!(rig.k.command_status(r), CommandStatus::Done);
    assert!(rig.k.axis_status(0).unwrap().switches.positive_limit);
    let here = rig.k.axis_status(0).unwrap().set.p;
    // Towards the switch: refused, naming it; the axis stays in Standstill.
    for cmd in [
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 5.0)),
        Command::MovePtp(MovePtp::new(PositioningMode::RelActual, 1.0)),
        Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, here + 5.0)),
        Command::Jog(Jog::new(MoveDirection::Positive, 3.0, 50.0, 50.0)),
    ] {
        let e = rig.k.command(0, cmd).unwrap_err();
        assert_eq!(
            e,
            CommandError::TowardsLimitSwitch {
                command: cmd.name(),
                side: LimitSide::Positive
            }
        );
        assert_eq!(
            e.to_string(),
            format!(
                "{}: the positive limit switch is active; only moves away from it are allowed",
                cmd.name()
            )
        );
        assert_eq!(rig.k.axis_status(0).unwrap().state, AxisState::Standstill);
    }
    // Away from it: taken, and it leaves the switch.
    let h = rig
        .k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 90.0)),
        )
        .unwrap();
    assert_eq!(
        rig.run_until_final(h, 20_000, &mut out),
        CommandStatus::Done
    );
    let s = rig.k.axis_status(0).unwrap();
    assert!(!s.switches.positive_limit);
    // Off the switch: positive moves are taken again (and stopped at the switch again).
    let h = rig
        .k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 95.0)),
        )
        .unwrap();
    assert_eq!(
        rig.run_until_final(h, 20_000, &mut out),
        CommandStatus::Done
    );
}

#[test]
fn the_negative_switch_works_the_same_and_error_stop_says_why() {
    let mut rig = Rig::new(axis_config(), Layout::STANDARD, -90.0);
    let h = rig
        .k
        .command(
            0,
            Command::Jog(Jog::new(MoveDirection::Negative, 10.0, 200.0, 200.0)),
        )
        .unwrap();
    let mut out = Vec::new();
    rig.run_until_final(h, 20_000, &mut out);
    rig.run(2000, &mut out);
    let s = rig.k.axis_status(0).unwrap();
    assert_eq!(
        s.error,
        Some(AxisFault::LimitSwitch {
            side: LimitSide::Negative
        })
    );
    // A command refused in ErrorStop names the switch as the cause.
    let e = rig
        .k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 0.0)),
        )
        .unwrap_err();
    assert_eq!(
        e,
        CommandError::InErrorStop {
            command: "MovePtp",
            cause: FaultSummary::LimitSwitch {
                side: LimitSide::Negative
            }
        }
    );
}

#[test]
fn standing_on_a_switch_is_no_error_and_moves_along_it_are_not_limited() {
    // Started on the positive switch (say, after power-up): no error while it stands.
    let mut rig = Rig::new(axis_config(), Layout::STANDARD, 101.0);
    let mut out = Vec::new();
    rig.run(100, &mut out);
    assert_eq!(rig.k.axis_status(0).unwrap().state, AxisState::Standstill);
    let h = rig
        .k
        .command(
            0,
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Negative, 5.0)),
        )
        .unwrap();
    rig.run(1000, &mut out);
    assert_eq!(rig.k.command_status(h), CommandStatus::Active);
    assert_eq!(
        rig.k.axis_status(0).unwrap().state,
        AxisState::ContinuousMotion
    );
}
