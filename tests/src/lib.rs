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

/// A configuration of `axes` axes on simulated servos in this process (`[bus] simulator`),
/// at `cycle_us`; the simulator's chain file is written to a temporary folder.
pub fn sim_config(axes: usize, cycle_us: u32) -> gantry::config::Config {
    let dir = std::env::temp_dir().join(format!("gantry-sim-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let sim = dir.join("sim.toml");
    let chain: String = (0..axes).map(|_| "[[slave]]\nkind = \"servo\"\n").collect();
    std::fs::write(&sim, format!("cycle_us = {cycle_us}\n{chain}")).expect("sim.toml");
    let mut text = format!(
        "[bus]\nkind = \"ethercat\"\nsimulator = {:?}\ncycle_us = {cycle_us}\n",
        sim.display().to_string()
    );
    for i in 0..axes {
        text += &format!(
            "[[axis]]\nname = \"a{i}\"\ndrive = {i}\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n"
        );
    }
    gantry::config::Config::parse(&text, "test.toml").expect("valid test configuration")
}
