//! Mechanics through the public API (SPEC §1, seed 000 §3): the seed's modulo examples,
//! one-way axes, and actual positions reported on the set value's side of the wrap. Units
//! ⇄ counts are tested with the drive layer (`drives/tests/units_counts.rs`).

use gantry_kernel::mechanics::{Direction, Mechanics, MechanicsError, Modulo, MotionKind};

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
fn configuration_errors_name_the_field_and_value() {
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
}
