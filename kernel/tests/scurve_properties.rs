//! Properties of the S-curve planner over random states and limits: limits never exceeded
//! (between samples too), exact end, continuity; and time-optimality against a
//! brute-force search (a discretised linear program over piecewise-constant jerk).

use gantry_kernel::profile::{scurve, KinematicState, Limits, Profile, Shape};
use minilp::{ComparisonOp, OptimizationDirection, Problem};
use proptest::prelude::*;

fn config(cases: u32, seed: u64) -> ProptestConfig {
    ProptestConfig {
        cases,
        failure_persistence: None,
        rng_seed: proptest::test_runner::RngSeed::Fixed(seed),
        ..ProptestConfig::default()
    }
}

/// Values with the degenerate draws a planner must survive.
fn num(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    prop_oneof![6 => lo..hi, 1 => Just(0.0), 1 => Just(1.0), 1 => Just(-1.0)]
}

fn limits() -> impl Strategy<Value = Limits> {
    (0.1..10.0f64, 0.1..20.0f64, 0.1..20.0f64, 0.5..200.0f64).prop_map(
        |(vmax, amax, dmax, jmax)| Limits {
            vmax,
            amax,
            dmax,
            jmax,
        },
    )
}

/// Checks a profile from `start` against `lim` at every segment boundary and at 4000
/// samples. A start beyond a limit may only come back: acceleration beyond its bound
/// shrinks at the jerk rate, and velocity may exceed vmax only by what the start's
/// acceleration makes unavoidable.
fn check_limits(p: &Profile, start: &KinematicState, lim: &Limits) {
    let tol = 1e-9;
    let v_stop = start.v + start.a * start.a.abs() / (2.0 * lim.jmax);
    let v_cap = lim.vmax.max(start.v.abs()).max(v_stop.abs()) * (1.0 + tol) + 1e-12;
    let n = 4000;
    let mut times: Vec<f64> = (0..=n)
        .map(|i| p.duration() * i as f64 / n as f64)
        .collect();
    let mut t0 = 0.0;
    for s in p.segments() {
        times.push(t0);
        t0 += s.duration;
        times.push(t0 - 1e-12);
        assert!(matches!(s.shape, Shape::Jerk(_)));
    }
    for &t in &times {
        let s = p.sample(t);
        assert!(s.v.abs() <= v_cap, "v {} > {v_cap} at t {t}", s.v);
        assert!(s.j.abs() <= lim.jmax * (1.0 + tol), "j {} at t {t}", s.j);
        let bound = if s.a * s.v > 0.0 { lim.amax } else { lim.dmax };
        let still_coming_back = start.a.abs() - lim.jmax * t;
        assert!(
            s.a.abs() <= bound * (1.0 + tol) + 1e-12
                || s.a.abs() <= still_coming_back + 1e-9 * (start.a.abs() + 1.0),
            "a {} > bound {bound} at t {t} (v {})",
            s.a,
            s.v
        );
    }
}

/// p, v and a continuous across every segment boundary.
fn check_continuity(p: &Profile) {
    for w in p.segments().windows(2) {
        let (a, b) = (w[0].end(), w[1].start);
        let scale = a.p.abs().max(1.0);
        assert!((a.p - b.p).abs() <= 1e-9 * scale, "p {} vs {}", a.p, b.p);
        assert!((a.v - b.v).abs() <= 1e-9 * a.v.abs().max(1.0));
        assert!((a.a - b.a).abs() <= 1e-9 * a.a.abs().max(1.0));
    }
}

