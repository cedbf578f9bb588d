//! PLCopen behaviour of the axis: buffer modes, command handles, the state machine,
//! homed-flag semantics, operand validation, and Logix MAJ jogs.

mod common;

use common::*;
use gantry_kernel::axis::command::{
    BufferMode, Command, CommandError, DynamicsChange, HaltMode, JerkUnits, Jog, JogProfile,
    MergeSpeed, MoveDirection, MovePtp, MoveVelocity, PositioningMode, RateUnits,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::mechanics::Direction;
use gantry_kernel::profile::RampType;
use gantry_kernel::{AxisConfig, AxisKind, Kernel};

fn ptp(target: f64) -> MovePtp {
    MovePtp::new(PositioningMode::AbsNormal, target)
}

#[test]
fn buffered_moves_leave_no_standstill_cycle() {
    for ramp in [
        RampType::Trapezoid,
        RampType::SCurve,
        RampType::Sine,
        RampType::LinearSine,
    ] {
        let mut k = kernel(vec![linear("x")]);
        let first = k
            .command(0, Command::MovePtp(ptp(10.0).ramp(ramp)))
            .unwrap();
        let mut handles = vec![first];
        for t in [20.0, 5.0, 30.0] {
            let h = k
                .command(
                    0,
                    Command::MovePtp(ptp(t).ramp(ramp).buffered(BufferMode::Buffered)),
                )
                .unwrap();
            assert_eq!(k.command_status(h), CommandStatus::Busy);
            handles.push(h);
        }
        let last = *handles.last().unwrap();
        let trace = run_until_final(&mut k, 0, last, 100_000);
        for h in &handles {
            assert_eq!(k.command_status(*h), CommandStatus::Done, "{ramp:?}");
        }
        // The axis never stands still in between: state stays DiscreteMotion and at most
        // one cycle (the junction itself, when it falls on a cycle) has zero velocity.
        let body = &trace[..trace.len() - 1];
        assert!(
            body.iter().all(|s| s.state == AxisState::DiscreteMotion),
            "{ramp:?}"
        );
        let mut run_len = 0;
        for s in &body[1..] {
            if s.set.v.abs() < 1e-12 {
                run_len += 1;
                assert!(run_len <= 1, "{ramp:?}: standstill cycle at p={}", s.set.p);
            } else {
                run_len = 0;
            }
        }
        assert!((trace.last().unwrap().set.p - 30.0).abs() < 1e-9);
        assert_eq!(trace.last().unwrap().state, AxisState::Standstill);
    }
}

/// Runs 0 → 10 then 10 → 20 with the given blending mode (speeds 10 then 4) and returns
/// the set velocity when the position passes 10.
fn junction_speed(mode: BufferMode, ramp: RampType) -> f64 {
    let mut k = kernel(vec![linear("x")]);
    k.command(
        0,
        Command::MovePtp(
            ptp(10.0)
                .speed(10.0)
                .ramp(ramp)
                .accel(100.0, 100.0)
                .jerk(10_000.0),
        ),
    )
    .unwrap();
    let h = k
        .command(
            0,
            Command::MovePtp(
                ptp(20.0)
                    .speed(4.0)
                    .ramp(ramp)
                    .accel(100.0, 100.0)
                    .jerk(10_000.0)
                    .buffered(mode),
            ),
        )
        .unwrap();
    let trace = run_until_final(&mut k, 0, h, 100_000);
    assert!((trace.last().unwrap().set.p - 20.0).abs() < 1e-9);
    let i = trace.iter().position(|s| s.set.p >= 10.0).unwrap();
    // Interpolate between the samples either side of the junction.
    (trace[i].set.v + trace[i.saturating_sub(1)].set.v) / 2.0
}

#[test]
fn blending_passes_the_junction_at_the_mode_velocity() {
    for ramp in [RampType::Trapezoid, RampType::SCurve] {
        let tol = 0.15; // one cycle at 100 units/s²
        let v = junction_speed(BufferMode::BlendingLow, ramp);
        assert!((v - 4.0).abs() < tol, "{ramp:?} low {v}");
        let v = junction_speed(BufferMode::BlendingNext, ramp);
        assert!((v - 4.0).abs() < tol, "{ramp:?} next {v}");
        let v = junction_speed(BufferMode::BlendingPrevious, ramp);
        assert!((v - 10.0).abs() < tol, "{ramp:?} previous {v}");
        let v = junction_speed(BufferMode::BlendingHigh, ramp);
        assert!((v - 10.0).abs() < tol, "{ramp:?} high {v}");
        let v = junction_speed(BufferMode::Buffered, ramp);
        assert!(v.abs() < tol, "{ramp:?} buffered {v}");
    }
}

#[test]
fn aborting_move_takes_over_and_reports_aborted() {
    let mut k = kernel(vec![linear("x")]);
    let a = k.command(0, Command::MovePtp(ptp(100.0))).unwrap();
    assert_eq!(k.command_status(a), CommandStatus::Active);
    run(&mut k, 0, 1500);
    let b = k.command(0, Command::MovePtp(ptp(-5.0))).unwrap();
    assert_eq!(k.command_status(a), CommandStatus::Aborted);
    let trace = run_until_final(&mut k, 0, b, 100_000);
    assert_eq!(k.command_status(b), CommandStatus::Done);
    assert!((trace.last().unwrap().set.p + 5.0).abs() < 1e-9);
    assert!(trace.last().unwrap().bits.in_target_window);
}

#[test]
fn in_target_window_is_set_only_near_the_target() {
    let mut k = kernel(vec![linear("x")]);
    let mut m = ptp(10.0);
    m.target_window = Some(0.5);
    let h = k.command(0, Command::MovePtp(m)).unwrap();
    let trace = run_until_final(&mut k, 0, h, 100_000);
    for s in &trace {
        assert_eq!(
            s.bits.in_target_window,
            (s.actual_position - 10.0).abs() <= 0.5
        );
    }
    assert!(trace.last().unwrap().bits.in_target_window);
    assert!(!trace[0].bits.in_target_window);
}

#[test]
fn stop_locks_the_axis_until_released() {
    let mut k = kernel(vec![linear("x")]);
    let mv = k.command(0, Command::MovePtp(ptp(100.0))).unwrap();
    run(&mut k, 0, 1500);
    let stop = k
        .command(
            0,
            Command::Stop {
                deceleration: Some(50.0),
            },
        )
        .unwrap();
    assert_eq!(k.command_status(mv), CommandStatus::Aborted);
    let e = k.command(0, Command::MovePtp(ptp(0.0))).unwrap_err();
    assert!(matches!(
        e,
        CommandError::NotAllowedInState {
            state: AxisState::Stopping,
            ..
        }
    ));
    let trace = run_until_final(&mut k, 0, stop, 100_000);
    assert!(trace.iter().all(|s| s.bits.stopping));
    run(&mut k, 0, 10);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Stopping);
    k.command(0, Command::Release).unwrap();
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
    k.command(0, Command::MovePtp(ptp(0.0))).unwrap();
}

