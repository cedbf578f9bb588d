//! Jerk-limited, time-optimal S-curve from an arbitrary state (p0, v0, a0).
//!
//! A time-optimal jerk-limited move is bang-bang in jerk with at most seven phases
//! (Ruckig's profiles). We parametrise it by its peak velocity `vp`, the velocity at which
//! acceleration passes zero between the two velocity changes:
//!
//! 1. a velocity change (v0, a0) → (vp, 0): jerk to the peak acceleration, hold it, jerk
//!    back to zero (≤ 3 phases, closed form, [`VelChange::new`]);
//! 2. a cruise at `vp` (≥ 0 s);
//! 3. a velocity change (vp, 0) → (v_end, 0) (≤ 3 phases).
//!
//! The distance the two changes cover, `D(vp)`, grows with `vp`; the fastest move takes
//! the largest `|vp| ≤ vmax` in the direction of the target whose `D` still fits, then
//! cruises for the rest. When even the full `vmax` does not fit, `D(vp) = distance` is
//! solved for `vp` by a bracketed root search (Illinois regula falsi, bounded iterations).
//! A target inside the stopping distance simply gets a `vp` of the other sign: the move
//! passes through zero velocity and comes back. A target beyond the shortest stop but
//! short of the stop after the first change's fastest landing (the "dip window", `dip`)
//! gets a shape of its own: the move follows that landing and leaves it by braking onto
//! the target. From beyond vmax the landing on (vmax, 0) is the braking rule, which the
//! move never outruns. Every result is verified by evaluating its end state before it is
//! returned.
//!
//! Acceleration bound of each velocity change (see the module doc of `profile`): `amax`
//! when speeding up, `dmax` when slowing down, `min(amax, dmax)` when the change crosses
//! zero velocity.

use super::{check_inputs, check_limits, KinematicState, Limits, PlanError, Profile, Shape};

/// Iterations of the root search; each halves the bracket at worst.
const MAX_ITERATIONS: usize = 200;

/// One constant-jerk phase.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Phase {
    t: f64,
    j: f64,
}

/// A time-optimal jerk-limited change of velocity ending with zero acceleration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct VelChange {
    phases: [Phase; 3],
}

impl VelChange {
    /// The change from (v0, a0) to (vt, 0) with peak acceleration `amax_bound` and jerk
    /// `jmax`.
    ///
    /// Bringing `a0` to zero at once reaches `v_stop = v0 + a0|a0| / 2J`; the change then
    /// goes in direction `σ = sign(vt − v_stop)`. Without a hold phase the peak `x` solves
    /// `σ(vt − v0) = (2x² − a0²) / 2J`; with `x` above the bound the peak is the bound and
    /// a hold phase makes up the rest.
    fn new(v0: f64, a0: f64, vt: f64, amax_bound: f64, jmax: f64) -> Self {
        let v_stop = v0 + a0 * a0.abs() / (2.0 * jmax);
        let dv = vt - v_stop;
        let mut out = Self::default();
        if dv == 0.0 {
            out.phases[0] = Phase {
                t: a0.abs() / jmax,
                j: -a0.signum() * jmax,
            };
            return out;
        }
        let sigma = dv.signum();
        let x2 = (2.0 * jmax * sigma * (vt - v0) + a0 * a0) / 2.0;
        let x = x2.max(0.0).sqrt();
        let ap = sigma * x.min(amax_bound);
        let t1 = (ap - a0).abs() / jmax;
        let j1 = (ap - a0).signum() * jmax;
        let t3 = ap.abs() / jmax;
        let mut t2 = 0.0;
        if x > amax_bound {
            let v_no_hold = v0 + (a0 + ap) / 2.0 * t1 + ap / 2.0 * t3;
            t2 = ((vt - v_no_hold) / ap).max(0.0);
        }
        out.phases = [
            Phase { t: t1, j: j1 },
            Phase { t: t2, j: 0.0 },
            Phase {
                t: t3,
                j: -sigma * jmax,
            },
        ];
        out
    }

    /// Integrates the change from `(p, v, a)`; returns the end state.
    fn integrate(&self, mut s: KinematicState) -> KinematicState {
        for ph in &self.phases {
            let t = ph.t;
            s.p += t * (s.v + t * (s.a / 2.0 + t * ph.j / 6.0));
            s.v += t * (s.a + t * ph.j / 2.0);
            s.a += t * ph.j;
        }
        s
    }
}

