//! Units ⇄ counts against exact integer references (moved from the kernel's mechanics
//! with the scaling).

use super::exact::{dyadic, mul_div_floor, scale2, Frac};
use super::*;
use proptest::prelude::*;

/// One period of 360 units (degrees).
const DEG: f64 = 360.0;

fn scaling(cpr: u32, motor: u32, load: u32, feed: f64, invert: bool) -> Scaling {
    Scaling::new(ScalingConfig {
        counts_per_motor_rev: cpr,
        motor_revs: motor,
        load_revs: load,
        units_per_load_rev: feed,
        invert,
    })
    .unwrap()
}

/// `⌊num / den + ½⌋` for exact integer references.
fn round_ref(num: i128, den: i128) -> i128 {
    (2 * num + den).div_euclid(2 * den)
}

// ---- Scaling ----

#[test]
fn scaling_is_exact_far_from_zero() {
    // 5 mm ball screw, 2:1 gear, 2^17 counts: 52428.8 counts per mm.
    let s = scaling(1 << 17, 2, 1, 5.0, false);
    for c in [0i64, 1, -1, 1_000_000_000, -1_000_000_007, 123_456_789_012] {
        assert_eq!(s.units_to_counts(s.counts_to_units(c)), c, "round trip {c}");
    }
    // Moving by whole millimetres 10^6 times lands on the exact count.
    let mut p = 0.0;
    for _ in 0..1_000_000 {
        p += 1.0;
    }
    assert_eq!(s.units_to_counts(p), 52_428_800_000);
}

#[test]
fn unit_steps_as_absolute_positions_never_drift() {
    // 200 counts/mm (1000 counts, 5 mm): every absolute position k·1 mm is exactly
    // 200·k counts, for all k up to 10^6.
    let s = scaling(1000, 1, 1, 5.0, false);
    let mut p = 0.0_f64;
    for k in 1..=1_000_000i64 {
        p += 1.0;
        assert_eq!(s.units_to_counts(p), 200 * k);
    }
    // 25/3 counts per degree (360°, gear 3:1 → 3000 counts per turn): 360° steps.
    let s = scaling(1000, 3, 1, 360.0, false);
    for k in [1i64, 7, 1000, 999_999, 1_000_000] {
        assert_eq!(s.units_to_counts(360.0 * k as f64), 3000 * k);
    }
    // A naive f64 factor is off for large positions: 8.333… · 3.6e8 rounds differently
    // only in the last bits, but exactness is the contract here.
    assert_eq!(s.units_to_counts(0.12), 1);
    assert_eq!(s.units_to_counts(-0.12), -1);
}

#[test]
fn rounding_is_half_up() {
    // 2 counts per unit: 0.25 units = 0.5 counts.
    let s = scaling(2, 1, 1, 1.0, false);
    assert_eq!(s.units_to_counts(0.25), 1);
    assert_eq!(s.units_to_counts(-0.25), 0);
    assert_eq!(s.units_to_counts(0.75), 2);
    assert_eq!(s.units_to_counts(-0.75), -1);
    assert_eq!(s.units_to_counts(0.2499999999999), 0);
    // Tiny values.
    assert_eq!(s.units_to_counts(1e-300), 0);
    assert_eq!(s.units_to_counts(-1e-300), 0);
    assert_eq!(s.units_to_counts(f64::MIN_POSITIVE / 4.0), 0);
    assert_eq!(s.units_to_counts(-0.0), 0);
}

#[test]
fn inverted_scaling_flips_counts() {
    let s = scaling(1 << 20, 1, 1, 360.0, true);
    assert_eq!(s.units_to_counts(360.0), -(1 << 20));
    assert_eq!(s.counts_to_units(-(1 << 20)), 360.0);
    assert_eq!(s.velocity_to_counts(360.0), -((1 << 20) as f64));
    assert_eq!(s.velocity_to_units(-((1 << 20) as f64)), 360.0);
    // The default scaling is the same, not inverted.
    assert_eq!(Scaling::default().units_to_counts(360.0), 1 << 20);
    assert_eq!(
        Scaling::default(),
        Scaling::new(ScalingConfig::default()).unwrap()
    );
}

