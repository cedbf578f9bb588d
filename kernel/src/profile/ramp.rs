//! Ramps without a jerk limit (seed 000 §6.1.1): trapezoid (linear), Sine (sine
//! acceleration, sine² deceleration: shock-free stop) and Linear/Sine (linear
//! acceleration, sine deceleration).
//!
//! Every ramp shape here is symmetric about its midpoint, so a ramp from speed `v1` to `v2`
//! covers `(v1 + v2) / 2 · T` whatever its shape; only its duration `T = |Δv| / a_eff`
//! differs. Planning is therefore a trapezoid with *effective* rates (closed form,
//! quadratics only, no iteration), rendered afterwards with each ramp's shape:
//!
//! | ramp | segment shape | peak \|a\| | duration for Δv | effective rate |
//! |---|---|---|---|---|
//! | linear | [`Shape::Accel`] | `A` | `Δv / A` | `A` |
//! | sine | [`Shape::Sine`] (`a = A sin(πτ/T)`) | `A` | `π Δv / 2A` | `2A/π` |
//! | sine² | [`Shape::SineSquared`] (`a = A sin²(πτ/T)`) | `A` | `2 Δv / A` | `A/2` |
//!
//! `A` is `amax` for a ramp that speeds up (|v| grows) and `dmax` for one that slows down;
//! a ramp through zero speed is split there (slow down to 0, then speed up), so the limit
//! semantics of [`super`] hold on every segment. Each ramp uses its full peak, which makes
//! the plan time-optimal among profiles made of these ramps and cruises.
//!
//! Start acceleration is ignored: these ramp types jump in acceleration by design.

use super::{check_inputs, check_limits, KinematicState, Limits, PlanError, Profile, Shape};

