//! The library opens no simulator: `[bus] simulator` comes up only on a link the caller
//! plugs in (the `gantry` binary's), and without one the bring-up says so instead of
//! reaching for a simulator it does not have. Its own process: the bus starts once per
//! process.

use gantry::config::Config;
use gantry::ethercat::bus::{EthercatBus, StartError};

#[test]
fn a_simulator_configuration_without_a_link_for_it_is_refused_by_name() {
    let config = Config::parse(
        "[bus]\nkind = \"ethercat\"\nsimulator = \"sim.toml\"\ncycle_us = 1000\n\
         [[axis]]\nname = \"a0\"\ndrive = 0\n\
         scaling = { counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }\n\
         max = { speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }\n",
        "gantry.toml",
    )
    .expect("a valid configuration");
    let e = EthercatBus::bring_up(&config, &mut std::io::sink())
        .err()
        .expect("no link for [bus] simulator in the library");
    assert!(matches!(e, StartError::NoLink(_)), "{e:?}");
    assert_eq!(
        e.to_string(),
        "[bus] simulator: this program has no in-process simulator (the gantry binary has)"
    );
}
