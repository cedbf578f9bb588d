//! The application behind a CANopen node: the same devices as on EtherCAT
//! (`crate::plant`), each with its device profile's objects, the objects its PDOs may
//! map and its power-on mapping. [`CanNode`](super::CanNode) runs the CiA 301 machinery
//! (NMT, SDO, PDOs, SYNC, EMCY, heartbeat) for any of them.
//!
//! - [`CanDevice::Servo`]: the CiA 402 servo of `plant::servo` (device type 0x00020192).
//! - [`CanDevice::Encoder`]: the incremental encoder module of `plant::encoder` as a CiA
//!   406 encoder (device type 0x00050196: profile 406, encoder type 5 "incremental rotary
//!   encoder with electronic counting"): 0x6004 position value (the module's 32-bit
//!   counter, TPDO-mappable), 0x6001 measuring units per revolution, 0x6003 preset value
//!   (a download sets the position value to it: the module's set-counter edge).
//! - [`CanDevice::Switches`]: the switch-cam input module of `plant::switches` as a CiA 401
//!   digital input device (device type 0x00010191: profile 401, digital inputs): 0x6000:01
//!   read input 8-bit (TPDO-mappable), 0x6002:01 polarity input 8-bit (a set bit inverts
//!   that input, CiA 401 §6). Its cams move with a servo on the same bus, named by node id:
//!   the bus hands the module that servo's position before it delivers each frame to it
//!   ([`super::bus::CanBus`]), so the inputs a TPDO carries at a SYNC and the servo's
//!   position at that SYNC agree to the count, as on EtherCAT.
//!
//! No allocation after construction: each module's process image is a fixed buffer (the
//! encoder's an ESC memory, the module being the EtherCAT one).

use gantry_drives::canopen::cob_id::NodeId;
use gantry_drives::cia402::image;
use gantry_drives::cia402::objects::{DataType, ObjectId};
use gantry_drives::cia402::State;

use crate::coe::od::ObjectDictionary as Od;
use crate::esc::memory::Memory;
use crate::plant::encoder::{self, EncoderModule};
use crate::plant::record::DriveRecord;
use crate::plant::servo::ServoDrive;
use crate::plant::switches::{SwitchCam, SwitchesModule};
use crate::plant::Exchange;

/// 0x1000 of the CiA 402 servo: profile 0x0192, servo drive 0x0002.
pub const DEVICE_TYPE_SERVO: u32 = 0x0002_0192;
/// 0x1000 of the encoder: profile 406 (0x0196), encoder type 5.
pub const DEVICE_TYPE_ENCODER: u32 = 0x0005_0196;
/// 0x1000 of the input module: profile 401 (0x0191), bit 16 digital inputs.
pub const DEVICE_TYPE_DIGITAL_INPUTS: u32 = 0x0001_0191;

/// CiA 406 0x6001 measuring units per revolution.
pub const MEASURING_UNITS_PER_REVOLUTION: u16 = 0x6001;
/// CiA 406 0x6003 preset value.
pub const PRESET_VALUE: u16 = 0x6003;
/// CiA 406 0x6004 position value.
pub const POSITION_VALUE: ObjectId = ObjectId {
    index: 0x6004,
    sub: 0,
    kind: DataType::U32,
    name: "Position value",
};
/// CiA 401 0x6000 read input 8-bit (sub 1: inputs 1–8).
pub const READ_INPUT_8: ObjectId = ObjectId {
    index: 0x6000,
    sub: 1,
    kind: DataType::U8,
    name: "Read input 8-bit",
};
/// CiA 401 0x6002 polarity input 8-bit.
pub const POLARITY_INPUT_8: u16 = 0x6002;

/// The encoder's TPDO-mappable objects, in its input image's order.
pub const ENCODER_INPUTS: [ObjectId; 1] = [POSITION_VALUE];
/// The input module's TPDO-mappable objects.
pub const SWITCHES_INPUTS: [ObjectId; 1] = [READ_INPUT_8];

/// Which device a node is (what its PDOs may map).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DeviceKind {
    /// CiA 402 servo.
    Servo,
    /// CiA 406 encoder.
    Encoder,
    /// CiA 401 digital inputs.
    Switches,
}

