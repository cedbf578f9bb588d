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
    let h = horizon / n as f64;
    let mut pb = Problem::new(OptimizationDirection::Minimize);
    let vars: Vec<_> = (0..n)
        .map(|_| pb.add_var(0.0, (-lim.jmax, lim.jmax)))
        .collect();
    let a_max = lim.amax;
    for k in 1..=n {
        let kf = k as f64;
        // a_k, v_k, p_k as linear functions of the jerks j_0..j_{k-1}.
        let a_terms: Vec<_> = (0..k).map(|i| (vars[i], h)).collect();
        let v_terms: Vec<_> = (0..k)
            .map(|i| (vars[i], h * h * (2.0 * (k - i) as f64 - 1.0) / 2.0))
            .collect();
        let a_base = start.a;
        let v_base = start.v + start.a * kf * h;
        pb.add_constraint(a_terms.as_slice(), ComparisonOp::Le, a_max - a_base);
        pb.add_constraint(a_terms.as_slice(), ComparisonOp::Ge, -a_max - a_base);
        pb.add_constraint(v_terms.as_slice(), ComparisonOp::Le, lim.vmax - v_base);
        pb.add_constraint(v_terms.as_slice(), ComparisonOp::Ge, -lim.vmax - v_base);
        if k == n {
            let p_terms: Vec<_> = (0..k)
                .map(|i| {
                    let m = (k - i) as f64;
                    (vars[i], h * h * h * (m.powi(3) - (m - 1.0).powi(3)) / 6.0)
                })
                .collect();
            let t = kf * h;
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
