//! The CANopen node's object dictionary (CiA 301 §7.4, §7.5): the communication objects
//! it owns (0x1000–0x1FFF) and its device's profile objects (0x6000–0x9FFF: the servo's CiA
//! 402 objects, the same as on
//! EtherCAT), served to the SDO server through the `ObjectDictionary` trait of
//! `gantry-drives`. No allocation after [`NodeDictionary::new`].
//!
//! | Object | Access | What |
//! |---|---|---|
//! | 0x1000 | const | device type: 0x00020192 CiA 402 servo drive; the encoder's and input module's in [`super::device`] |
//! | 0x1001 | ro | error register (CiA 301 §7.5.2.2) |
//! | 0x1003:00 / 01–08 | rw / ro | pre-defined error field: the last 8 EMCY codes, newest at sub 1; writing 0 to sub 0 clears it (§7.5.2.3) |
//! | 0x1005 | const | COB-ID SYNC 0x080 |
//! | 0x1006 | rw | communication cycle period (µs, 0 = off): the SYNC consumer's watchdog (§7.5.2.6) |
//! | 0x1008, 0x100A | const | manufacturer device name, software version (VISIBLE_STRING: uploaded segmented or by block) |
//! | 0x1014 | rw | COB-ID EMCY (power-on 0x080 + node; bit 31 = no EMCY; the identifier changes only while bit 31 is set, §7.5.2.13) |
//! | 0x1015 | rw | inhibit time EMCY (100 µs, §7.5.2.14) |
//! | 0x1019 | rw | synchronous counter overflow value: 0 SYNC without counter, 2..=240 with; writable only while 0x1006 is 0 (§7.5.2.22) |
//! | 0x1016:01 | rw | heartbeat consumer: node id << 16 \| time (ms) (§7.5.2.16) |
//! | 0x1017 | rw | heartbeat producer time (ms, 0 = off) (§7.5.2.17) |
//! | 0x1018:01–04 | ro | identity: vendor, product, revision, serial |
//! | 0x1029:01 | rw | error behaviour on a communication error: 0 pre-operational, 1 no change, 2 stopped (§7.5.2.32) |
//! | 0x1400–0x1403, 0x1600–0x1603 | rw | RPDO communication / mapping ([`super::pdo`]); up to 0x1407 / 0x1607 with `pdo_count` |
//! | 0x1800–0x1803, 0x1A00–0x1A03 | rw | TPDO communication / mapping; up to 0x1807 / 0x1A07 with `pdo_count` |
//! | 0x2010 | rw | missed SYNC setpoint limit (manufacturer-specific, see [`MISSED_SETPOINT_LIMIT`]) |
//! | 0x2100–0x2103 | rw, ro, rw, rw | the servo's commutation offset, pole pairs, open-loop current vector amplitude and angle (manufacturer-specific, `gantry_drives::cia402::objects::MANUFACTURER`; installed by the servo, as on EtherCAT) |
//! | 0x2F00 | ro | recorder: a manufacturer DOMAIN of `recorder_bytes` (chain file; absent when 0) whose byte `i` is [`recorder_byte`]`(i)`, for large SDO uploads (segmented, block) |
//! | 0x2F01 | rw | scratch: a manufacturer DOMAIN of up to `scratch_bytes` (chain file; absent when 0) that reads back what was last written to it (empty at power-on and after reset application), for large SDO downloads |
//! | 0x6007 | rw | abort connection option code (CiA 402-2): 0 none, 1 fault |
//! | 0x6000… | | the device's objects (`CanDevice::install_objects`) and every mappable one |

use gantry_drives::canopen::cob_id::{CobId, NodeId, SYNC_COB_ID};
use gantry_drives::canopen::sdo::{
    AbortCode, Access, EntryInfo, Multiplexer, ObjectDictionary as SdoDictionary, ObjectSize,
};
use gantry_drives::cia402::objects::ObjectId;

use super::device::{image_offset, CanDevice, DeviceKind};
use super::pdo::{self, Direction, Pdo, MAX_PDO_COUNT};
use crate::coe::od::{ObjectDictionary as Od, OdError};