impl DeviceKind {
    /// Objects an RPDO may map, in the full output image's order.
    pub const fn outputs(self) -> &'static [ObjectId] {
        match self {
            Self::Servo => &image::OUTPUT_OBJECTS,
            Self::Encoder | Self::Switches => &[],
        }
    }

    /// Objects a TPDO may map, in the full input image's order.
    pub const fn inputs(self) -> &'static [ObjectId] {
        match self {
            Self::Servo => &image::INPUT_OBJECTS,
            Self::Encoder => &ENCODER_INPUTS,
            Self::Switches => &SWITCHES_INPUTS,
        }
    }

    /// 0x1000.
    pub const fn device_type(self) -> u32 {
        match self {
            Self::Servo => DEVICE_TYPE_SERVO,
            Self::Encoder => DEVICE_TYPE_ENCODER,
            Self::Switches => DEVICE_TYPE_DIGITAL_INPUTS,
        }
    }

    /// 0x1008 manufacturer device name.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Servo => "gantry-sim CiA 402 servo",
            Self::Encoder => "gantry-sim CiA 406 encoder",
            Self::Switches => "gantry-sim CiA 401 switch-cam inputs",
        }
    }

    /// The power-on mapping: RPDO1 and TPDO1 objects, synchronous (the servo's: the
    /// minimal CSP layout, as on EtherCAT).
    pub fn power_on_mapping(self) -> (&'static [ObjectId], &'static [ObjectId]) {
        match self {
            Self::Servo => (&CSP_MINIMAL_OUTPUTS, &CSP_MINIMAL_INPUTS),
            Self::Encoder => (&[], &ENCODER_INPUTS),
            Self::Switches => (&[], &SWITCHES_INPUTS),
        }
    }
}

/// Controlword and target position (the EtherCAT servo's power-up RxPDO).
const CSP_MINIMAL_OUTPUTS: [ObjectId; 2] = [
    gantry_drives::cia402::objects::CONTROLWORD,
    gantry_drives::cia402::objects::TARGET_POSITION,
];
/// Statusword and position actual value (the EtherCAT servo's power-up TxPDO).
const CSP_MINIMAL_INPUTS: [ObjectId; 2] = [
    gantry_drives::cia402::objects::STATUSWORD,
    gantry_drives::cia402::objects::POSITION_ACTUAL_VALUE,
];

/// Name and type of a profile object of a `kind` device that the CiA 402 table does not
/// name (the encoder's CiA 406 and the input module's CiA 401 objects), for its EDS.
pub fn profile_object(kind: DeviceKind, index: u16, sub: u8) -> Option<(&'static str, DataType)> {
    Some(match (kind, index, sub) {
        (DeviceKind::Encoder, MEASURING_UNITS_PER_REVOLUTION, 0) => {
            ("Measuring units per revolution", DataType::U32)
        }
        (DeviceKind::Encoder, PRESET_VALUE, 0) => ("Preset value", DataType::U32),
        (DeviceKind::Encoder, 0x6004, 0) => (POSITION_VALUE.name, DataType::U32),
        (DeviceKind::Switches, 0x6000, 0) => ("Number of input 8-bit groups", DataType::U8),
        (DeviceKind::Switches, 0x6000, 1) => (READ_INPUT_8.name, DataType::U8),
        (DeviceKind::Switches, POLARITY_INPUT_8, 0) => {
            ("Number of polarity 8-bit groups", DataType::U8)
        }
        (DeviceKind::Switches, POLARITY_INPUT_8, 1) => ("Polarity input 8-bit", DataType::U8),
        // CiA 402-2 0x6099 Homing speeds: an ARRAY, sub 0 its highest sub-index.
        (DeviceKind::Servo, 0x6099, 0) => ("Highest sub-index supported", DataType::U8),
        _ => return None,
    })
}

/// Name of a profile ARRAY of a `kind` device, for its EDS.
pub fn profile_array(kind: DeviceKind, index: u16) -> Option<&'static str> {
    match (kind, index) {
        (DeviceKind::Switches, 0x6000) => Some("Read input 8-bit"),
        (DeviceKind::Switches, POLARITY_INPUT_8) => Some("Polarity input 8-bit"),
        (DeviceKind::Servo, 0x6099) => Some("Homing speeds"),
        _ => None,
    }
}

/// Byte offset of `o` in a full image of `list` (every object once, in order).
pub fn image_offset(list: &[ObjectId], o: ObjectId) -> Option<usize> {
    let mut at = 0;
    for x in list {
        if x.index == o.index && x.sub == o.sub && x.kind == o.kind {
            return Some(at);
        }
        at += x.kind.size();
    }
    None
}

/// The encoder module behind a CiA 406 node.
#[derive(Clone, Debug)]
pub struct EncoderDevice {
    module: EncoderModule,
    /// The module's process image (outputs at 0, inputs after), as on its ESC.
    mem: Memory,
    /// A preset value written and not yet loaded (loaded at the next run).
    preset: Option<u32>,
}

/// Where the encoder device keeps the module's outputs and inputs in its memory.
const ENC_OUT: u16 = crate::catalog::ENCODER_OUTPUTS_AT;
const ENC_IN: u16 = crate::catalog::ENCODER_INPUTS_AT;