#[test]
fn release_during_the_stop_ramp_takes_effect_when_stopped() {
    let mut k = kernel(vec![linear("x")]);
    k.command(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
    )
    .unwrap();
    run(&mut k, 0, 1500);
    let stop = k
        .command(
            0,
            Command::Stop {
                deceleration: Some(5.0),
            },
        )
        .unwrap();
    run(&mut k, 0, 100);
    k.command(0, Command::Release).unwrap();
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Stopping);
    run_until_final(&mut k, 0, stop, 100_000);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
}

#[test]
fn error_stop_refuses_motion_until_reset() {
    let mut cfg = linear("x");
    cfg.mechanics.software_limits = Some((-50.0, 50.0));
    let mut k = kernel(vec![cfg]);
    k.command(
        0,
        Command::SetPosition {
            position: 0.0,
            relative: false,
        },
    )
    .unwrap();
    let v = k
        .command(
            0,
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
        )
        .unwrap();
    let trace = run(&mut k, 0, 8000);
    // The velocity move brakes to stop exactly at the limit and the axis is in ErrorStop.
    let last = trace.last().unwrap();
    assert_eq!(last.state, AxisState::ErrorStop);
    assert!(last.bits.error);
    assert!((last.set.p - 50.0).abs() < 1e-9, "{}", last.set.p);
    assert!(trace.iter().all(|s| s.set.p <= 50.0 + 1e-9));
    assert!(matches!(k.command_status(v), CommandStatus::Error(_)));
    let reason = last.error.expect("a reason").to_string();
    assert!(reason.contains("software limit 50"), "{reason}");
    assert!(k.command(0, Command::MovePtp(ptp(0.0))).is_err());
    k.command(0, Command::Reset).unwrap();
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
    let h = k.command(0, Command::MovePtp(ptp(0.0))).unwrap();
    run_until_final(&mut k, 0, h, 100_000);
}

