//! Jetter MoveHome (seed 000 §6.3.2) in lockstep with an axis model: every mode × switch
//! configuration × direction × start position, the reference exactly where the edge or
//! index pulse is (from the latch), ReferenceOffset and NormalPosition honoured, the status
//! bits in order, every sample inside the run's speed, acceleration and jerk; the search
//! distances end in errors naming them; SetReference; optional parameters.

mod homing_model;

use gantry_kernel::axis::command::{Command, MoveDirection};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::homing::{HomingMode, MoveHome, MoveHomeCall, SwitchConfig};
use homing_model::cases::{rig_for, run_move_home};
use homing_model::expect::{expected_move_home as expected, MoveHomeExpect as Expect};
use homing_model::*;

const STARTS: [(&str, f64); 3] = [("1", -50.0), ("2", 20.0), ("3", 60.0)];
const MODES: [HomingMode; 4] = [
    HomingMode::ZeroPulse1Phase,
    HomingMode::ZeroPulse2Phase,
    HomingMode::SwitchingEdge1Phase,
    HomingMode::SwitchingEdge2Phase,
];
const CONFIGS: [SwitchConfig; 4] = [
    SwitchConfig::NoSwitch,
    SwitchConfig::RefAndLimitSwitch,
    SwitchConfig::RefSwitch,
    SwitchConfig::LimitSwitch,
];

fn params(direction: MoveDirection, switch_config: SwitchConfig, mode: HomingMode) -> MoveHome {
    let d = direction.sign();
    MoveHome {
        direction,
        switch_config,
        mode,
        acceleration: 250.0,
        jerk: 8_000.0,
        speed_switch_search: 25.0,
        max_distance_switch_search: 1_000.0,
        speed_reference_search: 2.5,
        max_distance_reference_search: 1_000.0,
        reference_offset: -4.0 * d,
        normal_position: 12.5,
    }
}

