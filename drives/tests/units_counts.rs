//! Units ⇄ counts through the public API (SPEC §1, seed 000 §3): long travel without
//! drift, a modulo axis turning for a long time with a wrapping 32-bit drive counter in
//! the loop, inverted motors, and configuration errors that name the field.

use gantry_drives::scaling::{CountExtender, ModuloCounts, Scaling, ScalingConfig};

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
    let mc = ModuloCounts::new(s, 360.0).unwrap();
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
        // Multiples of 0.5°: the remainder is exact.
        within = (within + 37.5) % 360.0;
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
fn inverted_motor_flips_counts_and_velocities() {
    let s = scaling(1 << 20, 1, 1, 360.0, true);
    assert_eq!(s.units_to_counts(90.0), -(1 << 18));
    assert_eq!(s.counts_to_units(1 << 18), -90.0);
    assert_eq!(s.velocity_to_counts(360.0), -f64::from(1 << 20));
    let mc = ModuloCounts::new(s, 360.0).unwrap();
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
        ModuloCounts::new(Scaling::default(), 0.0)
            .unwrap_err()
            .to_string(),
        "modulo period 0 must be a finite number > 0"
    );
    assert_eq!(
        CountExtender::with_width(40).unwrap_err().to_string(),
        "counter width 40 bits must be between 2 and 32"
    );
}
