//! Ramps without a jerk limit (seed 000 §6.1.1): trapezoid (linear), Sine (sine
//! acceleration, sine² deceleration) and Linear/Sine (linear acceleration, sine
//! deceleration).
//!
//! Every ramp shape here is symmetric about its midpoint, so a ramp from speed `v1` to `v2`
//! covers `(v1 + v2) / 2 · T` whatever its shape; only its duration `T = |Δv| / a_eff`
//! differs. Planning is therefore a trapezoid with *effective* rates (closed form, no
//! iteration), rendered afterwards with each ramp's shape:
//!
//! | ramp | shape | peak | effective rate |
//! |---|---|---|---|
//! | linear | `Accel` | `a` | `a` |
//! | sine | `Sine` (`a = A sin(πτ/T)`) | `A` | `2A/π` |
//! | sine² | `SineSquared` (`a = A sin²(πτ/T)`) | `A` | `A/2` |
//!
//! Start acceleration is ignored (these ramp types jump in acceleration by design).

use super::{check_inputs, check_limits, KinematicState, Limits, PlanError, Profile, Shape};

/// Shape of the speeding-up and slowing-down ramps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RampShape {
    /// Constant acceleration and deceleration (trapezoid velocity).
    Linear,
    /// Sine acceleration, sine² deceleration.
    Sine,
    /// Linear acceleration, sine deceleration.
    LinearSine,
}

/// The shape of one ramp segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Linear,
    Sine,
    SineSquared,
}

impl Kind {
    /// Effective rate (mean |a|) of a ramp of this kind with peak `a`.
    fn effective(self, a: f64) -> f64 {
        match self {
            Kind::Linear => a,
            Kind::Sine => a * 2.0 / core::f64::consts::PI,
            Kind::SineSquared => a / 2.0,
        }
    }
}

impl RampShape {
    /// Kind of the speeding-up ramps.
    fn up(self) -> Kind {
        match self {
            RampShape::Linear | RampShape::LinearSine => Kind::Linear,
            RampShape::Sine => Kind::Sine,
        }
    }

    /// Kind of the slowing-down ramps.
    fn down(self) -> Kind {
        match self {
            RampShape::Linear => Kind::Linear,
            RampShape::Sine => Kind::SineSquared,
            RampShape::LinearSine => Kind::Sine,
        }
    }
}

/// Effective rates of a shape under given limits.
#[derive(Clone, Copy, Debug)]
struct Rates {
    shape: RampShape,
    up: f64,
    down: f64,
    lim: Limits,
}

impl Rates {
    fn new(shape: RampShape, lim: &Limits) -> Self {
        Self {
            shape,
            up: shape.up().effective(lim.amax),
            down: shape.down().effective(lim.dmax),
            lim: *lim,
        }
    }

    /// Distance (signed) of a ramp from `v1` to `v2`, split at zero speed.
    fn distance(&self, v1: f64, v2: f64) -> f64 {
        if v1 * v2 < 0.0 {
            return self.distance(v1, 0.0) + self.distance(0.0, v2);
        }
        let rate = if v2.abs() >= v1.abs() {
            self.up
        } else {
            self.down
        };
        (v1 + v2) / 2.0 * (v2 - v1).abs() / rate
    }

    /// Appends a ramp from `v1` to `v2` (split at zero speed) to `p`.
    fn push(&self, p: &mut Profile, v1: f64, v2: f64) -> Result<(), PlanError> {
        if v1 == v2 {
            return Ok(());
        }
        if v1 * v2 < 0.0 {
            self.push(p, v1, 0.0)?;
            return self.push(p, 0.0, v2);
        }
        let dv = v2 - v1;
        let (kind, peak, rate) = if v2.abs() >= v1.abs() {
            (self.shape.up(), self.lim.amax, self.up)
        } else {
            (self.shape.down(), self.lim.dmax, self.down)
        };
        let t = dv.abs() / rate;
        let shape = match kind {
            Kind::Linear => Shape::Accel(dv.signum() * peak),
            Kind::Sine => Shape::Sine { dv },
            Kind::SineSquared => Shape::SineSquared { dv },
        };
        p.push(t, shape)
    }
}