proptest! {
    #![proptest_config(config(1000, 0x5c))]

    #[test]
    fn moves_end_exactly_on_target_within_limits(
        p0 in num(-100.0, 100.0),
        v0 in num(-15.0, 15.0),
        a0 in num(-30.0, 30.0),
        target in num(-100.0, 100.0),
        lim in limits(),
    ) {
        let start = KinematicState { p: p0, v: v0, a: a0, j: 0.0 };
        let p = scurve::plan_position(start, target, 0.0, &lim).expect("a plan");
        let end = p.end_state();
        prop_assert_eq!(end.p, target);
        prop_assert_eq!(end.v, 0.0);
        let sampled = p.sample(p.duration());
        prop_assert!((sampled.p - target).abs() <= 1e-9 * target.abs().max(1.0), "sampled end {}", sampled.p);
        prop_assert!(sampled.v.abs() <= 1e-9 * lim.vmax.max(1.0));
        prop_assert!(sampled.a.abs() <= 1e-6);
        let s0 = p.sample(0.0);
        prop_assert!((s0.p - p0).abs() < 1e-12 && (s0.v - v0).abs() < 1e-12 && (s0.a - a0).abs() < 1e-12);
        check_limits(&p, &start, &lim);
        check_continuity(&p);
    }

    #[test]
    fn blended_ends_reach_the_asked_velocity_or_less(
        v0 in num(0.0, 5.0),
        d in 0.001..50.0f64,
        v_end in 0.0..10.0f64,
        lim in limits(),
    ) {
        let start = KinematicState { p: 0.0, v: v0.min(lim.vmax), a: 0.0, j: 0.0 };
        let p = scurve::plan_position(start, d, v_end, &lim).expect("a plan");
        let e = p.end_state();
        prop_assert_eq!(e.p, d);
        prop_assert!(e.v >= 0.0 && e.v <= v_end.min(lim.vmax) + 1e-12);
        check_limits(&p, &start, &lim);
    }

    #[test]
    fn velocity_changes_reach_the_target_velocity(
        v0 in num(-15.0, 15.0),
        a0 in num(-30.0, 30.0),
        vt in num(-15.0, 15.0),
        lim in limits(),
    ) {
        let start = KinematicState { p: 0.0, v: v0, a: a0, j: 0.0 };
        let p = scurve::plan_velocity(start, vt, &lim).expect("a plan");
        let want = vt.clamp(-lim.vmax, lim.vmax);
        prop_assert!((p.sample(p.duration() + 1.0).v - want).abs() <= 1e-9 * lim.vmax.max(1.0));
        prop_assert!(p.sample(p.duration() + 1.0).a.abs() <= 1e-9);
        check_limits(&p, &start, &lim);
        check_continuity(&p);
    }

    #[test]
    fn garbage_never_panics(
        p0 in any::<f64>(), v0 in any::<f64>(), a0 in any::<f64>(), target in any::<f64>(),
        vmax in any::<f64>(), amax in any::<f64>(), jmax in any::<f64>(),
    ) {
        let lim = Limits { vmax, amax, dmax: amax, jmax };
        let _ = scurve::plan_position(KinematicState { p: p0, v: v0, a: a0, j: 0.0 }, target, 0.0, &lim);
        let _ = scurve::plan_velocity(KinematicState { p: p0, v: v0, a: a0, j: 0.0 }, target, &lim);
    }
}

/// Whether a trajectory of `n` constant-jerk steps over `horizon` seconds exists from
/// `start` to rest at `target` within symmetric limits (`amax` = `dmax`), checked at the
/// step boundaries. Every such trajectory is a continuous one, so infeasibility below our
/// duration means no trajectory on this grid beats the planner.
fn feasible(start: &KinematicState, target: f64, lim: &Limits, horizon: f64, n: usize) -> bool {
    let vmax = |_: f64| lim.vmax;
    feasible_under(start, target, lim, horizon, n, vmax, vmax)
}