#[test]
fn every_mode_switch_configuration_direction_and_start_position() {
    let mut failures = Vec::new();
    let mut n = 0;
    let mut kinds = [0usize; 3];
    for mode in MODES {
        for config in CONFIGS {
            for dir in [MoveDirection::Positive, MoveDirection::Negative] {
                for (name, x0) in STARTS {
                    n += 1;
                    let p = params(dir, config, mode);
                    let e = expected(&Layout::STANDARD, &p, x0);
                    kinds[match e {
                        Expect::Reference(_) => 0,
                        Expect::Refused => 1,
                        Expect::Limit(_) => 2,
                    }] += 1;
                    if let Err(why) = run_move_home(Layout::STANDARD, p, x0, e) {
                        failures.push(format!("{mode:?} {config:?} {dir:?} start {name}: {why}"));
                    }
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {n} failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert_eq!(n, 96);
    // 12 SwitchingEdge×NoSwitch refused, 8 RefSwitch runs with the cam behind them.
    assert_eq!(kinds, [76, 12, 8]);
}

#[test]
fn the_switch_search_distance_ends_in_an_error_naming_it() {
    let mut p = params(
        MoveDirection::Positive,
        SwitchConfig::RefAndLimitSwitch,
        HomingMode::SwitchingEdge2Phase,
    );
    p.max_distance_switch_search = 30.0;
    let mut rig = rig_for(Layout::STANDARD, &p, -50.0);
    let h = rig
        .k
        .command(0, Command::MoveHome(MoveHomeCall::all(p)))
        .unwrap();
    let mut out = Vec::new();
    let CommandStatus::Error(e) = rig.run_until_final(h, 100_000, &mut out) else {
        panic!()
    };
    let msg = e.to_string();
    assert!(
        msg.starts_with("MoveHome: MaxDistanceSwitchSearch = 30 exceeded (")
            && msg.ends_with(" travelled) without finding the reference switch"),
        "{msg}"
    );
    rig.run(2000, &mut out);
    let s = rig.k.axis_status(0).unwrap();
    assert_eq!(s.state, AxisState::ErrorStop);
    assert_eq!(s.set.v, 0.0);
    assert!(!s.bits.homed);
    // It stopped where the distance ran out: 30 on from −50 plus the braking.
    assert!(s.set.p > -20.0 && s.set.p < -17.0, "{}", s.set.p);
}

#[test]
fn the_reference_search_distance_ends_in_an_error_naming_it() {
    // From ③ positive: reverse at the positive limit, find the cam at 30, then the fine
    // search must cross the 20-unit cam to its negative edge: more than 5.
    let mut p = params(
        MoveDirection::Positive,
        SwitchConfig::RefAndLimitSwitch,
        HomingMode::SwitchingEdge2Phase,
    );
    p.max_distance_reference_search = 5.0;
    let mut rig = rig_for(Layout::STANDARD, &p, 60.0);
    let h = rig
        .k
        .command(0, Command::MoveHome(MoveHomeCall::all(p)))
        .unwrap();
    let mut out = Vec::new();
    let CommandStatus::Error(e) = rig.run_until_final(h, 200_000, &mut out) else {
        panic!()
    };
    assert!(
        e.to_string()
            .starts_with("MoveHome: MaxDistanceReferenceSearch = 5 exceeded"),
        "{e}"
    );
    let s = out.last().unwrap().status;
    assert!(
        s.homing.switch_found && !s.homing.reference_found,
        "{:?}",
        s.homing
    );
}

#[test]
fn a_call_without_parameters_uses_the_last_ones_and_a_partial_call_changes_only_what_it_gives() {
    let p = params(
        MoveDirection::Positive,
        SwitchConfig::RefAndLimitSwitch,
        HomingMode::SwitchingEdge2Phase,
    );
    let mut rig = rig_for(Layout::STANDARD, &p, -50.0);
    let mut out = Vec::new();
    let h = rig
        .k
        .command(0, Command::MoveHome(MoveHomeCall::all(p)))
        .unwrap();
    assert_eq!(
        rig.run_until_final(h, 100_000, &mut out),
        CommandStatus::Done
    );
    assert!((rig.sp.position - 6.0).abs() < 1e-9, "{}", rig.sp.position);
    // Seed 000: only ReferenceOffset and NormalPosition given; the rest as before.
    let call = MoveHomeCall {
        reference_offset: Some(-8.0),
        normal_position: Some(100.0),
        ..MoveHomeCall::default()
    };
    let h = rig.k.command(0, Command::MoveHome(call)).unwrap();
    assert_eq!(
        rig.run_until_final(h, 100_000, &mut out),
        CommandStatus::Done
    );
    assert!((rig.sp.position - 2.0).abs() < 1e-9, "{}", rig.sp.position);
    assert!((rig.k.axis_status(0).unwrap().set.p - 100.0).abs() < 1e-9);
    // And with no parameters at all, the same run again.
    let h = rig
        .k
        .command(0, Command::MoveHome(MoveHomeCall::default()))
        .unwrap();
    assert_eq!(
        rig.run_until_final(h, 100_000, &mut out),
        CommandStatus::Done
    );
    assert!((rig.sp.position - 2.0).abs() < 1e-9);
}

#[test]
fn a_bad_parameter_is_refused_naming_it_and_the_axis_goes_on() {
    let mut rig = Rig::new(axis_config(), Layout::STANDARD, 0.0);
    for (call, msg) in [
        (
            MoveHomeCall {
                speed_switch_search: Some(0.0),
                ..MoveHomeCall::default()
            },
            "MoveHome: parameter SpeedSwitchSearch = 0 must be > 0",
        ),
        (
            MoveHomeCall {
                speed_reference_search: Some(500.0),
                ..MoveHomeCall::default()
            },
            "MoveHome: parameter SpeedReferenceSearch = 500 exceeds the axis maximum",
        ),
        (
            MoveHomeCall {
                max_distance_reference_search: Some(-1.0),
                ..MoveHomeCall::default()
            },
            "MoveHome: parameter MaxDistanceReferenceSearch = -1 must be > 0",
        ),
        (
            MoveHomeCall {
                reference_offset: Some(f64::NAN),
                ..MoveHomeCall::default()
            },
            "MoveHome: parameter ReferenceOffset = NaN must be finite",
        ),
    ] {
        let e = rig.k.command(0, Command::MoveHome(call)).unwrap_err();
        assert_eq!(e.to_string(), msg);
        assert_eq!(rig.k.axis_status(0).unwrap().state, AxisState::Standstill);
    }
}

#[test]
fn set_reference_sets_the_position_without_moving_and_marks_reference_set() {
    let mut rig = Rig::new(axis_config(), Layout::STANDARD, 3.0);
    assert!(!rig.k.axis_status(0).unwrap().bits.homed);
    let h = rig.k.command(0, Command::SetReference(0.0)).unwrap();
    assert_eq!(rig.k.command_status(h), CommandStatus::Done);
    let mut out = Vec::new();
    rig.run(10, &mut out);
    let s = rig.k.axis_status(0).unwrap();
    assert!(s.bits.homed);
    assert!(s.homing.reference_set && !s.homing.started);
    assert_eq!(s.set.p, 0.0);
    assert_eq!(rig.sp.position, 3.0, "the drive did not move");
}

#[test]
fn a_stop_during_homing_aborts_it_and_leaves_the_axis_not_homed() {
    let p = params(
        MoveDirection::Positive,
        SwitchConfig::RefAndLimitSwitch,
        HomingMode::SwitchingEdge2Phase,
    );
    let mut rig = rig_for(Layout::STANDARD, &p, -50.0);
    rig.k.command(0, Command::SetReference(-50.0)).unwrap();
    let h = rig
        .k
        .command(0, Command::MoveHome(MoveHomeCall::all(p)))
        .unwrap();
    let mut out = Vec::new();
    rig.run(300, &mut out);
    assert_eq!(rig.k.axis_status(0).unwrap().state, AxisState::Homing);
    assert!(
        !rig.k.axis_status(0).unwrap().bits.homed,
        "not homed while homing"
    );
    let stop = rig
        .k
        .command(0, Command::Stop { deceleration: None })
        .unwrap();
    assert_eq!(rig.k.command_status(h), CommandStatus::Aborted);
    assert_eq!(
        rig.run_until_final(stop, 10_000, &mut out),
        CommandStatus::Done
    );
    let s = rig.k.axis_status(0).unwrap();
    assert!(!s.bits.homed && !s.homing.reference_set);
}

#[test]
fn a_simulated_axis_has_nothing_to_home_on_and_says_so() {
    let mut cfg = axis_config();
    cfg.kind = gantry_kernel::AxisKind::Simulated;
    let mut k = gantry_kernel::Kernel::new(DT, vec![cfg]).unwrap();
    k.command(
        0,
        Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
    )
    .unwrap();
    k.step(&[]);
    let e = k
        .command(0, Command::MoveHome(MoveHomeCall::default()))
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "MoveHome: a simulated axis has no switches or encoder to home on; use MoveHome.SetReference"
    );
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
    // SetReference works on it.
    k.command(0, Command::SetReference(1.0)).unwrap();
    assert!(k.axis_status(0).unwrap().bits.homed);
}

/// Seed 000: RefSwitch is "usually for rotary axes". On a modulo axis (360°, cam at
/// [100°, 120°], an index pulse every 36° from 5°) the search runs over the wrap, and the
/// reference is the cam edge (or the pulse after it) of the turn it found.
#[test]
fn a_rotary_axis_homes_over_the_wrap_on_its_reference_switch() {
    let layout = Layout {
        negative_limit: f64::NEG_INFINITY,
        positive_limit: f64::INFINITY,
        cam: (100.0, 120.0),
        index_pitch: 36.0,
        index_phase: 5.0,
        period: Some(360.0),
    };
    for (mode, reference) in [
        (HomingMode::SwitchingEdge2Phase, 100.0),
        (HomingMode::SwitchingEdge1Phase, 100.0),
        (HomingMode::ZeroPulse1Phase, 77.0),
        (HomingMode::ZeroPulse2Phase, 77.0),
    ] {
        let mut cfg = axis_config();
        cfg.mechanics.kind = gantry_kernel::mechanics::MotionKind::Rotary;
        cfg.mechanics.modulo = gantry_kernel::mechanics::Modulo::new(360.0);
        let mut rig = Rig::new(cfg, layout, 300.0);
        let mut p = params(MoveDirection::Positive, SwitchConfig::RefSwitch, mode);
        p.normal_position = 10.0;
        let h = rig
            .k
            .command(0, Command::MoveHome(MoveHomeCall::all(p)))
            .unwrap();
        let mut out = Vec::new();
        assert_eq!(
            rig.run_until_final(h, 100_000, &mut out),
            CommandStatus::Done,
            "{mode:?}"
        );
        check_limits(&out, 25.0, 250.0, 8_000.0).unwrap();
        let s = rig.k.axis_status(0).unwrap();
        assert!(s.bits.homed);
        assert!((s.set.p - 10.0).abs() < 1e-9, "{mode:?}: {}", s.set.p);
        // The drive stands at reference − 4 within its period, one turn on from 300°.
        let want = reference - 4.0;
        assert!(
            (rig.sp.position - want).abs() < 1e-9,
            "{mode:?}: drive at {} want {want}",
            rig.sp.position
        );
        assert!(rig.m.x > 360.0, "it went over the wrap: {}", rig.m.x);
    }
}

/// Seed 000 §5.2.6.2: saved parameters are loaded at start and a call without parameters
/// uses them; the axis reports the set in use so it can be saved again.
#[test]
fn saved_parameters_are_used_by_a_call_without_parameters() {
    let saved = params(
        MoveDirection::Negative,
        SwitchConfig::RefAndLimitSwitch,
        HomingMode::SwitchingEdge1Phase,
    );
    let mut cfg = axis_config();
    cfg.move_home = Some(saved);
    let mut rig = Rig::new(cfg, Layout::STANDARD, 60.0);
    assert_eq!(rig.k.axes()[0].move_home_parameters(), &saved);
    let h = rig
        .k
        .command(0, Command::MoveHome(MoveHomeCall::default()))
        .unwrap();
    let mut out = Vec::new();
    assert_eq!(
        rig.run_until_final(h, 100_000, &mut out),
        CommandStatus::Done
    );
    // Negative, so the cam's positive edge (30), plus the offset +4.
    assert!((rig.sp.position - 34.0).abs() < 1e-9, "{}", rig.sp.position);
    let changed = MoveHomeCall {
        normal_position: Some(1.0),
        ..MoveHomeCall::default()
    };
    rig.k.command(0, Command::MoveHome(changed)).unwrap();
    assert_eq!(rig.k.axes()[0].move_home_parameters().normal_position, 1.0);
}

/// An axis whose drive layer cannot put the touch probe on its limit switches
/// (`limit_edges_latched` off: no 0x60D0 configured) refuses MoveHome with LimitSwitch in
/// every mode — its edge (the reference, or where the index search starts) would be
/// another switch's latch — and still homes on its reference switch.
#[test]
fn a_limit_switch_edge_needs_the_probe_on_the_limit_switch() {
    let mut cfg = axis_config();
    cfg.limit_edges_latched = false;
    let mut rig = Rig::new(cfg, Layout::STANDARD, 0.0);
    for mode in MODES {
        let call = MoveHomeCall::all(params(
            MoveDirection::Positive,
            SwitchConfig::LimitSwitch,
            mode,
        ));
        let e = rig.k.command(0, Command::MoveHome(call)).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "MoveHome: parameter SwitchConfig = NaN needs the limit switch's edge from the \
                 drive's touch probe, which this axis cannot route to its limit switches"
            ),
            "{e}"
        );
        assert_eq!(rig.k.axis_status(0).unwrap().state, AxisState::Standstill);
    }
    let call = MoveHomeCall::all(params(
        MoveDirection::Positive,
        SwitchConfig::RefSwitch,
        HomingMode::SwitchingEdge1Phase,
    ));
    let h = rig.k.command(0, Command::MoveHome(call)).unwrap();
    assert_eq!(rig.k.command_status(h), CommandStatus::Busy);
}

/// A reference switch the probe cannot latch (read from an I/O module): every MoveHome
/// that looks for its edge is refused — SwitchingEdge (the reference) and ZeroPulse (the
/// index search starts at the edge) —, StepAbsoluteSwitch on an edge too; a ZeroPulse
/// run without a switch (the index pulse, latched by probe 2) and a Beckhoff search for
/// the switch's level (sampled, as TwinCAT's mcOn) still run.
#[test]
fn a_reference_switch_the_probe_cannot_latch_refuses_edge_homing_only() {
    use gantry_kernel::homing::{HomeDirection, StepAbsoluteSwitch, SwitchMode};
    let mut cfg = axis_config();
    cfg.reference_edges_latched = false;
    let mut rig = Rig::new(cfg, Layout::STANDARD, 0.0);
    for (config, mode) in [
        (SwitchConfig::RefSwitch, HomingMode::SwitchingEdge1Phase),
        (
            SwitchConfig::RefAndLimitSwitch,
            HomingMode::SwitchingEdge2Phase,
        ),
        (SwitchConfig::RefSwitch, HomingMode::ZeroPulse1Phase),
        (SwitchConfig::RefAndLimitSwitch, HomingMode::ZeroPulse2Phase),
    ] {
        let call = MoveHomeCall::all(params(MoveDirection::Positive, config, mode));
        let e = rig.k.command(0, Command::MoveHome(call)).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "MoveHome: parameter SwitchConfig = NaN needs the reference switch's edge"
            ),
            "{config:?} {mode:?}: {e}"
        );
        assert_eq!(rig.k.axis_status(0).unwrap().state, AxisState::Standstill);
    }
    let step = |mode| {
        Command::StepAbsoluteSwitch(StepAbsoluteSwitch {
            direction: HomeDirection::Positive,
            switch_mode: mode,
            position: 0.0,
            velocity: 10.0,
            acceleration: 100.0,
            deceleration: 100.0,
            jerk: 1_000.0,
            distance_limit: f64::INFINITY,
        })
    };
    let e = rig.k.command(0, step(SwitchMode::RisingEdge)).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("StepAbsoluteSwitch: parameter SwitchMode = NaN needs the reference"),
        "{e}"
    );
    let h = rig.k.command(0, step(SwitchMode::On)).unwrap();
    assert_eq!(rig.k.command_status(h), CommandStatus::Busy);
}

