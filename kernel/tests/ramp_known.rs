//! Ramps without a jerk limit (trapezoid, Sine, Linear/Sine; seed 000 §6.1.1): known
//! durations and samples worked out by hand, through the public planner entry points.

use core::f64::consts::PI;

use gantry_kernel::profile::ramp::{self, RampShape};
use gantry_kernel::profile::{self, KinematicState, Limits, RampType, Shape};

fn lim(vmax: f64, amax: f64, dmax: f64) -> Limits {
    Limits {
        vmax,
        amax,
        dmax,
        jmax: f64::INFINITY,
    }
}

fn moving(p: f64, v: f64) -> KinematicState {
    KinematicState {
        p,
        v,
        a: 0.0,
        j: 0.0,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn trapezoid_rest_to_rest_10_units_vmax_2_a_1_takes_7_s() {
    let p = profile::plan_position(
        RampType::Trapezoid,
        KinematicState::at_rest(0.0),
        10.0,
        0.0,
        &lim(2.0, 1.0, 1.0),
    )
    .unwrap();
    assert!(close(p.duration(), 7.0));
    // Samples: accelerating, cruising, decelerating.
    let s = p.sample(1.0);
    assert!(close(s.p, 0.5) && close(s.v, 1.0) && close(s.a, 1.0));
    let s = p.sample(3.5);
    assert!(close(s.p, 5.0) && close(s.v, 2.0) && s.a == 0.0);
    let s = p.sample(6.0);
    assert!(close(s.p, 9.5) && close(s.v, 1.0) && close(s.a, -1.0));
    assert_eq!(p.end_state(), KinematicState::at_rest(10.0));
    assert_eq!(p.sample(100.0), KinematicState::at_rest(10.0));
    // The shapes: constant acceleration, cruise, constant deceleration.
    let shapes: Vec<Shape> = p.segments().iter().map(|s| s.shape).collect();
    assert_eq!(
        shapes,
        [Shape::Accel(1.0), Shape::Accel(0.0), Shape::Accel(-1.0)]
    );
}

#[test]
fn trapezoid_negative_direction_mirrors_the_positive_one() {
    let l = lim(2.0, 1.0, 0.5);
    let fwd = ramp::plan_position(
        RampShape::Linear,
        KinematicState::at_rest(0.0),
        10.0,
        0.0,
        &l,
    )
    .unwrap();
    let back = ramp::plan_position(
        RampShape::Linear,
        KinematicState::at_rest(0.0),
        -10.0,
        0.0,
        &l,
    )
    .unwrap();
    assert_eq!(fwd.duration(), back.duration());
    // 2 s up (2 units), 4 s down (4 units), 4 units cruise in 2 s.
    assert!(close(fwd.duration(), 8.0));
    for i in 0..=80 {
        let t = f64::from(i) * 0.1;
        let (a, b) = (fwd.sample(t), back.sample(t));
        assert!(close(a.p, -b.p) && close(a.v, -b.v), "t {t}");
    }
}

#[test]
fn triangular_moves_peak_below_vmax() {
    // d = 1, a = d = 1: peak 1 at 1 s, 2 s in all.
    let p = ramp::plan_position(
        RampShape::Linear,
        KinematicState::at_rest(0.0),
        1.0,
        0.0,
        &lim(10.0, 1.0, 1.0),
    )
    .unwrap();
    assert!(close(p.duration(), 2.0));
    assert!(close(p.peaks().v, 1.0));
    assert_eq!(p.segments().len(), 2);
    // a = 1, d = 3, 2 units: w²/2 + w²/6 = 2 → w = √3; t = √3 + √3/3.
    let p = ramp::plan_position(
        RampShape::Linear,
        KinematicState::at_rest(0.0),
        2.0,
        0.0,
        &lim(10.0, 1.0, 3.0),
    )
    .unwrap();
    let w = 3.0_f64.sqrt();
    assert!(close(p.peaks().v, w));
    assert!(close(p.duration(), w + w / 3.0));
}

#[test]
fn sine_rest_to_rest_known_duration() {
    // vmax 2, a = d = 1, 10 units. Sine up: π·Δv/2a = π s over π units; sine² down:
    // 2·Δv/d = 4 s over 4 units; cruise (10 − π − 4)/2 s: 7 + π/2 in all.
    let p = profile::plan_position(
        RampType::Sine,
        KinematicState::at_rest(0.0),
        10.0,
        0.0,
        &lim(2.0, 1.0, 1.0),
    )
    .unwrap();
    assert!(close(p.duration(), 7.0 + PI / 2.0), "{}", p.duration());
    assert!(close(p.peaks().a, 1.0));
    let seg = p.segments();
    assert_eq!(seg.len(), 3);
    assert_eq!(seg[0].shape, Shape::Sine { dv: 2.0 });
    assert_eq!(seg[2].shape, Shape::SineSquared { dv: -2.0 });
    assert!(close(seg[0].duration, PI) && close(seg[2].duration, 4.0));
    // Shock-free stop: acceleration and jerk vanish at the end of the sine² ramp.
    let end = seg[2].sample(seg[2].duration);
    assert!(end.a.abs() < 1e-12 && end.j.abs() < 1e-12);
    // Acceleration starts smoothly too (a = 0 at t = 0).
    assert!(p.sample(0.0).a.abs() < 1e-12);
}

#[test]
fn linear_sine_rest_to_rest_known_duration() {
    // vmax 2, a = d = 1, 10 units: linear up 2 s (2 units), sine down π s (π units),
    // cruise (8 − π)/2 s: 6 + π/2 in all.
    let p = profile::plan_position(
        RampType::LinearSine,
        KinematicState::at_rest(0.0),
        10.0,
        0.0,
        &lim(2.0, 1.0, 1.0),
    )
    .unwrap();
    assert!(close(p.duration(), 6.0 + PI / 2.0), "{}", p.duration());
    let seg = p.segments();
    assert_eq!(seg[0].shape, Shape::Accel(1.0));
    assert_eq!(seg[2].shape, Shape::Sine { dv: -2.0 });
}

#[test]
fn sine_triangular_move_uses_effective_rates() {
    // Effective rates: up 2a/π, down d/2. a = d = 1, 1 unit:
    // w² (π/4 + 1) = 1 → w = 1/√(1 + π/4); t = w·π/2 + 2w.
    let p = ramp::plan_position(
        RampShape::Sine,
        KinematicState::at_rest(0.0),
        1.0,
        0.0,
        &lim(10.0, 1.0, 1.0),
    )
    .unwrap();
    let w = 1.0 / (1.0 + PI / 4.0).sqrt();
    assert!(close(p.peaks().v, w));
    assert!(close(p.duration(), w * PI / 2.0 + 2.0 * w));
    assert!(p.peaks().a <= 1.0 + 1e-12);
}

#[test]
fn velocity_ramps_take_their_shape_durations() {
    let l = lim(10.0, 2.0, 4.0);
    let rest = KinematicState::at_rest(0.0);
    let cases = [
        (RampShape::Linear, 0.0, 4.0, 2.0),
        (RampShape::Linear, 4.0, 0.0, 1.0),
        (RampShape::Sine, 0.0, 4.0, PI),
        (RampShape::Sine, 4.0, 0.0, 2.0),
        (RampShape::LinearSine, 0.0, 4.0, 2.0),
        (RampShape::LinearSine, 4.0, 0.0, PI / 2.0),
        // Through zero: slow down, then speed up the other way.
        (RampShape::Linear, 4.0, -4.0, 3.0),
        (RampShape::Sine, 4.0, -4.0, 2.0 + PI),
    ];
    for (shape, v0, v1, t) in cases {
        let p = ramp::plan_velocity(shape, moving(0.0, v0), v1, &l).unwrap();
        assert!(
            close(p.duration(), t),
            "{shape:?} {v0} → {v1}: {}",
            p.duration()
        );
        assert_eq!(p.end_state().v, v1);
        // Mean velocity over each ramp: distance (v0 + v1)/2 · T per ramp.
        let expect: f64 = p
            .segments()
            .iter()
            .map(|s| (s.start.v + s.end().v) / 2.0 * s.duration)
            .sum();
        assert!(close(p.end_state().p, expect));
    }
    // Targets beyond vmax are clamped.
    let p = ramp::plan_velocity(RampShape::Linear, rest, 25.0, &l).unwrap();
    assert_eq!(p.end_state().v, 10.0);
    let p = ramp::plan_velocity(RampShape::Linear, rest, -25.0, &l).unwrap();
    assert_eq!(p.end_state().v, -10.0);
}

#[test]
fn moving_away_from_the_target_stops_then_comes_back() {
    // At −1 units/s, target 4 ahead: stop in 1 s (0.5 back), then 4.5 units from rest
    // with vmax 3, a = d = 1: triangle peak √4.5 ≈ 2.12 in 2·√4.5 s.
    let p = ramp::plan_position(
        RampShape::Linear,
        moving(0.0, -1.0),
        4.0,
        0.0,
        &lim(3.0, 1.0, 1.0),
    )
    .unwrap();
    assert!(close(p.duration(), 1.0 + 2.0 * 4.5_f64.sqrt()));
    assert!(close(p.sample(1.0).p, -0.5));
    assert_eq!(p.end_state().p, 4.0);
}

#[test]
fn overshooting_target_stops_then_comes_back() {
    // At 2 units/s, 1 unit ahead, d = 1: stopping takes 2 units; stop at 2 after 2 s,
    // then 1 unit back from rest: 2 s more.
    let p = ramp::plan_position(
        RampShape::Linear,
        moving(0.0, 2.0),
        1.0,
        0.0,
        &lim(2.0, 1.0, 1.0),
    )
    .unwrap();
    assert!(close(p.duration(), 4.0));
    assert!(close(p.sample(2.0).p, 2.0));
    assert_eq!(p.end_state(), KinematicState::at_rest(1.0));
}

#[test]
fn target_exactly_at_the_stopping_point_needs_no_return() {
    for shape in [RampShape::Linear, RampShape::Sine, RampShape::LinearSine] {
        let l = lim(5.0, 1.0, 0.7);
        let v0 = 3.0;
        // Stopping distance from the velocity planner itself: the same rounding.
        let stop = ramp::plan_velocity(shape, moving(0.0, v0), 0.0, &l).unwrap();
        let target = stop.end_state().p;
        let p = ramp::plan_position(shape, moving(0.0, v0), target, 0.0, &l).unwrap();
        assert_eq!(p.segments().len(), 1, "{shape:?}");
        assert!(close(p.duration(), stop.duration()));
        // A hair nearer still does not turn round.
        let p =
            ramp::plan_position(shape, moving(0.0, v0), target * (1.0 - 1e-14), 0.0, &l).unwrap();
        assert_eq!(p.segments().len(), 1, "{shape:?}");
    }
}

#[test]
fn start_above_vmax_comes_down_at_once() {
    // v0 = 5 > vmax = 2, a = d = 1, 100 units ahead: 5 → 2 in 3 s (10.5 units), cruise,
    // 2 → 0 in 2 s (2 units): 3 + 87.5/2 + 2.
    let p = ramp::plan_position(
        RampShape::Linear,
        moving(0.0, 5.0),
        100.0,
        0.0,
        &lim(2.0, 1.0, 1.0),
    )
    .unwrap();
    assert!(close(p.duration(), 3.0 + 87.5 / 2.0 + 2.0));
    assert!(p.sample(0.0).a < 0.0);
    assert!(close(p.sample(3.0).v, 2.0));
}

#[test]
fn blending_end_velocity_cases() {
    let l = lim(2.0, 1.0, 1.0);
    let rest = KinematicState::at_rest(0.0);
    // Reachable: up to 2, cruise, down to 1.
    let p = ramp::plan_position(RampShape::Linear, rest, 10.0, 1.0, &l).unwrap();
    assert_eq!(p.end_state().v, 1.0);
    // 2 s up (2), 1 s down (1.5), cruise 6.5 units in 3.25 s.
    assert!(close(p.duration(), 6.25));
    // Unreachable end speed: accelerate the whole way, end at √(2·a·d).
    let p = ramp::plan_position(RampShape::Linear, rest, 0.5, 2.0, &l).unwrap();
    assert_eq!(p.end_state().v, 1.0);
    assert!(close(p.duration(), 1.0));
    // Negative moves take a negative end velocity.
    let p = ramp::plan_position(RampShape::Linear, rest, -10.0, -1.0, &l).unwrap();
    assert_eq!(p.end_state().v, -1.0);
    // Wrong sign: stop.
    let p = ramp::plan_position(RampShape::Linear, rest, -10.0, 1.0, &l).unwrap();
    assert_eq!(p.end_state().v, 0.0);
    // Already at speed, target close: cruise through at the end speed.
    let p = ramp::plan_position(RampShape::Sine, moving(0.0, 2.0), 1.0, 2.0, &l).unwrap();
    assert!(close(p.duration(), 0.5));
    // Zero-length move at the end speed: nothing to do.
    let p = ramp::plan_position(RampShape::Sine, moving(3.0, 2.0), 3.0, 2.0, &l).unwrap();
    assert_eq!(p.duration(), 0.0);
    assert_eq!(p.end_state().v, 2.0);
}

#[test]
fn zero_length_move_while_moving_stops_and_returns() {
    let l = lim(2.0, 1.0, 1.0);
    // At 1 units/s on the target: stop (0.5 out, 1 s), back 0.5 from rest (2·√0.5 s).
    let p = ramp::plan_position(RampShape::Linear, moving(3.0, 1.0), 3.0, 0.0, &l).unwrap();
    assert!(close(p.duration(), 1.0 + 2.0 * 0.5_f64.sqrt()));
    assert_eq!(p.end_state(), KinematicState::at_rest(3.0));
}

#[test]
fn start_acceleration_is_ignored() {
    let l = lim(2.0, 1.0, 1.0);
    let a = KinematicState {
        a: -7.0,
        ..KinematicState::at_rest(0.0)
    };
    let p = ramp::plan_position(RampShape::Linear, a, 10.0, 0.0, &l).unwrap();
    assert!(close(p.duration(), 7.0));
    assert_eq!(p.sample(0.0).a, 1.0);
}

#[test]
fn ramp_types_dispatch_to_their_shapes() {
    let l = lim(2.0, 1.0, 1.0);
    let rest = KinematicState::at_rest(0.0);
    for (ty, shape) in [
        (RampType::Trapezoid, RampShape::Linear),
        (RampType::Sine, RampShape::Sine),
        (RampType::LinearSine, RampShape::LinearSine),
    ] {
        assert_eq!(
            profile::plan_position(ty, rest, 3.0, 0.0, &l).unwrap(),
            ramp::plan_position(shape, rest, 3.0, 0.0, &l).unwrap()
        );
        assert_eq!(
            profile::plan_velocity(ty, rest, -1.5, &l).unwrap(),
            ramp::plan_velocity(shape, rest, -1.5, &l).unwrap()
        );
    }
}

#[test]
fn far_from_the_origin_positions_stay_exact() {
    // Positions near ±1e9 (the axis' bound) still land exactly on target.
    let l = lim(100.0, 1000.0, 1000.0);
    for p0 in [1e9, -1e9, 999_999_999.123_456] {
        for shape in [RampShape::Linear, RampShape::Sine, RampShape::LinearSine] {
            let target = p0 + 0.001;
            let p =
                ramp::plan_position(shape, KinematicState::at_rest(p0), target, 0.0, &l).unwrap();
            assert_eq!(p.end_state().p, target);
            assert!((p.sample(p.duration()).p - target).abs() < 1e-6);
            assert!(p.duration() > 0.0);
        }
    }
}