/// [`feasible`] with a velocity bound that changes with time: `upper(t) >= v(t) >=
/// -lower(t)` at every step boundary (`t` from the start of `start`). An acceleration
/// beyond `amax` at the start may only shrink at the jerk rate (so a start beyond its
/// acceleration bound is feasible at all).
///
/// minilp 0.2 sometimes panics on a singular basis (an `unwrap` inside its solver, about
/// 1 LP in 1000 here); the question is then asked again on a grid of one step more, and a
/// second failure fails the test.
fn feasible_under(
    start: &KinematicState,
    target: f64,
    lim: &Limits,
    horizon: f64,
    n: usize,
    upper: impl Fn(f64) -> f64,
    lower: impl Fn(f64) -> f64,
) -> bool {
    let ask = |n| {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            grid_feasible(start, target, lim, horizon, n, &upper, &lower)
        }))
    };
    ask(n)
        .or_else(|_| ask(n + 1))
        .expect("minilp failed on two grids")
}

fn grid_feasible(
    start: &KinematicState,
    target: f64,
    lim: &Limits,
    horizon: f64,
    n: usize,
    upper: &impl Fn(f64) -> f64,
    lower: &impl Fn(f64) -> f64,
) -> bool {
    let h = horizon / n as f64;
    let mut pb = Problem::new(OptimizationDirection::Minimize);
    let vars: Vec<_> = (0..n)
        .map(|_| pb.add_var(0.0, (-lim.jmax, lim.jmax)))
        .collect();
    for k in 1..=n {
        let kf = k as f64;
        let t = kf * h;
        let a_max = lim.amax.max(start.a.abs() - lim.jmax * t);
        // a_k, v_k, p_k as linear functions of the jerks j_0..j_{k-1}.
        let a_terms: Vec<_> = (0..k).map(|i| (vars[i], h)).collect();
        let v_terms: Vec<_> = (0..k)
            .map(|i| (vars[i], h * h * (2.0 * (k - i) as f64 - 1.0) / 2.0))
            .collect();
        let a_base = start.a;
        let v_base = start.v + start.a * t;
        pb.add_constraint(a_terms.as_slice(), ComparisonOp::Le, a_max - a_base);
        pb.add_constraint(a_terms.as_slice(), ComparisonOp::Ge, -a_max - a_base);
        pb.add_constraint(v_terms.as_slice(), ComparisonOp::Le, upper(t) - v_base);
        pb.add_constraint(v_terms.as_slice(), ComparisonOp::Ge, -lower(t) - v_base);
        if k == n {
            let p_terms: Vec<_> = (0..k)
                .map(|i| {
                    let m = (k - i) as f64;
                    (vars[i], h * h * h * (m.powi(3) - (m - 1.0).powi(3)) / 6.0)
                })
                .collect();
            let p_base = start.p + start.v * t + start.a * t * t / 2.0;
            pb.add_constraint(a_terms.as_slice(), ComparisonOp::Eq, -a_base);
            pb.add_constraint(v_terms.as_slice(), ComparisonOp::Eq, -v_base);
            pb.add_constraint(p_terms.as_slice(), ComparisonOp::Eq, target - p_base);
        }
    }
    pb.solve().is_ok()
}

/// Random states within the limits whose start acceleration does not already force the
/// velocity past vmax.
fn lp_case() -> impl Strategy<Value = (KinematicState, f64, Limits)> {
    (
        0.5..3.0f64,
        0.5..3.0f64,
        0.5..5.0f64,
        -0.9..0.9f64,
        -0.9..0.9f64,
        -5.0..5.0f64,
    )
        .prop_filter_map(
            "start must be inside the limits",
            |(vmax, amax, jmax, fv, fa, target)| {
                let lim = Limits {
                    vmax,
                    amax,
                    dmax: amax,
                    jmax,
                };
                let start = KinematicState {
                    p: 0.0,
                    v: fv * vmax,
                    a: fa * amax,
                    j: 0.0,
                };
                let v_stop = start.v + start.a * start.a.abs() / (2.0 * jmax);
                (v_stop.abs() < vmax).then_some((start, target, lim))
            },
        )
}