/// PLCopen: only Reset leaves ErrorStop. Powering off while the axis still brakes from
/// the error ends braking and power there, and leaves the axis in ErrorStop (it used to
/// pass through Stopping to Disabled, as if the error had been acknowledged).
#[test]
fn power_off_while_braking_in_error_stop_stays_in_error_stop() {
    let mut cfg = linear("x");
    cfg.mechanics.software_limits = Some((-50.0, 50.0));
    let mut k = kernel(vec![cfg]);
    k.command(
        0,
        Command::SetPosition {
            position: 45.0,
            relative: false,
        },
    )
    .unwrap();
    k.command(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
    )
    .unwrap();
    // Run until the limit check fires and the axis brakes in ErrorStop.
    let mut braking = false;
    for _ in 0..5000 {
        k.step(&[]);
        let s = k.axis_status(0).unwrap();
        if s.state == AxisState::ErrorStop && s.bits.moving {
            braking = true;
            break;
        }
    }
    assert!(braking, "the axis brakes in ErrorStop");
    let off = k
        .command(
            0,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Disable),
        )
        .unwrap();
    let trace = run_until_final(&mut k, 0, off, 100_000);
    assert!(trace.iter().all(|s| s.state == AxisState::ErrorStop));
    assert_eq!(k.command_status(off), CommandStatus::Done);
    assert!(!k.step(&[])[0].enable, "power is off");
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::ErrorStop);
    // Reset with power off: Disabled.
    k.command(0, Command::Reset).unwrap();
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Disabled);
    assert_eq!(k.axes()[0].refused_transitions(), 0);
}

#[test]
fn homed_flag_semantics() {
    let mut cfg = linear("x");
    cfg.homing_required = true;
    cfg.initial_position = 12.5;
    let mut k = kernel(vec![cfg]);
    let s = *k.axis_status(0).unwrap();
    assert!(
        (s.set.p - 12.5).abs() < 1e-12,
        "position restored at power-up"
    );
    assert!(!s.bits.homed, "restored but not homed");
    let e = k.command(0, Command::MovePtp(ptp(0.0))).unwrap_err();
    assert!(matches!(e, CommandError::NotHomed { .. }), "{e}");
    // Relative moves need no reference.
    let h = k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::RelActual, 1.0)),
        )
        .unwrap();
    run_until_final(&mut k, 0, h, 100_000);
    // A relative SetPosition does not home; an absolute one does.
    k.command(
        0,
        Command::SetPosition {
            position: 1.0,
            relative: true,
        },
    )
    .unwrap();
    assert!(!k.axis_status(0).unwrap().bits.homed);
    assert!((k.axis_status(0).unwrap().set.p - 14.5).abs() < 1e-12);
    k.command(
        0,
        Command::SetPosition {
            position: 0.0,
            relative: false,
        },
    )
    .unwrap();
    assert!(k.axis_status(0).unwrap().bits.homed);
    assert_eq!(k.axis_status(0).unwrap().set.p, 0.0);
    k.command(0, Command::MovePtp(ptp(3.0))).unwrap();
    // An explicit "is homed".
    let mut cfg = linear("y");
    cfg.homing_required = true;
    let mut k = kernel(vec![cfg]);
    k.command(0, Command::SetHomed(true)).unwrap();
    k.command(0, Command::MovePtp(ptp(3.0))).unwrap();
}

