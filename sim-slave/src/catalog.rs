//! The devices the simulator can emulate, each as a ready slave: its EEPROM description,
//! object dictionary and application. One place, so the demo, the tests and the
//! `gantry-sim` binary emulate the same hardware.

use crate::coe::od::ObjectDictionary;
use crate::esc::sii::{DeviceDescription, SmDescription};
use crate::plant::servo::ServoDrive;
use crate::plant::DeviceModel;
use crate::slave::Slave;

/// Vendor ID of every simulated device (not a registered ETG vendor ID).
pub const VENDOR_ID: u32 = 0x0A5A;
/// Product code of the simulated CiA-402 servo.
pub const SERVO_PRODUCT: u32 = 0x0402;

/// Where the servo's mailbox and process data lie in its ESC RAM.
pub const MAILBOX_OUT_AT: u16 = 0x1000;
/// Mailbox in (slave to master).
pub const MAILBOX_IN_AT: u16 = 0x1080;
/// Mailbox size, each direction.
pub const MAILBOX_BYTES: u16 = 128;
/// Output process data (SM2).
pub const OUTPUTS_AT: u16 = 0x1100;
/// Input process data (SM3).
pub const INPUTS_AT: u16 = 0x1400;

/// SII mailbox protocol bit: CoE.
const MAILBOX_COE: u16 = 0x0004;

/// How a simulated servo is set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoOptions {
    /// Serial number (object 0x1018:4 and the EEPROM).
    pub serial: u32,
    /// Absolute encoder value at power-up (counts).
    pub start_counts: i32,
    /// Position loop bandwidth (Hz).
    pub bandwidth_hz: f64,
}

impl Default for ServoOptions {
    fn default() -> Self {
        Self {
            serial: 1,
            start_counts: 0,
            bandwidth_hz: 200.0,
        }
    }
}

/// The servo's EEPROM: CoE mailbox on SM0/SM1, process data on SM2/SM3 (sized from the
/// PDO mapping the master reads by SDO).
pub fn servo_description(serial: u32) -> DeviceDescription {
    let sm = |start, length, control, kind| SmDescription {
        start,
        length,
        control,
        enable: true,
        kind,
    };
    DeviceDescription {
        vendor_id: VENDOR_ID,
        product_code: SERVO_PRODUCT,
        revision: 1,
        serial,
        order_code: "SIM-SERVO".into(),
        name: "gantry simulated CiA-402 servo".into(),
        mailbox: Some((MAILBOX_OUT_AT, MAILBOX_BYTES, MAILBOX_IN_AT, MAILBOX_BYTES)),
        mailbox_protocols: MAILBOX_COE,
        sync_managers: vec![
            sm(MAILBOX_OUT_AT, MAILBOX_BYTES, 0x26, 1),
            sm(MAILBOX_IN_AT, MAILBOX_BYTES, 0x22, 2),
            sm(OUTPUTS_AT, 0, 0x64, 3),
            sm(INPUTS_AT, 0, 0x20, 4),
        ],
        fmmus: vec![1, 2, 3],
        dc: false,
        tx_pdos: vec![],
        rx_pdos: vec![],
    }
}

/// A CiA-402 servo drive (CoE, CSP) as a slave.
pub fn servo(options: ServoOptions) -> Slave {
    let mut drive = ServoDrive::new(OUTPUTS_AT, INPUTS_AT, options.start_counts);
    drive.bandwidth_hz = options.bandwidth_hz;
    Slave::new(servo_description(options.serial))
        .with_coe(ObjectDictionary::cia402_servo(
            VENDOR_ID,
            SERVO_PRODUCT,
            1,
            options.serial,
        ))
        .with_device(DeviceModel::Servo(drive))
}
