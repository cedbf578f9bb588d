//! Unit tests that need the segments (exact left and right limits at the points); the
//! public-API properties are in `kernel/tests/cam_table.rs`.

use super::*;

fn pts(v: &[(f64, f64)]) -> Vec<CamPoint> {
    v.iter()
        .map(|&(master, slave)| CamPoint { master, slave })
        .collect()
}

/// A bumpy non-uniform table: rises, a dwell, a fall, a negative slave.
fn bumpy() -> Vec<CamPoint> {
    pts(&[
        (0.0, 0.0),
        (10.0, 4.0),
        (25.0, 4.0),
        (31.0, 9.5),
        (50.0, -2.0),
        (62.5, 1.0),
        (90.0, 0.0),
    ])
}

const ALL: [Interpolation; 3] = [
    Interpolation::Linear,
    Interpolation::Cubic,
    Interpolation::Quintic,
];

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

/// (left limit, right limit) of the samples at every interior point.
fn limits_at_interior_points(t: &CamTable) -> Vec<(CamSample, CamSample)> {
    t.segments
        .windows(2)
        .map(|w| (w[0].sample_u(1.0), w[1].sample_u(0.0)))
        .collect()
}

#[test]
fn names_round_trip_and_aliases() {
    for i in ALL {
        assert_eq!(Interpolation::from_name(i.name()), Some(i));
        assert_eq!(i.to_string(), i.name());
    }
    assert_eq!(
        Interpolation::from_name("5th-order"),
        Some(Interpolation::Quintic)
    );
    assert_eq!(
        Interpolation::from_name("Poly5"),
        Some(Interpolation::Quintic)
    );
    assert_eq!(Interpolation::from_name("spline"), None);
}

#[test]
fn cubic_is_c2_at_interior_points() {
    for periodic in [false, true] {
        let t = CamTable::new(bumpy(), Interpolation::Cubic, periodic).unwrap();
        for (i, (l, r)) in limits_at_interior_points(&t).iter().enumerate() {
            assert!(
                close(l.slave, r.slave, 1e-12),
                "point {}: {l:?} {r:?}",
                i + 1
            );
            assert!(close(l.d1, r.d1, 1e-9), "point {}: {l:?} {r:?}", i + 1);
            assert!(close(l.d2, r.d2, 1e-9), "point {}: {l:?} {r:?}", i + 1);
        }
    }
}

#[test]
fn quintic_is_c2_at_interior_points_and_matches_its_point_derivatives() {
    for periodic in [false, true] {
        let points = bumpy();
        let knots = knots::local_parabolas(&points, periodic);
        let t = CamTable::new(points, Interpolation::Quintic, periodic).unwrap();
        for (i, (l, r)) in limits_at_interior_points(&t).iter().enumerate() {
            let (d1, d2) = knots[i + 1];
            assert!(close(l.slave, r.slave, 1e-12), "point {}", i + 1);
            for (got, want) in [(l.d1, d1), (r.d1, d1), (l.d2, d2), (r.d2, d2)] {
                assert!(close(got, want, 1e-9), "point {}: {got} vs {want}", i + 1);
            }
        }
    }
}

#[test]
fn natural_cubic_has_zero_d2_at_both_ends() {
    let t = CamTable::new(bumpy(), Interpolation::Cubic, false).unwrap();
    let first = t.segments.first().unwrap().sample_u(0.0);
    let last = t.segments.last().unwrap().sample_u(1.0);
    assert!(first.d2.abs() < 1e-12, "{first:?}");
    assert!(last.d2.abs() < 1e-12, "{last:?}");
    assert_eq!(t.eval(90.0).d2, 0.0);
}

#[test]
fn periodic_end_conditions_hold_for_cubic_and_quintic() {
    // A rising periodic table: slave gains 7 per period.
    let points = pts(&[(0.0, 0.0), (30.0, 5.0), (55.0, 4.0), (100.0, 7.0)]);
    for i in [Interpolation::Cubic, Interpolation::Quintic] {
        let t = CamTable::new(points.clone(), i, true).unwrap();
        assert_eq!(t.slave_rise(), 7.0);
        let start = t.segments.first().unwrap().sample_u(0.0);
        let end = t.segments.last().unwrap().sample_u(1.0);
        assert!(close(start.d1, end.d1, 1e-9), "{i}: {start:?} {end:?}");
        assert!(close(start.d2, end.d2, 1e-9), "{i}: {start:?} {end:?}");
        // What eval reports at both ends (the end from the point data, not the segment).
        let (a, b) = (t.eval(0.0), t.eval(100.0));
        assert!(
            close(a.d1, b.d1, 1e-12) && close(a.d2, b.d2, 1e-12),
            "{a:?} {b:?}"
        );
    }
}