/// Plans a position move; see [`super::plan_position`].
pub fn plan_position(
    shape: RampShape,
    start: KinematicState,
    target: f64,
    v_end: f64,
    lim: &Limits,
) -> Result<Profile, PlanError> {
    check_limits(lim, false)?;
    check_inputs(&start, target)?;
    if !v_end.is_finite() {
        return Err(PlanError::NotFinite {
            name: "end velocity",
            value: v_end,
        });
    }
    let r = Rates::new(shape, lim);
    let origin = KinematicState {
        a: 0.0,
        j: 0.0,
        ..start
    };
    let mut p = Profile::new(origin);
    let v0 = start.v;
    let d = target - start.p;
    // Where the axis would stop if it braked now.
    let stop = r.distance(v0, 0.0);
    let ahead = if v0 != 0.0 {
        // Keep going if the target lies at or beyond the stopping point.
        v0.signum() * (d - stop) >= 0.0
    } else {
        true
    };
    let mut from = start.p;
    let mut u = v0;
    if !ahead {
        // Brake to a stop, then go back: the time-optimal way for linear ramps.
        r.push(&mut p, v0, 0.0)?;
        from += stop;
        u = 0.0;
    }
    let rest = target - from;
    let s = if rest != 0.0 {
        rest.signum()
    } else if u != 0.0 {
        u.signum()
    } else {
        1.0
    };
    let mut speed = u.abs();
    let mut remaining = rest.abs();
    if speed > lim.vmax {
        // Start above the speed limit: come down to it first.
        r.push(&mut p, s * speed, s * lim.vmax)?;
        remaining -= r.distance(speed, lim.vmax);
        speed = lim.vmax;
    }
    let mut ve = if v_end * s > 0.0 {
        v_end.abs().min(lim.vmax)
    } else {
        0.0
    };
    if ve > speed {
        // Speeding up to `ve` must fit in the distance; otherwise end at the best reachable.
        let reach = (speed * speed + 2.0 * r.up * remaining.max(0.0)).sqrt();
        ve = ve.min(reach);
    } else if r.distance(speed, ve) > remaining {
        // Slowing down to `ve` does not fit (only from rounding: we are ahead): stop at ve
        // reachable with the distance there is.
        let reach = (speed * speed - 2.0 * r.down * remaining.max(0.0))
            .max(0.0)
            .sqrt();
        ve = ve.max(reach);
    }
    // Peak speed: as high as the distance allows, capped at vmax.
    let full = r.distance(speed, lim.vmax) + r.distance(lim.vmax, ve);
    let peak = if full <= remaining {
        lim.vmax
    } else {
        let k = 1.0 / (2.0 * r.up) + 1.0 / (2.0 * r.down);
        let sq = (remaining + speed * speed / (2.0 * r.up) + ve * ve / (2.0 * r.down)) / k;
        sq.max(0.0).sqrt().clamp(speed.max(ve), lim.vmax)
    };
    r.push(&mut p, s * speed, s * peak)?;
    let cruise = remaining - r.distance(speed, peak) - r.distance(peak, ve);
    if cruise > 0.0 && peak > 0.0 {
        p.push(cruise / peak, Shape::Accel(0.0))?;
    }
    r.push(&mut p, s * peak, s * ve)?;
    finish(p, start, target, s * ve)
}

/// Checks that a profile lands on the target, then pins the exact end state.
fn finish(
    mut p: Profile,
    start: KinematicState,
    target: f64,
    v_end: f64,
) -> Result<Profile, PlanError> {
    let e = p.end_state();
    let tol = 1e-9 * target.abs().max(start.p.abs()).max(1.0);
    if (e.p - target).abs() > tol || (e.v - v_end).abs() > 1e-9 * v_end.abs().max(1.0) {
        return Err(PlanError::NoSolution {
            p: start.p,
            v: start.v,
            a: start.a,
            target,
        });
    }
    p.set_end(KinematicState {
        p: target,
        v: v_end,
        a: 0.0,
        j: 0.0,
    });
    Ok(p)
}