/// 0x1000 device type.
pub const DEVICE_TYPE: u16 = 0x1000;
/// Device type value of a CiA 402 servo drive: profile 0x0192 (402), type 0x0002 (servo).
pub const DEVICE_TYPE_CIA402_SERVO: u32 = super::device::DEVICE_TYPE_SERVO;
/// 0x1001 error register.
pub const ERROR_REGISTER: u16 = 0x1001;
/// 0x1003 pre-defined error field.
pub const PREDEFINED_ERROR_FIELD: u16 = 0x1003;
/// Errors 0x1003 keeps.
pub const ERROR_HISTORY: usize = 8;
/// 0x1005 COB-ID SYNC.
pub const COB_ID_SYNC: u16 = 0x1005;
/// 0x1006 communication cycle period.
pub const COMMUNICATION_CYCLE_PERIOD: u16 = 0x1006;
/// 0x1008 manufacturer device name.
pub const DEVICE_NAME: u16 = 0x1008;
/// 0x100A manufacturer software version.
pub const SOFTWARE_VERSION: u16 = 0x100A;
/// Value of 0x1008 of the servo (the other devices': [`DeviceKind::name`]).
pub const DEVICE_NAME_VALUE: &str = DeviceKind::Servo.name();
/// Value of 0x100A: the simulator's version.
pub const SOFTWARE_VERSION_VALUE: &str = env!("CARGO_PKG_VERSION");
/// 0x1014 COB-ID EMCY.
pub const COB_ID_EMCY: u16 = 0x1014;
/// 0x1016 consumer heartbeat time.
pub const CONSUMER_HEARTBEAT_TIME: u16 = 0x1016;
/// 0x1017 producer heartbeat time.
pub const PRODUCER_HEARTBEAT_TIME: u16 = 0x1017;
/// 0x1018 identity object.
pub const IDENTITY: u16 = 0x1018;
/// 0x1015 inhibit time EMCY.
pub const INHIBIT_TIME_EMCY: u16 = 0x1015;
/// 0x1019 synchronous counter overflow value.
pub const SYNC_COUNTER_OVERFLOW: u16 = 0x1019;
/// 0x1029 error behaviour.
pub const ERROR_BEHAVIOUR: u16 = 0x1029;
/// Manufacturer-specific 0x2010: SYNCs in a row without a synchronous RPDO, while the
/// drive is in Operation enabled, after which it faults with 0x8250 (CiA 301 Table 21
/// "RPDO timeout"); 0 = never. CiA 301 leaves RPDO deadline monitoring to the event timer
/// (time, not count); a count in a row is what EtherCAT drives configure (ETG.1020 0x10F1:02
/// "sync error counter limit"), so the CANopen drive is judged like the EtherCAT one.
pub const MISSED_SETPOINT_LIMIT: u16 = 0x2010;
/// Manufacturer-specific 0x2F00: the recorder, a read-only DOMAIN (CiA 301 §7.4.7.1
/// data type 0x000F: any length, uploaded segmented or by block, never expedited unless
/// 4 bytes or less) whose content is known ([`recorder_byte`]) so a client's upload can be
/// checked byte for byte. Present only with a length (chain file `recorder_bytes`).
pub const RECORDER: u16 = 0x2F00;
/// Largest recorder (bytes): a 64 KiB trace is what the SDO benchmark moves; 1 MiB
/// leaves room without letting a chain file ask for gigabytes.
pub const RECORDER_MAX_BYTES: usize = 1 << 20;

/// Manufacturer-specific 0x2F01: the scratch, a read-write DOMAIN of any length up to
/// the chain file's `scratch_bytes` (CiA 301 §7.4.7.1: a download of more is refused with
/// 0x06070012) that an upload reads back as last written, so a client's download can be
/// checked byte for byte. Present only with a length.
pub const SCRATCH: u16 = 0x2F01;

/// Byte `i` of the recorder 0x2F00: the top byte of a multiplicative hash of `i`
/// (Knuth's 2654435761), so that no 256-byte period hides a segment delivered in the
/// wrong place. Python: `((i * 2654435761) & 0xFFFFFFFF) >> 24`.
pub const fn recorder_byte(i: usize) -> u8 {
    ((i as u32).wrapping_mul(2_654_435_761) >> 24) as u8
}

/// CiA 402-2 0x6007 abort connection option code.
pub const ABORT_CONNECTION_OPTION_CODE: u16 = 0x6007;
/// Power-on value of 0x2010.
pub const DEFAULT_MISSED_SETPOINT_LIMIT: u16 = 4;

/// Bytes of the full process images (every mappable object once).
pub const IMAGE_BYTES: usize = 64;

/// Error behaviour 0x1029:01 values.
pub mod behaviour {
    /// Enter Pre-operational (if Operational).
    pub const PRE_OPERATIONAL: u8 = 0;
    /// No change of the NMT state.
    pub const NO_CHANGE: u8 = 1;
    /// Enter Stopped.
    pub const STOPPED: u8 = 2;
}

/// The communication objects that reset communication restores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Communication {
    /// 0x1016:01.
    pub heartbeat_consumer: u32,
    /// 0x1017.
    pub heartbeat_producer_ms: u16,
    /// 0x1006 (µs).
    pub cycle_period_us: u32,
    /// 0x1019.
    pub sync_overflow: u8,
    /// 0x1014.
    pub emcy_cob_id: u32,
    /// 0x1015 (100 µs).
    pub emcy_inhibit_100us: u16,
    /// 0x1029:01.
    pub error_behaviour: u8,
    /// PDOs the node has each way (1..=[`MAX_PDO_COUNT`]): the objects of the others do
    /// not exist, and their entries below stay invalid.
    pub pdo_count: u8,
    /// 0x1400… with 0x1600…
    pub rpdo: [Pdo; MAX_PDO_COUNT],
    /// 0x1800… with 0x1A00…
    pub tpdo: [Pdo; MAX_PDO_COUNT],
}