/// Velocity reached by bringing the start acceleration to zero at once: where a velocity
/// change really starts from, so it decides whether the change speeds up or slows down.
fn v_stop(s: &KinematicState, lim: &Limits) -> f64 {
    s.v + s.a * s.a.abs() / (2.0 * lim.jmax)
}

/// Bound of the first velocity change, from (v0, a0) to `vt`: judged from where it
/// starts, from `v_stop` and from where it ends, so that a change during which the
/// velocity crosses zero (even only while the start acceleration is brought down) holds
/// `min(amax, dmax)`.
fn first_bound(s: &KinematicState, vt: f64, lim: &Limits) -> f64 {
    accel_bound(s.v, vt, lim).min(accel_bound(v_stop(s, lim), vt, lim))
}

/// Acceleration bound of a velocity change from `va` to `vb`.
fn accel_bound(va: f64, vb: f64, lim: &Limits) -> f64 {
    if va * vb < 0.0 {
        lim.amax.min(lim.dmax)
    } else if vb.abs() >= va.abs() {
        lim.amax
    } else {
        lim.dmax
    }
}

/// The two velocity changes of a move through peak velocity `vp`, and the distance they
/// cover.
#[derive(Clone, Copy, Debug)]
struct Shape7 {
    first: VelChange,
    second: VelChange,
    distance: f64,
}

fn through(start: &KinematicState, vp: f64, v_end: f64, lim: &Limits) -> Shape7 {
    let first = VelChange::new(start.v, start.a, vp, first_bound(start, vp, lim), lim.jmax);
    let second = VelChange::new(vp, 0.0, v_end, accel_bound(vp, v_end, lim), lim.jmax);
    let origin = KinematicState { p: 0.0, ..*start };
    let mid = first.integrate(origin);
    let end = second.integrate(KinematicState {
        p: mid.p,
        v: vp,
        a: 0.0,
        j: 0.0,
    });
    Shape7 {
        first,
        second,
        distance: end.p,
    }
}

/// Solves `f(x) = 0` on `[lo, hi]` where `f(lo) < 0 < f(hi)` (Illinois regula falsi).
fn solve(
    mut lo: f64,
    mut hi: f64,
    mut flo: f64,
    mut fhi: f64,
    tol: f64,
    f: impl Fn(f64) -> f64,
) -> f64 {
    let mut side = 0i8;
    let mut x = lo;
    for _ in 0..MAX_ITERATIONS {
        x = if fhi != flo {
            (lo * fhi - hi * flo) / (fhi - flo)
        } else {
            0.5 * (lo + hi)
        };
        if !(x > lo && x < hi) {
            x = 0.5 * (lo + hi);
        }
        let fx = f(x);
        if fx.abs() <= tol || hi - lo <= f64::EPSILON * hi.abs().max(lo.abs()).max(1e-300) {
            return x;
        }
        if fx < 0.0 {
            lo = x;
            flo = fx;
            if side == -1 {
                fhi /= 2.0;
            }
            side = -1;
        } else {
            hi = x;
            fhi = fx;
            if side == 1 {
                flo /= 2.0;
            }
            side = 1;
        }
    }
    x
}

/// The largest peak velocity `vp` in `(-vmax, vmax)` with `f(vp) = 0` (the fastest move).
///
/// `D(vp)` is not monotone: a peak between zero and `v_stop` means slowing down, pausing
/// the deceleration, and slowing down again — it covers more distance than braking at
/// once, so such "dip" peaks can be roots too, but slower ones. `D` grows on
/// `[v_stop, vmax]` and on `[-vmax, 0]`, so the brackets are tried from the top.
fn largest_root(
    s: &KinematicState,
    lim: &Limits,
    f_lo: f64,
    f_hi: f64,
    tol: f64,
    f: impl Fn(f64) -> f64,
) -> f64 {
    let vmax = lim.vmax;
    let top = v_stop(s, lim).clamp(-vmax, vmax);
    let f_top = f(top);
    if f_top <= 0.0 {
        return solve(top, vmax, f_top, f_hi, tol, f);
    }
    let mid = top.min(0.0);
    let f_mid = if mid == top { f_top } else { f(mid) };
    if mid < top && f_mid <= 0.0 {
        return solve(mid, top, f_mid, f_top, tol, f);
    }
    if f_mid >= 0.0 {
        return solve(-vmax, mid, f_lo, f_mid, tol, f);
    }
    solve(-vmax, vmax, f_lo, f_hi, tol, f)
}