/// Plans a velocity change; see [`super::plan_velocity`].
pub fn plan_velocity(
    shape: RampShape,
    start: KinematicState,
    v_target: f64,
    lim: &Limits,
) -> Result<Profile, PlanError> {
    check_limits(lim, false)?;
    check_inputs(&start, v_target)?;
    let r = Rates::new(shape, lim);
    let mut p = Profile::new(KinematicState {
        a: 0.0,
        j: 0.0,
        ..start
    });
    let vt = v_target.clamp(-lim.vmax, lim.vmax);
    r.push(&mut p, start.v, vt)?;
    let e = p.end_state();
    p.set_end(KinematicState { v: vt, a: 0.0, ..e });
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const SHAPES: [RampShape; 3] = [RampShape::Linear, RampShape::Sine, RampShape::LinearSine];

    fn lim(v: f64, a: f64, d: f64) -> Limits {
        Limits {
            vmax: v,
            amax: a,
            dmax: d,
            jmax: f64::INFINITY,
        }
    }

    #[test]
    fn trapezoid_rest_to_rest_known_durations() {
        // d = 10, vmax = 2, a = 1: 2 s up (2 units), 3 s cruise (6), 2 s down (2): 7 s.
        let p = plan_position(
            RampShape::Linear,
            KinematicState::at_rest(0.0),
            10.0,
            0.0,
            &lim(2.0, 1.0, 1.0),
        )
        .unwrap();
        assert!((p.duration() - 7.0).abs() < 1e-12);
        // Triangular: d = 1, a = 1: 2 s.
        let p = plan_position(
            RampShape::Linear,
            KinematicState::at_rest(0.0),
            1.0,
            0.0,
            &lim(10.0, 1.0, 1.0),
        )
        .unwrap();
        assert!((p.duration() - 2.0).abs() < 1e-12);
        // Asymmetric: d = 3, a = 1, d = 2: peak v with v²/2 + v²/4 = 3 → v = 2: 2 s + 1 s.
        let p = plan_position(
            RampShape::Linear,
            KinematicState::at_rest(0.0),
            3.0,
            0.0,
            &lim(10.0, 1.0, 2.0),
        )
        .unwrap();
        assert!((p.duration() - 3.0).abs() < 1e-12);
    }

    #[test]
    fn sine_ramp_takes_pi_over_2_times_longer_and_sine_squared_twice() {
        let p = plan_velocity(
            RampShape::Sine,
            KinematicState::at_rest(0.0),
            4.0,
            &lim(10.0, 2.0, 2.0),
        )
        .unwrap();
        assert!((p.duration() - core::f64::consts::PI).abs() < 1e-12);
        assert!((p.peaks().a - 2.0).abs() < 1e-12);
        let p = plan_velocity(
            RampShape::Sine,
            KinematicState {
                v: 4.0,
                ..KinematicState::at_rest(0.0)
            },
            0.0,
            &lim(10.0, 2.0, 2.0),
        )
        .unwrap();
        assert!((p.duration() - 4.0).abs() < 1e-12, "sine² stop: 2·Δv/d");
        assert!((p.peaks().a - 2.0).abs() < 1e-12);
        // Sine² stops shock-free: acceleration and jerk end at zero.
        let end = p.segments()[0].sample(p.duration() - 1e-9);
        assert!(end.a.abs() < 1e-6 && end.j.abs() < 1e-3);
    }

    #[test]
    fn target_behind_brakes_then_returns() {
        let start = KinematicState {
            p: 0.0,
            v: 2.0,
            a: 0.0,
            j: 0.0,
        };
        let p = plan_position(RampShape::Linear, start, -1.0, 0.0, &lim(2.0, 1.0, 1.0)).unwrap();
        // Brake 2 s (2 units out), then 3 units back: triangular would peak at √3 < 2.
        let back = 2.0 * 3.0_f64.sqrt();
        assert!((p.duration() - (2.0 + back)).abs() < 1e-12);
        assert_eq!(p.end_state().p, -1.0);
    }

    #[test]
    fn blending_end_velocity_is_reached_or_reduced() {
        let p = plan_position(
            RampShape::Linear,
            KinematicState::at_rest(0.0),
            10.0,
            1.5,
            &lim(2.0, 1.0, 1.0),
        )
        .unwrap();
        assert_eq!(p.end_state().v, 1.5);
        // Too short to reach 2: ends at √(2·a·d) = √2.
        let p = plan_position(
            RampShape::Linear,
            KinematicState::at_rest(0.0),
            1.0,
            2.0,
            &lim(2.0, 1.0, 1.0),
        )
        .unwrap();
        assert!((p.end_state().v - 2.0_f64.sqrt()).abs() < 1e-12);
        // Wrong-direction end velocity means stop.
        let p = plan_position(
            RampShape::Linear,
            KinematicState::at_rest(0.0),
            1.0,
            -2.0,
            &lim(2.0, 1.0, 1.0),
        )
        .unwrap();
        assert_eq!(p.end_state().v, 0.0);
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        for bad in [f64::NAN, f64::INFINITY, -1.0, 0.0] {
            assert!(plan_position(
                RampShape::Sine,
                KinematicState::at_rest(0.0),
                1.0,
                0.0,
                &lim(bad, 1.0, 1.0)
            )
            .is_err());
            assert!(plan_velocity(
                RampShape::Sine,
                KinematicState::at_rest(0.0),
                1.0,
                &lim(1.0, 1.0, bad)
            )
            .is_err());
        }
        assert!(plan_position(
            RampShape::Linear,
            KinematicState::at_rest(f64::NAN),
            1.0,
            0.0,
            &lim(1.0, 1.0, 1.0)
        )
        .is_err());
        assert!(plan_position(
            RampShape::Linear,
            KinematicState::at_rest(0.0),
            f64::INFINITY,
            0.0,
            &lim(1.0, 1.0, 1.0)
        )
        .is_err());
    }

    /// Checks limits (at dense samples), continuity of p and v, and the exact end.
    fn check(shape: RampShape, start: KinematicState, target: f64, v_end: f64, l: &Limits) {
        let p = plan_position(shape, start, target, v_end, l).unwrap();
        let e = p.end_state();
        assert_eq!(e.p, target);
        assert!((p.sample(p.duration()).p - target).abs() <= 1e-9 * target.abs().max(1.0));
        assert!(e.v * v_end >= 0.0 && e.v.abs() <= v_end.abs() + 1e-12);
        let vcap = l.vmax.max(start.v.abs()) * (1.0 + 1e-9);
        let n = 2000;
        let mut prev = p.sample(0.0);
        assert!((prev.p - start.p).abs() < 1e-12 && (prev.v - start.v).abs() < 1e-12);
        for i in 1..=n {
            let t = p.duration() * i as f64 / n as f64;
            let s = p.sample(t);
            assert!(s.v.abs() <= vcap, "{shape:?} v {} > {vcap}", s.v);
            let bound = if s.a * s.v > 0.0 { l.amax } else { l.dmax };
            assert!(
                s.a.abs() <= bound * (1.0 + 1e-9) + 1e-12,
                "{shape:?} a {} > {bound} at v {}",
                s.a,
                s.v
            );
            let dt = p.duration() / n as f64;
            assert!((s.p - prev.p).abs() <= vcap * dt * (1.0 + 1e-9) + 1e-9);
            assert!((s.v - prev.v).abs() <= l.amax.max(l.dmax) * dt * (1.0 + 1e-9) + 1e-9);
            prev = s;
        }
        // Segment boundaries: start of each segment is the end of the previous one.
        let segs = p.segments();
        for w in segs.windows(2) {
            let (a, b) = (w[0].end(), w[1].start);
            assert!(
                (a.p - b.p).abs() <= 1e-9 * a.p.abs().max(1.0)
                    && (a.v - b.v).abs() <= 1e-9 * a.v.abs().max(1.0)
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, rng_seed: proptest::test_runner::RngSeed::Fixed(7), failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn limits_hold_and_moves_end_on_target(
            shape in 0usize..3,
            p0 in -100.0..100.0f64,
            v0 in prop_oneof![Just(0.0), -20.0..20.0f64],
            target in prop_oneof![Just(0.0), -100.0..100.0f64],
            v_end in prop_oneof![3 => Just(0.0), 1 => -10.0..10.0f64],
            vmax in 0.1..10.0f64,
            amax in 0.1..100.0f64,
            dmax in 0.1..100.0f64,
        ) {
            check(SHAPES[shape], KinematicState { p: p0, v: v0, a: 0.0, j: 0.0 }, target, v_end, &lim(vmax, amax, dmax));
        }

        #[test]
        fn sine_is_never_faster_than_linear(
            d in 0.01..100.0f64, vmax in 0.1..10.0f64, a in 0.1..100.0f64,
        ) {
            let l = lim(vmax, a, a);
            let t = |s| plan_position(s, KinematicState::at_rest(0.0), d, 0.0, &l).unwrap().duration();
            prop_assert!(t(RampShape::Sine) >= t(RampShape::Linear) - 1e-12);
            prop_assert!(t(RampShape::LinearSine) >= t(RampShape::Linear) - 1e-12);
        }
    }
}