impl Communication {
    /// Power-on values for `node` of a `kind` device: RPDO1 and TPDO1 map the device's
    /// power-on objects ([`DeviceKind::power_on_mapping`]; the servo's: controlword +
    /// target position and statusword + position actual value, the EtherCAT servo's
    /// power-up mapping), synchronous on every SYNC, on their predefined COB-IDs; a PDO
    /// that maps nothing and the others exist not (COB-ID bit 31). `pdo_count` PDOs each
    /// way (at most [`MAX_PDO_COUNT`]): PDOs 2–4 invalid on their predefined COB-IDs,
    /// PDOs 5 and up invalid on none (0x80000000: CiA 301 predefines four).
    pub fn power_on(
        node: NodeId,
        heartbeat_producer_ms: u16,
        kind: DeviceKind,
        pdo_count: u8,
    ) -> Self {
        let (outputs, inputs) = kind.power_on_mapping();
        let id = |c: Result<CobId, _>| c.map(CobId::id).unwrap_or(0);
        let mut rpdo = [Pdo::unused(kind, Direction::Receive, 0); MAX_PDO_COUNT];
        let mut tpdo = [Pdo::unused(kind, Direction::Transmit, 0); MAX_PDO_COUNT];
        // CobId::rpdo/tpdo refuse PDO 5 and up: identifier 0.
        for (n, (r, t)) in rpdo.iter_mut().zip(tpdo.iter_mut()).enumerate() {
            let k = n as u8 + 1;
            *r = Pdo::unused(kind, Direction::Receive, id(CobId::rpdo(k, node)));
            *t = Pdo::unused(kind, Direction::Transmit, id(CobId::tpdo(k, node)));
        }
        if !outputs.is_empty() {
            rpdo[0] = Pdo::synchronous(kind, Direction::Receive, id(CobId::rpdo(1, node)), outputs);
        }
        if !inputs.is_empty() {
            tpdo[0] = Pdo::synchronous(kind, Direction::Transmit, id(CobId::tpdo(1, node)), inputs);
        }
        Self {
            heartbeat_consumer: 0,
            heartbeat_producer_ms,
            cycle_period_us: 0,
            sync_overflow: 0,
            emcy_cob_id: u32::from(CobId::Emcy(node).id()),
            emcy_inhibit_100us: 0,
            error_behaviour: behaviour::PRE_OPERATIONAL,
            pdo_count: pdo_count.clamp(1, MAX_PDO_COUNT as u8),
            rpdo,
            tpdo,
        }
    }

    /// Whether the EMCY exists (0x1014 bit 31 clear).
    pub const fn emcy_valid(&self) -> bool {
        self.emcy_cob_id & pdo::COB_ID_INVALID == 0
    }

    /// The EMCY's 11-bit identifier.
    pub const fn emcy_can_id(&self) -> u16 {
        (self.emcy_cob_id & 0x7FF) as u16
    }

    /// The heartbeat consumer entry: (node, time in ms), if it monitors one.
    pub fn consumer(&self) -> Option<(u8, u16)> {
        let node = ((self.heartbeat_consumer >> 16) & 0xFF) as u8;
        let ms = self.heartbeat_consumer as u16;
        (node != 0 && ms != 0).then_some((node, ms))
    }
}

/// Something an SDO write changed that the node's protocol side must act on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Changed {
    /// 0x1016 was written: monitoring restarts.
    pub heartbeat_consumer: bool,
    /// RPDO n's or TPDO n's communication parameter was written: its run-time state
    /// (pending data, SYNC count, last sent) restarts.
    pub rpdo: [bool; MAX_PDO_COUNT],
    /// Same for TPDOs.
    pub tpdo: [bool; MAX_PDO_COUNT],
    /// 0x1006 was written: the SYNC watchdog restarts.
    pub sync_watchdog: bool,
}

/// The node's dictionary and the device behind it.
#[derive(Debug)]
pub struct NodeDictionary {
    node: NodeId,
    identity: [u32; 4],
    /// Communication objects in use.
    pub comm: Communication,
    comm_power_on: Communication,
    /// 0x1001, kept by the node.
    pub error_register: u8,
    /// 0x1003:01..: newest first; `error_count` of them valid.
    error_history: [u32; ERROR_HISTORY],
    error_count: u8,
    /// 0x2010.
    pub missed_setpoint_limit: u16,
    /// The application: the servo, the encoder or the input module.
    pub device: CanDevice,
    od: Od,
    od_power_on: Od,
    /// Full output image (every [`DeviceKind::outputs`] object once): what the device
    /// takes.
    pub rx_image: [u8; IMAGE_BYTES],
    /// Full input image (every [`DeviceKind::inputs`] object once): what TPDOs are cut
    /// from.
    pub tx_image: [u8; IMAGE_BYTES],
    /// What the last SDO writes changed (the node takes and clears it).
    pub changed: Changed,
    /// 0x2F00's content (empty: no recorder).
    recorder: Box<[u8]>,
    /// 0x2F01's room (empty: no scratch) and the bytes of it written last.
    scratch: Box<[u8]>,
    scratch_len: usize,
}