/// Builds the profile of a planned move (in the mirrored frame: `m` is ±1).
fn build(start: KinematicState, shape: &Shape7, cruise: f64, m: f64) -> Result<Profile, PlanError> {
    let mut p = Profile::new(KinematicState { j: 0.0, ..start });
    for ph in &shape.first.phases {
        p.push(ph.t, Shape::Jerk(m * ph.j))?;
    }
    p.push(cruise, Shape::Jerk(0.0))?;
    for ph in &shape.second.phases {
        p.push(ph.t, Shape::Jerk(m * ph.j))?;
    }
    Ok(p)
}

fn no_solution(start: &KinematicState, target: f64) -> PlanError {
    PlanError::NoSolution {
        p: start.p,
        v: start.v,
        a: start.a,
        target,
    }
}

/// Plans a position move; see [`super::plan_position`].
pub fn plan_position(
    start: KinematicState,
    target: f64,
    v_end: f64,
    lim: &Limits,
) -> Result<Profile, PlanError> {
    check_limits(lim, true)?;
    check_inputs(&start, target)?;
    if !v_end.is_finite() {
        return Err(PlanError::NotFinite {
            name: "end velocity",
            value: v_end,
        });
    }
    let d = target - start.p;
    // Mirror so the target lies ahead (d ≥ 0); jerks are mirrored back when building.
    let m = if d < 0.0 { -1.0 } else { 1.0 };
    let s = KinematicState {
        p: 0.0,
        v: m * start.v,
        a: m * start.a,
        j: 0.0,
    };
    let dist = m * d;
    let mut ve = if m * v_end > 0.0 && dist > 0.0 {
        (m * v_end).min(lim.vmax)
    } else {
        0.0
    };
    // Size of the distances involved, for the root tolerance: the move, the braking
    // distance, and what the start acceleration alone carries the axis.
    let scale = dist
        .max(start.v * start.v / lim.amax.min(lim.dmax))
        .max(start.a.abs().powi(3) / (lim.jmax * lim.jmax))
        .max(start.v.abs() * start.a.abs() / lim.jmax)
        .max(v_stop(&s, lim).powi(2) / lim.amax.min(lim.dmax))
        .max(1e-12);
    let tol = 1e-13 * scale.max(1.0);
    // The end velocity must be reachable: ending at `ve` without a second change must not
    // overshoot; otherwise end at the fastest speed that still fits.
    if ve > 0.0 {
        let g = |w: f64| through(&s, w, w, lim).distance - dist;
        let g_ve = g(ve);
        if g_ve > 0.0 {
            // Largest reachable end speed: search above v_stop first (g grows there).
            let lo = v_stop(&s, lim).clamp(0.0, ve);
            let g_lo = g(lo);
            ve = if g_lo < 0.0 {
                solve(lo, ve, g_lo, g_ve, tol, g)
            } else {
                0.0
            };
        }
    }
    if ve == 0.0 {
        if let Some((prefix, change)) = dip(&s, dist, lim, tol) {
            let mut profile = Profile::new(KinematicState { j: 0.0, ..start });
            for ph in prefix.iter().chain(&change.phases) {
                profile.push(ph.t, Shape::Jerk(m * ph.j))?;
            }
            return pin_end(profile, &start, target, 0.0, scale, lim);
        }
    }
    let f = |vp: f64| through(&s, vp, ve, lim).distance - dist;
    let vmax = lim.vmax;
    let f_hi = f(vmax);
    let (vp, cruise) = if f_hi <= 0.0 {
        (vmax, -f_hi / vmax)
    } else {
        let f_lo = f(-vmax);
        if f_lo >= 0.0 {
            (-vmax, f_lo / vmax)
        } else {
            (largest_root(&s, lim, f_lo, f_hi, tol, f), 0.0)
        }
    };
    let shape = through(&s, vp, ve, lim);
    // A root found only to within `tol` leaves a residual; fold it into a cruise when the
    // peak allows, else it stays (far below the verification tolerance).
    let residual = dist - shape.distance - vp * cruise;
    let cruise = if vp.abs() > 0.0 && (cruise + residual / vp) >= 0.0 {
        cruise + residual / vp
    } else {
        cruise
    };
    let profile = build(start, &shape, cruise, m)?;
    pin_end(profile, &start, target, m * ve, scale, lim)
}