#[test]
fn bad_operands_name_the_operand_and_leave_the_move_running() {
    let mut cfg = linear("x");
    cfg.mechanics.software_limits = Some((-100.0, 100.0));
    let mut k = kernel(vec![cfg.clone()]);
    k.command(
        0,
        Command::SetPosition {
            position: 0.0,
            relative: false,
        },
    )
    .unwrap();
    let mut reference = kernel(vec![cfg]);
    reference
        .command(
            0,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        )
        .unwrap();
    let good = ptp(80.0);
    let h = k.command(0, Command::MovePtp(good)).unwrap();
    reference.command(0, Command::MovePtp(good)).unwrap();
    run(&mut k, 0, 500);
    run(&mut reference, 0, 500);
    let bad: [(Command, &str); 9] = [
        (Command::MovePtp(ptp(10.0).speed(0.0)), "speed"),
        (Command::MovePtp(ptp(10.0).speed(-3.0)), "speed"),
        (Command::MovePtp(ptp(10.0).speed(1e9)), "speed"),
        (
            Command::MovePtp(ptp(10.0).accel(f64::NAN, 1.0)),
            "acceleration",
        ),
        (
            Command::MovePtp(ptp(10.0).accel(1.0, f64::INFINITY)),
            "deceleration",
        ),
        (Command::MovePtp(ptp(10.0).jerk(-1.0)), "jerk"),
        (Command::MovePtp(ptp(f64::NAN)), "target"),
        (Command::MovePtp(ptp(150.0)), "software limits"),
        (
            Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloPos, 10.0)),
            "modulo",
        ),
    ];
    for (cmd, word) in bad {
        let e = k.command(0, cmd).unwrap_err();
        assert!(e.to_string().contains(word), "{e} should name {word}");
        assert_eq!(k.command_status(h), CommandStatus::Active);
    }
    let a = run(&mut k, 0, 20_000);
    let b = run(&mut reference, 0, 20_000);
    assert_eq!(a, b, "the refused commands changed nothing");
    assert_eq!(k.command_status(h), CommandStatus::Done);
}

#[test]
fn direction_restrictions_are_enforced() {
    let mut cfg = rotary("r");
    cfg.mechanics.direction = Direction::PositiveOnly;
    let mut k = kernel(vec![cfg]);
    let e = k
        .command(
            0,
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Negative, 5.0)),
        )
        .unwrap_err();
    assert!(matches!(e, CommandError::DirectionNotAllowed { .. }), "{e}");
    assert!(k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloNeg, 10.0))
        )
        .is_err());
    assert!(k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::RelActual, -10.0))
        )
        .is_err());
    // Auto on a positive-only axis goes the positive way round.
    k.command(
        0,
        Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloAuto, 50.0)),
    )
    .unwrap();
    run(&mut k, 0, 5000);
    let h = k
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloAuto, 40.0)),
        )
        .unwrap();
    let trace = run_until_final(&mut k, 0, h, 100_000);
    assert!(trace.iter().all(|s| s.set.v >= -1e-12));
    assert!((trace.last().unwrap().set.p - 40.0).abs() < 1e-9);
}

#[test]
fn external_and_shadow_axes_are_never_commanded() {
    let mut k = Kernel::new(
        DT,
        vec![
            linear("x"),
            AxisConfig::new("enc", AxisKind::External),
            AxisConfig::new("xs", AxisKind::Shadow { source: 0 }),
        ],
    )
    .unwrap();
    for axis in [1, 2] {
        let e = k
            .command(
                axis,
                Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
            )
            .unwrap_err();
        assert!(matches!(e, CommandError::NotCommandable { .. }), "{e}");
    }
    // The shadow axis mirrors its source.
    k.command(
        0,
        Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
    )
    .unwrap();
    k.command(0, Command::MovePtp(ptp(3.0))).unwrap();
    for _ in 0..500 {
        k.step(&[]);
        let src = *k.axis_status(0).unwrap();
        let sh = *k.axis_status(2).unwrap();
        assert_eq!(sh.actual_position, src.actual_position);
    }
    // An external axis reports its encoder.
    let fb = [
        Default::default(),
        gantry_kernel::axis::AxisFeedback {
            position: 42.0,
            velocity: 1.5,
            ..Default::default()
        },
    ];
    k.step(&fb);
    assert_eq!(k.axis_status(1).unwrap().actual_position, 42.0);
    assert_eq!(k.axis_status(1).unwrap().state, AxisState::Disabled);
}

