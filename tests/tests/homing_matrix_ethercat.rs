//! The homing matrix (`gantry_tests::homing_matrix`) over EtherCAT at a 1 ms cycle, in
//! lockstep: every MoveHome mode × switch configuration × direction × start × search
//! speed, every seed-003 StepAbsoluteSwitch case at a normal and at a small deceleration,
//! and the error paths, one bring-up for all (the EtherCAT bus starts once per process;
//! `homing_matrix_ethercat_4ms.rs` runs it at 4 ms).
//! `HOMING_MATRIX_ONLY=<part of a case name>` runs a subset while debugging.

#[test]
fn homing_matrix_over_ethercat_at_1_ms() {
    gantry_tests::homing_matrix::over_ethercat(1000);
}