#[test]
fn velocities_scale_by_counts_per_unit() {
    let s = scaling(10_000, 3, 1, 5.0, false);
    assert_eq!(s.counts_per_unit(), 6000.0);
    assert_eq!(s.velocity_to_counts(2.5), 15_000.0);
    assert_eq!(s.velocity_to_units(15_000.0), 2.5);
}

#[test]
fn bad_scaling_names_the_field() {
    let cfg = ScalingConfig::default();
    for (c, field) in [
        (
            ScalingConfig {
                counts_per_motor_rev: 0,
                ..cfg
            },
            "counts_per_motor_rev",
        ),
        (
            ScalingConfig {
                motor_revs: 0,
                ..cfg
            },
            "motor_revs",
        ),
        (
            ScalingConfig {
                load_revs: 0,
                ..cfg
            },
            "load_revs",
        ),
    ] {
        assert_eq!(
            Scaling::new(c),
            Err(ScalingError::BadScaling { field, value: 0.0 })
        );
    }
    for feed in [0.0, -5.0, f64::NAN, f64::INFINITY, 1e-320] {
        let r = Scaling::new(ScalingConfig {
            units_per_load_rev: feed,
            ..cfg
        });
        assert!(
            matches!(
                r,
                Err(ScalingError::BadScaling {
                    field: "units_per_load_rev",
                    ..
                })
            ),
            "{feed}: {r:?}"
        );
    }
}

#[test]
fn out_of_range_positions_are_errors_or_saturate() {
    let s = scaling(1 << 20, 1, 1, 360.0, false);
    assert!(matches!(
        s.try_units_to_counts(f64::NAN),
        Err(ScalingError::NotFinite { .. })
    ));
    assert_eq!(
        s.try_units_to_counts(1e30),
        Err(ScalingError::CountsOutOfRange { value: 1e30 })
    );
    assert_eq!(s.units_to_counts(1e30), i64::MAX);
    assert_eq!(s.units_to_counts(-1e30), i64::MIN);
    assert_eq!(s.units_to_counts(f64::INFINITY), i64::MAX);
    assert_eq!(s.units_to_counts(f64::NAN), 0);
    assert_eq!(s.units_to_counts(f64::MAX), i64::MAX);
    let inv = scaling(1 << 20, 1, 1, 360.0, true);
    assert_eq!(inv.units_to_counts(1e30), i64::MIN);
    // The largest counts survive.
    assert!(s.counts_to_units(i64::MAX).is_finite());
    assert!(inv.counts_to_units(i64::MIN).is_finite());
}

#[test]
fn dyadic_decomposition_is_exact() {
    for x in [
        1.0,
        0.1,
        -3.5,
        360.0,
        5.0,
        f64::MIN_POSITIVE,
        5e-324,
        f64::MAX,
        -0.0,
    ] {
        let (m, e) = dyadic(x);
        assert_eq!(scale2(m as f64, e), x, "{x}");
        assert!(m == 0 || m % 2 != 0);
    }
    assert_eq!(dyadic(360.0), (45, 3));
    assert_eq!(dyadic(-0.75), (-3, -2));
}

#[test]
fn wide_products_divide_exactly() {
    // (2^63 · (2^126 − 1)) / (2^126 − 3): the 192-bit path.
    let b = (1u128 << 126) - 1;
    let c = (1u128 << 126) - 3;
    let s = mul_div_floor(1i128 << 63, b, c).unwrap();
    // = 2^63 · (1 + 2/c) = 2^63 + 2^64/c → floor 2^63, remainder 2^64.
    assert_eq!(s.q, 1i128 << 63);
    assert!(matches!(s.frac, Frac::Exact { r, d } if r == 1u128 << 64 && d == c));
    let s = mul_div_floor(-(1i128 << 63), b, c).unwrap();
    assert_eq!(s.q, -(1i128 << 63) - 1);
    assert_eq!(mul_div_floor(7, 3, 2).unwrap().q, 10);
    assert_eq!(mul_div_floor(-7, 3, 2).unwrap().q, -11);
    assert!(mul_div_floor(1 << 62, 1 << 126, 1).is_none());
}

// ---- ModuloCounts ----

