//! Drive-side homing over EtherCAT, in lockstep (`gantry_tests::rig`): a drive that
//! never reports homing attained (the timeout) and one that refuses methods 0 and 21
//! (`[slave.homing]`), on the "csp-minimal" layout: the mode goes by SDO.

use gantry_tests::drive_homing;

#[test]
fn drive_homing_refused_methods_and_timeout_over_ethercat() {
    let (mut r, config) = drive_homing::ethercat_rig(
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