#[test]
fn periodic_cubic_with_three_points_uses_the_two_unknown_system() {
    let points = pts(&[(0.0, 0.0), (1.0, 1.0), (3.0, 0.0)]);
    let t = CamTable::new(points, Interpolation::Cubic, true).unwrap();
    let (l, r) = limits_at_interior_points(&t)[0];
    assert!(close(l.d1, r.d1, 1e-12) && close(l.d2, r.d2, 1e-12));
    let start = t.eval(0.0);
    let end = t.segments[1].sample_u(1.0);
    assert!(close(start.d1, end.d1, 1e-12) && close(start.d2, end.d2, 1e-12));
}

#[test]
fn quintic_dwells_are_flat_and_rises_between_them_are_3_4_5() {
    // Dwell 0..90 at 0, rise to 100 at 180, dwell to 270, fall back by 360.
    let points = pts(&[
        (0.0, 0.0),
        (90.0, 0.0),
        (180.0, 100.0),
        (270.0, 100.0),
        (360.0, 0.0),
    ]);
    let t = CamTable::new(points, Interpolation::Quintic, true).unwrap();
    for x in [0.0, 17.0, 45.0, 89.999] {
        assert_eq!(t.eval(x).slave, 0.0, "dwell at {x}");
    }
    for x in [180.0, 200.0, 269.0] {
        assert_eq!(t.eval(x).slave, 100.0, "dwell at {x}");
    }
    // 3-4-5 polynomial: s(u) = 100 (10u³ - 15u⁴ + 6u⁵); at u = 1/2 it is 50, d1 peaks
    // there at 100 · 15/8 / 90 per degree.
    let mid = t.eval(135.0);
    assert!(close(mid.slave, 50.0, 1e-12), "{mid:?}");
    assert!(close(mid.d1, 100.0 * 15.0 / 8.0 / 90.0, 1e-12), "{mid:?}");
    assert!(close(t.max_d1(), 100.0 * 15.0 / 8.0 / 90.0, 1e-12));
    // Peak d2 of 3-4-5 is 10/√3 · Δs / h² at u = (3 - √3)/6.
    let want_d2 = 10.0 / 3f64.sqrt() * 100.0 / (90.0 * 90.0);
    assert!(
        close(t.max_d2(), want_d2, 1e-9),
        "{} vs {want_d2}",
        t.max_d2()
    );
}

#[test]
fn linear_max_derivatives_are_the_steepest_slope_and_zero() {
    let t = CamTable::new(bumpy(), Interpolation::Linear, false).unwrap();
    assert_eq!(t.max_d1(), 5.5 / 6.0); // 25 → 31: 4 → 9.5
    assert_eq!(t.max_d2(), 0.0);
}

