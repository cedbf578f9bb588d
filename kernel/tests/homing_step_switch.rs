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
use homing_model::cases::run_step_switch;
use homing_model::expect::{expected, Expect};
use homing_model::*;

/// The seed's start positions on the standard layout (cam [10, 30], limits ±100).
const STARTS: [(&str, f64); 3] = [("1", -50.0), ("2", 20.0), ("3", 60.0)];

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

fn matrix(layout: Layout, deceleration: f64) -> usize {
    let mut failures = Vec::new();
    let mut n = 0;
    for mode in SwitchMode::ALL {
        for dir in HomeDirection::ALL {
            for (name, x0) in STARTS {
                n += 1;
                let e = expected(&layout, mode, dir, name);
                if let Err(why) = run_step_switch(layout, x0, params(dir, mode, deceleration), e) {
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
                if let Err(why) = run_step_switch(layout, x0, params(dir, mode, 15.0), e) {
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
    let out = run_step_switch(layout, 20.0, p, e).expect("homes");
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
        run_step_switch(Layout::STANDARD, 20.0, p, e).unwrap_or_else(|e| panic!("{dir:?}: {e}"));
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
