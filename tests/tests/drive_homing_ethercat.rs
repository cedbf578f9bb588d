//! Drive-side homing over EtherCAT, in lockstep (`gantry_tests::rig`): every CiA 402
//! homing method of the simulated servo, the timeout of a drive that never reports homing
//! attained, a refused method and skip (`gantry_tests::drive_homing`). The "csp" layout
//! maps 0x6060/0x6061: the mode goes by PDO. One test per process (the bus starts once).

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
fn every_drive_homing_method_and_skip_over_ethercat() {
    let (mut r, config) = rig("", "csp");
    let base = config.axes[0]
        .drive_homing_params()
        .expect("valid")
        .expect("configured");
    drive_homing::every_method(&mut r, base);
    drive_homing::skip(&mut r, base);
}
