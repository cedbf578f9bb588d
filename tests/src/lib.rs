//! End-to-end tests of gantry: the master and the simulator together. The tests live in
//! `tests/tests/`; what they share lives here and in the master (`gantry::ethercat`).

pub mod lockstep;
pub mod netns;

pub use gantry::ethercat::embedded::EmbeddedBus;

use gantry_kernel::mechanics::{Scaling, ScalingConfig};

/// The axis the end-to-end tests drive: a 5 mm ball screw on a 2^17-count motor.
pub fn ball_screw_5mm() -> Scaling {
    Scaling::new(ScalingConfig {
        counts_per_motor_rev: 1 << 17,
        motor_revs: 1,
        load_revs: 1,
        units_per_load_rev: 5.0,
        invert: false,
    })
    .expect("a valid scaling")
}

/// A chain of `n` catalog servos with serial numbers 1…n.
pub fn servo_chain(n: u32) -> gantry_sim::chain::SlaveChain {
    use gantry_sim::catalog::{self, ServoOptions};
    gantry_sim::chain::SlaveChain::new(
        (1..=n)
            .map(|serial| {
                catalog::servo(ServoOptions {
                    serial,
                    ..ServoOptions::default()
                })
            })
            .collect(),
    )
}
