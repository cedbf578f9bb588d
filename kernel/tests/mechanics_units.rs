//! Mechanics and units through the public API (SPEC §1, seed 000 §3): the seed's modulo
//! examples, long travel without drift, a modulo axis turning for a long time with a
//! wrapping 32-bit drive counter in the loop, and actual positions reported on the set
//! value's side of the wrap.

use gantry_kernel::mechanics::{
    CountExtender, Direction, Mechanics, MechanicsError, Modulo, ModuloCounts, MotionKind, Scaling,
    ScalingConfig,
};

fn scaling(cpr: u32, motor: u32, load: u32, feed: f64, invert: bool) -> Scaling {
    Scaling::new(ScalingConfig {
        counts_per_motor_rev: cpr,
        motor_revs: motor,
        load_revs: load,
        units_per_load_rev: feed,
        invert,
    })
    .expect("valid scaling")
}

#[test]
fn seed_000_modulo_positioning_examples() {
    let m = Modulo::new(360.0).unwrap();
    assert_eq!(
        m.delta_positive(50.0, 40.0),
        350.0,
        "AbsModuloPos 50° → 40°"
    );
    assert_eq!(
        m.delta_negative(40.0, 50.0),
        -350.0,
        "AbsModuloNeg 40° → 50°"
    );
    assert_eq!(
        m.delta_shortest(40.0, 50.0),
        10.0,
        "AbsModuloAuto 40° → 50°"
    );
    // KeepDirection: the last move went positive (40° → 50°), the next target 20°.
    assert_eq!(m.delta_keep(50.0, 20.0, 1.0), 330.0);
    assert_eq!(m.delta_keep(40.0, 20.0, 1.0), 340.0);
}

#[test]
fn one_way_axes_refuse_the_other_direction_with_a_clear_error() {
    let mech = Mechanics {
        kind: MotionKind::Rotary,
        modulo: Modulo::new(360.0),
        direction: Direction::PositiveOnly,
        software_limits: None,
    };
    mech.validate().unwrap();
    let m = mech.modulo.unwrap();
    let d = m.delta_shortest(40.0, 20.0);
    let err = mech.check_direction(d).unwrap_err();
    assert_eq!(
        err,
        MechanicsError::DirectionNotAllowed {
            delta: -20.0,
            allowed: Direction::PositiveOnly
        }
    );
    assert_eq!(
        err.to_string(),
        "a move by -20 is not allowed: direction is positive only"
    );
    assert!(mech.check_direction(m.delta_positive(40.0, 20.0)).is_ok());
}

#[test]
fn ball_screw_long_travel_is_exact() {
    // 5 mm lead, 10000 counts per motor rev, gear 7:3: 4666⅔ counts per mm.
    let s = scaling(10_000, 7, 3, 5.0, false);
    // Every half millimetre out to 1000 mm, as absolute positions: the count is the exact
    // rounded rational p · 14000/3.
    for k in 0..=2000i64 {
        let p = k as f64 * 0.5;
        let exact = (2 * k * 70_000 + 30).div_euclid(2 * 30);
        assert_eq!(s.units_to_counts(p), exact, "{p} mm");
    }
    // Far out: 10^9 counts and back is exact, and so are 10^9 mm.
    for c in [1_000_000_000i64, -1_000_000_000, 4_000_000_000_000] {
        assert_eq!(s.units_to_counts(s.counts_to_units(c)), c);
    }
    assert_eq!(s.units_to_counts(1e9), 4_666_666_666_667);
    assert_eq!(s.units_to_counts(-1e9), -4_666_666_666_667);
}

