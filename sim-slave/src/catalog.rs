//! The devices the simulator can emulate, each as a ready slave: its EEPROM description,
//! object dictionary and application. One place, so the demo, the tests and the
//! `gantry-sim` binary emulate the same hardware.

use crate::coe::od::ObjectDictionary;
use crate::esc::al::Firmware;
use crate::esc::sii::{config_area, PDI_DIGITAL_IO_DEVICE_EMULATION};
use crate::esc::sii::{DeviceDescription, PdoDescription, PdoEntry, SmDescription};
use crate::plant::encoder::{self, EncoderModule};
use crate::plant::servo::{ServoDrive, ServoParams};
use crate::plant::switches::{self, CamError, SwitchCam, SwitchesModule};
use crate::plant::DeviceModel;
use crate::slave::Slave;

/// Vendor ID of every simulated device (not a registered ETG vendor ID).
pub const VENDOR_ID: u32 = 0x0A5A;
/// Product code of the simulated CiA-402 servo.
pub const SERVO_PRODUCT: u32 = 0x0402;

/// Product code of the simulated encoder module (after the EL5101 it imitates).
pub const ENCODER_PRODUCT: u32 = 0x5101;
/// Product code of the simulated 8-channel digital-input module (after the EL1008).
pub const SWITCHES_PRODUCT: u32 = 0x1008;

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

/// Where the encoder module's outputs lie (SM0; it has no mailbox).
pub const ENCODER_OUTPUTS_AT: u16 = 0x1000;
/// Where the encoder module's inputs lie (SM1).
pub const ENCODER_INPUTS_AT: u16 = 0x1100;
/// Where the digital-input module's input byte lies (SM0).
pub const SWITCHES_INPUTS_AT: u16 = 0x1000;

/// SyncManager kinds in the EEPROM (ETG.2010 Table 13).
const SM_PROCESS_DATA_OUT: u8 = 3;
const SM_PROCESS_DATA_IN: u8 = 4;
/// FMMU usage in the EEPROM: outputs, inputs.
const FMMU_OUTPUTS: u8 = 1;
const FMMU_INPUTS: u8 = 2;

/// SII mailbox protocol bit: CoE.
const MAILBOX_COE: u16 = 0x0004;

/// How a simulated servo is set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoOptions {
    /// Serial number (object 0x1018:4 and the EEPROM).
    pub serial: u32,
    /// Absolute encoder value at power-up (counts).
    pub start_counts: i32,
    /// The motor, load, tuning and object power-up values (default: a 400 W servo).
    pub params: ServoParams,
    /// Its firmware's transition times and checks.
    pub firmware: Firmware,
}

impl Default for ServoOptions {
    fn default() -> Self {
        Self {
            serial: 1,
            start_counts: 0,
            params: ServoParams::default(),
            firmware: Firmware::SERVO,
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
        dc: true,
        tx_pdos: vec![],
        rx_pdos: vec![],
    }
}

/// A CiA-402 servo drive (CoE, CSP) as a slave.
pub fn servo(options: ServoOptions) -> Slave {
    let drive =
        ServoDrive::with_params(OUTPUTS_AT, INPUTS_AT, options.start_counts, options.params);
    let mut od = ObjectDictionary::cia402_servo(VENDOR_ID, SERVO_PRODUCT, 1, options.serial);
    drive.install_objects(&mut od);
    Slave::new(servo_description(options.serial))
        .with_coe(od)
        .with_device(DeviceModel::Servo(drive))
        .with_firmware(options.firmware)
}

/// A SyncManager for process data, sized by the master from the PDOs.
fn process_data_sm(start: u16, kind: u8) -> SmDescription {
    let control = if kind == SM_PROCESS_DATA_OUT {
        0x64 // buffered, ECAT writes, watchdog trigger
    } else {
        0x20 // buffered, ECAT reads
    };
    SmDescription {
        start,
        length: 0,
        control,
        enable: true,
        kind,
    }
}

/// A fixed PDO: `(object, sub-index, bits)` entries.
fn pdo(index: u16, sync_manager: u8, entries: &[(u16, u8, u8)]) -> PdoDescription {
    PdoDescription {
        index,
        sync_manager,
        entries: entries
            .iter()
            .map(|&(index, sub, bits)| PdoEntry { index, sub, bits })
            .collect(),
    }
}

/// How a simulated encoder module is set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderOptions {
    /// Serial number (EEPROM).
    pub serial: u32,
    /// Counts per shaft revolution.
    pub counts_per_rev: u32,
    /// Speed at which the shaft turns by itself (rev/s); 0: the test turns it.
    pub shaft_speed_rev_s: f64,
}

