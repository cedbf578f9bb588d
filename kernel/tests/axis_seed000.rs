//! The examples of the Jetter axes application note (seed 000) as tests: positioning
//! modes (§6.4.3), ramp break modes (§6.1.2), halt modes (§6.4.5), velocity moves (§6.4.4)
//! and the power commands (§6.2).

mod common;

use common::*;
use gantry_kernel::axis::command::{
    Command, HaltMode, MoveDirection, MovePtp, MoveVelocity, PositioningMode, PowerCommand,
    RampBreakMode,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::SlopeState;
use gantry_kernel::profile::RampType;

/// Moves a fresh rotary axis to `from` (AbsModuloAuto), then runs `mode` to `to` and
/// returns the signed travel of the second move.
fn modulo_travel(from: f64, to: f64, mode: PositioningMode) -> f64 {
    let mut k = kernel(vec![rotary("r")]);
    let h = k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloAuto, from)),
        )
        .unwrap();
    run_until_final(&mut k, 0, h, 100_000);
    let start = unwrapped(k.axis_status(0).unwrap(), 360.0);
    let h = k
        .command(0, Command::MovePtp(MovePtp::new(mode, to)))
        .unwrap();
    run_until_final(&mut k, 0, h, 100_000);
    assert_eq!(k.command_status(h), CommandStatus::Done);
    let s = k.axis_status(0).unwrap();
    assert!((s.set.p - to).abs() < 1e-9, "ends at {} not {to}", s.set.p);
    unwrapped(s, 360.0) - start
}

#[test]
fn abs_modulo_pos_from_50_to_40_travels_plus_350() {
    assert!((modulo_travel(50.0, 40.0, PositioningMode::AbsModuloPos) - 350.0).abs() < 1e-9);
}

#[test]
fn abs_modulo_neg_from_40_to_50_travels_minus_350() {
    assert!((modulo_travel(40.0, 50.0, PositioningMode::AbsModuloNeg) + 350.0).abs() < 1e-9);
}

#[test]
fn abs_modulo_auto_from_40_to_50_travels_plus_10() {
    assert!((modulo_travel(40.0, 50.0, PositioningMode::AbsModuloAuto) - 10.0).abs() < 1e-9);
}

#[test]
fn keep_direction_after_moving_40_to_50_goes_plus_330_to_20() {
    let mut k = kernel(vec![rotary("r")]);
    for (mode, target) in [
        (PositioningMode::AbsModuloAuto, 40.0),
        (PositioningMode::AbsModuloPos, 50.0),
    ] {
        let h = k
            .command(0, Command::MovePtp(MovePtp::new(mode, target)))
            .unwrap();
        run_until_final(&mut k, 0, h, 100_000);
    }
    let start = unwrapped(k.axis_status(0).unwrap(), 360.0);
    let h = k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloKeepDirection, 20.0)),
        )
        .unwrap();
    let trace = run_until_final(&mut k, 0, h, 100_000);
    let travel = unwrapped(k.axis_status(0).unwrap(), 360.0) - start;
    assert!((travel - 330.0).abs() < 1e-9, "travel {travel}");
    assert!(trace.iter().all(|s| s.set.v >= 0.0), "never moves negative");
    // Positions stay wrapped in [0, 360) all the way.
    assert!(trace.iter().all(|s| (0.0..360.0).contains(&s.set.p)));
}

#[test]
fn rel_target_zero_finishes_an_interrupted_move() {
    let mut k = kernel(vec![linear("x")]);
    k.command(
        0,
        Command::SetPosition {
            position: 0.0,
            relative: false,
        },
    )
    .unwrap();
    k.command(
        0,
        Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 100.0)),
    )
    .unwrap();
    run(&mut k, 0, 3000);
    let h = k
        .command(
            0,
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: None,
            },
        )
        .unwrap();
    run_until_final(&mut k, 0, h, 100_000);
    let stopped = k.axis_status(0).unwrap().set.p;
    assert!(
        stopped < 100.0 - 1.0,
        "halted short of the target at {stopped}"
    );
    let h = k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::RelTarget, 0.0)),
        )
        .unwrap();
    run_until_final(&mut k, 0, h, 100_000);
    assert!((k.axis_status(0).unwrap().set.p - 100.0).abs() < 1e-9);
}

#[test]
fn rel_actual_moves_from_the_actual_position() {
    let mut k = kernel(vec![linear("x")]);
    move_abs(&mut k, 0, 7.0);
    let h = k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::RelActual, -2.5)),
        )
        .unwrap();
    run_until_final(&mut k, 0, h, 100_000);
    assert!((k.axis_status(0).unwrap().set.p - 4.5).abs() < 1e-12);
}