#[test]
fn modulo_turns_convert_without_accumulated_error() {
    // 360° per load rev, gear 1:3 (one motor rev per three turns), 1000 counts per
    // motor rev: 333⅓ counts per turn, not an integer.
    let s = scaling(1000, 1, 3, 360.0, false);
    let mc = ModuloCounts::new(s, DEG).unwrap();
    assert_eq!(mc.counts_per_period(), (1000, 3));
    // 10^6 turns · 1000/3 = 333_333_333.33… → 333_333_333.
    assert_eq!(mc.to_counts(1_000_000, 0.0), 333_333_333);
    assert_eq!(mc.to_counts(1_000_001, 0.0), 333_333_667);
    assert_eq!(mc.to_counts(-1_000_000, 0.0), -333_333_333);
    assert_eq!(mc.to_counts(1_000_000, 180.0), 333_333_500);
    // Every turn count up to 10^5 and around 10^6, 10^12, 10^15 against integer math.
    let check = |n: i64| {
        assert_eq!(
            i128::from(mc.to_counts(n, 0.0)),
            round_ref(i128::from(n) * 1000, 3),
            "turns {n}"
        );
    };
    (-100_000..=100_000).for_each(check);
    for base in [1_000_000i64, 1_000_000_000_000, 1_000_000_000_000_000] {
        (base - 10..base + 10).for_each(check);
        (-base - 10..-base + 10).for_each(check);
    }
    // Gear 3:1: 3000 counts per turn.
    let mc = ModuloCounts::new(scaling(1000, 3, 1, 360.0, false), DEG).unwrap();
    assert_eq!(mc.to_counts(1_000_000, 0.0), 3_000_000_000);
    assert_eq!(mc.to_counts(1_000_000, 90.0), 3_000_000_750);
}

#[test]
fn modulo_counts_round_half_up_at_exact_ties() {
    // 1001 counts per rev, gear 1:2: 500.5 counts per turn.
    let mc = ModuloCounts::new(scaling(1001, 1, 2, 360.0, false), DEG).unwrap();
    assert_eq!(mc.to_counts(1, 0.0), 501);
    assert_eq!(mc.to_counts(-1, 0.0), -500);
    assert_eq!(mc.to_counts(3, 0.0), 1502);
    assert_eq!(mc.to_counts(2_000_001, 0.0), 1_001_000_501);
    // Within-period ties too: 180° = 250.25 counts; 1 turn + 180° = 750.75 → 751.
    assert_eq!(mc.to_counts(1, 180.0), 751);
}

#[test]
fn modulo_counts_agree_with_scaling_and_invert() {
    let s = scaling(1 << 17, 7, 5, 360.0, true);
    let mc = ModuloCounts::new(s, DEG).unwrap();
    for w in [0.0, 0.1, 90.0, 359.9] {
        assert_eq!(mc.to_counts(0, w), s.units_to_counts(w), "{w}");
        for n in [-3i64, 1, 1000] {
            let direct = s.units_to_counts(360.0 * n as f64 + w);
            assert!((mc.to_counts(n, w) - direct).abs() <= 1, "{n} {w}");
        }
    }
    assert_eq!(
        mc.to_counts(5, 0.0),
        -i64::try_from(round_ref(5 * (1 << 17) * 7, 5)).unwrap()
    );
}

#[test]
fn modulo_counts_back_to_position() {
    let mc = ModuloCounts::new(scaling(1000, 1, 3, 360.0, false), DEG).unwrap();
    assert_eq!(mc.to_position(0), (0, 0.0));
    assert_eq!(mc.to_position(1000), (3, 0.0));
    let (n, w) = mc.to_position(333_333_500);
    assert_eq!(n, 1_000_000);
    assert!((w - 180.0).abs() < 1e-9, "{w}");
    let (n, w) = mc.to_position(-1);
    assert_eq!(n, -1);
    assert!((w - (360.0 - 1.08)).abs() < 1e-9, "{w}");
    let (n, _) = mc.to_position(i64::MIN);
    assert!(n < 0);
}

