//! Drive-side homing over EtherCAT, in lockstep (`gantry_tests::rig`): a drive that
//! never reports homing attained (the timeout) and one that refuses methods 0 and 21
//! (`[slave.homing]`), on the "csp-minimal" layout: the mode goes by SDO.

use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::drive_homing;
use gantry_tests::homing::servo_switches_toml;
use gantry_tests::rig::Rig;
use gantry_tests::servo_rig::EthercatServo;
use gantry_tests::{sim_config_text, DEFAULT_SYNC_ERROR_LIMIT};

/// A rig whose servo has the switch cams and `homing` in `[slave.homing]`, the axis
/// mapped `pdo`, with `[axis.drive_homing]`.
fn rig(homing: &str, pdo: &str) -> (EthercatServo, gantry::config::Config) {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}\n{}\
         [slave.homing]\n{homing}\n",
        servo_switches_toml()
    );
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\npdo = \"{pdo}\"\nhoming_required = false\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
         max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n\
         [axis.drive_homing]\nmethod = 19\nspeed_switch = 50.0\nspeed_zero = 5.0\n\
         acceleration = 500.0\nhome_offset = 2.0\ntimeout = 10.0\n"
    );
    let config = sim_config_text(1000, &slaves, "", &axes);
    let mut rig = EthercatServo {
        rig: Rig::new(&config),
        cycle_s: 1e-3,
    };
    let h = rig
        .rig
        .ctl
        .command(0, Command::Power(PowerCommand::Enable))
        .expect("queued");
    assert_eq!(rig.rig.finish(&h, 5000), CommandStatus::Done);
    (rig, config)
}

#[test]
fn drive_homing_refused_methods_and_timeout_over_ethercat() {
    let (mut r, config) = rig(
        "never_attains = true\nrefuse_methods = [0, 21]",
        "csp-minimal",
    );
    let base = config.axes[0]
        .drive_homing_params()
        .expect("valid")
        .expect("configured");
    drive_homing::refused_method(&mut r, base, 0);
    drive_homing::refused_method(&mut r, base, 21);
    drive_homing::timeout_path(&mut r, base);
    drive_homing::cancel_and_power_off(&mut r, base);
}
