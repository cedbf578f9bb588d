//! Property: whatever a master does and whatever gear, cam, out, halt, reset and enable
//! commands a follower gets, the follower's set values never jump and never exceed its
//! limits — speed, acceleration and deceleration (a master asking more puts the follower
//! in ErrorStop, braking within them) — and while it is in gear and in sync it is exactly
//! on the ratio.

mod common;

use common::sync::{assert_smooth, follower, velocity, virtual_master};
use common::*;
use gantry_kernel::axis::command::{Command, HaltMode, PowerCommand};
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisStatus;
use gantry_kernel::cam::{CamPoint, CamTable, Interpolation};
use gantry_kernel::mechanics::Modulo;
use gantry_kernel::sync::command::{CamIn, GearIn};
use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Step {
    MasterVelocity(f64),
    MasterHalt,
    Gear(i32, u32),
    GearOut,
    Cam,
    CamOut,
    Halt,
    Reset,
    Enable,
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        3 => (-300.0..300.0f64).prop_map(Step::MasterVelocity),
        1 => Just(Step::MasterHalt),
        3 => ((-3i32..=3).prop_filter("not 0", |n| *n != 0), 1u32..=4)
            .prop_map(|(n, d)| Step::Gear(n, d)),
        1 => Just(Step::GearOut),
        2 => Just(Step::Cam),
        1 => Just(Step::CamOut),
        1 => Just(Step::Halt),
        2 => Just(Step::Reset),
        1 => Just(Step::Enable),
    ]
}

const VMAX: f64 = 100.0;
const AMAX: f64 = 800.0;

/// What a run went through: cycles checked on the ratio, in ErrorStop for a limit, camming.
#[derive(Debug, Default)]
struct Seen {
    on_ratio: usize,
    limited: usize,
    cammed: usize,
}

fn check(seq: &[(usize, Step)], modulo: bool) -> Seen {
    let mut seen = Seen::default();
    let mut m = virtual_master();
    m.max.vmax = 300.0;
    let mut f = follower("f");
    f.max.vmax = VMAX;
    f.max.amax = AMAX;
    f.max.dmax = AMAX;
    f.max.jmax = 100_000.0;
    f.defaults.acceleration = 400.0;
    f.defaults.deceleration = 400.0;
    if modulo {
        m.mechanics.modulo = Modulo::new(360.0);
        f.mechanics.modulo = Modulo::new(100.0);
    }
    let period = modulo.then_some(100.0);
    let mut k = kernel(vec![m, f]);
    let table = CamTable::new(
        [(0.0, 0.0), (60.0, 20.0), (120.0, 15.0), (200.0, 30.0)]
            .iter()
            .map(|&(master, slave)| CamPoint { master, slave })
            .collect(),
        Interpolation::Cubic,
        true,
    )
    .unwrap();
    k.set_cam_table(0, Some(table)).unwrap();
    let mut prev: Option<AxisStatus> = None;
    let mut gear_ref: Option<(f64, f64)>;
    let mut ratio = 0.0;
    for (gap, s) in seq {
        let r = match *s {
            Step::MasterVelocity(v) => k.command(0, velocity(v)),
            Step::MasterHalt => k.command(
                0,
                Command::Halt {
                    mode: HaltMode::Normal,
                    deceleration: None,
                },
            ),
            Step::Gear(n, d) => k.command(1, Command::GearIn(GearIn::new(0, n, d))),
            Step::GearOut => k.command(1, Command::GearOut),
            Step::Cam => k.command(1, Command::CamIn(CamIn::new(0, 0, true))),
            Step::CamOut => k.command(1, Command::CamOut),
            Step::Halt => k.command(
                1,
                Command::Halt {
                    mode: HaltMode::Normal,
                    deceleration: None,
                },
            ),
            Step::Reset => k.command(1, Command::Reset),
            Step::Enable => k.command(1, Command::Power(PowerCommand::Enable)),
        };
        if let (Step::Gear(n, d), Ok(_)) = (s, r) {
            ratio = f64::from(*n) / f64::from(*d);
        }
        gear_ref = None;
        for _ in 0..*gap {
            k.step(&[]);
            let (ms, fs) = (*k.axis_status(0).unwrap(), *k.axis_status(1).unwrap());
            assert!(
                fs.set.v.abs() <= VMAX * (1.0 + 1e-9),
                "speed {} above {VMAX}: {fs:?}",
                fs.set.v
            );
            if let Some(p) = prev {
                assert_smooth(&[p, fs], period, AMAX * 1.01, f64::INFINITY, "follower");
            }
            // In gear and in sync: on the ratio from where it first was in sync.
            if fs.bits.gearing && fs.bits.in_sync && fs.state == AxisState::SynchronizedMotion {
                let mu = common::sync::unwrapped(&ms, modulo.then_some(360.0));
                let fu = common::sync::unwrapped(&fs, period);
                seen.on_ratio += 1;
                match gear_ref {
                    None => gear_ref = Some((mu, fu)),
                    Some((m0, f0)) => assert!(
                        ((fu - f0) - ratio * (mu - m0)).abs() < 1e-6,
                        "off the ratio {ratio} by {}",
                        (fu - f0) - ratio * (mu - m0)
                    ),
                }
            }
            if matches!(
                fs.error,
                Some(gantry_kernel::axis::status::AxisFault::SyncLimit(_))
            ) {
                seen.limited += 1;
            }
            seen.cammed += usize::from(fs.bits.camming);
            prev = Some(fs);
        }
    }
    seen
}

#[test]
fn the_property_checks_gears_on_the_ratio_cams_and_limit_stops() {
    // A slow master geared, cammed, then too fast for the follower at 3:1.
    let seq = [
        (300, Step::MasterVelocity(20.0)),
        (600, Step::Gear(2, 1)),
        (600, Step::Cam),
        (300, Step::Gear(3, 1)),
        (600, Step::MasterVelocity(290.0)),
    ];
    for modulo in [false, true] {
        let seen = check(&seq, modulo);
        assert!(seen.on_ratio > 500, "{seen:?}");
        assert!(seen.cammed > 500, "{seen:?}");
        assert!(seen.limited > 100, "{seen:?}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 48,
        failure_persistence: None,
        rng_algorithm: proptest::test_runner::RngAlgorithm::ChaCha,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x5359_4e43),
        ..ProptestConfig::default()
    })]

    #[test]
    fn followers_never_jump_nor_exceed_their_limits(
        seq in prop::collection::vec((1usize..400, step()), 1..25)
    ) {
        check(&seq, false);
    }

    #[test]
    fn modulo_followers_never_jump_nor_exceed_their_limits(
        seq in prop::collection::vec((1usize..400, step()), 1..25)
    ) {
        check(&seq, true);
    }
}