#[test]
fn modulo_counts_refuse_unusable_periods() {
    let s = scaling(1, 1, 1, 360.0, false);
    // A period of one degree at 1/360 count per degree: less than a count.
    assert!(matches!(
        ModuloCounts::new(s, 1.0),
        Err(ScalingError::CountsPerPeriodOutOfRange { .. })
    ));
    let s = scaling(1 << 20, 1, 1, 1e-30, false);
    assert!(ModuloCounts::new(s, 1e30).is_err());
    // The period itself must be a finite number > 0 (the kernel's `Modulo` rule).
    for period in [0.0, -360.0, f64::NAN, f64::INFINITY] {
        let e = ModuloCounts::new(scaling(1000, 1, 1, 360.0, false), period).unwrap_err();
        assert!(
            matches!(e, ScalingError::BadPeriod { .. }),
            "{period}: {e:?}"
        );
    }
    assert_eq!(
        ScalingError::BadPeriod { period: 0.0 }.to_string(),
        "modulo period 0 must be a finite number > 0"
    );
    let mc = ModuloCounts::new(scaling(1000, 1, 1, 360.0, false), DEG).unwrap();
    assert!(mc.try_to_counts(1, f64::NAN).is_err());
    assert!(mc.try_to_counts(i64::MAX, 0.0).is_err());
    assert_eq!(mc.to_counts(i64::MAX, 0.0), i64::MAX);
    assert_eq!(mc.to_counts(i64::MIN, 0.0), i64::MIN);
}

// ---- CountExtender ----

#[test]
fn count_extender_rides_through_wraps() {
    let mut e = CountExtender::default();
    assert_eq!(e.value(), None);
    assert_eq!(e.update(i32::MAX - 10), (i32::MAX - 10) as i64);
    assert_eq!(e.update(i32::MIN + 9), i32::MAX as i64 + 10);
    let mut raw = i32::MIN + 9;
    let mut expected = i32::MAX as i64 + 10;
    for _ in 0..10_000 {
        raw = raw.wrapping_add(1_000_000);
        expected += 1_000_000;
        assert_eq!(e.update(raw), expected);
    }
    assert!(expected > 10_000_000_000, "many wraps: {expected}");
    for _ in 0..20_000 {
        raw = raw.wrapping_sub(1_000_000);
        expected -= 1_000_000;
        assert_eq!(e.update(raw), expected);
    }
    assert_eq!(e.value(), Some(expected));
}

#[test]
fn count_extender_handles_the_extremes() {
    let mut e = CountExtender::new();
    assert_eq!(e.update(i32::MIN), i64::from(i32::MIN));
    assert_eq!(e.update(i32::MAX), i64::from(i32::MIN) - 1, "one step back");
    assert_eq!(e.update(i32::MIN), i64::from(i32::MIN));
    // Largest forward step: 2^31 − 1.
    assert_eq!(e.update(-1), i64::from(i32::MIN) + i64::from(i32::MAX));
    // 10^9-count steps up to 10^12.
    let mut e = CountExtender::new();
    let mut truth: i64 = 0;
    e.update(0);
    while truth < 1_000_000_000_000 {
        truth += 1_000_000_000;
        assert_eq!(e.update(truth as i32), truth);
    }
    // Rebase (a stored absolute position) and reset.
    e.rebase(42);
    assert_eq!(e.update(truth as i32 + 1), 43);
    e.reset();
    assert_eq!(e.update(7), 7);
    let mut fresh = CountExtender::new();
    fresh.rebase(-5_000_000_000);
    assert_eq!(fresh.value(), None);
    assert_eq!(fresh.update(123), -5_000_000_000);
    assert_eq!(fresh.update(124), -4_999_999_999);
}