#[test]
fn modulo_axis_with_wrapping_drive_counter_over_a_million_turns() {
    // Rotary table, 360° per turn, gear 1:3 with a 2^17-count encoder: 43690⅔ counts per
    // turn. The drive's 32-bit counter wraps every ~49000 turns.
    let s = scaling(1 << 17, 1, 3, 360.0, false);
    let m = Modulo::new(360.0).unwrap();
    let mc = ModuloCounts::new(s, m).unwrap();
    assert_eq!(mc.counts_per_period(), (1 << 17, 3));
    let mut ext = CountExtender::new();
    // Walk the set position in big steps (turns, within) and feed the drive's wrapped
    // counter back through the extender: the extended count is the exact rounded
    // rational of the set position every time, and converts back to it.
    let mut turns: i64 = 0;
    let mut within = 0.0;
    let step_turns = 9_973; // < 2^31 counts per step
    ext.update(0);
    while turns < 1_000_000 {
        turns += step_turns;
        within = m.wrap(within + 37.5);
        let set_counts = mc.to_counts(turns, within);
        let exact = {
            // (turns·360 + within) · 2^17 / (3·360), within a multiple of 0.5°.
            let half_degrees = i128::from(turns) * 720 + (within * 2.0) as i128;
            let num = half_degrees * (1 << 17);
            let den = 3 * 720;
            (2 * num + den).div_euclid(2 * den)
        };
        assert_eq!(
            i128::from(set_counts),
            exact,
            "turns {turns} within {within}"
        );
        let actual = ext.update(set_counts as i32);
        assert_eq!(actual, set_counts);
        let (n, w) = mc.to_position(actual);
        assert_eq!(n, turns);
        assert!((w - within).abs() <= 360.0 / 43_690.0, "{w} vs {within}");
    }
    // Position 0 after exactly 10^6 + some turns maps to the rounded rational.
    assert_eq!(
        mc.to_counts(1_000_000, 0.0),
        (1_000_000i64 * (1 << 17) * 2 + 3) / 6
    );
}

#[test]
fn actual_position_is_reported_on_the_set_side_of_the_wrap() {
    let m = Modulo::new(360.0).unwrap();
    // Set value just past the wrap, actual lagging by 2°.
    assert_eq!(m.follow(0.0, 358.0), -2.0);
    assert_eq!(m.follow(1.0, 359.0), -1.0);
    // Actual ahead across the wrap.
    assert_eq!(m.follow(359.0, 1.0), 361.0);
    // Unwrapped set values (the axis keeps whole turns apart) work the same.
    assert_eq!(m.follow(3600.0, 358.0), 3598.0);
}

#[test]
fn inverted_motor_flips_counts_and_velocities() {
    let s = scaling(1 << 20, 1, 1, 360.0, true);
    assert_eq!(s.units_to_counts(90.0), -(1 << 18));
    assert_eq!(s.counts_to_units(1 << 18), -90.0);
    assert_eq!(s.velocity_to_counts(360.0), -f64::from(1 << 20));
    let mc = ModuloCounts::new(s, Modulo::new(360.0).unwrap()).unwrap();
    assert_eq!(mc.to_counts(2, 90.0), -(2 * (1 << 20) + (1 << 18)));
    assert_eq!(mc.to_position(-(2 * (1 << 20) + (1 << 18))), (2, 90.0));
}

#[test]
fn configuration_errors_name_the_field_and_value() {
    let e = Scaling::new(ScalingConfig {
        load_revs: 0,
        ..ScalingConfig::default()
    })
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "scaling load_revs = 0 must be > 0 (and finite)"
    );
    let e = Scaling::new(ScalingConfig {
        units_per_load_rev: -5.0,
        ..ScalingConfig::default()
    })
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "scaling units_per_load_rev = -5 must be > 0 (and finite)"
    );
    assert_eq!(
        Modulo::try_new(0.0).unwrap_err().to_string(),
        "modulo period 0 must be a finite number > 0"
    );
    let mech = Mechanics {
        software_limits: Some((0.0, 500.0)),
        ..Mechanics::default()
    };
    assert_eq!(
        mech.check_target(-1.0).unwrap_err().to_string(),
        "target -1 is below the software limit min 0"
    );
    assert_eq!(
        CountExtender::with_width(40).unwrap_err().to_string(),
        "counter width 40 bits must be between 2 and 32"
    );
}
