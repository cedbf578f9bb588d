//! The homing matrix over EtherCAT at a 4 ms cycle (the longest EtherCAT cycle gantry
//! takes): the same cases as `homing_matrix_ethercat.rs` at 1 ms, four times the travel
//! between two samples, the reference still from the drive's latch.

#[test]
fn homing_matrix_over_ethercat_at_4_ms() {
    gantry_tests::homing_matrix::over_ethercat(4000);
}