/// Shape of the speeding-up and slowing-down ramps (seed 000 §6.1.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RampShape {
    /// Constant acceleration and deceleration (trapezoid velocity).
    Linear,
    /// Sine acceleration, sine² deceleration (acceleration and jerk end at zero at a stop).
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
    /// Effective rate (`|Δv| / T`, the mean |a|) of a ramp of this kind with peak `a`.
    fn effective(self, a: f64) -> f64 {
        match self {
            Kind::Linear => a,
            Kind::Sine => a * 2.0 / core::f64::consts::PI,
            Kind::SineSquared => a / 2.0,
        }
    }

    /// The segment shape of a ramp changing velocity by `dv` with peak |a| `peak`.
    fn shape(self, dv: f64, peak: f64) -> Shape {
        match self {
            Kind::Linear => Shape::Accel(dv.signum() * peak),
            Kind::Sine => Shape::Sine { dv },
            Kind::SineSquared => Shape::SineSquared { dv },
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

/// A shape with its limits and effective rates: everything planning needs.
#[derive(Clone, Copy, Debug)]
struct Rates {
    shape: RampShape,
    lim: Limits,
    /// Effective rate of a speeding-up ramp (units/s²).
    up: f64,
    /// Effective rate of a slowing-down ramp (units/s²).
    down: f64,
}

impl Rates {
    fn new(shape: RampShape, lim: &Limits) -> Self {
        Self {
            shape,
            lim: *lim,
            up: shape.up().effective(lim.amax),
            down: shape.down().effective(lim.dmax),
        }
    }

    /// Distance covered speeding up from speed `s1` to `s2` (`0 <= s1 <= s2`).
    fn up_distance(&self, s1: f64, s2: f64) -> f64 {
        (s2 * s2 - s1 * s1) / (2.0 * self.up)
    }

    /// Distance covered slowing down from speed `s1` to `s2` (`s1 >= s2 >= 0`).
    fn down_distance(&self, s1: f64, s2: f64) -> f64 {
        (s1 * s1 - s2 * s2) / (2.0 * self.down)
    }

    /// Signed distance of a ramp from velocity `v1` to `v2`, split at zero speed.
    fn distance(&self, v1: f64, v2: f64) -> f64 {
        if v1 * v2 < 0.0 {
            return self.distance(v1, 0.0) + self.distance(0.0, v2);
        }
        let (a, b) = (v1.abs(), v2.abs());
        let d = if b >= a {
            self.up_distance(a, b)
        } else {
            self.down_distance(a, b)
        };
        // The sign of the motion: whichever of v1, v2 is non-zero.
        if v1 + v2 < 0.0 {
            -d
        } else {
            d
        }
    }

    /// Appends a ramp from velocity `v1` to `v2` to `p`, split at zero speed. `v1` must be
    /// the velocity the profile ends with so far.
    fn ramp(&self, p: &mut Profile, v1: f64, v2: f64) -> Result<(), PlanError> {
        if v1 == v2 {
            return Ok(());
        }
        if v1 * v2 < 0.0 {
            self.ramp(p, v1, 0.0)?;
            return self.ramp(p, 0.0, v2);
        }
        let dv = v2 - v1;
        let (kind, peak, rate) = if v2.abs() >= v1.abs() {
            (self.shape.up(), self.lim.amax, self.up)
        } else {
            (self.shape.down(), self.lim.dmax, self.down)
        };
        p.push(dv.abs() / rate, kind.shape(dv, peak))
    }
}

/// The end speed (≥ 0, ≤ vmax) wanted when arriving in direction `dir` (±1): `v_end`
/// counts only when it points the way the axis arrives; otherwise the move ends at rest.
fn wanted_end_speed(v_end: f64, dir: f64, vmax: f64) -> f64 {
    if v_end * dir > 0.0 {
        v_end.abs().min(vmax)
    } else {
        0.0
    }
}

/// Relative slack when deciding whether the axis can still slow down before the target:
/// a target computed as "the stopping point" may miss it by a rounding error, and turning
/// round for 1e-16 units would add two needless segments. The final ramp then overshoots
/// by at most this fraction of the distance, far inside [`finish`]'s tolerance.
const ROOM_SLACK: f64 = 1e-12;

/// Plans a position move from `start` to `target`, arriving at velocity `v_end`; see
/// [`super::plan_position`].
///
/// Cases, with `dir` the direction of the target (along the current velocity for a
/// zero-length move) and `u` the speed towards it:
/// 1. `u >= 0` and the axis can come down to the wanted end speed before the target:
///    approach directly (`approach`): slow down to `vmax` first if beyond it, speed up
///    to the highest peak the distance allows (at most `vmax`), cruise, slow down.
/// 2. Otherwise (moving away, or too fast to stop in time): slow down to rest, which is
///    unavoidable, then approach the target from rest as in 1.
///
/// `v_end` is honoured only when it points the way the axis finally arrives; when it
/// cannot be reached in the distance the move ends at the largest reachable speed below
/// it. The result is verified to land within 1e-9 (relative) of the target and its end
/// state is then pinned exactly on `(target, v_end)`.
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
    let d = target - start.p;
    if !d.is_finite() {
        return Err(no_solution(&start, target));
    }
    let r = Rates::new(shape, lim);
    let mut p = Profile::new(KinematicState {
        a: 0.0,
        j: 0.0,
        ..start
    });
    let v0 = start.v;
    let dir = if d > 0.0 || (d == 0.0 && v0 >= 0.0) {
        1.0
    } else {
        -1.0
    };
    let u = dir * v0;
    let dist = dir * d;
    let ve_direct = wanted_end_speed(v_end, dir, lim.vmax);
    let need = r.down_distance(u, ve_direct.min(u));
    let stop = r.distance(v0, 0.0);
    let (dir, ve) = if u >= 0.0 && need <= dist + ROOM_SLACK * dist.max(need) {
        (dir, approach(&r, &mut p, dir, u, dist, ve_direct)?)
    } else {
        r.ramp(&mut p, v0, 0.0)?;
        let rest = target - (start.p + stop);
        let dir = if rest < 0.0 { -1.0 } else { 1.0 };
        let ve = wanted_end_speed(v_end, dir, lim.vmax);
        (dir, approach(&r, &mut p, dir, 0.0, dir * rest, ve)?)
    };
    let path = 2.0 * stop.abs() + d.abs();
    finish(p, &start, target, dir * ve, path, lim.vmax)
}

/// Appends the direct approach to a target `dist >= 0` ahead in direction `dir` (±1),
/// starting at speed `u >= 0` towards it, ending at speed `ve_req` (`<= vmax`) or the
/// largest reachable below it. Returns the end speed used.
///
/// Peak speed `w` of the triangle: `up(u→w) + down(w→ve) = dist`, i.e.
/// `(w² − u²)/2·up + (w² − ve²)/2·down = dist`, so
/// `w² = (2·up·down·dist + down·u² + up·ve²) / (up + down)`; capped at `vmax` with a
/// cruise filling the rest.
fn approach(
    r: &Rates,
    p: &mut Profile,
    dir: f64,
    u: f64,
    dist: f64,
    ve_req: f64,
) -> Result<f64, PlanError> {
    let vmax = r.lim.vmax;
    let mut speed = u;
    let mut rem = dist;
    if speed > vmax {
        // Beyond the speed limit: come back to it at once, never further out.
        r.ramp(p, dir * speed, dir * vmax)?;
        rem -= r.down_distance(speed, vmax);
        speed = vmax;
    }
    let rem = rem.max(0.0);
    let ve = if ve_req > speed {
        // Speeding up all the way may still not reach the wanted end speed.
        ve_req.min((speed * speed + 2.0 * r.up * rem).sqrt())
    } else {
        ve_req
    };
    let floor = speed.max(ve);
    let peak = if r.up_distance(speed, vmax) + r.down_distance(vmax, ve) <= rem {
        vmax
    } else {
        let sq =
            (2.0 * r.up * r.down * rem + r.down * speed * speed + r.up * ve * ve) / (r.up + r.down);
        sq.max(0.0).sqrt().max(floor).min(vmax)
    };
    r.ramp(p, dir * speed, dir * peak)?;
    let cruise = rem - r.up_distance(speed, peak) - r.down_distance(peak, ve);
    if cruise > 0.0 && peak > 0.0 {
        p.push(cruise / peak, Shape::Accel(0.0))?;
    }
    r.ramp(p, dir * peak, dir * ve)?;
    Ok(ve)
}

fn no_solution(start: &KinematicState, target: f64) -> PlanError {
    PlanError::NoSolution {
        p: start.p,
        v: start.v,
        a: start.a,
        target,
    }
}

/// Checks that a profile lands on `target` at `v_end`, then pins that exact end state.
///
/// Tolerances: 1e-9 of the path length (at least 1e-9 units) plus a few ulps of the
/// position's magnitude for position; 1e-9 of the largest speed (at least 1e-9 units/s)
/// for velocity. Non-finite intermediate results fail here too.
fn finish(
    mut p: Profile,
    start: &KinematicState,
    target: f64,
    v_end: f64,
    path: f64,
    vmax: f64,
) -> Result<Profile, PlanError> {
    let e = p.end_state();
    let ptol = 1e-9 * path.max(1.0) + 16.0 * f64::EPSILON * target.abs().max(start.p.abs());
    let vtol = 1e-9 * vmax.max(start.v.abs()).max(1.0);
    let p_ok = (e.p - target).abs() <= ptol;
    let v_ok = (e.v - v_end).abs() <= vtol;
    if !(p_ok && v_ok && p.duration().is_finite()) {
        return Err(no_solution(start, target));
    }
    p.set_end(KinematicState {
        p: target,
        v: v_end,
        a: 0.0,
        j: 0.0,
    });
    Ok(p)
}

/// Plans a velocity change from `start` to `v_target` (clamped to ±vmax), continuing at
/// that velocity forever; see [`super::plan_velocity`]. A change through zero speed slows
/// down to rest with the slowing-down ramp, then speeds up with the speeding-up ramp.
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
    r.ramp(&mut p, start.v, vt)?;
    let e = p.end_state();
    let vtol = 1e-9 * lim.vmax.max(start.v.abs()).max(1.0);
    if (e.v - vt).abs() > vtol || !e.p.is_finite() || !p.duration().is_finite() {
        return Err(no_solution(&start, v_target));
    }
    p.set_end(KinematicState {
        v: vt,
        a: 0.0,
        j: 0.0,
        ..e
    });
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;
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

    fn moving(p: f64, v: f64) -> KinematicState {
        KinematicState {
            p,
            v,
            a: 0.0,
            j: 0.0,
        }
    }

    fn rest(p: f64) -> KinematicState {
        KinematicState::at_rest(p)
    }

    #[test]
    fn trapezoid_rest_to_rest_known_durations() {
        // d = 10, vmax = 2, a = 1: 2 s up (2 units), 3 s cruise (6), 2 s down (2): 7 s.
        let p =
            plan_position(RampShape::Linear, rest(0.0), 10.0, 0.0, &lim(2.0, 1.0, 1.0)).unwrap();
        assert!((p.duration() - 7.0).abs() < 1e-12);
        assert_eq!(p.segments().len(), 3);
        assert!((p.sample(3.5).v - 2.0).abs() < 1e-12);
        // Triangular: d = 1, a = 1: 2 s.
        let p =
            plan_position(RampShape::Linear, rest(0.0), 1.0, 0.0, &lim(10.0, 1.0, 1.0)).unwrap();
        assert!((p.duration() - 2.0).abs() < 1e-12);
        assert!((p.peaks().v - 1.0).abs() < 1e-12);
        // Asymmetric: d = 3, a = 1, dec = 2: v²/2 + v²/4 = 3 → v = 2: 2 s + 1 s.
        let p =
            plan_position(RampShape::Linear, rest(0.0), 3.0, 0.0, &lim(10.0, 1.0, 2.0)).unwrap();
        assert!((p.duration() - 3.0).abs() < 1e-12);
    }

    #[test]
    fn sine_ramp_takes_pi_over_2_times_longer_and_sine_squared_twice() {
        let l = lim(10.0, 2.0, 2.0);
        let p = plan_velocity(RampShape::Sine, rest(0.0), 4.0, &l).unwrap();
        assert!((p.duration() - PI).abs() < 1e-12);
        assert!((p.peaks().a - 2.0).abs() < 1e-12);
        let p = plan_velocity(RampShape::Sine, moving(0.0, 4.0), 0.0, &l).unwrap();
        assert!((p.duration() - 4.0).abs() < 1e-12, "sine² stop: 2·Δv/d");
        assert!((p.peaks().a - 2.0).abs() < 1e-12);
        // Sine² stops shock-free: acceleration and jerk end at zero.
        let end = p.segments()[0].sample(p.duration() - 1e-9);
        assert!(end.a.abs() < 1e-6 && end.j.abs() < 1e-3);
        // Linear/Sine: linear up (Δv/a), sine down (π Δv / 2d).
        let p = plan_velocity(RampShape::LinearSine, moving(0.0, 4.0), 0.0, &l).unwrap();
        assert!((p.duration() - PI).abs() < 1e-12);
        let p = plan_velocity(RampShape::LinearSine, rest(0.0), 4.0, &l).unwrap();
        assert!((p.duration() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn target_behind_brakes_then_returns() {
        let p = plan_position(
            RampShape::Linear,
            moving(0.0, 2.0),
            -1.0,
            0.0,
            &lim(2.0, 1.0, 1.0),
        )
        .unwrap();
        // Brake 2 s (2 units out), then 3 units back: triangular would peak at √3 < 2.
        let back = 2.0 * 3.0_f64.sqrt();
        assert!((p.duration() - (2.0 + back)).abs() < 1e-12);
        assert_eq!(p.end_state().p, -1.0);
    }

    #[test]
    fn blending_end_velocity_is_reached_or_reduced() {
        let l = lim(2.0, 1.0, 1.0);
        let p = plan_position(RampShape::Linear, rest(0.0), 10.0, 1.5, &l).unwrap();
        assert_eq!(p.end_state().v, 1.5);
        // Too short to reach 2: ends at √(2·a·d) = √2.
        let p = plan_position(RampShape::Linear, rest(0.0), 1.0, 2.0, &l).unwrap();
        assert!((p.end_state().v - 2.0_f64.sqrt()).abs() < 1e-12);
        // Wrong-direction end velocity means stop.
        let p = plan_position(RampShape::Linear, rest(0.0), 1.0, -2.0, &l).unwrap();
        assert_eq!(p.end_state().v, 0.0);
    }

    #[test]
    fn blending_at_speed_into_a_close_target_cruises_instead_of_turning_round() {
        // At 2 units/s with the target 1 unit ahead and v_end = 2: the stopping distance
        // (2) is longer than the move, but no stop is wanted: cruise 0.5 s.
        let l = lim(2.0, 1.0, 1.0);
        let p = plan_position(RampShape::Linear, moving(0.0, 2.0), 1.0, 2.0, &l).unwrap();
        assert!((p.duration() - 0.5).abs() < 1e-12);
        assert_eq!(p.end_state().v, 2.0);
        // v_end = 1: slow from 2 to 1 takes 1.5 units > 1: turn round, end at rest
        // (arriving backwards, so the forward v_end does not apply).
        let p = plan_position(RampShape::Linear, moving(0.0, 2.0), 1.0, 1.0, &l).unwrap();
        assert_eq!(p.end_state().v, 0.0);
        assert!(p.peaks().v <= 2.0);
        // v_end = 1 with 2 units: cruise 0.5 s, slow 1 s.
        let p = plan_position(RampShape::Linear, moving(0.0, 2.0), 2.0, 1.0, &l).unwrap();
        assert!((p.duration() - 1.25).abs() < 1e-12, "{}", p.duration());
    }

    #[test]
    fn start_beyond_vmax_slows_down_first() {
        // v0 = 4 > vmax = 2, a = d = 1, 100 units ahead.
        let l = lim(2.0, 1.0, 1.0);
        let p = plan_position(RampShape::Linear, moving(0.0, 4.0), 100.0, 0.0, &l).unwrap();
        // 4 → 2 in 2 s (6 units), 2 → 0 in 2 s (2 units), cruise 92 units in 46 s.
        assert!((p.duration() - 50.0).abs() < 1e-12, "{}", p.duration());
        assert!(p.peaks().v <= 4.0);
        assert!(p.sample(0.5).v < 4.0);
        let p = plan_velocity(RampShape::Sine, moving(0.0, -4.0), -3.0, &l).unwrap();
        assert_eq!(p.end_state().v, -2.0);
        assert!(
            (p.duration() - 4.0).abs() < 1e-12,
            "sine² from 4 to 2 at d = 1"
        );
    }

    #[test]
    fn zero_length_moves_are_empty_and_exact() {
        for shape in SHAPES {
            let p = plan_position(shape, rest(5.0), 5.0, 0.0, &lim(1.0, 1.0, 1.0)).unwrap();
            assert_eq!(p.duration(), 0.0);
            assert_eq!(p.end_state(), KinematicState::at_rest(5.0));
            let p = plan_velocity(shape, moving(1.0, 0.5), 0.5, &lim(1.0, 1.0, 1.0)).unwrap();
            assert_eq!(p.duration(), 0.0);
            assert_eq!(p.sample(2.0).p, 2.0);
        }
    }

    #[test]
    fn reversing_velocity_splits_at_zero() {
        let l = lim(5.0, 1.0, 2.0);
        for shape in SHAPES {
            let p = plan_velocity(shape, moving(0.0, 2.0), -2.0, &l).unwrap();
            assert_eq!(p.segments().len(), 2);
            assert_eq!(p.segments()[1].start.v, 0.0);
            let slow = shape.down().effective(2.0);
            let fast = shape.up().effective(1.0);
            assert!((p.duration() - (2.0 / slow + 2.0 / fast)).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -1.0, 0.0] {
            for shape in SHAPES {
                for l in [lim(bad, 1.0, 1.0), lim(1.0, bad, 1.0), lim(1.0, 1.0, bad)] {
                    assert!(plan_position(shape, rest(0.0), 1.0, 0.0, &l).is_err());
                    assert!(plan_velocity(shape, rest(0.0), 1.0, &l).is_err());
                }
            }
        }
        let l = lim(1.0, 1.0, 1.0);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for shape in SHAPES {
                assert!(plan_position(shape, rest(bad), 1.0, 0.0, &l).is_err());
                assert!(plan_position(shape, moving(0.0, bad), 1.0, 0.0, &l).is_err());
                assert!(plan_position(shape, rest(0.0), bad, 0.0, &l).is_err());
                assert!(plan_position(shape, rest(0.0), 1.0, bad, &l).is_err());
                assert!(plan_velocity(shape, rest(0.0), bad, &l).is_err());
                assert!(plan_velocity(shape, moving(0.0, bad), 1.0, &l).is_err());
            }
        }
        // Overflowing distances are errors, not NaN profiles.
        assert!(plan_position(RampShape::Linear, rest(-f64::MAX), f64::MAX, 0.0, &l).is_err());
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
        for w in p.segments().windows(2) {
            let (a, b) = (w[0].end(), w[1].start);
            assert!(
                (a.p - b.p).abs() <= 1e-9 * a.p.abs().max(1.0)
                    && (a.v - b.v).abs() <= 1e-9 * a.v.abs().max(1.0)
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 300,
            rng_seed: proptest::test_runner::RngSeed::Fixed(7),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

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
            check(SHAPES[shape], moving(p0, v0), target, v_end, &lim(vmax, amax, dmax));
        }

        #[test]
        fn sine_is_never_faster_than_linear(
            d in 0.01..100.0f64, vmax in 0.1..10.0f64, a in 0.1..100.0f64,
        ) {
            let l = lim(vmax, a, a);
            let t = |s| plan_position(s, rest(0.0), d, 0.0, &l).unwrap().duration();
            prop_assert!(t(RampShape::Sine) >= t(RampShape::Linear) - 1e-12);
            prop_assert!(t(RampShape::LinearSine) >= t(RampShape::Linear) - 1e-12);
        }
    }
}
