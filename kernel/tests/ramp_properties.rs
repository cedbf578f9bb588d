//! Seeded property tests of the ramps without a jerk limit over random start states,
//! limits and targets, for all three shapes: limits hold at dense samples (the semantics
//! of `profile`'s module doc), moves end exactly on target, position and velocity are
//! continuous, starts beyond vmax never go further out, Sine is never faster than linear,
//! and the direction of a move does not matter (mirror symmetry).

use gantry_kernel::profile::ramp::{plan_position, plan_velocity, RampShape};
use gantry_kernel::profile::{KinematicState, Limits, Profile, Shape};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

const SHAPES: [RampShape; 3] = [RampShape::Linear, RampShape::Sine, RampShape::LinearSine];

fn config(cases: u32, seed: u64) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

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

/// Limits at `n` dense samples plus every segment boundary (and just inside it), the
/// "never further out" rule for a start beyond vmax, and continuity of p and v.
fn check_profile(p: &Profile, start: &KinematicState, l: &Limits) -> Result<(), TestCaseError> {
    let vcap = l.vmax.max(start.v.abs());
    let v_tol = 1e-9 * vcap.max(1.0);
    // At (numerically) zero speed a segment may be ending a stop or starting from rest;
    // the per-segment check below decides those exactly.
    let a_ok = |s: &KinematicState| {
        let bound = if s.v.abs() <= 1e-12 * vcap {
            l.amax.max(l.dmax)
        } else if s.a * s.v > 0.0 {
            l.amax
        } else {
            l.dmax
        };
        s.a.abs() <= bound * (1.0 + 1e-9) + 1e-12
    };
    let mut times: Vec<f64> = (0..=1000)
        .map(|i| p.duration() * f64::from(i) / 1000.0)
        .collect();
    let mut t0 = 0.0;
    for seg in p.segments() {
        times.extend([
            t0,
            t0 + seg.duration * 1e-9,
            t0 + seg.duration * (1.0 - 1e-9),
        ]);
        t0 += seg.duration;
    }
    times.sort_by(f64::total_cmp);
    let mut was_inside = start.v.abs() <= l.vmax;
    let mut prev_speed = start.v.abs();
    for &t in &times {
        let s = p.sample(t);
        prop_assert!(s.v.abs() <= vcap + v_tol, "|v| {} > {vcap} at {t}", s.v);
        prop_assert!(a_ok(&s), "a {} at v {} (t {t}) breaks {l:?}", s.a, s.v);
        if was_inside {
            prop_assert!(s.v.abs() <= l.vmax + v_tol, "back out beyond vmax at {t}");
        } else {
            // Beyond vmax: the speed only comes down until it is inside.
            prop_assert!(s.v.abs() <= prev_speed + v_tol, "speeding up beyond vmax");
        }
        was_inside |= s.v.abs() <= l.vmax + v_tol;
        prev_speed = s.v.abs();
    }
    let segs = p.segments();
    for seg in segs {
        // No segment passes through zero speed (ramps are split there), so each one
        // either speeds up or slows down throughout; its peak |a| is in closed form.
        let (v1, v2) = (seg.start.v, seg.end().v);
        // (A ramp to rest may end a rounding error past zero.)
        let tiny = 1e-12 * v1.abs().max(v2.abs());
        prop_assert!(
            v1 * v2 >= 0.0 || v1.abs().min(v2.abs()) <= tiny,
            "segment crosses zero speed: {seg:?}"
        );
        let dv = (v2 - v1).abs();
        let peak = match seg.shape {
            Shape::Accel(a) => a.abs(),
            Shape::Sine { .. } => core::f64::consts::PI * dv / (2.0 * seg.duration),
            Shape::SineSquared { .. } => 2.0 * dv / seg.duration,
            Shape::Jerk(_) => return Err(TestCaseError::fail("jerk segment in a ramp")),
        };
        let bound = if v2.abs() > v1.abs() { l.amax } else { l.dmax };
        prop_assert!(
            dv == 0.0 || peak <= bound * (1.0 + 1e-9),
            "peak {peak} > {bound}: {seg:?}"
        );
    }
    if let Some(first) = segs.first() {
        prop_assert_eq!(first.start.p, start.p);
        prop_assert_eq!(first.start.v, start.v);
    }
    for w in segs.windows(2) {
        let (a, b) = (w[0].end(), w[1].start);
        prop_assert!((a.p - b.p).abs() <= 1e-12 * a.p.abs().max(1.0));
        prop_assert!((a.v - b.v).abs() <= 1e-12 * a.v.abs().max(1.0));
    }
    Ok(())
}

