//! Switches on an I/O module of the EtherCAT bus, in lockstep: a simulated servo and a
//! digital-input module (like an EL1008) whose inputs are switch cams on the servo's
//! travel; the axis reads its limit and reference switches from the module every cycle
//! (`gantry_tests::homing::module_scenario`). One test: the EtherCAT bus starts once per
//! process.

use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::homing::{
    module_scenario, module_switches_toml, HomingRig, AXIS_MODULE_SWITCHES_TOML,
};
use gantry_tests::rig::Rig;
use gantry_tests::servo_rig::{EthercatServo, ServoRig};
use gantry_tests::{sim_config_text, DEFAULT_SYNC_ERROR_LIMIT};

#[test]
fn switches_on_an_io_module_reach_the_axis_and_stop_it() {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}\n{}",
        module_switches_toml()
    );
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\npdo = \"csp-minimal\"\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
         max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n\
         {AXIS_MODULE_SWITCHES_TOML}"
    );
    let config = sim_config_text(1000, &slaves, "", &axes);
    // The drive maps no 0x60FD: the switches come from the module only.
    assert!(!config.axes[0]
        .pdo_layout()
        .expect("layout")
        .inputs
        .iter()
        .any(|o| o.index == 0x60FD));
    let mut rig = EthercatServo {
        rig: Rig::new(&config),
        cycle_s: 1e-3,
    };
    assert_eq!(
        rig.run_command(Command::Power(PowerCommand::Enable), 5000),
        CommandStatus::Done
    );
    // Both limit switches are normally closed: at 0 neither input is low, none active.
    let sw = rig.status().switches;
    assert!(!sw.negative_limit && !sw.positive_limit && !sw.reference);
    module_scenario(&mut rig);
}