/// The setpoint asks the drive layer for the probe on the limit switch exactly while a
/// MoveHome with LimitSwitch runs (ZeroPulse too: its index search starts at the switch's
/// edge), not for one on the reference switch, not after the run.
#[test]
fn the_setpoint_routes_the_probe_to_the_limit_switch_for_the_run_only() {
    for (direction, mode, routed) in [
        (
            MoveDirection::Positive,
            HomingMode::SwitchingEdge1Phase,
            Some(gantry_kernel::homing::LimitSide::Positive),
        ),
        (
            MoveDirection::Negative,
            HomingMode::SwitchingEdge2Phase,
            Some(gantry_kernel::homing::LimitSide::Negative),
        ),
        (
            MoveDirection::Positive,
            HomingMode::ZeroPulse2Phase,
            Some(gantry_kernel::homing::LimitSide::Positive),
        ),
    ] {
        let p = params(direction, SwitchConfig::LimitSwitch, mode);
        let mut rig = rig_for(Layout::STANDARD, &p, 20.0);
        assert_eq!(rig.sp.probe_on_limit, None);
        let h = rig
            .k
            .command(0, Command::MoveHome(MoveHomeCall::all(p)))
            .unwrap();
        assert_eq!(rig.cycle().setpoint.probe_on_limit, routed, "{mode:?}");
        let mut out = Vec::new();
        assert_eq!(
            rig.run_until_final(h, 200_000, &mut out),
            CommandStatus::Done,
            "{direction:?} {mode:?}"
        );
        assert!(out
            .iter()
            .all(|s| s.setpoint.probe_on_limit == routed || s.setpoint.probe_on_limit.is_none()));
        assert_eq!(rig.cycle().setpoint.probe_on_limit, None, "after the run");
    }
    let p = params(
        MoveDirection::Positive,
        SwitchConfig::RefAndLimitSwitch,
        HomingMode::SwitchingEdge1Phase,
    );
    let mut rig = rig_for(Layout::STANDARD, &p, 20.0);
    rig.k
        .command(0, Command::MoveHome(MoveHomeCall::all(p)))
        .unwrap();
    assert_eq!(
        rig.cycle().setpoint.probe_on_limit,
        None,
        "reference switch"
    );
}