/// Runs the seed's ramp-break scenario: a move 0 → 100 (v 10, a = d = 10, trapezoid);
/// 0.2 s into its deceleration ramp a second move to `second` with deceleration `decel2`.
/// Returns the recorded set positions and velocities after the second command.
fn ramp_break(mode: RampBreakMode, second: f64, decel2: f64) -> Vec<(f64, f64)> {
    let mut cfg = linear("x");
    cfg.ramp_break = mode;
    let mut k = kernel(vec![cfg]);
    k.command(
        0,
        Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 100.0)),
    )
    .unwrap();
    // Accelerate 1 s (5 units), cruise to 95 at t = 10 s, decelerate 10 s → 11 s.
    let trace = run(&mut k, 0, 10_200);
    assert_eq!(trace.last().unwrap().slope, SlopeState::Decelerating);
    let h = k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, second).accel(10.0, decel2)),
        )
        .unwrap();
    let out = run_until_final(&mut k, 0, h, 1_000_000);
    assert_eq!(k.command_status(h), CommandStatus::Done);
    assert!((out.last().unwrap().set.p - second).abs() < 1e-9);
    out.iter().map(|s| (s.set.p, s.set.v)).collect()
}

/// Whether the axis came to rest at `p` on the way.
fn rests_at(trace: &[(f64, f64)], p: f64) -> bool {
    trace
        .iter()
        .any(|&(x, v)| (x - p).abs() < 1e-6 && v.abs() < 1e-6)
}

#[test]
fn ramp_break_none_with_room_reaches_first_target_first() {
    let t = ramp_break(RampBreakMode::None, 200.0, 10.0);
    assert!(rests_at(&t, 100.0));
}

#[test]
fn ramp_break_none_without_room_reaches_first_target_first() {
    let t = ramp_break(RampBreakMode::None, 100.5, 1.0);
    assert!(rests_at(&t, 100.0));
}

#[test]
fn ramp_break_immediate_with_room_aborts_the_deceleration() {
    let t = ramp_break(RampBreakMode::Immediate, 200.0, 10.0);
    assert!(!rests_at(&t, 100.0));
    // It never stops on the way: velocity stays positive until the end.
    let moving = &t[..t.len() - 1];
    assert!(moving.iter().all(|&(_, v)| v > 0.0));
}

#[test]
fn ramp_break_immediate_without_room_reaches_first_target_first() {
    let t = ramp_break(RampBreakMode::Immediate, 100.5, 1.0);
    assert!(rests_at(&t, 100.0));
    assert!(t.iter().all(|&(x, _)| x <= 100.5 + 1e-9), "no overshoot");
}

#[test]
fn halt_at_actual_position_returns_to_where_it_was_given() {
    for ramp in [RampType::Trapezoid, RampType::SCurve, RampType::Sine] {
        let mut k = kernel(vec![linear("x")]);
        let mut v = MoveVelocity::new(MoveDirection::Positive, 10.0);
        v.ramp = Some(ramp);
        k.command(0, Command::MoveVelocity(v)).unwrap();
        run(&mut k, 0, 2500);
        let at = k.axis_status(0).unwrap().actual_position;
        let h = k
            .command(
                0,
                Command::Halt {
                    mode: HaltMode::AtActualPosition,
                    deceleration: Some(20.0),
                },
            )
            .unwrap();
        let trace = run_until_final(&mut k, 0, h, 100_000);
        let end = trace.last().unwrap();
        assert_eq!(k.command_status(h), CommandStatus::Done, "{ramp:?}");
        assert!(
            (end.set.p - at).abs() < 1e-9,
            "{ramp:?}: {} vs {at}",
            end.set.p
        );
        assert!(
            trace.iter().any(|s| s.set.p > at + 1.0),
            "it overran, then came back"
        );
        // Slope: decelerating, then accelerating and decelerating back (seed figure).
        let first_dec = trace
            .iter()
            .position(|s| s.slope == SlopeState::Decelerating);
        let back_acc = trace
            .iter()
            .position(|s| s.slope == SlopeState::Accelerating && s.set.v < 0.0);
        assert!(first_dec.is_some() && back_acc.is_some() && first_dec < back_acc);
        assert_eq!(end.slope, SlopeState::Stopped);
        assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
    }
}