fn od_abort(e: OdError) -> AbortCode {
    match e {
        OdError::NoObject => AbortCode::OBJECT_DOES_NOT_EXIST,
        OdError::NoSubIndex => AbortCode::SUB_INDEX_DOES_NOT_EXIST,
        OdError::ReadOnly => AbortCode::READ_ONLY,
        OdError::LengthMismatch => AbortCode::LENGTH_MISMATCH,
        OdError::WrongState => AbortCode::CANNOT_STORE_DEVICE_STATE,
        OdError::NotMappable => AbortCode::NOT_MAPPABLE,
        OdError::PdoTooLong => AbortCode::PDO_LENGTH_EXCEEDED,
        OdError::ValueRange => AbortCode::INVALID_VALUE,
        OdError::ValueTooHigh => AbortCode::VALUE_TOO_HIGH,
    }
}

fn put(out: &mut [u8], v: &[u8]) -> Result<usize, AbortCode> {
    out.get_mut(..v.len())
        .ok_or(AbortCode::OUT_OF_MEMORY)?
        .copy_from_slice(v);
    Ok(v.len())
}

fn fixed(access: Access, n: usize) -> EntryInfo {
    EntryInfo {
        access,
        size: ObjectSize::Fixed(n),
    }
}

/// The PDO an index names on a node with `count` PDOs each way: (direction, number
/// 0..count, mapping?).
fn pdo_of(index: u16, count: u8) -> Option<(Direction, usize, bool)> {
    let n = u16::from(count);
    let (dir, base, mapping) = match index {
        i if (pdo::RPDO_COMMUNICATION..pdo::RPDO_COMMUNICATION + n).contains(&i) => {
            (Direction::Receive, pdo::RPDO_COMMUNICATION, false)
        }
        i if (pdo::RPDO_MAPPING..pdo::RPDO_MAPPING + n).contains(&i) => {
            (Direction::Receive, pdo::RPDO_MAPPING, true)
        }
        i if (pdo::TPDO_COMMUNICATION..pdo::TPDO_COMMUNICATION + n).contains(&i) => {
            (Direction::Transmit, pdo::TPDO_COMMUNICATION, false)
        }
        i if (pdo::TPDO_MAPPING..pdo::TPDO_MAPPING + n).contains(&i) => {
            (Direction::Transmit, pdo::TPDO_MAPPING, true)
        }
        _ => return None,
    };
    Some((dir, usize::from(index - base), mapping))
}

/// Writes `bytes` of `o` at its place in a full image.
pub fn image_put(image: &mut [u8], at: Option<usize>, o: ObjectId, bytes: &[u8]) {
    let n = o.kind.size();
    if let (Some(at), Some(src)) = (at, bytes.get(..n)) {
        if let Some(dst) = image.get_mut(at..at + n) {
            dst.copy_from_slice(src);
        }
    }
}

impl NodeDictionary {
    /// The dictionary of `node` with `identity` (vendor, product, revision, serial) and
    /// `device` behind it; 0x1017 powers on with `heartbeat_producer_ms`; `pdo_count`
    /// PDOs each way (1..=[`MAX_PDO_COUNT`], clamped).
    pub fn new(
        node: NodeId,
        identity: [u32; 4],
        heartbeat_producer_ms: u16,
        mut device: CanDevice,
        pdo_count: u8,
    ) -> Self {
        let kind = device.kind();
        let mut od = Od::default();
        for o in kind.outputs() {
            od.insert(o.index, o.sub, &vec![0; o.kind.size()], true);
        }
        for o in kind.inputs() {
            od.insert(o.index, o.sub, &vec![0; o.kind.size()], false);
        }
        if kind == DeviceKind::Servo {
            od.insert_ranged(ABORT_CONNECTION_OPTION_CODE, 0, &1i16.to_le_bytes(), 0, 1);
        }
        device.install_objects(&mut od);
        let comm = Communication::power_on(node, heartbeat_producer_ms, kind, pdo_count);
        let mut d = Self {
            node,
            identity,
            comm,
            comm_power_on: comm,
            error_register: 0,
            error_history: [0; ERROR_HISTORY],
            error_count: 0,
            missed_setpoint_limit: DEFAULT_MISSED_SETPOINT_LIMIT,
            device,
            od_power_on: Od::default(),
            od,
            rx_image: [0; IMAGE_BYTES],
            tx_image: [0; IMAGE_BYTES],
            changed: Changed::default(),
            recorder: Box::default(),
            scratch: Box::default(),
            scratch_len: 0,
        };
        d.refresh_objects();
        d.od_power_on = d.od.clone();
        d.sync_rx_image();
        d
    }

    /// Gives the node the recorder 0x2F00 of `bytes` bytes ([`recorder_byte`]; 0: none).
    /// Allocates: call it before the node runs.
    pub fn set_recorder(&mut self, bytes: usize) {
        self.recorder = (0..bytes).map(recorder_byte).collect();
    }

    /// Bytes of the recorder 0x2F00 (0: the node has none).
    pub fn recorder_len(&self) -> usize {
        self.recorder.len()
    }

    /// Gives the node the scratch 0x2F01 of up to `bytes` bytes, empty (0: none).
    /// Allocates: call it before the node runs.
    pub fn set_scratch(&mut self, bytes: usize) {
        self.scratch = vec![0; bytes].into_boxed_slice();
        self.scratch_len = 0;
    }