/// A drive whose touch probe stays on the home switch although the axis says its limit
/// edges are latched (its probe source 0x60D0 not set to the limit switch): a LimitSwitch
/// run must never take the home cam's latches for the limit switch's edge (before the fix
/// it homed on the cam's end, silently). It crosses the limit switch, sees no latch of it,
/// and fails naming the reference search's distance and the limit switch, in ErrorStop.
#[test]
fn limit_switch_homing_never_takes_the_home_switch_latch_for_the_limit_edge() {
    use gantry_kernel::axis::command::CommandError;
    use gantry_kernel::axis::status::AxisFault;
    use gantry_kernel::homing::HomingError;
    for mode in MODES {
        for dir in [MoveDirection::Positive, MoveDirection::Negative] {
            // From below, on and above the cam: the search crosses the cam on its way to
            // the limit switch from one side or the other.
            for (name, x0) in STARTS {
                let mut p = params(dir, SwitchConfig::LimitSwitch, mode);
                // Far enough to cross the limit switch from every start, short of the
                // other one when a second phase comes back from it.
                p.max_distance_switch_search = 180.0;
                p.max_distance_reference_search = 180.0;
                let mut rig = rig_for(Layout::STANDARD, &p, x0);
                rig.probe_routed = false;
                rig.m.probe_source = ProbeSource::Reference;
                let h = rig
                    .k
                    .command(0, Command::MoveHome(MoveHomeCall::all(p)))
                    .expect("accepted");
                let mut samples = Vec::new();
                let st = rig.run_until_final(h, 600_000, &mut samples);
                let what = format!("{mode:?} {dir:?} start {name}");
                assert!(
                    !samples.iter().any(|s| s.status.homing.reference_found),
                    "{what}: took a home-switch latch for the limit's edge"
                );
                assert_ne!(st, CommandStatus::Done, "{what}");
                let status = *rig.k.axis_status(0).expect("axis");
                assert_eq!(status.state, AxisState::ErrorStop, "{what}");
                let limit = if dir == MoveDirection::Positive {
                    "positive limit switch"
                } else {
                    "negative limit switch"
                };
                assert!(
                    matches!(
                        status.error,
                        Some(AxisFault::Command(CommandError::Homing(
                            HomingError::DistanceExceeded { looking_for, .. }
                        ))) if looking_for == limit
                    ),
                    "{what}: {:?}",
                    status.error
                );
                // It did cross the limit switch it looked for.
                let beyond = samples
                    .iter()
                    .any(|s| s.load * dir.sign() >= Layout::STANDARD.positive_limit);
                assert!(beyond, "{what}: never reached the limit switch");
            }
        }
    }
}