/// What a drive at rest at `position` reports for the one axis of a kernel.
fn drive_at(
    position: f64,
    operation_enabled: bool,
    fault: Option<u16>,
) -> [gantry_kernel::axis::AxisFeedback; 1] {
    [gantry_kernel::axis::AxisFeedback {
        position,
        velocity: 0.0,
        operation_enabled,
        fault,
        ..Default::default()
    }]
}

#[test]
fn modulo_actual_is_reported_on_the_same_side_as_set() {
    let mut cfg = rotary("r");
    cfg.kind = AxisKind::Real;
    let mut k = Kernel::new(DT, vec![cfg]).unwrap();
    let h = k
        .command(
            0,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
        )
        .unwrap();
    assert_eq!(
        k.command_status(h),
        CommandStatus::Busy,
        "waits for the drive"
    );
    let fb = |p| drive_at(p, true, None);
    k.step(&fb(0.0));
    assert_eq!(k.command_status(h), CommandStatus::Done);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
    // Set 0, actual lagging by 2: report -2, not 358.
    k.step(&fb(358.0));
    assert_eq!(k.axis_status(0).unwrap().set.p, 0.0);
    assert!((k.axis_status(0).unwrap().actual_position + 2.0).abs() < 1e-9);
    // A drive fault puts the axis in ErrorStop with the code.
    let mut f = fb(358.0);
    f[0].fault = Some(0x2310);
    k.step(&f);
    let s = k.axis_status(0).unwrap();
    assert_eq!(s.state, AxisState::ErrorStop);
    assert!(s.error.unwrap().to_string().contains("0x2310"));
}

fn jog(dir: MoveDirection, speed: f64) -> Jog {
    Jog::new(dir, speed, 20.0, 20.0)
}

#[test]
fn jog_runs_until_halted_and_sets_the_jogging_bit() {
    let mut k = kernel(vec![linear("x")]);
    let h = k
        .command(0, Command::Jog(jog(MoveDirection::Negative, 5.0)))
        .unwrap();
    let t = run(&mut k, 0, 3000);
    assert!(t.iter().all(|s| s.bits.jogging));
    assert!((t.last().unwrap().set.v + 5.0).abs() < 1e-12);
    assert_eq!(t.last().unwrap().state, AxisState::ContinuousMotion);
    let halt = k
        .command(
            0,
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: None,
            },
        )
        .unwrap();
    assert_eq!(k.command_status(h), CommandStatus::Aborted);
    run_until_final(&mut k, 0, halt, 10_000);
    assert!(!k.axis_status(0).unwrap().bits.jogging);
}

#[test]
fn jog_speed_in_percent_of_max() {
    let mut k = kernel(vec![linear("x")]);
    let mut j = jog(MoveDirection::Positive, 10.0);
    j.speed_units = RateUnits::PercentOfMax; // 10 % of 100
    j.accel = 50.0;
    j.accel_units = RateUnits::PercentOfMax; // 500 units/s²
    k.command(0, Command::Jog(j)).unwrap();
    let t = run(&mut k, 0, 100);
    assert!((t.last().unwrap().set.v - 10.0).abs() < 1e-12);
    assert!((t[5].set.a - 500.0).abs() < 1e-9);
    j.speed = 150.0;
    let e = k.command(0, Command::Jog(j)).unwrap_err();
    assert_eq!(e.operand_number(), 3, "{e}");
}

#[test]
fn jog_merge_current_keeps_the_speed_of_the_running_move() {
    let mut k = kernel(vec![linear("x")]);
    let mv = k
        .command(
            0,
            Command::MovePtp(ptp(1000.0).speed(30.0).accel(100.0, 100.0)),
        )
        .unwrap();
    run(&mut k, 0, 1000);
    let mut j = jog(MoveDirection::Positive, 5.0);
    j.merge = true;
    j.merge_speed = MergeSpeed::Current;
    k.command(0, Command::Jog(j)).unwrap();
    assert_eq!(k.command_status(mv), CommandStatus::Aborted);
    let t = run(&mut k, 0, 1000);
    assert!(t.iter().all(|s| (s.set.v - 30.0).abs() < 1e-9));
    // Merge programmed: goes to the jog's own speed.
    j.merge_speed = MergeSpeed::Programmed;
    k.command(0, Command::Jog(j)).unwrap();
    let t = run(&mut k, 0, 3000);
    assert!((t.last().unwrap().set.v - 5.0).abs() < 1e-12);
    assert!(t.iter().all(|s| s.set.v >= 5.0 - 1e-9), "no undershoot");
}