/// Verifies that `profile` lands on `target` at `v_end` with zero acceleration, then pins
/// the exact end state (so rounding never reaches the end position).
fn pin_end(
    mut profile: Profile,
    start: &KinematicState,
    target: f64,
    v_end: f64,
    scale: f64,
    lim: &Limits,
) -> Result<Profile, PlanError> {
    let end = profile.end_state();
    let ptol = 1e-9 * target.abs().max(start.p.abs()).max(scale).max(1.0);
    let vtol = 1e-9 * lim.vmax.max(start.v.abs()).max(1.0);
    if (end.p - target).abs() > ptol
        || (end.v - v_end).abs() > vtol
        || end.a.abs() > 1e-6 * lim.amax.max(lim.dmax)
    {
        return Err(no_solution(start, target));
    }
    profile.set_end(KinematicState {
        p: target,
        v: v_end,
        a: 0.0,
        j: 0.0,
    });
    Ok(profile)
}

/// The "dip window": moving towards the target with the target beyond the shortest
/// stopping point but short of where the axis stops after it has followed its
/// *envelope* to the end. The envelope is the fastest the axis may go:
/// - inside the limits and already braking (a0 < 0 in the frame where the target is
///   ahead), easing the braking to zero at once (the speed falls to `v_stop`);
/// - beyond a limit (`v_stop > vmax`: |v0| > vmax, or a0 carrying v past vmax), the
///   braking rule: landing on vmax with a = 0 as fast as the jerk allows (the velocity
///   change to (vmax, 0)). The axis never goes faster than this landing.
///
/// The time-optimal move follows the envelope for a while and leaves it by braking to
/// rest on the target: the later it leaves, the faster it has gone and the further it
/// gets. So the departure time `τ` in the envelope's last phase (the one that eases the
/// acceleration to zero; before it the envelope brakes at full jerk or full deceleration,
/// and braking from there is the plain stop) is found by a bracketed root search
/// (distance grows from the plain stop at `τ = 0` to the stop after the whole envelope).
/// Stopping from a slower speed at a = 0 instead — a peak velocity `vp` below the
/// envelope's end, what the `vp` search finds in this window — pauses the braking and is
/// slower (in issue 11's example from beyond vmax, the rest once back inside the limits
/// took 16.6 % longer than the optimum from there).
///
/// Returns the envelope up to the departure and the braking change, or `None` outside
/// the window.
fn dip(s: &KinematicState, dist: f64, lim: &Limits, tol: f64) -> Option<([Phase; 3], VelChange)> {
    let vs = v_stop(s, lim);
    let j = lim.jmax;
    let envelope = if vs > lim.vmax {
        VelChange::new(s.v, s.a, lim.vmax, first_bound(s, lim.vmax, lim), j)
    } else if s.a < 0.0 && s.v > 0.0 && vs > 0.0 {
        let ease = Phase { t: -s.a / j, j };
        VelChange {
            phases: [Phase::default(), Phase::default(), ease],
        }
    } else {
        return None;
    };
    let [first, hold, last] = envelope.phases;
    // The last phase eases a ≤ 0 back to zero: a departure only makes sense there.
    if !(last.j > 0.0 && last.t > 0.0) {
        return None;
    }
    let origin = KinematicState { p: 0.0, ..*s };
    let plan = |tau: f64| {
        let prefix = VelChange {
            phases: [first, hold, Phase { t: tau, j: last.j }],
        };
        let after = prefix.integrate(origin);
        let change = VelChange::new(after.v, after.a, 0.0, first_bound(&after, 0.0, lim), j);
        (prefix.phases, change, change.integrate(after).p)
    };
    let plain = plan(0.0).2;
    let whole = plan(last.t).2;
    if !(dist > plain && dist < whole) {
        return None;
    }
    let g = |tau: f64| plan(tau).2 - dist;
    let tau = solve(0.0, last.t, plain - dist, whole - dist, tol, g);
    let (prefix, change, _) = plan(tau);
    Some((prefix, change))
}

