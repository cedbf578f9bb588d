//! Drive-side homing over CANopen, in lockstep (`gantry_tests::can_rig`): every CiA 402
//! homing method of the simulated CANopen servo and skip on the "csp-minimal" layout (the
//! mode by SDO through the node's SDO server), then a drive that never reports homing
//! attained and refuses methods 0 and 21 on the "csp" layout (the mode by PDO) — the same
//! code as on EtherCAT (`gantry_tests::drive_homing`).

use gantry_drives::canopen::NodeId;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use gantry_sim::config::{SimConfig, SlaveConfig};
use gantry_tests::can_rig::CanRig;
use gantry_tests::drive_homing;
use gantry_tests::homing::servo_switches_toml;
use gantry_tests::servo_rig::CanopenServo;

const NODE: u8 = 5;
/// The cycle time (`cycle_us = 2000`).
const CYCLE_S: f64 = 2e-3;

fn rig(homing: &str, pdo: &str) -> (CanopenServo, gantry::config::Config) {
    let chain = SimConfig::parse(
        &format!(
            "[[slave]]\nkind = \"servo\"\nnode = {NODE}\n{}[slave.homing]\n{homing}\n",
            servo_switches_toml()
        ),
        "sim.toml",
    )
    .expect("chain");
    let SlaveConfig::Servo(servo) = &chain.slaves[0] else {
        panic!("a servo");
    };
    let node = CanNode::new(CanNodeConfig::from_servo(
        NodeId::new(NODE).expect("node id"),
        servo,
    ))
    .expect("node");
    let config = gantry::config::Config::parse(
        &format!(
            "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\ncycle_us = 2000\n\
             [[axis]]\nname = \"x\"\nnode = {NODE}\npdo = \"{pdo}\"\nhoming_required = false\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n\
             [axis.drive_homing]\nmethod = 19\nspeed_switch = 50.0\nspeed_zero = 5.0\n\
             acceleration = 500.0\nhome_offset = 2.0\ntimeout = 10.0\n"
        ),
        "can.toml",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut rig = CanopenServo {
        rig: CanRig::new(&config, vec![node]),
        node: NODE,
        cycle_s: CYCLE_S,
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
fn every_drive_homing_method_and_skip_over_canopen() {
    let (mut r, config) = rig("", "csp-minimal");
    let base = config.axes[0]
        .drive_homing_params()
        .expect("valid")
        .expect("configured");
    drive_homing::every_method(&mut r, base);
    drive_homing::skip(&mut r, base);
}

#[test]
fn drive_homing_refused_methods_and_timeout_over_canopen() {
    let (mut r, config) = rig("never_attains = true\nrefuse_methods = [0, 21]", "csp");
    let base = config.axes[0]
        .drive_homing_params()
        .expect("valid")
        .expect("configured");
    drive_homing::refused_method(&mut r, base, 0);
    drive_homing::refused_method(&mut r, base, 21);
    drive_homing::timeout_path(&mut r, base);
    drive_homing::cancel_and_power_off(&mut r, base);
}