/// The "dip window" of a moving start: beyond the shortest stopping point but short of
/// where the axis stops when it first eases its braking to zero. The optimum there eases
/// the braking only part way — a profile shape of its own, so these cases get a test of
/// their own.
fn dip_window(start: &KinematicState, lim: &Limits) -> Option<(f64, f64)> {
    if start.v == 0.0 {
        return None;
    }
    let brake = scurve::plan_velocity(*start, 0.0, lim)
        .unwrap()
        .end_state()
        .p;
    let v_stop = start.v + start.a * start.a.abs() / (2.0 * lim.jmax);
    let eased = scurve::plan_velocity(*start, v_stop, lim)
        .unwrap()
        .end_state();
    let eased_stop = scurve::plan_velocity(eased, 0.0, lim)
        .unwrap()
        .end_state()
        .p;
    Some(if brake <= eased_stop {
        (brake, eased_stop)
    } else {
        (eased_stop, brake)
    })
}

/// Cases whose target lies inside the dip window.
fn dip_case() -> impl Strategy<Value = (KinematicState, f64, Limits)> {
    (lp_case(), 0.05..0.95f64).prop_filter_map("needs a dip window", |((start, _, lim), u)| {
        let (lo, hi) = dip_window(&start, &lim)?;
        (hi - lo > 1e-6).then_some((start, lo + u * (hi - lo), lim))
    })
}

proptest! {
    #![proptest_config(config(lp_cases(), 0x1b))]

    #[test]
    fn no_grid_trajectory_is_3_percent_faster((start, target, lim) in lp_case()) {
        let p = scurve::plan_position(start, target, 0.0, &lim).expect("a plan");
        let t = p.duration();
        prop_assume!(t > 0.05);
        let n = 120;
        prop_assert!(!feasible(&start, target, &lim, 0.97 * t, n), "LP beat the planner: {t} s");
        prop_assert!(feasible(&start, target, &lim, 1.10 * t, n), "LP finds nothing at 110 % of {t} s: the check itself is broken");
    }

    #[test]
    fn no_grid_trajectory_is_3_percent_faster_in_the_dip_window((start, target, lim) in dip_case()) {
        let p = scurve::plan_position(start, target, 0.0, &lim).expect("a plan");
        let t = p.duration();
        prop_assume!(t > 0.05);
        prop_assert!(!feasible(&start, target, &lim, 0.97 * t, 120), "LP beat the planner: {t} s");
        prop_assert!(feasible(&start, target, &lim, 1.10 * t, 120), "LP finds nothing at 110 % of {t} s");
    }
}

