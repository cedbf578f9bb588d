//! Beckhoff MC_StepAbsoluteSwitch (seed 003) in lockstep with an axis model: every
//! Direction × SwitchMode from each of the seed's three start positions (① between the
//! negative limit and the cam, ② on the cam, ③ between the cam and the positive limit),
//! with the reference and the direction the seed defines, including the cases the seed
//! documents as failing in TwinCAT 3.0.23.0, and with a deceleration so small the axis
//! brakes across the whole cam.

mod homing_model;

use gantry_kernel::axis::command::Command;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::homing::{HomeDirection, StepAbsoluteSwitch, SwitchMode};
use homing_model::*;

/// The seed's start positions on the standard layout (cam [10, 30], limits ±100).
const STARTS: [(&str, f64); 3] = [("1", -50.0), ("2", 20.0), ("3", 60.0)];

/// What the seed says a run ends on.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    /// The edge at `at`, crossed moving `moving` (±1).
    Edge { at: f64, moving: f64 },
    /// At once, where the axis stands (mcOn on the cam, mcOff off it, seed 003).
    AtOnce,
}

/// The seed's definitions, written out per mode (not derived from the kernel's goals).
fn expected(layout: &Layout, mode: SwitchMode, dir: HomeDirection, start: &str) -> Expect {
    let (low, high) = layout.cam;
    let d = dir.sign();
    let rising_side = |m: f64| if m > 0.0 { low } else { high };
    let falling_side = |m: f64| if m > 0.0 { high } else { low };
    let edge = |at, moving| Expect::Edge { at, moving };
    use HomeDirection as D;
    match mode {
        // "Ends on the rising edge in the set direction" (reverses when it passes it the
        // other way), and so on for the three others.
        SwitchMode::RisingEdge => edge(rising_side(d), d),
        SwitchMode::FallingEdge => edge(falling_side(d), d),
        SwitchMode::RisingEdgeInverse => edge(rising_side(-d), -d),
        SwitchMode::FallingEdgeInverse => edge(falling_side(-d), -d),
        // "Always the left edge; ① ends moving positive, ② and ③ moving negative."
        SwitchMode::EdgeSwitchPositive => edge(low, if start == "1" { 1.0 } else { -1.0 }),
        // "Always the right edge; ① and ② end moving positive, ③ moving negative."
        SwitchMode::EdgeSwitchNegative => edge(high, if start == "3" { -1.0 } else { 1.0 }),
        // mcOn: ends when the signal is on.
        SwitchMode::On => match (start, dir) {
            ("1", _) => edge(low, 1.0),
            ("3", _) => edge(high, -1.0),
            (_, D::Positive | D::Negative) => Expect::AtOnce,
            (_, D::SwitchPositive) => edge(low, 1.0),
            (_, D::SwitchNegative) => edge(high, -1.0),
        },
        // mcOff: ends when the signal is off.
        SwitchMode::Off => match (start, dir) {
            ("1" | "3", _) => Expect::AtOnce,
            (_, D::Positive) => edge(high, 1.0),
            (_, D::Negative) => edge(low, -1.0),
            (_, D::SwitchPositive) => edge(low, -1.0),
            (_, D::SwitchNegative) => edge(high, 1.0),
        },
    }
}

fn params(dir: HomeDirection, mode: SwitchMode, deceleration: f64) -> StepAbsoluteSwitch {
    StepAbsoluteSwitch {
        direction: dir,
        switch_mode: mode,
        position: 7.0,
        velocity: 20.0,
        acceleration: 200.0,
        deceleration,
        jerk: 5_000.0,
        distance_limit: f64::INFINITY,
    }
}

/// Runs one case; returns the samples or a description of what went wrong.
fn run_case(
    layout: Layout,
    x0: f64,
    p: StepAbsoluteSwitch,
    expect: Expect,
) -> Result<Vec<Sample>, String> {
    let mut rig = Rig::new(axis_config(), layout, x0);
    let h = rig
        .k
        .command(0, Command::StepAbsoluteSwitch(p))
        .map_err(|e| format!("refused: {e}"))?;
    let mut out = Vec::new();
    let st = rig.run_until_final(h, 200_000, &mut out);
    if st != CommandStatus::Done {
        return Err(format!("ended {st:?}"));
    }
    let last = out.last().copied().ok_or("no samples")?;
    let s = last.status;
    if s.state != AxisState::Standstill || !s.bits.homed {
        return Err(format!("state {:?}, homed {}", s.state, s.bits.homed));
    }
    check_limits(&out, p.velocity, p.acceleration.max(p.deceleration), p.jerk)?;
    let seq = check_status_sequence(&out)?;
    let h = s.homing;
    if !(h.started && h.switch_found && h.reference_found && h.reference_set) {
        return Err(format!("final status {h:?} (sequence {seq:?})"));
    }
    match expect {
        Expect::AtOnce => {
            if out.iter().any(|x| x.status.set.v != 0.0) {
                return Err("moved although the level held at the start".into());
            }
            if (s.set.p - p.position).abs() > 1e-9 {
                return Err(format!("position {} != {}", s.set.p, p.position));
            }
        }
        Expect::Edge { at, moving } => {
            // Axis frame − drive frame is the same everywhere: the reference (drive frame
            // `at`) has the position `p.position`.
            let got = s.set.p - last.setpoint.position;
            let want = p.position - at;
            if (got - want).abs() > 1e-9 {
                return Err(format!(
                    "reference at drive {} (want {at})",
                    last.setpoint.position - (s.set.p - p.position)
                ));
            }
            let found = out
                .iter()
                .find(|x| x.status.homing.reference_found)
                .ok_or("reference never found")?;
            let v = found.status.actual_velocity;
            if v * moving <= 0.0 {
                return Err(format!("found moving {v}, want sign {moving}"));
            }
            if (last.setpoint.position - at) * moving < -1e-9 {
                return Err(format!(
                    "stands at {} before the edge {at} (moving {moving})",
                    last.setpoint.position
                ));
            }
        }
    }
    Ok(out)
}