#[test]
fn every_error_names_the_point() {
    let cases: Vec<(Vec<CamPoint>, Interpolation, bool, CamError, &str)> = vec![
        (
            pts(&[(0.0, 1.0)]),
            Interpolation::Linear,
            false,
            CamError::TooFewPoints { count: 1 },
            "at least 2 points, got 1",
        ),
        (
            pts(&[(0.0, 0.0), (1.0, f64::NAN), (2.0, 0.0)]),
            Interpolation::Cubic,
            false,
            CamError::NotFinite {
                index: 1,
                master: 1.0,
                slave: f64::NAN,
            },
            "cam point 1 (master 1, slave NaN)",
        ),
        (
            pts(&[(0.0, 0.0), (1.0, 0.0), (f64::INFINITY, 0.0)]),
            Interpolation::Cubic,
            false,
            CamError::NotFinite {
                index: 2,
                master: f64::INFINITY,
                slave: 0.0,
            },
            "cam point 2",
        ),
        (
            pts(&[(0.0, 0.0), (2.0, 0.0), (2.0, 1.0)]),
            Interpolation::Linear,
            false,
            CamError::NotIncreasing {
                index: 2,
                previous_master: 2.0,
                master: 2.0,
            },
            "cam points 1 and 2: master positions must strictly increase, got 2 then 2",
        ),
        (
            pts(&[(0.0, 0.0), (3.0, 0.0), (1.0, 1.0)]),
            Interpolation::Quintic,
            false,
            CamError::NotIncreasing {
                index: 2,
                previous_master: 3.0,
                master: 1.0,
            },
            "got 3 then 1",
        ),
        (
            pts(&[(0.0, 0.0), (1.0, 1.0)]),
            Interpolation::Cubic,
            true,
            CamError::PeriodicTooFewPoints {
                interpolation: Interpolation::Cubic,
                count: 2,
            },
            "periodic cubic cam table needs at least 3 points, got 2",
        ),
        (
            pts(&[(0.0, 0.0), (1.0, 1.0)]),
            Interpolation::Quintic,
            true,
            CamError::PeriodicTooFewPoints {
                interpolation: Interpolation::Quintic,
                count: 2,
            },
            "periodic quintic",
        ),
        (
            pts(&[(0.0, 0.0), (1e-320, 1e300), (1.0, 0.0)]),
            Interpolation::Linear,
            false,
            CamError::Degenerate {
                index: 0,
                master_from: 0.0,
                master_to: 1e-320,
            },
            "between points 0 and 1",
        ),
    ];
    for (points, i, periodic, want, text) in cases {
        let err = CamTable::new(points, i, periodic).unwrap_err();
        // NaN != NaN: compare the message for that case, the value for the others.
        if !matches!(err, CamError::NotFinite { slave, .. } if slave.is_nan()) {
            assert_eq!(err, want);
        }
        assert!(err.to_string().contains(text), "{err} lacks {text:?}");
    }
    let too_many = (0..=MAX_POINTS)
        .map(|i| CamPoint {
            master: i as f64,
            slave: 0.0,
        })
        .collect();
    assert_eq!(
        CamTable::new(too_many, Interpolation::Linear, false),
        Err(CamError::TooManyPoints {
            count: MAX_POINTS + 1,
            max: MAX_POINTS
        })
    );
}

#[test]
fn periodic_linear_with_two_points_is_a_ramp() {
    let t = CamTable::new(pts(&[(0.0, 0.0), (2.0, 1.0)]), Interpolation::Linear, true).unwrap();
    assert_eq!(
        t.eval(1.0),
        CamSample {
            slave: 0.5,
            d1: 0.5,
            d2: 0.0
        }
    );
}

#[test]
fn explicit_derivatives_are_matched_and_checked() {
    let points = pts(&[(0.0, 0.0), (1.0, 1.0), (2.0, 0.0)]);
    let d = [(0.0, 0.0), (0.5, -3.0), (0.0, 0.0)];
    let t = CamTable::with_derivatives(points.clone(), &d, true).unwrap();
    assert_eq!(t.interpolation(), Interpolation::Quintic);
    let at1 = t.eval(1.0);
    assert_eq!(at1.slave, 1.0);
    assert!(
        close(at1.d1, 0.5, 1e-12) && close(at1.d2, -3.0, 1e-12),
        "{at1:?}"
    );
    let left = t.segments[0].sample_u(1.0);
    assert!(close(left.d1, 0.5, 1e-12) && close(left.d2, -3.0, 1e-12));

    assert_eq!(
        CamTable::with_derivatives(points.clone(), &d[..2], false),
        Err(CamError::DerivativeCount {
            points: 3,
            derivatives: 2
        })
    );
    let bad = [(0.0, 0.0), (f64::INFINITY, 0.0), (0.0, 0.0)];
    assert!(matches!(
        CamTable::with_derivatives(points.clone(), &bad, false),
        Err(CamError::DerivativeNotFinite { index: 1, .. })
    ));
    let unequal = [(1.0, 0.0), (0.0, 0.0), (0.0, 0.0)];
    assert_eq!(
        CamTable::with_derivatives(points.clone(), &unequal, true),
        Err(CamError::PeriodicDerivativesDiffer {
            first_d1: 1.0,
            first_d2: 0.0,
            last_d1: 0.0,
            last_d2: 0.0
        })
    );
    assert!(CamTable::with_derivatives(points, &unequal, false).is_ok());
}