/// Plans a velocity change; see [`super::plan_velocity`].
pub fn plan_velocity(
    start: KinematicState,
    v_target: f64,
    lim: &Limits,
) -> Result<Profile, PlanError> {
    check_limits(lim, true)?;
    check_inputs(&start, v_target)?;
    let vt = v_target.clamp(-lim.vmax, lim.vmax);
    let change = VelChange::new(start.v, start.a, vt, first_bound(&start, vt, lim), lim.jmax);
    let mut p = Profile::new(KinematicState { j: 0.0, ..start });
    for ph in &change.phases {
        p.push(ph.t, Shape::Jerk(ph.j))?;
    }
    let end = p.end_state();
    if (end.v - vt).abs() > 1e-9 * lim.vmax.max(start.v.abs()).max(1.0) {
        return Err(no_solution(&start, v_target));
    }
    p.set_end(KinematicState {
        v: vt,
        a: 0.0,
        ..end
    });
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lim(v: f64, a: f64, d: f64, j: f64) -> Limits {
        Limits {
            vmax: v,
            amax: a,
            dmax: d,
            jmax: j,
        }
    }

    #[test]
    fn rest_to_rest_unit_limits_takes_2_pow_5_3() {
        let p = plan_position(
            KinematicState::at_rest(0.0),
            1.0,
            0.0,
            &lim(1.0, 1.0, 1.0, 1.0),
        )
        .unwrap();
        assert!(
            (p.duration() - 2f64.powf(5.0 / 3.0)).abs() < 1e-9,
            "{}",
            p.duration()
        );
        assert!((p.duration() - 3.1748).abs() < 1e-4);
    }

    #[test]
    fn rest_to_rest_reaching_all_limits() {
        // vmax 1, amax 1, jerk 10: ramp 1.1 s covering 0.55; d = 10 → 2.2 + 8.9 = 11.1 s.
        let p = plan_position(
            KinematicState::at_rest(0.0),
            10.0,
            0.0,
            &lim(1.0, 1.0, 1.0, 10.0),
        )
        .unwrap();
        assert!((p.duration() - 11.1).abs() < 1e-9, "{}", p.duration());
        // Asymmetric: deceleration 2 → ramp down 0.7 s covering 0.35: 1.1 + 0.7 + 9.1.
        let p = plan_position(
            KinematicState::at_rest(0.0),
            10.0,
            0.0,
            &lim(1.0, 1.0, 2.0, 10.0),
        )
        .unwrap();
        assert!((p.duration() - 10.9).abs() < 1e-9, "{}", p.duration());
        let pk = p.peaks();
        assert!(
            (pk.v - 1.0).abs() < 1e-12 && (pk.a - 2.0).abs() < 1e-12 && (pk.j - 10.0).abs() < 1e-12
        );
    }

    #[test]
    fn velocity_change_from_rest() {
        // 0 → 1 with a 1, j 1: triangular acceleration, 2 s.
        let p = plan_velocity(KinematicState::at_rest(0.0), 1.0, &lim(5.0, 1.0, 1.0, 1.0)).unwrap();
        assert!((p.duration() - 2.0).abs() < 1e-12);
        assert!((p.sample(10.0).v - 1.0).abs() < 1e-12);
    }

    #[test]
    fn target_behind_comes_back_without_error() {
        let start = KinematicState {
            p: 0.0,
            v: 2.0,
            a: 1.0,
            j: 0.0,
        };
        let p = plan_position(start, -1.0, 0.0, &lim(2.0, 1.0, 1.0, 2.0)).unwrap();
        assert_eq!(p.end_state().p, -1.0);
        assert!((p.sample(p.duration()).p + 1.0).abs() < 1e-9);
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let z = KinematicState::at_rest(0.0);
        assert!(plan_position(z, 1.0, 0.0, &lim(1.0, 1.0, 1.0, f64::INFINITY)).is_err());
        assert!(plan_position(z, f64::NAN, 0.0, &lim(1.0, 1.0, 1.0, 1.0)).is_err());
        assert!(plan_velocity(z, 1.0, &lim(1.0, -1.0, 1.0, 1.0)).is_err());
    }
}