#[test]
fn jog_without_merge_is_superimposed_on_the_running_move() {
    let mut k = kernel(vec![linear("x")]);
    let mv = k
        .command(
            0,
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
        )
        .unwrap();
    run(&mut k, 0, 2000);
    let j = k
        .command(0, Command::Jog(jog(MoveDirection::Positive, 3.0)))
        .unwrap();
    assert_eq!(k.command_status(mv), CommandStatus::Active, "not aborted");
    let t = run(&mut k, 0, 2000);
    assert!((t.last().unwrap().set.v - 13.0).abs() < 1e-9);
    assert!(t.last().unwrap().bits.jogging);
    // Stop ends both.
    let stop = k.command(0, Command::Stop { deceleration: None }).unwrap();
    assert_eq!(k.command_status(j), CommandStatus::Aborted);
    assert_eq!(k.command_status(mv), CommandStatus::Aborted);
    let t = run_until_final(&mut k, 0, stop, 10_000);
    // Continuous across the fold of the jog into the axis' own values.
    let first = t.first().unwrap();
    assert!(
        first.set.v <= 13.0 + 1e-9 && first.set.v >= 12.0 - 1e-9,
        "{}",
        first.set.v
    );
}

#[test]
fn jog_s_curve_percent_of_time_is_triangular_at_100_percent() {
    let mut k = kernel(vec![linear("x")]);
    let mut j = jog(MoveDirection::Positive, 10.0);
    j.profile = JogProfile::SCurve;
    j.jerk_units = JerkUnits::PercentOfTime;
    j.accel_jerk = 100.0;
    j.decel_jerk = 100.0;
    k.command(0, Command::Jog(j)).unwrap();
    let t = run(&mut k, 0, 3000);
    // Triangular acceleration to 20 units/s² over a change of 10 units/s: 1 s, peak at 0.5 s.
    let peak = t.iter().map(|s| s.set.a).fold(0.0, f64::max);
    assert!((peak - 20.0).abs() < 0.1, "peak {peak}");
    let reached = t
        .iter()
        .position(|s| (s.set.v - 10.0).abs() < 1e-9)
        .unwrap();
    assert!((reached as f64 * DT - 1.0).abs() < 0.003, "{reached}");
}

#[test]
fn lowering_deceleration_near_the_target_does_not_overshoot() {
    for ramp in [RampType::Trapezoid, RampType::SCurve] {
        let mut k = kernel(vec![linear("x")]);
        let h = k
            .command(
                0,
                Command::MovePtp(ptp(20.0).ramp(ramp).accel(50.0, 50.0).jerk(1000.0)),
            )
            .unwrap();
        // Run into the deceleration ramp, then ask for a much lower deceleration.
        loop {
            k.step(&[]);
            let s = k.axis_status(0).unwrap();
            if s.slope == gantry_kernel::axis::status::SlopeState::Decelerating {
                break;
            }
        }
        run(&mut k, 0, 20);
        k.command(0, Command::Change(DynamicsChange::Deceleration, 1.0))
            .unwrap();
        k.command(0, Command::Change(DynamicsChange::Jerk, 1.0))
            .unwrap();
        let t = run_until_final(&mut k, 0, h, 100_000);
        assert!(
            t.iter().all(|s| s.set.p <= 20.0 + 1e-9),
            "{ramp:?} overshoot"
        );
        assert!(t.iter().all(|s| s.set.v >= -1e-12), "{ramp:?} reversal");
        assert!((t.last().unwrap().set.p - 20.0).abs() < 1e-9);
    }
}