/// Random limits: spread over several decades, sometimes equal acceleration and
/// deceleration.
fn limits() -> impl Strategy<Value = Limits> {
    (
        prop_oneof![0.01..1.0f64, 1.0..1000.0f64],
        prop_oneof![0.01..1.0f64, 1.0..10_000.0f64],
        prop_oneof![Just(None), (0.01..10_000.0f64).prop_map(Some)],
    )
        .prop_map(|(vmax, amax, dmax)| lim(vmax, amax, dmax.unwrap_or(amax)))
}

/// Start velocity as a multiple of vmax (so starts beyond it are common), with {-1, 0, 1}
/// draws for the degenerate cases.
fn start_speed_factor() -> impl Strategy<Value = f64> {
    prop_oneof![
        2 => Just(0.0),
        1 => Just(1.0),
        1 => Just(-1.0),
        6 => -3.0..3.0f64,
    ]
}

proptest! {
    #![proptest_config(config(2000, 0x5eed_0000))]

    #[test]
    fn position_moves_respect_limits_and_end_exactly_on_target(
        shape in 0usize..3,
        l in limits(),
        p0 in prop_oneof![Just(0.0), -1000.0..1000.0f64],
        vf in start_speed_factor(),
        dist in prop_oneof![1 => Just(0.0), 1 => -1e-6..1e-6f64, 8 => -1000.0..1000.0f64],
        vef in prop_oneof![3 => Just(0.0), 1 => Just(1.0), 2 => -1.5..1.5f64],
    ) {
        let shape = SHAPES[shape];
        let start = moving(p0, vf * l.vmax);
        let target = p0 + dist;
        let v_end = vef * l.vmax;
        let p = plan_position(shape, start, target, v_end, &l)
            .map_err(|e| TestCaseError::fail(format!("{e}")))?;
        // Exactly on target, at rest or at a speed no higher than wanted, pointing the way
        // of v_end.
        let e = p.end_state();
        prop_assert_eq!(e.p, target);
        prop_assert_eq!(e.a, 0.0);
        prop_assert!(e.v == 0.0 || e.v * v_end > 0.0, "v_end {v_end} end {e:?}");
        prop_assert!(e.v.abs() <= v_end.abs().min(l.vmax));
        // Sampling lands there too (the closed form agrees with the pinned end).
        let last = p.segments().last().map_or(p.end_state(), |s| s.end());
        let scale = dist.abs() + (start.v * start.v / l.dmax).max(1.0);
        prop_assert!((last.p - target).abs() <= 1e-9 * scale, "{} vs {target}", last.p);
        prop_assert!((last.v - e.v).abs() <= 1e-9 * l.vmax.max(start.v.abs()).max(1.0));
        check_profile(&p, &start, &l)?;
        // Past the end the move continues at the end velocity.
        let after = p.sample(p.duration() + 2.0);
        prop_assert!((after.p - (target + 2.0 * e.v)).abs() <= 1e-9 * scale.max(e.v.abs()));
    }

    #[test]
    fn velocity_changes_respect_limits_and_end_at_the_clamped_target(
        shape in 0usize..3,
        l in limits(),
        vf in start_speed_factor(),
        vtf in prop_oneof![Just(0.0), Just(1.0), Just(-1.0), -2.0..2.0f64],
    ) {
        let start = moving(0.0, vf * l.vmax);
        let vt = vtf * l.vmax;
        let p = plan_velocity(SHAPES[shape], start, vt, &l)
            .map_err(|e| TestCaseError::fail(format!("{e}")))?;
        prop_assert_eq!(p.end_state().v, vt.clamp(-l.vmax, l.vmax));
        check_profile(&p, &start, &l)?;
        // The velocity moves monotonically from start to end: no overshoot.
        let (lo, hi) = (start.v.min(p.end_state().v), start.v.max(p.end_state().v));
        for i in 0..=200 {
            let v = p.sample(p.duration() * f64::from(i) / 200.0).v;
            prop_assert!(v >= lo - 1e-12 * hi.abs().max(1.0) && v <= hi + 1e-12 * hi.abs().max(1.0));
        }
    }

    /// Only from inside the speed limit: from beyond it every shape must come back to vmax
    /// at once, and a gentler deceleration then covers more ground at the higher speed, so
    /// a Sine move can legitimately arrive first.
    #[test]
    fn sine_and_linear_sine_are_never_faster_than_linear(
        l in limits(),
        vf in prop_oneof![Just(0.0), Just(1.0), Just(-1.0), -1.0..1.0f64],
        dist in -1000.0..1000.0f64,
        vef in prop_oneof![Just(0.0), -1.5..1.5f64],
    ) {
        let start = moving(0.0, vf * l.vmax);
        let t = |s| plan_position(s, start, dist, vef * l.vmax, &l).map(|p| p.duration());
        let lin = t(RampShape::Linear).map_err(|e| TestCaseError::fail(format!("{e}")))?;
        for s in [RampShape::Sine, RampShape::LinearSine] {
            let other = t(s).map_err(|e| TestCaseError::fail(format!("{e}")))?;
            prop_assert!(other >= lin * (1.0 - 1e-9), "{s:?} {other} < linear {lin}");
        }
    }

    #[test]
    fn sine_plans_are_linear_plans_with_effective_rates(
        l in limits(),
        vf in start_speed_factor(),
        dist in -1000.0..1000.0f64,
    ) {
        // Every ramp is symmetric, so a Sine move takes exactly as long as a trapezoid with
        // rates 2·amax/π and dmax/2 (Linear/Sine: amax and 2·dmax/π).
        let start = moving(0.0, vf * l.vmax);
        let t = |s, l: &Limits| plan_position(s, start, dist, 0.0, l).map(|p| p.duration());
        let pi = core::f64::consts::PI;
        let sine = t(RampShape::Sine, &l).map_err(|e| TestCaseError::fail(format!("{e}")))?;
        let eq = t(RampShape::Linear, &lim(l.vmax, 2.0 * l.amax / pi, l.dmax / 2.0))
            .map_err(|e| TestCaseError::fail(format!("{e}")))?;
        prop_assert!((sine - eq).abs() <= 1e-9 * eq.max(1.0), "{sine} vs {eq}");
        let ls = t(RampShape::LinearSine, &l).map_err(|e| TestCaseError::fail(format!("{e}")))?;
        let eq = t(RampShape::Linear, &lim(l.vmax, l.amax, 2.0 * l.dmax / pi))
            .map_err(|e| TestCaseError::fail(format!("{e}")))?;
        prop_assert!((ls - eq).abs() <= 1e-9 * eq.max(1.0), "{ls} vs {eq}");
    }

    #[test]
    fn mirrored_moves_mirror_the_profile(
        shape in 0usize..3,
        l in limits(),
        vf in start_speed_factor(),
        dist in -100.0..100.0f64,
        vef in prop_oneof![Just(0.0), -1.5..1.5f64],
    ) {
        let shape = SHAPES[shape];
        let a = plan_position(shape, moving(0.0, vf * l.vmax), dist, vef * l.vmax, &l)
            .map_err(|e| TestCaseError::fail(format!("{e}")))?;
        let b = plan_position(shape, moving(0.0, -vf * l.vmax), -dist, -vef * l.vmax, &l)
            .map_err(|e| TestCaseError::fail(format!("{e}")))?;
        prop_assert!((a.duration() - b.duration()).abs() <= 1e-12 * a.duration().max(1.0));
        for i in 0..=50 {
            let t = a.duration() * f64::from(i) / 50.0;
            let (sa, sb) = (a.sample(t), b.sample(t));
            prop_assert!((sa.p + sb.p).abs() <= 1e-9 * dist.abs().max(1.0));
            prop_assert!((sa.v + sb.v).abs() <= 1e-9 * l.vmax.max(1.0));
        }
    }

    #[test]
    fn non_finite_inputs_are_errors_never_panics(
        shape in 0usize..3,
        which in 0usize..7,
        bad in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)],
    ) {
        let shape = SHAPES[shape];
        let mut l = lim(1.0, 1.0, 1.0);
        let mut start = KinematicState::at_rest(0.0);
        let (mut target, mut v_end) = (1.0, 0.0);
        match which {
            0 => l.vmax = bad,
            1 => l.amax = bad,
            2 => l.dmax = bad,
            3 => start.p = bad,
            4 => start.v = bad,
            5 => target = bad,
            _ => v_end = bad,
        }
        prop_assert!(plan_position(shape, start, target, v_end, &l).is_err());
        if which != 3 && which != 6 {
            prop_assert!(plan_velocity(shape, start, target, &l).is_err());
        }
    }
}