impl EncoderDevice {
    /// An encoder of `counts_per_rev` whose shaft turns by itself at `shaft_speed_rev_s`
    /// (0: the test turns it).
    pub fn new(counts_per_rev: u32, shaft_speed_rev_s: f64) -> Self {
        let mut module = EncoderModule::new(ENC_OUT, ENC_IN, counts_per_rev);
        module.shaft_speed_rev_s = shaft_speed_rev_s;
        Self {
            module,
            mem: Memory::new(),
            preset: None,
        }
    }

    /// The module (its shaft, counter).
    pub fn module(&self) -> &EncoderModule {
        &self.module
    }

    /// The module, mutable (a test turns its shaft).
    pub fn module_mut(&mut self) -> &mut EncoderModule {
        &mut self.module
    }

    /// One step of the module: a pending preset is loaded with the set-counter edge
    /// (0x7000 bit 2 with 0x7000:11, the EL5101's), which the next step releases.
    fn run(&mut self, dt_s: f64) {
        let (control, value) = match self.preset.take() {
            Some(v) => (encoder::control::SET_COUNTER, v),
            None => (0, 0),
        };
        let mut out = [0u8; encoder::OUTPUT_BYTES];
        let (c, v) = (control.to_le_bytes(), value.to_le_bytes());
        for (d, s) in out.iter_mut().zip(c.iter().chain(&v)) {
            *d = *s;
        }
        self.mem.pdi_write(ENC_OUT, &out);
        self.module.step(&mut self.mem, dt_s, Exchange::OP);
        if control != 0 {
            // Release the edge at once (zero time: the shaft does not move).
            self.mem.pdi_write(ENC_OUT, &[0u8; encoder::OUTPUT_BYTES]);
            self.module.step(&mut self.mem, 0.0, Exchange::OP);
        }
    }
}

/// The switch-cam module behind a CiA 401 node.
#[derive(Clone, Debug)]
pub struct SwitchesDevice {
    module: SwitchesModule,
    /// The node of the servo whose position moves the cams.
    pub axis: NodeId,
    /// 0x6002:01.
    polarity: u8,
    /// Scratch ESC memory the module writes its input byte to (unused here).
    mem: Memory,
}

impl SwitchesDevice {
    /// The module with `cams` on the servo at node `axis`.
    pub fn new(axis: NodeId, cams: &[SwitchCam]) -> Result<Self, crate::plant::switches::CamError> {
        Ok(Self {
            module: SwitchesModule::new(crate::catalog::SWITCHES_INPUTS_AT, 0, cams.to_vec())?,
            axis,
            polarity: 0,
            mem: Memory::new(),
        })
    }

    /// The inputs as 0x6000:01 reads them: the switches' levels, each inverted where
    /// 0x6002:01 sets its bit.
    pub fn inputs(&self) -> u8 {
        self.module.inputs() ^ self.polarity
    }

    /// The module.
    pub fn module(&self) -> &SwitchesModule {
        &self.module
    }
}

/// What a node's device is built from (Copy, as [`super::CanNodeConfig`] is).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CanDeviceConfig {
    /// The servo of the node config's `params` and `start_counts`.
    Servo,
    /// The encoder module.
    Encoder {
        /// Counts per shaft revolution.
        counts_per_rev: u32,
        /// Speed at which the shaft turns by itself (rev/s); 0: the test turns it.
        shaft_speed_rev_s: f64,
    },
    /// The switch-cam input module.
    Switches {
        /// The servo's node.
        axis: NodeId,
        /// The cams, at most one per input.
        cams: [Option<SwitchCam>; crate::plant::switches::INPUTS as usize],
    },
}

/// The application of a node.
// A servo's model is larger than the others'; each node holds one, built once.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum CanDevice {
    /// CiA 402 servo.
    Servo(ServoDrive),
    /// CiA 406 encoder.
    Encoder(EncoderDevice),
    /// CiA 401 switch-cam inputs.
    Switches(SwitchesDevice),
}

impl CanDevice {
    /// Which device.
    pub const fn kind(&self) -> DeviceKind {
        match self {
            Self::Servo(_) => DeviceKind::Servo,
            Self::Encoder(_) => DeviceKind::Encoder,
            Self::Switches(_) => DeviceKind::Switches,
        }
    }

    /// Adds the device's profile objects to its dictionary (the mappable ones are there
    /// already), with their power-on values.
    pub fn install_objects(&mut self, od: &mut Od) {
        match self {
            Self::Servo(s) => {
                s.configure(gantry_drives::cia402::pdo::PdoLayout {
                    outputs: image::OUTPUT_OBJECTS.to_vec(),
                    inputs: image::INPUT_OBJECTS.to_vec(),
                });
                s.install_objects(od);
            }
            Self::Encoder(e) => {
                od.insert(
                    MEASURING_UNITS_PER_REVOLUTION,
                    0,
                    &e.module.counts_per_rev.to_le_bytes(),
                    false,
                );
                od.insert(PRESET_VALUE, 0, &0u32.to_le_bytes(), true);
            }
            Self::Switches(_) => {
                // CiA 401: sub 0 the number of 8-bit groups.
                od.insert(READ_INPUT_8.index, 0, &[1], false);
                od.insert(POLARITY_INPUT_8, 0, &[1], false);
                od.insert(POLARITY_INPUT_8, 1, &[0], true);
            }
        }
    }

