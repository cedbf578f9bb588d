//! Drive-side homing over EtherCAT, in lockstep (`gantry_tests::rig`): every CiA 402
//! homing method of the simulated servo, the timeout of a drive that never reports homing
//! attained, a refused method and skip (`gantry_tests::drive_homing`). The "csp" layout
//! maps 0x6060/0x6061: the mode goes by PDO. One test per process (the bus starts once).

use gantry_tests::drive_homing;

#[test]
fn every_drive_homing_method_and_skip_over_ethercat() {
    let (mut r, config) = drive_homing::ethercat_rig("", "csp");
    let base = config.axes[0]
        .drive_homing_params()
        .expect("valid")
        .expect("configured");
    drive_homing::every_method(&mut r, base);
    drive_homing::skip(&mut r, base);
}