#[test]
fn halt_normal_decelerates_to_a_stop_and_reports_slope_states() {
    let mut k = kernel(vec![linear("x")]);
    k.command(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
    )
    .unwrap();
    let ramp = run(&mut k, 0, 2000);
    assert_eq!(ramp[10].slope, SlopeState::Accelerating);
    assert_eq!(ramp[1999].slope, SlopeState::ConstantSpeed);
    assert_eq!(ramp[1999].state, AxisState::ContinuousMotion);
    let h = k
        .command(
            0,
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: Some(85.0),
            },
        )
        .unwrap();
    let trace = run_until_final(&mut k, 0, h, 100_000);
    assert!(trace[..trace.len() - 1]
        .iter()
        .all(|s| s.slope == SlopeState::Decelerating));
    assert_eq!(trace.last().unwrap().slope, SlopeState::Stopped);
    // 10 units/s at 85 units/s² stops in 10/85 s.
    let expected = (10.0_f64 / 85.0 / DT).ceil() as usize;
    assert!(
        (trace.len() as i64 - expected as i64).abs() <= 1,
        "{} vs {expected}",
        trace.len()
    );
}

#[test]
fn velocity_reverse_runs_the_other_way_at_the_same_speed() {
    let mut k = kernel(vec![linear("x")]);
    let h = k
        .command(
            0,
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
        )
        .unwrap();
    run(&mut k, 0, 1500);
    k.command(0, Command::Reverse).unwrap();
    let trace = run(&mut k, 0, 3000);
    assert!((trace.last().unwrap().set.v + 10.0).abs() < 1e-9);
    // Reversal uses the move's acceleration (10): 20 units/s of change takes 2 s.
    let reached = trace
        .iter()
        .position(|s| (s.set.v + 10.0).abs() < 1e-9)
        .unwrap();
    assert!((reached as f64 * DT - 2.0).abs() < 0.002, "{reached}");
    assert_eq!(k.command_status(h), CommandStatus::Active);
}

#[test]
fn velocity_new_speed_changes_speed_not_direction() {
    let mut k = kernel(vec![linear("x")]);
    k.command(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Negative, 10.0)),
    )
    .unwrap();
    run(&mut k, 0, 1500);
    k.command(
        0,
        Command::Change(gantry_kernel::axis::command::DynamicsChange::Speed, 4.0),
    )
    .unwrap();
    let trace = run(&mut k, 0, 1500);
    assert!((trace.last().unwrap().set.v + 4.0).abs() < 1e-9);
    assert!(trace.iter().all(|s| s.set.v < 0.0));
}

#[test]
fn velocity_operands_must_be_positive() {
    let mut k = kernel(vec![linear("x")]);
    for (speed, acc, dec, exerr) in [
        (0.0, 1.0, 1.0, 3),
        (5.0, -1.0, 1.0, 4),
        (5.0, 1.0, 0.0, 5),
        (f64::NAN, 1.0, 1.0, 3),
    ] {
        let mut v = MoveVelocity::new(MoveDirection::Positive, speed);
        v.acceleration = Some(acc);
        v.deceleration = Some(dec);
        let e = k.command(0, Command::MoveVelocity(v)).unwrap_err();
        assert_eq!(e.operand_number(), exerr, "{e}");
    }
}

#[test]
fn power_commands_follow_the_note() {
    let mut k = kernel(vec![linear("x")]);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
    // Disable (normal) while moving: brake, then disabled.
    k.command(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
    )
    .unwrap();
    run(&mut k, 0, 2000);
    let h = k.command(0, Command::Power(PowerCommand::Disable)).unwrap();
    let trace = run_until_final(&mut k, 0, h, 100_000);
    assert!(trace.len() > 100, "it braked for a while");
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Disabled);
    assert_eq!(k.axis_status(0).unwrap().set.v, 0.0);
    // Motion is refused while disabled.
    let e = k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::RelActual, 1.0)),
        )
        .unwrap_err();
    assert!(e.to_string().contains("Disabled"), "{e}");
    // QuickStop: stop with the quick-stop deceleration, then disabled.
    k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    k.command(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
    )
    .unwrap();
    run(&mut k, 0, 2000);
    let h = k.command(0, Command::QuickStop).unwrap();
    let trace = run_until_final(&mut k, 0, h, 100_000);
    let n = trace.len();
    assert!(
        (9..=12).contains(&n),
        "quick stop at 1000 units/s² from 10 units/s: {n} cycles"
    );
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Disabled);
    // Forced disable: at once.
    k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    k.command(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
    )
    .unwrap();
    run(&mut k, 0, 500);
    k.command(0, Command::Power(PowerCommand::DisableForced))
        .unwrap();
    let s = run(&mut k, 0, 1)[0];
    assert_eq!(s.state, AxisState::Disabled);
    assert_eq!(s.set.v, 0.0);
}