    /// Writes the present values into the dictionary (before an SDO upload).
    pub fn publish_objects(&self, od: &mut Od) {
        if let Self::Servo(s) = self {
            s.publish_objects(od);
        }
    }

    /// Takes what an SDO download wrote to `index`:`sub`.
    pub fn take_objects(&mut self, od: &Od, index: u16, sub: u8) {
        match self {
            Self::Servo(s) => s.take_objects(od),
            Self::Encoder(e) => {
                if (index, sub) == (PRESET_VALUE, 0) {
                    if let Ok(b) = od.read(PRESET_VALUE, 0) {
                        let mut v = [0u8; 4];
                        for (d, s) in v.iter_mut().zip(b) {
                            *d = *s;
                        }
                        e.preset = Some(u32::from_le_bytes(v));
                        // CiA 406: the position value takes the preset when it is
                        // written, not at the next cycle.
                        e.run(0.0);
                    }
                }
            }
            Self::Switches(s) => {
                if let Ok(b) = od.read(POLARITY_INPUT_8, 1) {
                    s.polarity = b.first().copied().unwrap_or(0);
                }
            }
        }
    }

    /// The full input image (every [`DeviceKind::inputs`] object once).
    pub fn publish_input_image(&self, buf: &mut [u8]) {
        match self {
            Self::Servo(s) => s.publish_input_image(buf),
            Self::Encoder(e) => {
                if let Some(d) = buf.get_mut(0..4) {
                    d.copy_from_slice(&e.module.counter().to_le_bytes());
                }
            }
            Self::Switches(s) => {
                if let Some(d) = buf.first_mut() {
                    *d = s.inputs();
                }
            }
        }
    }

    /// Takes the full output image (the servo's command).
    pub fn take_output_image(&mut self, buf: &[u8]) {
        if let Self::Servo(s) = self {
            s.take_output_image(buf);
        }
    }

    /// Runs `dt_s` seconds of the application.
    pub fn run(&mut self, dt_s: f64) {
        match self {
            Self::Servo(s) => s.run(dt_s),
            Self::Encoder(e) => e.run(dt_s),
            Self::Switches(_) => {}
        }
    }

    /// Reset application (NMT reset node): the application's power-on state; the
    /// physical things (a shaft, a load) stay where they are. The encoder's counter is
    /// electronic: it restarts at 0, as at power-on, and counts the shaft from there.
    pub fn power_on_reset(&mut self) {
        match self {
            Self::Servo(s) => s.power_on_reset(),
            Self::Encoder(e) => {
                e.preset = Some(0);
                e.run(0.0);
            }
            Self::Switches(s) => s.polarity = 0,
        }
    }

    /// The CiA 402 state (None: no drive).
    pub fn drive_state(&self) -> Option<State> {
        match self {
            Self::Servo(s) => Some(s.state()),
            _ => None,
        }
    }

    /// Whether the drive is in Fault or Fault reaction active.
    pub fn faulted(&self) -> bool {
        matches!(
            self.drive_state(),
            Some(State::Fault | State::FaultReactionActive)
        )
    }

    /// The drive's error code (0x603F), 0 without a drive.
    pub fn error_code(&self) -> u16 {
        match self {
            Self::Servo(s) => s.error_code(),
            _ => 0,
        }
    }

    /// A communication error the drive reacts to (CiA 402-2 0x6007); no drive, no
    /// reaction.
    pub fn communication_fault(&mut self, code: u16) {
        if let Self::Servo(s) = self {
            s.communication_fault(code);
        }
    }

    /// The drive's record (None: no drive).
    pub fn record_mut(&mut self) -> Option<&mut DriveRecord> {
        match self {
            Self::Servo(s) => Some(s.record_mut()),
            _ => None,
        }
    }

    /// The position a servo reports as its actual value (counts), for modules coupled
    /// to its axis.
    pub fn axis_position(&self) -> Option<i64> {
        match self {
            Self::Servo(s) => Some(s.position_counts()),
            _ => None,
        }
    }

    /// The node whose axis moves this device's cams.
    pub fn coupled_axis(&self) -> Option<NodeId> {
        match self {
            Self::Switches(s) => Some(s.axis),
            _ => None,
        }
    }

    /// The coupled axis is at `position` (counts).
    pub fn sense_axis(&mut self, position: i64) {
        if let Self::Switches(s) = self {
            s.module.sense(&mut s.mem, position, Exchange::OP);
        }
    }
}