    /// The most the scratch 0x2F01 holds (0: the node has none).
    pub fn scratch_capacity(&self) -> usize {
        self.scratch.len()
    }

    /// What was last written to the scratch 0x2F01.
    pub fn scratch(&self) -> &[u8] {
        self.scratch.get(..self.scratch_len).unwrap_or_default()
    }

    /// The device's profile objects (0x6000…): index, sub-index, in the order installed.
    pub fn device_objects(&self) -> impl Iterator<Item = (u16, u8)> + '_ {
        self.od.entries().iter().map(|e| (e.index, e.sub))
    }

    /// Which device.
    pub fn kind(&self) -> DeviceKind {
        self.device.kind()
    }

    /// Offset of `o` in the full input image.
    pub fn input_offset(&self, o: ObjectId) -> Option<usize> {
        image_offset(self.kind().inputs(), o)
    }

    /// Offset of `o` in the full output image.
    pub fn output_offset(&self, o: ObjectId) -> Option<usize> {
        image_offset(self.kind().outputs(), o)
    }

    /// The values an SDO download may write to the device object `index`:`sub`
    /// (inclusive), if the device limits them (its EDS's LowLimit/HighLimit).
    pub fn servo_range(&self, index: u16, sub: u8) -> Option<(i64, i64)> {
        self.od.entry(index, sub).ok().and_then(|e| e.range)
    }

    /// The node id.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// Records an EMCY's error code in 0x1003 (CiA 301 §7.5.2.3: newest at sub 1, the
    /// oldest drops out when full).
    pub fn push_error(&mut self, code: u16) {
        self.error_history.copy_within(..ERROR_HISTORY - 1, 1);
        if let Some(first) = self.error_history.first_mut() {
            *first = u32::from(code);
        }
        self.error_count = (self.error_count + 1).min(ERROR_HISTORY as u8);
    }

    /// 0x6007 abort connection option code.
    pub fn abort_connection_option(&self) -> i16 {
        self.od
            .read(ABORT_CONNECTION_OPTION_CODE, 0)
            .ok()
            .map(|b| {
                i16::from_le_bytes([
                    b.first().copied().unwrap_or(1),
                    b.get(1).copied().unwrap_or(0),
                ])
            })
            .unwrap_or(1)
    }

    /// Reset communication (CiA 301 §7.3.2.2.1): 0x1000–0x1FFF to power-on values.
    pub fn reset_communication(&mut self) {
        self.comm = self.comm_power_on;
        self.error_register = 0;
        self.error_count = 0;
    }

    /// Reset application: 0x2000–0x9FFF to power-on values, the device restarts.
    pub fn reset_application(&mut self) {
        self.missed_setpoint_limit = DEFAULT_MISSED_SETPOINT_LIMIT;
        self.scratch_len = 0;
        self.device.power_on_reset();
        self.od.copy_values_from(&self.od_power_on);
        // The command objects start from where the drive is, not where it powered on.
        self.device.take_objects(&self.od, 0, 0);
        self.refresh_objects();
        self.sync_rx_image();
    }

    /// Writes the device's present values into its objects (before an SDO read) and the
    /// full input image.
    pub fn refresh_objects(&mut self) {
        self.device.publish_objects(&mut self.od);
        self.device.publish_input_image(&mut self.tx_image);
        for &o in self.kind().inputs() {
            if let Some(at) = self.input_offset(o) {
                if let Some(b) = self.tx_image.get(at..at + o.kind.size()) {
                    let _ = self.od.set(o.index, o.sub, b);
                }
            }
        }
    }

    /// Copies the command objects' values into the full output image (after an SDO write
    /// or a reset, so that the next SYNC takes what SDO wrote for objects no RPDO maps).
    pub fn sync_rx_image(&mut self) {
        for &o in self.kind().outputs() {
            let offset = self.output_offset(o);
            if let Ok(b) = self.od.read(o.index, o.sub) {
                image_put(&mut self.rx_image, offset, o, b);
            }
        }
    }

    fn comm_entry(&self, mux: Multiplexer) -> Result<EntryInfo, AbortCode> {
        use Access::{Const, ReadOnly, ReadWrite};
        let sub_missing = Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST);
        match (mux.index, mux.sub) {
            (DEVICE_TYPE, 0) | (COB_ID_SYNC, 0) => Ok(fixed(Const, 4)),
            (COB_ID_EMCY, 0) => Ok(fixed(ReadWrite, 4)),
            (INHIBIT_TIME_EMCY, 0) => Ok(fixed(ReadWrite, 2)),
            (COMMUNICATION_CYCLE_PERIOD, 0) => Ok(fixed(ReadWrite, 4)),
            (ERROR_REGISTER, 0) => Ok(fixed(ReadOnly, 1)),
            (PREDEFINED_ERROR_FIELD, 0) => Ok(fixed(ReadWrite, 1)),
            (PREDEFINED_ERROR_FIELD, 1..=8) => Ok(fixed(ReadOnly, 4)),
            (DEVICE_NAME, 0) => Ok(fixed(Const, self.kind().name().len())),
            (SOFTWARE_VERSION, 0) => Ok(fixed(Const, SOFTWARE_VERSION_VALUE.len())),
            (CONSUMER_HEARTBEAT_TIME, 0) | (IDENTITY, 0) | (ERROR_BEHAVIOUR, 0) => {
                Ok(fixed(Const, 1))
            }
            (CONSUMER_HEARTBEAT_TIME, 1) => Ok(fixed(ReadWrite, 4)),
            (PRODUCER_HEARTBEAT_TIME, 0) | (MISSED_SETPOINT_LIMIT, 0) => Ok(fixed(ReadWrite, 2)),
            (IDENTITY, 1..=4) => Ok(fixed(ReadOnly, 4)),
            (ERROR_BEHAVIOUR, 1) | (SYNC_COUNTER_OVERFLOW, 0) => Ok(fixed(ReadWrite, 1)),
            (
                DEVICE_TYPE
                | ERROR_REGISTER
                | PREDEFINED_ERROR_FIELD
                | COMMUNICATION_CYCLE_PERIOD
                | SYNC_COUNTER_OVERFLOW
                | DEVICE_NAME
                | SOFTWARE_VERSION
                | COB_ID_SYNC
                | COB_ID_EMCY
                | INHIBIT_TIME_EMCY
                | CONSUMER_HEARTBEAT_TIME
                | PRODUCER_HEARTBEAT_TIME
                | IDENTITY
                | ERROR_BEHAVIOUR
                | MISSED_SETPOINT_LIMIT,
                _,
            ) => sub_missing,
            (index, sub) => {
                let (dir, n, mapping) =
                    pdo_of(index, self.comm.pdo_count).ok_or(AbortCode::OBJECT_DOES_NOT_EXIST)?;
                let p = self.pdo(dir, n)?;
                if mapping {
                    p.mapping_entry(sub).map(|len| fixed(ReadWrite, len))
                } else {
                    let (len, w) = p.comm_entry(sub)?;
                    Ok(fixed(if w { ReadWrite } else { Const }, len))
                }
            }
        }
    }

    fn pdo(&self, dir: Direction, n: usize) -> Result<&Pdo, AbortCode> {
        let set = match dir {
            Direction::Receive => &self.comm.rpdo,
            Direction::Transmit => &self.comm.tpdo,
        };
        set.get(n).ok_or(AbortCode::OBJECT_DOES_NOT_EXIST)
    }

    fn pdo_mut(&mut self, dir: Direction, n: usize) -> Result<&mut Pdo, AbortCode> {
        let set = match dir {
            Direction::Receive => &mut self.comm.rpdo,
            Direction::Transmit => &mut self.comm.tpdo,
        };
        set.get_mut(n).ok_or(AbortCode::OBJECT_DOES_NOT_EXIST)
    }
}