#[test]
fn lowering_jog_jerk_while_ramping_does_not_overshoot_the_speed() {
    let mut k = kernel(vec![linear("x")]);
    let mut j = jog(MoveDirection::Positive, 10.0);
    j.profile = JogProfile::SCurve;
    j.jerk_units = JerkUnits::PerSecond3;
    j.accel_jerk = 200.0;
    j.decel_jerk = 200.0;
    j.accel = 50.0;
    k.command(0, Command::Jog(j)).unwrap();
    run(&mut k, 0, 300);
    k.command(0, Command::Change(DynamicsChange::Jerk, 1.0))
        .unwrap();
    let t = run(&mut k, 0, 5000);
    assert!(t.iter().all(|s| s.set.v <= 10.0 + 1e-9), "speed overshoot");
    assert!((t.last().unwrap().set.v - 10.0).abs() < 1e-9);
}

#[test]
fn a_real_axis_takes_over_where_the_drive_stands_when_it_is_enabled() {
    let mut cfg = linear("x");
    cfg.kind = AxisKind::Real;
    let mut k = Kernel::new(DT, vec![cfg]).unwrap();
    // Commanded before any feedback arrived; the drive then reports 12.5 and, later, enabled.
    let h = k
        .command(
            0,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
        )
        .unwrap();
    let fb = |p, on| drive_at(p, on, None);
    k.step(&fb(12.5, false));
    assert_eq!(k.command_status(h), CommandStatus::Busy);
    k.step(&fb(12.5, true));
    assert_eq!(k.command_status(h), CommandStatus::Done);
    assert_eq!(k.axis_status(0).unwrap().set.p, 12.5, "no jump on enable");
    assert_eq!(k.step(&fb(12.5, true))[0].position, 12.5);
}

#[test]
fn an_axis_that_is_off_has_its_set_value_where_the_drive_is() {
    use gantry_kernel::axis::command::PowerCommand;
    let mut cfg = linear("x");
    cfg.kind = AxisKind::Real;
    let mut k = Kernel::new(DT, vec![cfg]).unwrap();
    let fb = |p, on| drive_at(p, on, None);
    // Pushed by hand while off: the set value follows, as TwinCAT's SetPos does.
    for p in [3.0, 3.5, 4.25] {
        k.step(&fb(p, false));
        assert_eq!(k.axis_status(0).unwrap().set.p, p);
    }
    // Switching off an axis that is off is no error (MC_Power with Enable = FALSE).
    let h = k.command(0, Command::Power(PowerCommand::Disable)).unwrap();
    assert_eq!(k.command_status(h), CommandStatus::Done);
    // Enabled, it holds: the set value no longer follows a drive that drifts.
    k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    k.step(&fb(4.25, true));
    k.step(&fb(4.3, true));
    assert_eq!(k.axis_status(0).unwrap().set.p, 4.25);
}

#[test]
fn reset_of_a_drive_fault_asks_the_drive_and_waits_for_it() {
    use gantry_kernel::axis::command::PowerCommand;
    use gantry_kernel::axis::DRIVE_RESET_TICKS;
    let mut cfg = linear("x");
    cfg.kind = AxisKind::Real;
    let mut k = Kernel::new(DT, vec![cfg]).unwrap();
    let fb = |on, fault| drive_at(1.0, on, fault);
    k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    k.step(&fb(true, None));
    k.step(&fb(false, Some(0x8700)));
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::ErrorStop);
    // Reset while the drive still has its fault: the set values ask for a fault reset,
    // and the Reset stays Busy until the drive clears it.
    let h = k.command(0, Command::Reset).unwrap();
    assert_eq!(k.command_status(h), CommandStatus::Busy);
    assert!(k.step(&fb(false, Some(0x8700)))[0].reset_fault);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::ErrorStop);
    let sp = k.step(&fb(false, None))[0];
    assert_eq!(k.command_status(h), CommandStatus::Done);
    assert!(!sp.reset_fault && !sp.enable, "no more reset, power off");
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Disabled);
    assert_eq!(k.axis_status(0).unwrap().error, None);

    // A drive that keeps its fault: the Reset fails with its code after the timeout.
    k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    k.step(&fb(true, None));
    k.step(&fb(false, Some(0x2310)));
    let h = k.command(0, Command::Reset).unwrap();
    for _ in 0..=DRIVE_RESET_TICKS + 1 {
        k.step(&fb(false, Some(0x2310)));
    }
    assert_eq!(
        k.command_status(h),
        CommandStatus::Error(CommandError::DriveResetFailed { code: 0x2310 })
    );
    assert!(!k.step(&fb(false, Some(0x2310)))[0].reset_fault);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::ErrorStop);
}