impl Default for EncoderOptions {
    fn default() -> Self {
        Self {
            serial: 1,
            counts_per_rev: 4096,
            shaft_speed_rev_s: 0.0,
        }
    }
}

/// The encoder module's EEPROM: no mailbox, outputs on SM0 (RxPDO 0x1600: control, set
/// counter value), inputs on SM1 (TxPDO 0x1A00: status, counter value, latch value).
pub fn encoder_description(serial: u32) -> DeviceDescription {
    use encoder::{
        ENC_INPUTS, ENC_OUTPUTS, SUB_COUNTER_VALUE, SUB_LATCH_VALUE, SUB_SET_COUNTER_VALUE,
    };
    DeviceDescription {
        vendor_id: VENDOR_ID,
        product_code: ENCODER_PRODUCT,
        revision: 1,
        serial,
        order_code: "SIM-ENC".into(),
        name: "gantry simulated incremental encoder module".into(),
        mailbox: None,
        mailbox_protocols: 0,
        sync_managers: vec![
            process_data_sm(ENCODER_OUTPUTS_AT, SM_PROCESS_DATA_OUT),
            process_data_sm(ENCODER_INPUTS_AT, SM_PROCESS_DATA_IN),
        ],
        fmmus: vec![FMMU_OUTPUTS, FMMU_INPUTS],
        dc: false,
        rx_pdos: vec![pdo(
            0x1600,
            0,
            &[
                (ENC_OUTPUTS, 0, 16),
                (ENC_OUTPUTS, SUB_SET_COUNTER_VALUE, 32),
            ],
        )],
        tx_pdos: vec![pdo(
            0x1A00,
            1,
            &[
                (ENC_INPUTS, 0, 16),
                (ENC_INPUTS, SUB_COUNTER_VALUE, 32),
                (ENC_INPUTS, SUB_LATCH_VALUE, 32),
            ],
        )],
    }
}

/// An incremental encoder module as a slave.
pub fn encoder(options: EncoderOptions) -> Slave {
    let mut module = EncoderModule::new(
        ENCODER_OUTPUTS_AT,
        ENCODER_INPUTS_AT,
        options.counts_per_rev,
    );
    module.shaft_speed_rev_s = options.shaft_speed_rev_s;
    Slave::new(encoder_description(options.serial)).with_device(DeviceModel::Encoder(module))
}

/// How a simulated digital-input module with switch cams is set up.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SwitchesOptions {
    /// Serial number (EEPROM).
    pub serial: u32,
    /// Chain index of the servo whose position moves the cams.
    pub axis: usize,
    /// The cams, at most one per input.
    pub cams: Vec<SwitchCam>,
}

/// The digital-input module's EEPROM: no mailbox, no outputs, the input byte on SM0 as
/// eight one-bit TxPDOs 0x1A00…0x1A07 (channel n: object 0x6000 + 0x10·n, sub-index 1).
pub fn switches_description(serial: u32) -> DeviceDescription {
    let channels = (0..u16::from(switches::INPUTS))
        .map(|n| {
            pdo(
                switches::TXPDO_CHANNEL_0 + n,
                0,
                &[(switches::DI_CHANNEL_0 + 0x10 * n, 1, 1)],
            )
        })
        .collect();
    DeviceDescription {
        vendor_id: VENDOR_ID,
        product_code: SWITCHES_PRODUCT,
        revision: 1,
        serial,
        order_code: "SIM-DI8".into(),
        name: "gantry simulated 8-channel digital input (switch cams)".into(),
        mailbox: None,
        mailbox_protocols: 0,
        sync_managers: vec![process_data_sm(SWITCHES_INPUTS_AT, SM_PROCESS_DATA_IN)],
        fmmus: vec![FMMU_INPUTS],
        dc: false,
        rx_pdos: vec![],
        tx_pdos: channels,
    }
}

/// A digital-input module whose inputs are cams on the servo at chain index
/// `options.axis` (the chain passes that servo's position along each tick).
pub fn switches(options: SwitchesOptions) -> Result<Slave, CamError> {
    let module = SwitchesModule::new(SWITCHES_INPUTS_AT, options.axis, options.cams)?;
    // A simple input terminal: no firmware, the ESC in device emulation mirrors AL control.
    Ok(Slave::new(switches_description(options.serial))
        .with_eeprom_word(config_area::PDI_CONTROL, PDI_DIGITAL_IO_DEVICE_EMULATION)
        .with_device(DeviceModel::Switches(module)))
}
