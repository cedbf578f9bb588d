//! The homing matrix (`gantry_tests::homing_matrix`) over EtherCAT at a 1 ms cycle, in
//! lockstep: every MoveHome mode × switch configuration × direction × start × search
//! speed, every seed-003 StepAbsoluteSwitch case at a normal and at a small deceleration,
//! and the error paths, one bring-up for all (the EtherCAT bus starts once per process).
//! `HOMING_MATRIX_ONLY=<part of a case name>` runs a subset while debugging.

use std::time::Instant;

use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::homing::{HomingRig, AXIS_SWITCHES_TOML};
use gantry_tests::homing_matrix::{self as matrix, Tally, AXIS_MAX_TOML};
use gantry_tests::rig::Rig;
use gantry_tests::servo_rig::EthercatServo;
use gantry_tests::{sim_config_text, DEFAULT_SYNC_ERROR_LIMIT};

const CYCLE_US: u32 = 1000;

fn report(part: &str, t: &Tally, since: Instant) {
    eprintln!(
        "{part}: {} cases, {} cycles, {:.1} s",
        t.cases,
        t.cycles,
        since.elapsed().as_secs_f64()
    );
}

#[test]
fn homing_matrix_over_ethercat_at_1_ms() {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}\n{}",
        matrix::servo_switches_toml(true)
    );
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\npdo = \"csp-minimal\"\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
         {AXIS_MAX_TOML}\n{AXIS_SWITCHES_TOML}"
    );
    let config = sim_config_text(CYCLE_US, &slaves, "", &axes);
    let mut rig = EthercatServo {
        rig: Rig::new(&config),
        cycle_s: f64::from(CYCLE_US) * 1e-6,
    };
    assert_eq!(
        rig.run_command(Command::Power(PowerCommand::Enable), 5000),
        CommandStatus::Done
    );
    let only = std::env::var("HOMING_MATRIX_ONLY").unwrap_or_default();
    let mut failures = Vec::new();
    let mut cases = 0;
    let t = Instant::now();
    let m = matrix::move_home_matrix(&mut rig, &only, true);
    report("MoveHome", &m, t);
    let t = Instant::now();
    let mut s = matrix::step_switch_matrix(&mut rig, 1000.0, &only, true);
    let small = matrix::step_switch_matrix(&mut rig, 40.0, &only, true);
    s.cases += small.cases;
    s.cycles += small.cycles;
    s.failures.extend(small.failures);
    report("StepAbsoluteSwitch", &s, t);
    for tally in [m, s] {
        cases += tally.cases;
        failures.extend(tally.failures);
    }
    if only.is_empty() {
        let t = Instant::now();
        let e = matrix::error_cases(&mut rig);
        report("errors", &e, t);
        cases += e.cases;
    }
    assert!(cases > 0, "no case matches {only:?}");
    assert!(
        failures.is_empty(),
        "{} of {cases} cases failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