/// The drive-frame set position `turns · period + position` of a real modulo axis moves
/// by exactly what the set position moves, also when a SetPosition offset carries the
/// drive position across a period boundary the axis position has not crossed: the drive
/// layer counts `turns` exactly, so turns that belonged to the axis frame would make the
/// drive step a full period (issue 10 §1).
#[test]
fn drive_setpoint_turns_belong_to_the_drive_position_under_a_set_position_offset() {
    use gantry_kernel::axis::command::PowerCommand;
    let mut cfg = rotary("c");
    cfg.kind = AxisKind::Real;
    cfg.max.vmax = 720.0;
    cfg.max.amax = 7200.0;
    cfg.max.dmax = 7200.0;
    let mut k = Kernel::new(DT, vec![cfg]).unwrap();
    let unwrapped = |sp: &gantry_kernel::axis::AxisSetpoint| sp.turns as f64 * 360.0 + sp.position;
    // The drive stands at 10° (drive frame); the user declares it 350°: offset 340°.
    let fb = |p, on| drive_at(p, on, None);
    k.step(&fb(10.0, false));
    k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    k.step(&fb(10.0, true));
    k.command(
        0,
        Command::SetPosition {
            position: 350.0,
            relative: false,
        },
    )
    .unwrap();
    let mut last = k.step(&fb(10.0, true))[0];
    assert!(
        (unwrapped(&last) - 10.0).abs() < 1e-9,
        "the drive frame keeps 10°: {last:?}"
    );
    // Move +720° (two turns) at 360°/s: the axis wraps at 360 while the drive wraps at
    // 20° past it; the drive-frame position must never step more than v·T.
    k.command(
        0,
        Command::MovePtp(
            MovePtp::new(PositioningMode::RelTarget, 720.0)
                .speed(360.0)
                .accel(3600.0, 3600.0),
        ),
    )
    .unwrap();
    let mut max_step: f64 = 0.0;
    for _ in 0..4000 {
        let drive = (unwrapped(&last)).rem_euclid(360.0);
        let sp = k.step(&fb(drive, true))[0];
        max_step = max_step.max((unwrapped(&sp) - unwrapped(&last)).abs());
        assert!((0.0..360.0).contains(&sp.position), "{sp:?}");
        last = sp;
    }
    assert!(max_step <= 360.0 * DT + 1e-6, "largest step {max_step}°");
    assert!(
        (unwrapped(&last) - 730.0).abs() < 1e-6,
        "drive frame ends at 10° + 720°: {last:?}"
    );
}

/// PLCopen MC_Reset: ErrorStop → Standstill only with the drive's power on. A drive that
/// left Operation enabled without a fault while its axis was in ErrorStop (a CANopen node
/// reset by its power or another master: Switch on disabled) leaves the axis Disabled
/// after the reset, not Standstill on a drive that takes no set value; one that stayed
/// enabled goes back to Standstill.
#[test]
fn reset_leaves_the_axis_disabled_when_its_drive_lost_power_without_a_fault() {
    for drive_kept_power in [true, false] {
        let mut cfg = linear("x");
        cfg.kind = AxisKind::Real;
        let mut k = Kernel::new(DT, vec![cfg]).unwrap();
        k.command(
            0,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
        )
        .unwrap();
        k.step(&drive_at(0.0, true, None));
        assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
        // The bus lost the drive for a while (the master's communication fault).
        k.step(&drive_at(0.0, false, Some(0x8100)));
        assert_eq!(k.axis_status(0).unwrap().state, AxisState::ErrorStop);
        // Back: enabled still, or switched off without a fault.
        k.step(&drive_at(0.0, drive_kept_power, None));
        let h = k.command(0, Command::Reset).unwrap();
        assert_eq!(k.command_status(h), CommandStatus::Done);
        let expected = if drive_kept_power {
            AxisState::Standstill
        } else {
            AxisState::Disabled
        };
        assert_eq!(k.axis_status(0).unwrap().state, expected);
    }
}
