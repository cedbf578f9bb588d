//! The homing matrix (`gantry_tests::homing_matrix`) over CANopen at 4 ms and at 2 ms
//! cycles (the EtherCAT run has 1 ms), in lockstep on the in-memory bus: every MoveHome mode × switch
//! configuration × direction × start × search speed, every seed-003 StepAbsoluteSwitch
//! case at a normal and at a small deceleration, the error paths, and a servo without a
//! home cam (the missing reference switch). One bring-up per servo and cycle time.
//! `HOMING_MATRIX_ONLY=<part of a case name>` runs a subset while debugging.

use std::time::Instant;

use gantry_drives::canopen::NodeId;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use gantry_sim::config::{SimConfig, SlaveConfig};
use gantry_tests::can_rig::CanRig;
use gantry_tests::homing::{HomingRig, AXIS_SWITCHES_TOML};
use gantry_tests::homing_matrix::{self as matrix, Tally, AXIS_MAX_TOML};
use gantry_tests::servo_rig::CanopenServo;

const NODE: u8 = 5;
/// The cycle times the matrix runs at (µs): 2 ms is the shortest the layout with the
/// switches and the probe fits at 1 Mbit/s.
const CYCLES_US: [u32; 2] = [4000, 2000];

/// An enabled axis on a simulated CANopen servo with the matrix' switch cams (`home`:
/// with the home cam), cycling every `cycle_us`.
fn rig(home: bool, cycle_us: u32) -> CanopenServo {
    let chain = SimConfig::parse(
        &format!(
            "[[slave]]\nkind = \"servo\"\nnode = {NODE}\n{}",
            matrix::servo_switches_toml(home)
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
            "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\ncycle_us = {cycle_us}\n\
             [[axis]]\nname = \"x\"\nnode = {NODE}\npdo = \"csp-minimal\"\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             {AXIS_MAX_TOML}\n{AXIS_SWITCHES_TOML}"
        ),
        "can.toml",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut rig = CanopenServo {
        rig: CanRig::new(&config, vec![node]),
        node: NODE,
        cycle_s: f64::from(cycle_us) * 1e-6,
    };
    assert_eq!(
        rig.run_command(Command::Power(PowerCommand::Enable), 5000),
        CommandStatus::Done
    );
    rig
}

fn report(part: &str, t: &Tally, since: Instant) {
    eprintln!(
        "{part}: {} cases, {} cycles, {:.1} s",
        t.cases,
        t.cycles,
        since.elapsed().as_secs_f64()
    );
}

#[test]
fn homing_matrix_over_canopen_at_4_and_2_ms() {
    let only = std::env::var("HOMING_MATRIX_ONLY").unwrap_or_default();
    let mut failures = Vec::new();
    let mut cases = 0;
    for cycle_us in CYCLES_US {
        let mut rig = rig(true, cycle_us);
        let at = |part: &str| format!("{part} at {} ms", f64::from(cycle_us) / 1000.0);
        let t = Instant::now();
        let m = matrix::move_home_matrix(&mut rig, &only, true);
        report(&at("MoveHome"), &m, t);
        let t = Instant::now();
        let mut s = matrix::step_switch_matrix(&mut rig, 1000.0, &only, true);
        let small = matrix::step_switch_matrix(&mut rig, 40.0, &only, true);
        s.cases += small.cases;
        s.cycles += small.cycles;
        s.failures.extend(small.failures);
        report(&at("StepAbsoluteSwitch"), &s, t);
        for tally in [m, s] {
            cases += tally.cases;
            failures.extend(
                tally
                    .failures
                    .into_iter()
                    .map(|f| format!("{} ms: {f}", f64::from(cycle_us) / 1000.0)),
            );
        }
        if only.is_empty() {
            let t = Instant::now();
            let e = matrix::error_cases(&mut rig);
            report(&at("errors"), &e, t);
            cases += e.cases;
            let t = Instant::now();
            let e = matrix::missing_reference_switch(&mut self::rig(false, cycle_us));
            report(&at("missing reference switch"), &e, t);
            cases += e.cases;
        }
    }
    assert!(cases > 0, "no case matches {only:?}");
    assert!(
        failures.is_empty(),
        "{} of {cases} cases failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
