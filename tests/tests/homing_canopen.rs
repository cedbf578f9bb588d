//! Switches and homing end to end over CANopen, in lockstep (`gantry_tests::can_rig`): the
//! scenario of `gantry_tests::homing` on a simulated CANopen servo with switch cams, its
//! digital inputs and touch probe carried in its PDOs (the same code as on EtherCAT).

use gantry_drives::canopen::NodeId;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use gantry_sim::config::{SimConfig, SlaveConfig};
use gantry_tests::can_rig::CanRig;
use gantry_tests::homing::{scenario, servo_switches_toml, HomingRig, AXIS_SWITCHES_TOML};
use gantry_tests::servo_rig::CanopenServo;

const NODE: u8 = 5;
/// The cycle time (`cycle_us = 2000`).
const CYCLE_S: f64 = 2e-3;

#[test]
fn switches_limit_switches_and_move_home_over_canopen() {
    // The simulated servo from a chain description with the switch cams.
    let chain = SimConfig::parse(
        &format!(
            "[[slave]]\nkind = \"servo\"\nnode = {NODE}\n{}",
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
    // The minimal layout with the switches and the probe: 8 output bytes (1 RPDO), 24
    // input bytes (3 TPDOs); at 1 Mbit/s a 2 ms cycle carries them.
    let config = gantry::config::Config::parse(
        &format!(
            "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\ncycle_us = 2000\n\
             [[axis]]\nname = \"x\"\nnode = {NODE}\npdo = \"csp-minimal\"\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n{AXIS_SWITCHES_TOML}"
        ),
        "can.toml",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut rig = CanopenServo {
        rig: CanRig::new(&config, vec![node]),
        node: NODE,
        cycle_s: CYCLE_S,
    };
    assert_eq!(
        rig.run_command(Command::Power(PowerCommand::Enable), 5000),
        CommandStatus::Done
    );
    scenario(&mut rig);
}