#[test]
fn narrow_counters_wrap_at_their_width() {
    let mut e = CountExtender::with_width(16).unwrap();
    assert_eq!(e.update(65_530), 65_530);
    assert_eq!(e.update(5), 65_541);
    assert_eq!(e.update(65_535), 65_535);
    let mut e = CountExtender::with_width(24).unwrap();
    let mut truth: i64 = 0;
    e.update(0);
    for _ in 0..1000 {
        truth -= 3_000_000;
        assert_eq!(e.update(truth.rem_euclid(1 << 24) as i32), truth);
    }
    assert_eq!(
        CountExtender::with_width(1),
        Err(ScalingError::BadCounterWidth { bits: 1 })
    );
    assert!(CountExtender::with_width(33).is_err());
    assert_eq!(CountExtender::with_width(32), Ok(CountExtender::new()));
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 2000,
        rng_seed: proptest::test_runner::RngSeed::Fixed(11),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn counts_round_trip_exactly(
        c in prop_oneof![
            -4_000_000_000_000i64..4_000_000_000_000,
            -(1i64 << 50)..(1i64 << 50),
        ],
        cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100,
        feed in prop_oneof![0.1..1000.0f64, Just(360.0), Just(5.0)],
        invert: bool,
    ) {
        let s = scaling(cpr, mr, lr, feed, invert);
        prop_assert_eq!(s.units_to_counts(s.counts_to_units(c)), c);
    }

    #[test]
    fn units_to_counts_matches_integer_math_on_integer_positions(
        k in -1_000_000_000i64..1_000_000_000,
        cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100,
        feed in 1u32..1000,
    ) {
        // Integer positions and feed: counts = k · cpr · mr / (lr · feed), exactly.
        let s = scaling(cpr, mr, lr, f64::from(feed), false);
        let num = i128::from(k) * i128::from(cpr) * i128::from(mr);
        let den = i128::from(lr) * i128::from(feed);
        prop_assert_eq!(i128::from(s.units_to_counts(k as f64)), round_ref(num, den));
    }

    #[test]
    fn units_to_counts_rounds_to_the_nearest_count(
        p in prop_oneof![-1e6..1e6f64, -1.0..1.0f64],
        cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100,
        feed in prop_oneof![0.01..1000.0f64, Just(360.0), Just(0.1)],
        invert: bool,
    ) {
        // Against the f64 product: the exact count is within ½ of p · counts/unit, and the
        // f64 product is within a few ulp of that.
        let s = scaling(cpr, mr, lr, feed, invert);
        let c = s.units_to_counts(p) as f64;
        let x = s.velocity_to_counts(p);
        prop_assert!((c - x).abs() <= 0.5 + 1e-15 * x.abs().max(1.0), "{p}: {c} vs {x}");
    }

    #[test]
    fn modulo_counts_match_integer_math(
        n in prop_oneof![-1_000_000_000_000i64..1_000_000_000_000, -1000i64..1000],
        w in 0u32..360,
        cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100,
    ) {
        let s = scaling(cpr, mr, lr, 360.0, false);
        let mc = ModuloCounts::new(s, DEG).unwrap();
        let num = (i128::from(n) * 360 + i128::from(w)) * i128::from(cpr) * i128::from(mr);
        let den = i128::from(lr) * 360;
        let expect = round_ref(num, den);
        if i64::try_from(expect).is_err() {
            prop_assert!(mc.try_to_counts(n, f64::from(w)).is_err());
            return Ok(());
        }
        prop_assert_eq!(i128::from(mc.to_counts(n, f64::from(w))), expect);
        // And back: whole turns and the position within, to a count.
        let c = mc.to_counts(n, f64::from(w));
        let (n2, w2) = mc.to_position(c);
        let back = (n2 as f64 - n as f64) * 360.0 + (w2 - f64::from(w));
        prop_assert!(back.abs() <= 1.0 / s.counts_per_unit() + 1e-9, "{n} {w} → {n2} {w2}");
    }

    #[test]
    fn count_extender_tracks_random_walks(
        start in any::<i32>(),
        steps in proptest::collection::vec(-(i32::MAX as i64)..=(i32::MAX as i64), 1..200),
        bits in prop_oneof![Just(32u32), 8u32..32],
    ) {
        let mut e = CountExtender::with_width(bits).unwrap();
        let range = 1i64 << bits;
        let half = range / 2;
        let raw = |t: i64| if bits == 32 { t as i32 } else { t.rem_euclid(range) as i32 };
        let mut truth = if bits == 32 { i64::from(start) } else { i64::from(start).rem_euclid(range) };
        prop_assert_eq!(e.update(raw(truth)), truth);
        for s in steps {
            let s = s.clamp(-half + 1, half - 1);
            truth += s;
            prop_assert_eq!(e.update(raw(truth)), truth);
        }
    }
}