/// LP cases per run (`GANTRY_LP_CASES` for more); each solves two LPs of 120 variables.
fn lp_cases() -> u32 {
    std::env::var("GANTRY_LP_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(24)
}

// ---------------------------------------------------------------------------------------
// Starts beyond the limits (issue 11 §7).
//
// From |v0| > vmax, or with a0 carrying v past vmax, no move can stay inside the limits,
// so "time-optimal" needs a rule for the way back. The planner's rule (the braking rule):
// the axis never goes faster than the fastest landing on vmax with a = 0 — the kernel's
// own velocity change from the start to ±vmax, `scurve::plan_velocity`, called the
// envelope here (when braking already under way takes the axis below vmax, the envelope
// eases that braking to zero at once and ends at v_stop). Below the envelope the move is
// free within the limits, and must be the fastest such move. Two checks:
//
// - the issue's measure: once the axis is back inside its limits (|v| <= vmax and its
//   acceleration no longer carrying it past vmax), the rest of the profile is exactly as
//   long as the planner's own plan from that state, which the inside-limits LP tests
//   check for optimality (cheap, so it runs over many states);
// - the LP: the envelope's phases before its last one (jerk towards braking, then full
//   deceleration) are the fastest braking there is, so a move that must stay below the
//   envelope has no choice there: the rule fixes them. The LP starts where they end and
//   compares only what the rule leaves free: piecewise-constant jerk to rest on the
//   target with |a| <= amax and -vmax <= v <= max(vmax, envelope) at every step (on
//   the side beyond; the other side keeps vmax), within `LP_TOL` of the planner.
// ---------------------------------------------------------------------------------------

fn v_stop(s: &KinematicState, lim: &Limits) -> f64 {
    s.v + s.a * s.a.abs() / (2.0 * lim.jmax)
}

/// The side (±1) on which `s` is beyond vmax, or `None` when it is inside the limits.
fn beyond_side(s: &KinematicState, lim: &Limits) -> Option<f64> {
    let vs = v_stop(s, lim);
    if s.v > lim.vmax || vs > lim.vmax {
        Some(1.0)
    } else if s.v < -lim.vmax || vs < -lim.vmax {
        Some(-1.0)
    } else {
        None
    }
}

/// The braking rule's envelope of a start beyond the limits: its side and the landing.
fn envelope(s: &KinematicState, lim: &Limits) -> Option<(f64, Profile)> {
    let side = beyond_side(s, lim)?;
    let land = side * (side * v_stop(s, lim)).min(lim.vmax);
    Some((
        side,
        scurve::plan_velocity(*s, land, lim).expect("a landing"),
    ))
}

/// Whether a state is inside the limits: |v| <= vmax and not carried past it.
fn inside(s: &KinematicState, lim: &Limits) -> bool {
    let tol = 1e-9 * lim.vmax.max(1.0);
    s.v.abs() <= lim.vmax + tol && v_stop(s, lim).abs() <= lim.vmax + tol
}

/// The first instant at which profile `p` is back inside the limits (bisection to 1e-15
/// of its duration between the first inside sample of 10 000 and the one before).
fn back_inside(p: &Profile, lim: &Limits) -> f64 {
    let t_end = p.duration();
    let n = 10_000;
    let first = (0..=n)
        .find(|&i| inside(&p.sample(t_end * i as f64 / n as f64), lim))
        .expect("a move ends at rest, inside the limits");
    if first == 0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (
        t_end * (first - 1) as f64 / n as f64,
        t_end * first as f64 / n as f64,
    );
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if inside(&p.sample(mid), lim) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// Random starts beyond the limits (symmetric limits, as the LP needs): either |v0| above
/// vmax, or v0 inside with a0 carrying v past vmax; |a0| inside its bound.
fn beyond_case() -> impl Strategy<Value = (KinematicState, f64, Limits)> {
    let limits = (0.5..3.0f64, 0.5..3.0f64, 0.5..5.0f64).prop_map(|(vmax, amax, jmax)| Limits {
        vmax,
        amax,
        dmax: amax,
        jmax,
    });
    let too_fast = (limits.clone(), 1.01..1.6f64, -0.9..0.9f64)
        .prop_map(|(lim, fv, fa)| (lim, fv * lim.vmax, fa * lim.amax));
    // v0 = vmax − u·a0²/2J: stopping the acceleration at once ends (1 − u)·a0²/2J past vmax.
    let carried = (limits, 0.3..0.95f64, 0.05..0.95f64).prop_map(|(lim, fa, u)| {
        let a = fa * lim.amax;
        (lim, lim.vmax - u * a * a / (2.0 * lim.jmax), a)
    });
    (prop_oneof![too_fast, carried], any::<bool>(), -5.0..5.0f64).prop_filter_map(
        "start beyond the limits on one side only",
        |((lim, v, a), flip, target)| {
            let m = if flip { -1.0 } else { 1.0 };
            let start = KinematicState {
                p: 0.0,
                v: m * v,
                a: m * a,
                j: 0.0,
            };
            let vs = v_stop(&start, &lim);
            let one_side = !(start.v.abs() > lim.vmax && vs * start.v < -lim.vmax * start.v.abs());
            (beyond_side(&start, &lim).is_some() && one_side && start.v.abs() <= 1.6 * lim.vmax)
                .then_some((start, target, lim))
        },
    )
}

/// Checks the rule on a planned move from a start beyond the limits: the profile follows
/// the envelope through its fixed phases and never goes faster than it. Returns the
/// envelope's side and profile and the time its fixed phases end.
fn check_rule(p: &Profile, start: &KinematicState, lim: &Limits) -> (f64, Profile, f64) {
    let (side, env) = envelope(start, lim).expect("start beyond the limits");
    let segs = env.segments();
    let fixed: f64 = segs
        .iter()
        .take(segs.len().saturating_sub(1))
        .map(|s| s.duration)
        .sum();
    assert!(
        p.duration() >= fixed - 1e-12,
        "the move ends ({} s) before the braking rule's fixed phases ({fixed} s)",
        p.duration()
    );
    let scale = start.v.abs().max(start.a.abs()).max(1.0);
    for i in 0..=200 {
        let t = fixed * i as f64 / 200.0;
        let (a, b) = (p.sample(t), env.sample(t));
        assert!(
            (a.p - b.p).abs() <= 1e-9 * scale && (a.v - b.v).abs() <= 1e-9 * scale,
            "leaves the fixed braking at t {t}: {a:?} vs envelope {b:?}"
        );
    }
    for i in 0..=4000 {
        let t = p.duration() * i as f64 / 4000.0;
        let v = side * p.sample(t).v;
        let cap = lim.vmax.max(side * env.sample(t).v);
        assert!(
            v <= cap + 1e-9 * scale,
            "faster than the braking rule at t {t}: {v} > {cap}"
        );
    }
    (side, env, fixed)
}

/// The issue's measure: the rest of the move once the axis is back inside its limits,
/// and the planner's own plan from there. Returns (rest of the move, plan from there).
///
/// Only "the rest is not slower" is asserted: the duration of a plan is continuous in its
/// start state but not Lipschitz (a target a distance δ beyond the shortest stop costs
/// about √δ of time), so the state found to within 1e-9 of the crossing of vmax may give
/// a plan a few 1e-7 of its length longer than the rest, never shorter.
fn rest_once_inside(p: &Profile, target: f64, lim: &Limits) -> (f64, f64) {
    let t_in = back_inside(p, lim);
    let from = p.sample(t_in);
    let from = KinematicState { j: 0.0, ..from };
    let again = scurve::plan_position(from, target, 0.0, lim).expect("a plan from inside");
    (p.duration() - t_in, again.duration())
}

/// Relative tolerance of the LP comparison of the free part, both ways: 0.5 %. The LP
/// can beat a real trajectory only by what its grid lets slip between step boundaries (v
/// may overshoot a bound by at most jmax·h²/8 inside a step, about 10⁻⁴·vmax here), so a
/// planner slower than optimal by more than a trifle shows as a feasible LP at 99.5 %.
/// Its own pessimism (jerk switches only on the grid) made its optimum 1.0000 to 1.0008
/// times the planner's free part over 150 seeded cases of `beyond_case` (bisection to
/// 10⁻⁵), so it must find a move at 100.5 %. The issue's cases were up to 16.6 % slow.
const LP_TOL: f64 = 0.005;

/// Checks the free part of a move from beyond the limits against the rule's LP.
fn check_lp_beyond(start: &KinematicState, target: f64, lim: &Limits, p: &Profile) {
    let (side, env, fixed) = check_rule(p, start, lim);
    let free = p.duration() - fixed;
    if free < 0.05 {
        return;
    }
    let from = env.sample(fixed);
    let bound = |sign: f64| {
        let env = &env;
        move |t: f64| {
            if sign == side {
                lim.vmax.max(side * env.sample(fixed + t).v)
            } else {
                lim.vmax
            }
        }
    };
    let n = 120;
    assert!(
        !feasible_under(
            &from,
            target,
            lim,
            (1.0 - LP_TOL) * free,
            n,
            bound(1.0),
            bound(-1.0)
        ),
        "LP beat the planner's free part ({free} s after {fixed} s of fixed braking)"
    );
    assert!(
        feasible_under(
            &from,
            target,
            lim,
            (1.0 + LP_TOL) * free,
            n,
            bound(1.0),
            bound(-1.0)
        ),
        "LP finds nothing at {} % of the free part ({free} s): the check itself is broken",
        100.0 * (1.0 + LP_TOL)
    );
}

/// Issue 11's example: from −3.1978 units/s (vmax 2.8466) while braking, the old planner
/// braked to 1.25 units/s, paused the braking there and braked again: 0.5098 s, 16.6 %
/// slower than optimal once back inside the limits. The optimum follows the braking rule
/// and leaves it by braking straight onto the target.
#[test]
fn issue_11_example_beyond_vmax_is_optimal_once_back_inside() {
    let start = KinematicState {
        p: 0.3794,
        v: -3.1978,
        a: 1.9090,
        j: 0.0,
    };
    let target = -0.3618;
    let lim = Limits {
        vmax: 2.8466,
        amax: 11.8221,
        dmax: 11.8221,
        jmax: 90.9856,
    };
    let p = scurve::plan_position(start, target, 0.0, &lim).expect("a plan");
    assert_eq!(p.end_state().p, target);
    check_limits(&p, &start, &lim);
    check_continuity(&p);
    let (rest, again) = rest_once_inside(&p, target, &lim);
    assert!(
        rest <= again * (1.0 + 1e-9),
        "once back inside: {rest} s left, {again} s from there"
    );
    check_lp_beyond(&start, target, &lim, &p);
}

proptest! {
    #![proptest_config(config(1000, 0x11))]

    #[test]
    fn beyond_the_limits_the_rest_is_optimal_once_back_inside((start, target, lim) in beyond_case()) {
        let p = scurve::plan_position(start, target, 0.0, &lim).expect("a plan");
        prop_assert_eq!(p.end_state().p, target);
        check_limits(&p, &start, &lim);
        check_continuity(&p);
        check_rule(&p, &start, &lim);
        let (rest, again) = rest_once_inside(&p, target, &lim);
        prop_assert!(
            rest <= again * (1.0 + 1e-9),
            "once back inside: {} s left, {} s from there", rest, again
        );
    }
}

proptest! {
    // Asymmetric limits: a change whose velocity crosses zero holds min(amax, dmax)
    // (the module's conservative rule, README's known limitations), which from beyond
    // vmax brakes more gently than the landing on vmax: the rule is asserted for moves
    // that do not reverse. Most random targets need a reversal, hence the rejects.
    #![proptest_config(ProptestConfig { max_global_rejects: 100_000, ..config(1000, 0x11a) })]

    #[test]
    fn beyond_the_limits_with_asymmetric_limits_the_rest_is_optimal_once_back_inside(
        (start, target, lim) in beyond_case(),
        dmax_factor in 0.3..3.0f64,
    ) {
        let lim = Limits { dmax: lim.amax * dmax_factor, ..lim };
        let p = scurve::plan_position(start, target, 0.0, &lim).expect("a plan");
        let reverses = (0..=1000).any(|k| p.sample(p.duration() * k as f64 / 1000.0).v * start.v < 0.0);
        prop_assume!(!reverses);
        prop_assert_eq!(p.end_state().p, target);
        check_limits(&p, &start, &lim);
        check_rule(&p, &start, &lim);
        let (rest, again) = rest_once_inside(&p, target, &lim);
        prop_assert!(
            rest <= again * (1.0 + 1e-9),
            "once back inside: {} s left, {} s from there", rest, again
        );
    }
}

proptest! {
    #![proptest_config(config(lp_cases(), 0x11b))]

    #[test]
    fn no_grid_trajectory_beats_the_free_part_beyond_the_limits((start, target, lim) in beyond_case()) {
        let p = scurve::plan_position(start, target, 0.0, &lim).expect("a plan");
        check_lp_beyond(&start, target, &lim, &p);
    }
}
