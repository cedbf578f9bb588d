// Random motion commands for fuzzing: operands from ordinary to hostile (NaN, ±∞, huge,
// zero, negative), every command kind. Shared by the kernel's fuzz test and the engine's
// (`tests/tests/runtime_command_fuzz.rs`, by `include!`), so both see the same inputs.

use gantry_kernel::axis::command::{
    BufferMode, Command, DynamicsChange, HaltMode, Jog, JogProfile, MoveDirection, MovePtp,
    MoveVelocity, PositioningMode, PowerCommand,
};
use gantry_kernel::profile::RampType;
use proptest::prelude::*;

fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -200.0..200.0f64,
        1 => Just(0.0),
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(-1e300),
        1 => 1e-9..1e-3f64,
    ]
}

fn speed() -> impl Strategy<Value = f64> {
    prop_oneof![8 => 0.5..100.0f64, 1 => value()]
}

fn mode() -> impl Strategy<Value = PositioningMode> {
    prop_oneof![
        Just(PositioningMode::AbsNormal),
        Just(PositioningMode::RelTarget),
        Just(PositioningMode::RelActual),
        Just(PositioningMode::AbsModuloPos),
        Just(PositioningMode::AbsModuloNeg),
        Just(PositioningMode::AbsModuloAuto),
        Just(PositioningMode::AbsModuloKeepDirection),
    ]
}

fn buffer() -> impl Strategy<Value = BufferMode> {
    prop_oneof![
        3 => Just(BufferMode::Aborting),
        1 => Just(BufferMode::Buffered),
        1 => Just(BufferMode::BlendingLow),
        1 => Just(BufferMode::BlendingPrevious),
        1 => Just(BufferMode::BlendingNext),
        1 => Just(BufferMode::BlendingHigh),
    ]
}

fn dir() -> impl Strategy<Value = MoveDirection> {
    prop_oneof![Just(MoveDirection::Positive), Just(MoveDirection::Negative)]
}

/// Commands whose ramps are all S-curves (when `scurve_only`), or anything.
pub fn command(scurve_only: bool) -> impl Strategy<Value = Command> {
    let ramp = if scurve_only {
        Just(RampType::SCurve).boxed()
    } else {
        prop_oneof![
            Just(RampType::Trapezoid),
            Just(RampType::SCurve),
            Just(RampType::Sine),
            Just(RampType::LinearSine)
        ]
        .boxed()
    };
    let ptp = (
        mode(),
        value(),
        speed(),
        speed(),
        speed(),
        speed(),
        buffer(),
        ramp.clone(),
    )
        .prop_map(|(mode, target, v, a, d, j, b, r)| {
            Command::MovePtp(MovePtp {
                mode,
                target,
                speed: Some(v),
                acceleration: Some(a * 10.0),
                deceleration: Some(d * 10.0),
                jerk: Some(j * 100.0),
                target_window: Some(0.01),
                ramp: Some(r),
                buffer: b,
            })
        });
    let vel =
        (dir(), speed(), speed(), speed(), buffer(), ramp).prop_map(|(d, v, a, dec, b, r)| {
            let mut m = MoveVelocity::new(d, v);
            m.acceleration = Some(a * 10.0);
            m.deceleration = Some(dec * 10.0);
            m.jerk = Some(500.0);
            m.ramp = Some(r);
            m.buffer = b;
            Command::MoveVelocity(m)
        });
    let jog = (dir(), speed(), any::<bool>(), any::<bool>()).prop_map(move |(d, v, merge, cur)| {
        let mut j = Jog::new(d, v, 50.0, 50.0);
        j.merge = merge;
        if cur {
            j.merge_speed = gantry_kernel::axis::command::MergeSpeed::Current;
        }
        if scurve_only {
            j.profile = JogProfile::SCurve;
        }
        Command::Jog(j)
    });
    let change = (
        prop_oneof![
            Just(DynamicsChange::Speed),
            Just(DynamicsChange::Acceleration),
            Just(DynamicsChange::Deceleration),
            Just(DynamicsChange::Jerk)
        ],
        speed(),
    )
        .prop_map(|(c, v)| Command::Change(c, v));
    let misc = prop_oneof![
        Just(Command::Reverse),
        Just(Command::Halt {
            mode: HaltMode::Normal,
            deceleration: None
        }),
        Just(Command::Halt {
            mode: HaltMode::AtActualPosition,
            deceleration: Some(30.0)
        }),
        Just(Command::Stop { deceleration: None }),
        Just(Command::Release),
        Just(Command::Reset),
        Just(Command::Power(PowerCommand::Enable)),
        Just(Command::Power(PowerCommand::Disable)),
        Just(Command::SetHomed(true)),
        value().prop_map(|p| Command::SetPosition {
            position: p,
            relative: false
        }),
    ];
    let rare = prop_oneof![
        Just(Command::QuickStop),
        Just(Command::Power(PowerCommand::DisableForced)),
    ];
    if scurve_only {
        prop_oneof![6 => ptp, 2 => vel, 2 => jog, 2 => change, 3 => misc].boxed()
    } else {
        prop_oneof![6 => ptp, 2 => vel, 2 => jog, 2 => change, 3 => misc, 1 => rare].boxed()
    }
}
