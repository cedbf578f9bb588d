//! Time-optimality of the trapezoid planner, checked independently with a linear program.
//!
//! For a forward move (velocity never negative) the set of velocity profiles on a grid of
//! `N` steps with `0 <= v_k <= vmax`, `-dmax·dt <= v_{k+1} − v_k <= amax·dt`, fixed start
//! and end velocity and `Σ (v_k + v_{k+1})/2 · dt = distance` is a polytope. A feasible
//! point is a real piecewise-linear profile within the limits, so the LP can never beat
//! the true optimum: the LP must be infeasible just below the planned duration (else the
//! planner is not time-optimal), and feasible a few grid steps above it (else the LP or the
//! planner's geometry is wrong).

use gantry_kernel::profile::ramp::{plan_position, RampShape};
use gantry_kernel::profile::{KinematicState, Limits};
use minilp::{ComparisonOp, OptimizationDirection, Problem};

const STEPS: usize = 400;

/// Is there a forward profile of duration `t` from speed `u` to `ve` over `dist`?
fn feasible(t: f64, u: f64, ve: f64, dist: f64, l: &Limits) -> bool {
    let dt = t / STEPS as f64;
    let mut lp = Problem::new(OptimizationDirection::Minimize);
    let v: Vec<_> = (0..=STEPS)
        .map(|k| {
            let bounds = match k {
                0 => (u, u),
                k if k == STEPS => (ve, ve),
                _ => (0.0, l.vmax),
            };
            lp.add_var(0.0, bounds)
        })
        .collect();
    for w in v.windows(2) {
        lp.add_constraint([(w[1], 1.0), (w[0], -1.0)], ComparisonOp::Le, l.amax * dt);
        lp.add_constraint([(w[0], 1.0), (w[1], -1.0)], ComparisonOp::Le, l.dmax * dt);
    }
    let coeffs: Vec<_> = v
        .iter()
        .enumerate()
        .map(|(k, &var)| {
            let w = if k == 0 || k == STEPS { 0.5 } else { 1.0 };
            (var, w * dt)
        })
        .collect();
    lp.add_constraint(coeffs.as_slice(), ComparisonOp::Eq, dist);
    lp.solve().is_ok()
}

fn lim(vmax: f64, amax: f64, dmax: f64) -> Limits {
    Limits {
        vmax,
        amax,
        dmax,
        jmax: f64::INFINITY,
    }
}

/// Cases with a forward optimum: (start speed, end speed wanted, distance, limits).
/// Trapezoids, triangles, asymmetric limits, moving starts, blending ends.
fn cases() -> Vec<(f64, f64, f64, Limits)> {
    vec![
        (0.0, 0.0, 10.0, lim(2.0, 1.0, 1.0)),
        (0.0, 0.0, 1.0, lim(10.0, 1.0, 1.0)),
        (0.0, 0.0, 3.0, lim(10.0, 1.0, 2.0)),
        (0.0, 0.0, 50.0, lim(3.0, 0.5, 4.0)),
        (1.0, 0.0, 5.0, lim(2.0, 1.0, 1.0)),
        (2.0, 0.0, 2.5, lim(2.0, 1.0, 1.0)),
        (1.5, 0.0, 1.2, lim(3.0, 2.0, 1.0)),
        (0.0, 1.0, 10.0, lim(2.0, 1.0, 1.0)),
        (0.5, 1.5, 0.8, lim(2.0, 1.0, 3.0)),
        (2.0, 2.0, 1.0, lim(2.0, 1.0, 1.0)),
        (1.0, 0.5, 7.0, lim(4.0, 0.3, 0.7)),
    ]
}

/// Deterministic pseudo-random forward cases (xorshift, fixed seed): start and wanted end
/// speed inside vmax, distance long enough to slow down without turning round.
fn random_cases(n: usize) -> Vec<(f64, f64, f64, Limits)> {
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let l = lim(0.5 + 4.0 * next(), 0.2 + 3.0 * next(), 0.2 + 3.0 * next());
            let u = l.vmax * next();
            let ve = if next() < 0.5 { 0.0 } else { l.vmax * next() };
            let stop = u * u / (2.0 * l.dmax);
            (u, ve, stop + 20.0 * next(), l)
        })
        .collect()
}

#[test]
fn trapezoid_plans_are_time_optimal_against_a_linear_program() {
    for (u, ve, dist, l) in cases().into_iter().chain(random_cases(20)) {
        let start = KinematicState {
            p: 0.0,
            v: u,
            a: 0.0,
            j: 0.0,
        };
        let p = plan_position(RampShape::Linear, start, dist, ve, &l).unwrap();
        let t = p.duration();
        let wanted = ve;
        let ve = p.end_state().v;
        // Forward only, so the LP's v >= 0 bound is no restriction.
        assert!(p.peaks().v <= l.vmax + 1e-12);
        for i in 0..=200 {
            assert!(p.sample(t * f64::from(i) / 200.0).v >= -1e-12);
        }
        assert!(
            !feasible(t * (1.0 - 1e-3), u, ve, dist, &l),
            "LP beats the planner: {u} → {ve} over {dist} with {l:?}: planned {t}"
        );
        if ve < wanted {
            // End speed cut to what the distance allows: a single full-acceleration ramp,
            // the only profile there is (a longer one reaching the same speed would cover
            // more distance), which the grid represents exactly.
            assert_eq!(p.segments().len(), 1);
            assert!(feasible(t, u, ve, dist, &l), "{u} → {ve} over {dist}");
        } else {
            assert!(
                feasible(t * (1.0 + 3.0 / STEPS as f64) + 1e-9, u, ve, dist, &l),
                "LP infeasible above the planned {t}: {u} → {ve} over {dist}"
            );
        }
    }
}