impl SdoDictionary for NodeDictionary {
    fn entry(&self, mux: Multiplexer) -> Result<EntryInfo, AbortCode> {
        if mux.index == RECORDER && !self.recorder.is_empty() {
            return match mux.sub {
                0 => Ok(fixed(Access::ReadOnly, self.recorder.len())),
                _ => Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST),
            };
        }
        if mux.index == SCRATCH && !self.scratch.is_empty() {
            return match mux.sub {
                0 => Ok(EntryInfo {
                    access: Access::ReadWrite,
                    size: ObjectSize::Variable {
                        max: self.scratch.len(),
                    },
                }),
                _ => Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST),
            };
        }
        if mux.index < 0x2000 || mux.index == MISSED_SETPOINT_LIMIT {
            return self.comm_entry(mux);
        }
        let e = self.od.entry(mux.index, mux.sub).map_err(od_abort)?;
        Ok(fixed(
            if e.writable {
                Access::ReadWrite
            } else {
                Access::ReadOnly
            },
            e.value.len(),
        ))
    }

    fn read(&mut self, mux: Multiplexer, out: &mut [u8]) -> Result<usize, AbortCode> {
        match (mux.index, mux.sub) {
            (DEVICE_TYPE, 0) => put(out, &self.kind().device_type().to_le_bytes()),
            (ERROR_REGISTER, 0) => put(out, &[self.error_register]),
            (PREDEFINED_ERROR_FIELD, 0) => put(out, &[self.error_count]),
            (PREDEFINED_ERROR_FIELD, s) => {
                // A sub-index beyond the errors recorded holds no data (0x08000024).
                if s > self.error_count {
                    return Err(AbortCode::NO_DATA);
                }
                let e = self.error_history.get(usize::from(s) - 1).copied();
                put(out, &e.ok_or(AbortCode::NO_DATA)?.to_le_bytes())
            }
            (DEVICE_NAME, 0) => put(out, self.kind().name().as_bytes()),
            (COMMUNICATION_CYCLE_PERIOD, 0) => put(out, &self.comm.cycle_period_us.to_le_bytes()),
            (SOFTWARE_VERSION, 0) => put(out, SOFTWARE_VERSION_VALUE.as_bytes()),
            (COB_ID_SYNC, 0) => put(out, &u32::from(SYNC_COB_ID).to_le_bytes()),
            (COB_ID_EMCY, 0) => put(out, &self.comm.emcy_cob_id.to_le_bytes()),
            (INHIBIT_TIME_EMCY, 0) => put(out, &self.comm.emcy_inhibit_100us.to_le_bytes()),
            (CONSUMER_HEARTBEAT_TIME, 0) | (ERROR_BEHAVIOUR, 0) => put(out, &[1]),
            (CONSUMER_HEARTBEAT_TIME, 1) => put(out, &self.comm.heartbeat_consumer.to_le_bytes()),
            (PRODUCER_HEARTBEAT_TIME, 0) => {
                put(out, &self.comm.heartbeat_producer_ms.to_le_bytes())
            }
            (IDENTITY, 0) => put(out, &[4]),
            (IDENTITY, s @ 1..=4) => put(
                out,
                &self
                    .identity
                    .get(usize::from(s) - 1)
                    .copied()
                    .unwrap_or(0)
                    .to_le_bytes(),
            ),
            (ERROR_BEHAVIOUR, 1) => put(out, &[self.comm.error_behaviour]),
            (SYNC_COUNTER_OVERFLOW, 0) => put(out, &[self.comm.sync_overflow]),
            (MISSED_SETPOINT_LIMIT, 0) => put(out, &self.missed_setpoint_limit.to_le_bytes()),
            (RECORDER, 0) if !self.recorder.is_empty() => put(out, &self.recorder),
            (SCRATCH, 0) if !self.scratch.is_empty() => {
                let written = self.scratch.get(..self.scratch_len).unwrap_or_default();
                put(out, written)
            }
            (index, sub) if index < 0x2000 => {
                let (dir, n, mapping) =
                    pdo_of(index, self.comm.pdo_count).ok_or(AbortCode::OBJECT_DOES_NOT_EXIST)?;
                let p = self.pdo(dir, n)?;
                if mapping {
                    p.read_mapping(sub, out)
                } else {
                    p.read_comm(sub, out)
                }
            }
            (index, sub) => {
                self.refresh_objects();
                let v = self.od.read(index, sub).map_err(od_abort)?;
                put(out, v)
            }
        }
    }

    fn write(&mut self, mux: Multiplexer, data: &[u8]) -> Result<(), AbortCode> {
        let u16_of = |d: &[u8]| {
            u16::from_le_bytes([
                d.first().copied().unwrap_or(0),
                d.get(1).copied().unwrap_or(0),
            ])
        };
        match (mux.index, mux.sub) {
            (PREDEFINED_ERROR_FIELD, 0) => {
                // Only 0 may be written: it clears the history (§7.5.2.3).
                if data.first().copied() != Some(0) {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.error_count = 0;
                Ok(())
            }
            (CONSUMER_HEARTBEAT_TIME, 1) => {
                let v = u32::from_le_bytes([
                    data.first().copied().unwrap_or(0),
                    data.get(1).copied().unwrap_or(0),
                    data.get(2).copied().unwrap_or(0),
                    data.get(3).copied().unwrap_or(0),
                ]);
                // Bits 24–31 reserved, node id 0..=127 (CiA 301 §7.5.2.16).
                let node = (v >> 16) & 0xFF;
                if v >> 24 != 0 || node > 127 {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.comm.heartbeat_consumer = v;
                self.changed.heartbeat_consumer = true;
                Ok(())
            }
            (PRODUCER_HEARTBEAT_TIME, 0) => {
                self.comm.heartbeat_producer_ms = u16_of(data);
                Ok(())
            }
            (COB_ID_EMCY, 0) => {
                let v = u32::from_le_bytes([
                    data.first().copied().unwrap_or(0),
                    data.get(1).copied().unwrap_or(0),
                    data.get(2).copied().unwrap_or(0),
                    data.get(3).copied().unwrap_or(0),
                ]);
                // 11-bit identifiers only; the identifier changes only while the EMCY
                // does not exist (§7.5.2.13).
                let new_valid = v & pdo::COB_ID_INVALID == 0;
                let id_changes = (v & 0x7FF) != (self.comm.emcy_cob_id & 0x7FF);
                if v & 0x7FFF_F800 != 0
                    || (new_valid && self.comm.emcy_valid() && id_changes)
                    || (new_valid && v & 0x7FF == 0)
                {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.comm.emcy_cob_id = v;
                Ok(())
            }
            (INHIBIT_TIME_EMCY, 0) => {
                self.comm.emcy_inhibit_100us = u16_of(data);
                Ok(())
            }
            (COMMUNICATION_CYCLE_PERIOD, 0) => {
                self.comm.cycle_period_us = u32::from_le_bytes([
                    data.first().copied().unwrap_or(0),
                    data.get(1).copied().unwrap_or(0),
                    data.get(2).copied().unwrap_or(0),
                    data.get(3).copied().unwrap_or(0),
                ]);
                self.changed.sync_watchdog = true;
                Ok(())
            }
            (SYNC_COUNTER_OVERFLOW, 0) => {
                // Only while the communication cycle period is 0 (§7.5.2.22); 1 and
                // above 240 are no overflow values.
                if self.comm.cycle_period_us != 0 {
                    return Err(AbortCode::CANNOT_STORE_DEVICE_STATE);
                }
                let v = data.first().copied().unwrap_or(0);
                if v == 1 || v > pdo::TT_SYNC_MAX {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.comm.sync_overflow = v;
                Ok(())
            }
            (ERROR_BEHAVIOUR, 1) => {
                let v = data.first().copied().unwrap_or(0);
                if v > behaviour::STOPPED {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.comm.error_behaviour = v;
                Ok(())
            }
            (MISSED_SETPOINT_LIMIT, 0) => {
                self.missed_setpoint_limit = u16_of(data);
                Ok(())
            }
            (SCRATCH, 0) if !self.scratch.is_empty() => {
                let dst = self
                    .scratch
                    .get_mut(..data.len())
                    .ok_or(AbortCode::LENGTH_TOO_HIGH)?;
                dst.copy_from_slice(data);
                self.scratch_len = data.len();
                Ok(())
            }
            (index, sub) if index < 0x2000 => {
                let (dir, n, mapping) =
                    pdo_of(index, self.comm.pdo_count).ok_or(AbortCode::READ_ONLY)?;
                let p = self.pdo_mut(dir, n)?;
                if mapping {
                    p.write_mapping(sub, data)
                } else {
                    p.write_comm(sub, data)?;
                    let flags = match dir {
                        Direction::Receive => &mut self.changed.rpdo,
                        Direction::Transmit => &mut self.changed.tpdo,
                    };
                    if let Some(f) = flags.get_mut(n) {
                        *f = true;
                    }
                    Ok(())
                }
            }
            (index, sub) => {
                self.refresh_objects();
                self.od.write(index, sub, data).map_err(od_abort)?;
                self.device.take_objects(&self.od, index, sub);
                self.sync_rx_image();
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::servo::ServoDrive;

    fn dict() -> NodeDictionary {
        let node = NodeId::new(3).unwrap();
        NodeDictionary::new(
            node,
            [1, 2, 3, 4],
            100,
            CanDevice::Servo(ServoDrive::new(0, 0, 0)),
            pdo::DEFAULT_PDO_COUNT,
        )
    }

    #[test]
    fn error_field_keeps_the_newest_eight() {
        let mut d = dict();
        for code in 1..=10u16 {
            d.push_error(code);
        }
        let mut out = [0u8; 4];
        assert_eq!(
            d.read(Multiplexer::new(PREDEFINED_ERROR_FIELD, 0), &mut out),
            Ok(1)
        );
        assert_eq!(out[0], 8);
        let at = |d: &mut NodeDictionary, s| {
            let mut out = [0u8; 4];
            d.read(Multiplexer::new(PREDEFINED_ERROR_FIELD, s), &mut out)
                .map(|_| u32::from_le_bytes(out))
        };
        assert_eq!(at(&mut d, 1), Ok(10), "newest at sub 1");
        assert_eq!(at(&mut d, 8), Ok(3));
        assert_eq!(
            d.entry(Multiplexer::new(PREDEFINED_ERROR_FIELD, 9)),
            Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST)
        );
        d.reset_communication();
        assert_eq!(at(&mut d, 1), Err(AbortCode::NO_DATA));
    }

    #[test]
    fn communication_objects_power_on_values() {
        let mut d = dict();
        let mut out = [0u8; 32];
        let mut read = |i, s| {
            let n = d.read(Multiplexer::new(i, s), &mut out).unwrap();
            out[..n].to_vec()
        };
        assert_eq!(read(DEVICE_TYPE, 0), 0x0002_0192u32.to_le_bytes());
        assert_eq!(read(COB_ID_EMCY, 0), 0x83u32.to_le_bytes());
        assert_eq!(read(COB_ID_SYNC, 0), 0x80u32.to_le_bytes());
        assert_eq!(read(0x1400, 1), 0x203u32.to_le_bytes());
        assert_eq!(read(0x1401, 1), (0x8000_0000u32 | 0x303).to_le_bytes());
        assert_eq!(read(0x1803, 1), (0x8000_0000u32 | 0x483).to_le_bytes());
        assert_eq!(read(0x1A00, 0), [2]);
        assert_eq!(read(0x1A00, 1), 0x6041_0010u32.to_le_bytes());
        assert_eq!(read(0x1A00, 2), 0x6064_0020u32.to_le_bytes());
        assert_eq!(read(0x1600, 2), 0x607A_0020u32.to_le_bytes());
        assert_eq!(read(ABORT_CONNECTION_OPTION_CODE, 0), 1i16.to_le_bytes());
        assert_eq!(read(MISSED_SETPOINT_LIMIT, 0), 4u16.to_le_bytes());
        assert_eq!(read(IDENTITY, 3), 3u32.to_le_bytes());
        assert_eq!(
            d.entry(Multiplexer::new(0x1404, 1)),
            Err(AbortCode::OBJECT_DOES_NOT_EXIST),
            "four PDOs"
        );
        for i in [
            DEVICE_TYPE,
            ERROR_REGISTER,
            DEVICE_NAME,
            SOFTWARE_VERSION,
            COB_ID_SYNC,
        ] {
            assert_eq!(
                d.entry(Multiplexer::new(i, 1)),
                Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST),
                "{i:#06x}"
            );
        }
    }
}
