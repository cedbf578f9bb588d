//! Switches and homing end to end over EtherCAT, in lockstep (`gantry_tests::rig`): the
//! scenario of `gantry_tests::homing` on a simulated servo with switch cams. One test: the
//! EtherCAT bus starts once per process.

use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::homing::{scenario, servo_switches_toml, HomingRig, AXIS_SWITCHES_TOML};
use gantry_tests::rig::Rig;
use gantry_tests::servo_rig::EthercatServo;
use gantry_tests::{sim_config_text, DEFAULT_SYNC_ERROR_LIMIT};

#[test]
fn switches_limit_switches_and_move_home_over_ethercat() {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}\n{}",
        servo_switches_toml()
    );
    // "csp" with the switches, the probe and its source for the limit switches: 12 inputs
    // (0x60BD for probe 2 on the positive limit), more than one PDO takes (the simulated
    // drive, as many real ones, takes at most 10; the master puts 8 in each), so the
    // master maps 0x1A00 and 0x1A01 and assigns both to SM3.
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\npdo = \"csp\"\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
         max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n{AXIS_SWITCHES_TOML}"
    );
    let config = sim_config_text(1000, &slaves, "", &axes);
    let mut rig = EthercatServo {
        rig: Rig::new(&config),
        cycle_s: 1e-3,
    };
    {
        // What the drive was left with: two TxPDOs on SM3, one RxPDO on SM2.
        let chain = rig.rig.chain.lock().expect("the chain");
        let od = chain.slaves()[0].object_dictionary().expect("CoE");
        assert_eq!(od.read(0x1C13, 0), Ok(&[2u8][..]));
        assert_eq!(od.read(0x1C13, 2), Ok(&0x1A01u16.to_le_bytes()[..]));
        assert_eq!(od.read(0x1A01, 0), Ok(&[4u8][..]));
        assert_eq!(od.read(0x1C12, 0), Ok(&[1u8][..]));
        // The touch probe sources for the limit switches, written at bring-up.
        assert_eq!(od.read(0x60D0, 1), Ok(&(-1i16).to_le_bytes()[..]));
        assert_eq!(od.read(0x60D0, 2), Ok(&(-2i16).to_le_bytes()[..]));
    }
    assert_eq!(
        rig.run_command(Command::Power(PowerCommand::Enable), 5000),
        CommandStatus::Done
    );
    scenario(&mut rig);
}
