//! Cam tables through the public API: every interpolation passes through every point,
//! linear derivatives, clamping, a known analytic case (sin over one period), and seeded
//! properties over random strictly increasing tables (continuity, finiteness, the maxima
//! bound every sample). Tests that need exact left/right limits at the points are next
//! to the code (`kernel/src/cam/tests.rs`). `eval` runs under a counting allocator.

use std::f64::consts::PI;

use gantry_kernel::cam::{CamError, CamPoint, CamSample, CamTable, Interpolation};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

mod counting {
    include!("common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

const ALL: [Interpolation; 3] = [
    Interpolation::Linear,
    Interpolation::Cubic,
    Interpolation::Quintic,
];

fn pts(v: &[(f64, f64)]) -> Vec<CamPoint> {
    v.iter()
        .map(|&(master, slave)| CamPoint { master, slave })
        .collect()
}

fn table() -> Vec<CamPoint> {
    pts(&[
        (-5.0, 2.0),
        (0.0, 0.0),
        (12.5, 3.25),
        (13.0, 3.3),
        (40.0, -7.0),
        (41.0, -7.0),
        (100.0, 1e3),
    ])
}

#[test]
fn every_interpolation_passes_through_every_point() {
    for i in ALL {
        for periodic in [false, true] {
            let t = CamTable::new(table(), i, periodic).unwrap();
            for p in t.points() {
                let s = t.eval(p.master).slave;
                assert!(
                    (s - p.slave).abs() <= 1e-12 * p.slave.abs().max(1.0),
                    "{i} periodic {periodic}: at {} got {s}, want {}",
                    p.master,
                    p.slave
                );
            }
        }
    }
}

#[test]
fn accessors_report_the_table() {
    let t = CamTable::new(table(), Interpolation::Quintic, true).unwrap();
    assert_eq!(t.points(), table().as_slice());
    assert_eq!(t.interpolation(), Interpolation::Quintic);
    assert!(t.is_periodic());
    assert_eq!(t.master_range(), (-5.0, 100.0));
    assert_eq!(t.slave_rise(), 998.0);
}

#[test]
fn linear_derivative_is_the_slope_of_the_segment_to_the_right() {
    let t = CamTable::new(table(), Interpolation::Linear, false).unwrap();
    let mid = t.eval(6.25);
    assert_eq!(mid.slave, 1.625);
    assert_eq!(mid.d1, 3.25 / 12.5);
    assert_eq!(mid.d2, 0.0);
    // At a point: the segment to its right.
    assert!((t.eval(12.5).d1 - 0.05 / 0.5).abs() < 1e-12);
    // At the last point (and beyond): the last segment's.
    assert_eq!(t.eval(100.0).d1, 1007.0 / 59.0);
    assert_eq!(t.eval(1e9).d1, 1007.0 / 59.0);
}

#[test]
fn eval_clamps_into_the_master_range() {
    for i in ALL {
        let t = CamTable::new(table(), i, false).unwrap();
        assert_eq!(t.eval(-1e9), t.eval(-5.0), "{i}");
        assert_eq!(t.eval(f64::NEG_INFINITY), t.eval(-5.0), "{i}");
        assert_eq!(t.eval(1e9), t.eval(100.0), "{i}");
        assert_eq!(t.eval(f64::INFINITY).slave, 1e3, "{i}");
        assert!(t.eval(f64::NAN).slave.is_nan(), "{i}: NaN in, NaN out");
    }
}

/// eval is called every cycle: no allocation, for every interpolation, inside and outside
/// the range and at the points (the counter watches this thread only).
#[test]
fn eval_does_not_allocate() {
    let tables: Vec<CamTable> = ALL
        .iter()
        .flat_map(|&i| [false, true].map(|p| CamTable::new(table(), i, p).unwrap()))
        .collect();
    let mut sum = 0.0;
    counting::watch(true);
    for t in &tables {
        for k in -100..=1100 {
            let s = t.eval(-5.0 + 0.105 * k as f64);
            sum += s.slave + s.d1 + s.d2;
        }
        for p in t.points() {
            sum += t.eval(p.master).slave;
        }
    }
    counting::watch(false);
    assert_eq!(counting::take_count(), 0, "eval allocated");
    assert!(sum.is_finite());
}

/// sin sampled at `n` equal steps over one period, both ends included.
fn sine(n: usize) -> Vec<CamPoint> {
    (0..=n)
        .map(|k| {
            let master = 2.0 * PI * k as f64 / n as f64;
            CamPoint {
                master,
                slave: if k == n { 0.0 } else { master.sin() },
            }
        })
        .collect()
}

/// Largest error vs sin, cos, -sin over 100 samples per segment.
fn sine_errors(t: &CamTable, n: usize) -> (f64, f64, f64) {
    let mut e = (0.0_f64, 0.0_f64, 0.0_f64);
    for k in 0..=100 * n {
        let x = 2.0 * PI * k as f64 / (100 * n) as f64;
        let s = t.eval(x);
        e.0 = e.0.max((s.slave - x.sin()).abs());
        e.1 = e.1.max((s.d1 - x.cos()).abs());
        e.2 = e.2.max((s.d2 + x.sin()).abs());
    }
    e
}

/// A periodic spline of a periodic function is the complete spline, whose errors are
/// bounded by 5/384 h⁴ max|f⁗| for the value and h³/24 max|f⁗| for d1 (Hall & Meyer,
/// "Optimal error bounds for cubic spline interpolation", J. Approx. Theory 16, 1976);
/// max|sin⁗| = 1. With 16 segments, h = π/8: 3.1e-4 and 2.5e-3;
/// measured 6.3e-5 and 4.9e-4 (d2: 1.3e-2 against 5.8e-2).
#[test]
fn periodic_cubic_through_sin_is_within_the_spline_error_bound() {
    for n in [8, 16, 64] {
        let t = CamTable::new(sine(n), Interpolation::Cubic, true).unwrap();
        let h = 2.0 * PI / n as f64;
        let (e0, e1, e2) = sine_errors(&t, n);
        assert!(e0 <= 5.0 / 384.0 * h.powi(4), "n {n}: value error {e0}");
        assert!(e1 <= h.powi(3) / 24.0, "n {n}: d1 error {e1}");
        // d2 error is O(h²) (3/8 h² for the complete spline's second derivative).
        assert!(e2 <= 3.0 / 8.0 * h * h, "n {n}: d2 error {e2}");
        // The maxima are those of cos and -sin, within the same bounds.
        assert!(
            (t.max_d1() - 1.0).abs() <= h.powi(3) / 24.0,
            "n {n}: {}",
            t.max_d1()
        );
        assert!(
            (t.max_d2() - 1.0).abs() <= 3.0 / 8.0 * h * h,
            "n {n}: {}",
            t.max_d2()
        );
        println!(
            "cubic n {n}: errors {e0:.2e} {e1:.2e} {e2:.2e}, h⁴ {:.2e}",
            h.powi(4)
        );
    }
}

/// Quintic with local-parabola point derivatives through sin: d1 at the points is the
/// parabola's (error h²/6 max|f'''|), so the value error is O(h³) rather than the spline's
/// O(h⁴), d1 O(h²) and d2 O(h); bounded here by h³/10, h²/2 and h (measured h³/40,
/// h²/6 and 0.95 h at n = 16 and 64: the price of locality and exact dwells).
#[test]
fn periodic_quintic_through_sin_converges() {
    for n in [16, 64] {
        let t = CamTable::new(sine(n), Interpolation::Quintic, true).unwrap();
        let h = 2.0 * PI / n as f64;
        let (e0, e1, e2) = sine_errors(&t, n);
        assert!(e0 <= h.powi(3) / 10.0, "n {n}: value error {e0}");
        assert!(e1 <= h * h / 2.0, "n {n}: d1 error {e1}");
        assert!(e2 <= h, "n {n}: d2 error {e2}");
        println!(
            "quintic n {n}: errors {e0:.2e} {e1:.2e} {e2:.2e}, h³ {:.2e}",
            h.powi(3)
        );
    }
}

#[test]
fn errors_come_back_from_new() {
    assert_eq!(
        CamTable::new(Vec::new(), Interpolation::Cubic, false),
        Err(CamError::TooFewPoints { count: 0 })
    );
    let err = CamTable::new(
        pts(&[(0.0, 0.0), (1.0, 1.0), (0.5, 2.0)]),
        Interpolation::Linear,
        false,
    )
    .unwrap_err();
    assert_eq!(
        err.to_string(),
        "cam points 1 and 2: master positions must strictly increase, got 1 then 0.5"
    );
}

fn config(cases: u32, seed: u64) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// A random strictly increasing table: 2 to 24 points, steps 0.01 to 10, slaves -100 to
/// 100 with some repeated (dwells); sometimes a larger master offset.
fn arb_table() -> impl Strategy<Value = Vec<CamPoint>> {
    (
        prop::collection::vec((0.01f64..10.0, -100.0f64..100.0, 0u8..4), 2..24),
        prop_oneof![Just(0.0), -1e3f64..1e3],
    )
        .prop_map(|(steps, start)| {
            let mut master = start;
            let mut previous = 0.0;
            steps
                .into_iter()
                .map(|(step, slave, repeat)| {
                    master += step;
                    let slave = if repeat == 0 { previous } else { slave };
                    previous = slave;
                    CamPoint { master, slave }
                })
                .collect()
        })
}

fn arb_interpolation() -> impl Strategy<Value = Interpolation> {
    prop_oneof![
        Just(Interpolation::Linear),
        Just(Interpolation::Cubic),
        Just(Interpolation::Quintic)
    ]
}

fn build(points: Vec<CamPoint>, i: Interpolation, periodic: bool) -> Option<CamTable> {
    let n = points.len();
    match CamTable::new(points, i, periodic) {
        Ok(t) => Some(t),
        Err(CamError::PeriodicTooFewPoints { count, .. }) => {
            assert!(periodic && i != Interpolation::Linear && count == n && n < 3);
            None
        }
        Err(e) => panic!("a valid table refused: {e}"),
    }
}

fn finite(s: CamSample) -> bool {
    s.slave.is_finite() && s.d1.is_finite() && s.d2.is_finite()
}

proptest! {
    #![proptest_config(config(400, 0xca11))]

    /// Mean value theorem: a step dx moves the slave by at most max_d1·|dx| (and d1 by at
    /// most max_d2·|dx| for the C2 interpolations), so eval is continuous with the maxima
    /// as its Lipschitz constants; every sample is finite.
    #[test]
    fn eval_is_continuous_and_finite(
        points in arb_table(),
        i in arb_interpolation(),
        periodic in any::<bool>(),
        at in 0.0f64..1.0,
        dx in 1e-9f64..1e-3,
    ) {
        let Some(t) = build(points, i, periodic) else { return Ok(()) };
        let (lo, hi) = t.master_range();
        let x = lo + at * (hi - lo);
        let (a, b) = (t.eval(x), t.eval(x + dx));
        prop_assert!(finite(a) && finite(b), "{a:?} {b:?}");
        let slack = 1e-9 * (1.0 + a.slave.abs());
        prop_assert!((b.slave - a.slave).abs() <= t.max_d1() * dx * (1.0 + 1e-9) + slack,
            "slave {} → {} over {dx}, max_d1 {}", a.slave, b.slave, t.max_d1());
        if i != Interpolation::Linear {
            let slack = 1e-7 * (1.0 + a.d1.abs());
            prop_assert!((b.d1 - a.d1).abs() <= t.max_d2() * dx * (1.0 + 1e-9) + slack,
                "d1 {} → {} over {dx}, max_d2 {}", a.d1, b.d1, t.max_d2());
        }
    }

    /// `eval_near` gives exactly what `eval` gives, whatever the hint and wherever the
    /// next position is (forward, backwards, far, at the points, outside the table).
    #[test]
    fn eval_near_is_eval_whatever_the_hint(
        points in arb_table(),
        i in arb_interpolation(),
        periodic in any::<bool>(),
        walk in prop::collection::vec(-0.2f64..1.2, 1..60),
        hint0 in any::<usize>(),
    ) {
        let Some(t) = build(points, i, periodic) else { return Ok(()) };
        let (lo, hi) = t.master_range();
        let mut hint = hint0;
        let xs = walk
            .iter()
            .map(|a| lo + a * (hi - lo))
            .chain(t.points().iter().map(|p| p.master));
        for x in xs {
            let (a, b) = (t.eval(x), t.eval_near(x, &mut hint));
            prop_assert_eq!(a, b, "at {}", x);
        }
    }

    /// The maxima bound |d1| and |d2| at 200 samples per segment and at every point, and
    /// each is reached (to 1%) somewhere on the dense grid.
    #[test]
    fn maxima_bound_every_sample(
        points in arb_table(),
        i in arb_interpolation(),
        periodic in any::<bool>(),
    ) {
        let Some(t) = build(points, i, periodic) else { return Ok(()) };
        let (mut d1, mut d2) = (0.0_f64, 0.0_f64);
        for w in t.points().windows(2) {
            for k in 0..=200 {
                let s = t.eval(w[0].master + (w[1].master - w[0].master) * k as f64 / 200.0);
                prop_assert!(finite(s));
                d1 = d1.max(s.d1.abs());
                d2 = d2.max(s.d2.abs());
            }
        }
        prop_assert!(t.max_d1().is_finite() && t.max_d2().is_finite());
        prop_assert!(d1 <= t.max_d1() * (1.0 + 1e-9) + 1e-12, "sampled {d1} > max_d1 {}", t.max_d1());
        prop_assert!(d2 <= t.max_d2() * (1.0 + 1e-9) + 1e-12, "sampled {d2} > max_d2 {}", t.max_d2());
        prop_assert!(d1 >= t.max_d1() * 0.99 - 1e-12, "max_d1 {} never reached ({d1})", t.max_d1());
        prop_assert!(d2 >= t.max_d2() * 0.99 - 1e-12, "max_d2 {} never reached ({d2})", t.max_d2());
    }

    /// Every point is reproduced exactly (to 1e-12 relative), whatever the interpolation.
    #[test]
    fn random_tables_pass_through_their_points(
        points in arb_table(),
        i in arb_interpolation(),
        periodic in any::<bool>(),
    ) {
        let Some(t) = build(points, i, periodic) else { return Ok(()) };
        for p in t.points() {
            let s = t.eval(p.master).slave;
            prop_assert!((s - p.slave).abs() <= 1e-12 * p.slave.abs().max(1.0), "{s} vs {}", p.slave);
        }
    }
}