fn matrix(layout: Layout, deceleration: f64) -> usize {
    let mut failures = Vec::new();
    let mut n = 0;
    for mode in SwitchMode::ALL {
        for dir in HomeDirection::ALL {
            for (name, x0) in STARTS {
                n += 1;
                let e = expected(&layout, mode, dir, name);
                if let Err(why) = run_case(layout, x0, params(dir, mode, deceleration), e) {
                    failures.push(format!("{mode:?} {dir:?} start {name}: {why}"));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {n} cases failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
    n
}

#[test]
fn every_direction_and_switch_mode_from_every_start_position() {
    assert_eq!(matrix(Layout::STANDARD, 200.0), 96);
}

/// Seed 003, "FAQ": with a small deceleration TwinCAT may never end the run. Here the axis
/// brakes 13 units past a 2-unit cam (and deep into the limit switches when it reverses):
/// every case still ends on the latched edge.
#[test]
fn a_small_deceleration_that_brakes_across_the_cam_still_ends_on_the_edge() {
    let layout = Layout {
        cam: (10.0, 12.0),
        ..Layout::STANDARD
    };
    // Start ② on the narrow cam.
    let mut failures = Vec::new();
    for mode in SwitchMode::ALL {
        for dir in HomeDirection::ALL {
            for (name, x0) in [("1", -50.0), ("2", 11.0), ("3", 60.0)] {
                let e = expected(&layout, mode, dir, name);
                if let Err(why) = run_case(layout, x0, params(dir, mode, 15.0), e) {
                    failures.push(format!("{mode:?} {dir:?} start {name}: {why}"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Seed 003 on mcEdgeSwitchPositive: "at ② with mcSwitchNegative the expected path is the
/// red dashed one, but TwinCAT 3.0.23.0 takes the red solid one and ends elsewhere". The
/// direction says: on the cam, leave it positive first, then search negative; the mode ends
/// on the cam's negative edge. We leave over the positive edge, turn, cross the cam
/// negative and end on its negative edge moving negative.
#[test]
fn edge_switch_positive_on_the_cam_with_switch_negative_leaves_positive_then_ends_on_the_negative_edge(
) {
    let layout = Layout::STANDARD;
    let p = params(
        HomeDirection::SwitchNegative,
        SwitchMode::EdgeSwitchPositive,
        200.0,
    );
    let e = Expect::Edge {
        at: 10.0,
        moving: -1.0,
    };
    let out = run_case(layout, 20.0, p, e).expect("homes");
    let first_move = out.iter().find(|s| s.status.set.v != 0.0).expect("moves");
    assert!(
        first_move.status.set.v > 0.0,
        "leaves the cam positive first"
    );
    // It left over the positive edge before it turned.
    let max = out.iter().map(|s| s.load).fold(f64::MIN, f64::max);
    assert!(max > 30.0, "went past the positive edge ({max})");
}

/// Seed 003 on mcEdgeSwitchNegative: "at ② with mcSwitchXxx the run should end moving
/// positive, but TwinCAT reverses once more and ends moving negative". We end moving
/// positive on the positive edge with both Switch directions.
#[test]
fn edge_switch_negative_on_the_cam_with_switch_directions_ends_moving_positive() {
    for dir in [HomeDirection::SwitchPositive, HomeDirection::SwitchNegative] {
        let p = params(dir, SwitchMode::EdgeSwitchNegative, 200.0);
        let e = Expect::Edge {
            at: 30.0,
            moving: 1.0,
        };
        run_case(Layout::STANDARD, 20.0, p, e).unwrap_or_else(|e| panic!("{dir:?}: {e}"));
    }
}

#[test]
fn a_cam_that_is_not_there_ends_in_an_error_naming_it_after_both_limits() {
    let layout = Layout {
        cam: (500.0, 510.0),
        ..Layout::STANDARD
    };
    let mut rig = Rig::new(axis_config(), layout, 0.0);
    let p = params(HomeDirection::Positive, SwitchMode::RisingEdge, 200.0);
    let h = rig.k.command(0, Command::StepAbsoluteSwitch(p)).unwrap();
    let mut out = Vec::new();
    let st = rig.run_until_final(h, 100_000, &mut out);
    let CommandStatus::Error(e) = st else {
        panic!("{st:?}")
    };
    assert_eq!(
        e.to_string(),
        "StepAbsoluteSwitch: the reference switch was not found between the limit switches"
    );
    rig.run(3000, &mut out);
    let s = rig.k.axis_status(0).unwrap();
    assert_eq!(s.state, AxisState::ErrorStop);
    assert_eq!(s.set.v, 0.0, "stopped");
    assert!(!s.bits.homed);
}

#[test]
fn the_distance_limit_ends_the_search_with_an_error_naming_it() {
    let mut rig = Rig::new(axis_config(), Layout::STANDARD, -50.0);
    let mut p = params(HomeDirection::Positive, SwitchMode::RisingEdge, 200.0);
    p.distance_limit = 40.0;
    let h = rig.k.command(0, Command::StepAbsoluteSwitch(p)).unwrap();
    let mut out = Vec::new();
    let CommandStatus::Error(e) = rig.run_until_final(h, 100_000, &mut out) else {
        panic!()
    };
    assert!(
        e.to_string()
            .starts_with("StepAbsoluteSwitch: DistanceLimit = 40 exceeded"),
        "{e}"
    );
    assert!(
        e.to_string()
            .ends_with("without finding the reference switch"),
        "{e}"
    );
}
