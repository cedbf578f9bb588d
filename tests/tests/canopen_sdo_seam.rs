//! The SDO seam on a bus that does not carry transfers beside the cycle yet: CANopen's
//! `CycleBus` keeps the trait's default (`start_sdo` refuses with `NotSupported`), so a
//! `gantry sdo` on a CANopen configuration is answered at once with that reason — never
//! left waiting — and the cycle runs on. When the CANopen bus implements `start_sdo` with
//! its SDO client, this test changes to real transfers (`runtime_sdo.rs` is EtherCAT's).

use gantry::runtime::sdo::{SdoError, SdoRequest};
use gantry_tests::can_rig::{can_config, servos, CanRig};

#[test]
fn a_bus_without_sdo_beside_the_cycle_says_so_at_once() {
    let config = can_config(&[1], 1000, "csp");
    let mut rig = CanRig::new(&config, servos(&[1]));
    rig.run(20);
    let h = rig
        .ctl
        .sdo(SdoRequest::upload(0, 0x1018, 1))
        .expect("queued");
    rig.cycle();
    let outcome = h.outcome().expect("answered in the cycle that took it");
    assert_eq!(outcome, Err(SdoError::NotSupported));
    assert_eq!(
        outcome.unwrap_err().to_string(),
        "this bus does not carry SDO transfers while the cycle runs"
    );
    rig.enable_and_home(0);
}
