//! A CANopen node (CiA 301 slave): the NMT slave ([`super::nmt`]) with its boot-up
//! message, heartbeat producer (0x1017) and consumer (0x1016), EMCY producer, SYNC
//! consumer, SDO server on [`NodeDictionary`], PDOs ([`super::pdo`]) and a device behind
//! them ([`super::device`]): the servo plant of `plant::servo` (the same drive as on
//! EtherCAT), the encoder module or the switch-cam input module. What follows about
//! setpoints concerns the servo; the modules have none (their TPDOs carry inputs sampled
//! at the SYNC, and they never fault).
//!
//! Sans-I/O and lockstep: [`CanNode::receive`] takes a frame and the time, [`CanNode::tick`]
//! the time alone; both return the frames the node sends in answer, in order. Nothing
//! allocates after [`CanNode::new`] (frames go out through a fixed buffer).
//!
//! Timing of the drive (a CSP drive on CANopen, CiA 402-2 with CiA 301 §7.2.5): at a SYNC
//! the drive (1) runs its loops up to the SYNC on the command it took at the previous
//! one, (2) samples its inputs and sends the synchronous TPDOs due with them, (3) takes
//! the data of the synchronous RPDOs received since the previous SYNC as its new
//! setpoint. A SYNC in Operation enabled with none of them is a missed setpoint (counted
//! in the drive's record as the EtherCAT drive counts a SYNC0 edge without one), and
//! [`MISSED_SETPOINT_LIMIT`](super::dictionary::MISSED_SETPOINT_LIMIT) in a row fault it
//! with 0x8250. Without SYNCs (Pre-operational, a silent master) the loops still run from
//! [`CanNode::tick`], so a stop or a fault reaction completes.

use gantry_drives::canopen::cob_id::{CobId, NodeId, NMT_COB_ID, SYNC_COB_ID};
use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::canopen::heartbeat::Heartbeat;
use gantry_drives::canopen::nmt::NmtFrame;
use gantry_drives::canopen::sdo::command::ClientCommand;
use gantry_drives::canopen::sdo::{
    AbortCode, EntryInfo, Multiplexer, SdoConfig, SdoConfigError, SdoServer,
};
use gantry_drives::canopen::sync::{Sync, SyncError};
use gantry_drives::canopen::CanFrame;
use gantry_drives::cia402::State;
use thiserror::Error;

use super::device::{CanDevice, CanDeviceConfig, EncoderDevice, SwitchesDevice};
use super::dictionary::{behaviour, image_put, NodeDictionary, IMAGE_BYTES};
use super::nmt::{NmtAction, NmtSlaveState};
use super::pdo::{Pdo, Trigger, DEFAULT_PDO_COUNT, MAX_PDO_COUNT};
use crate::catalog;
use crate::config::{ServoConfig, SimConfig, SlaveConfig};
use crate::plant::servo::{ParamError, ServoDrive, ServoParams};
use crate::plant::switches::{self, check_cams, CamError, SwitchCam};

/// Most frames one call returns (a block upload's sub-block of 127 segments and more).
pub const OUTBOX_FRAMES: usize = 192;
/// Without a SYNC for this long the drive's loops run from `tick` (10 ms).
pub const IDLE_RUN_NS: u64 = 10_000_000;
/// The SYNC watchdog's margin by default (communication cycle periods): CANopenNode's.
pub const SYNC_TIMEOUT_PERIODS: f64 = 1.5;
/// EMCYs the inhibit time may hold back.
pub const EMCY_QUEUE: usize = 8;
/// Longest single run of the loops (the plant allows 100 ms).
const MAX_RUN_NS: u64 = 100_000_000;
/// Most runs one call makes to catch up (10 s of simulated time; bounded work).
const MAX_RUNS: u32 = 100;

/// EMCY error codes (CiA 301 Table 21) the node itself raises.
pub mod emcy_code {
    /// Error reset / no error.
    pub const NO_ERROR: u16 = 0x0000;
    /// Communication, generic: the NMT master stopped or reset the node's communication
    /// while the drive was enabled (CiA 402-2 0x6007 event), or the SYNC stayed away
    /// (0x1006 watchdog).
    pub const COMMUNICATION: u16 = 0x8100;
    /// Life guard or heartbeat error: the heartbeat consumer timed out.
    pub const HEARTBEAT: u16 = 0x8130;
    /// PDO not processed due to length error (an RPDO shorter than its mapping).
    pub const PDO_LENGTH: u16 = 0x8210;
    /// Unexpected SYNC data length.
    pub const SYNC_LENGTH: u16 = 0x8240;
    /// RPDO timeout: synchronous RPDOs missed at
    /// [`super::super::dictionary::MISSED_SETPOINT_LIMIT`] SYNCs in a row, or an RPDO not
    /// received within its event timer (0x1400:05).
    pub const RPDO_TIMEOUT: u16 = 0x8250;
}

/// What a node is built from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CanNodeConfig {
    /// Node id 1..=127.
    pub node: NodeId,
    /// 0x1018:01–04 vendor id, product code, revision, serial number.
    pub identity: [u32; 4],
    /// 0x1017 at power-on (ms, 0 = no heartbeat).
    pub heartbeat_ms: u16,
    /// The device behind the node.
    pub device: CanDeviceConfig,
    /// The servo's motor, load and tuning (a servo node).
    pub params: ServoParams,
    /// The absolute encoder's position at power-up (counts).
    pub start_counts: i32,
    /// SDO server timing and block size.
    pub sdo: SdoConfig,
    /// Largest object served segmented or by block (bytes); at least the recorder's.
    pub sdo_buffer: usize,
    /// Bytes of the recorder DOMAIN 0x2F00 (0: none; see
    /// [`super::dictionary::RECORDER`]).
    pub recorder_bytes: usize,
    /// Bytes the scratch DOMAIN 0x2F01 holds at most (0: none; see
    /// [`super::dictionary::SCRATCH`]).
    pub scratch_bytes: usize,
    /// The SYNC watchdog's margin (periods of 0x1006; at least 1).
    pub sync_timeout_periods: f64,
    /// PDOs each way (1..=[`MAX_PDO_COUNT`]; [`DEFAULT_PDO_COUNT`] by default).
    pub pdo_count: u8,
}

impl CanNodeConfig {
    /// Node `node` with the default servo at 0, heartbeat every 100 ms; the identity of
    /// the catalog's servo (the EtherCAT one's vendor and product), serial = node id.
    pub fn servo(node: NodeId) -> Self {
        Self {
            node,
            identity: [
                catalog::VENDOR_ID,
                catalog::SERVO_PRODUCT,
                1,
                u32::from(node.get()),
            ],
            heartbeat_ms: 100,
            device: CanDeviceConfig::Servo,
            params: ServoParams::default(),
            start_counts: 0,
            sdo: SdoConfig::default(),
            sdo_buffer: 1024,
            recorder_bytes: 0,
            scratch_bytes: 0,
            sync_timeout_periods: SYNC_TIMEOUT_PERIODS,
            pdo_count: DEFAULT_PDO_COUNT,
        }
    }
}

impl CanNodeConfig {
    /// Node `node` with the servo a chain description (`[[slave]] kind = "servo"`)
    /// gives: its motor, load, tuning and start position, as on EtherCAT.
    pub fn from_servo(node: NodeId, servo: &ServoConfig) -> Self {
        Self {
            params: servo.params(),
            start_counts: servo.start_position,
            sync_timeout_periods: servo.sync_timeout_periods,
            recorder_bytes: servo.recorder_bytes as usize,
            pdo_count: servo.pdo_count,
            scratch_bytes: servo.scratch_bytes as usize,
            sdo: SdoConfig {
                timeout_ns: u64::from(servo.sdo_timeout_ms) * 1_000_000,
                ..SdoConfig::default()
            },
            ..Self::servo(node)
        }
    }

    /// Node `node` with the encoder module (CiA 406) of `counts_per_rev` whose shaft
    /// turns by itself at `shaft_speed_rev_s` (0: the test turns it); the catalog's
    /// encoder identity, serial = node id.
    pub fn encoder(node: NodeId, counts_per_rev: u32, shaft_speed_rev_s: f64) -> Self {
        let mut c = Self::servo(node);
        c.identity[1] = catalog::ENCODER_PRODUCT;
        c.device = CanDeviceConfig::Encoder {
            counts_per_rev,
            shaft_speed_rev_s,
        };
        c
    }

    /// Node `node` with the switch-cam input module (CiA 401) whose `cams` move with
    /// the servo at node `axis`; the catalog's input module identity, serial = node id.
    pub fn switches(node: NodeId, axis: NodeId, cams: &[SwitchCam]) -> Result<Self, CamError> {
        check_cams(cams)?;
        let mut slots = [None; switches::INPUTS as usize];
        for (slot, cam) in slots.iter_mut().zip(cams) {
            *slot = Some(*cam);
        }
        let mut c = Self::servo(node);
        c.identity[1] = catalog::SWITCHES_PRODUCT;
        c.device = CanDeviceConfig::Switches { axis, cams: slots };
        Ok(c)
    }

    /// The node of slave `index` of a chain description: its kind, its `node` id, for a
    /// switch-cam module the node id of the servo its `axis` names.
    pub fn from_slave(config: &SimConfig, index: usize) -> Result<Self, SlaveNodeError> {
        let slave = config
            .slaves
            .get(index)
            .ok_or(SlaveNodeError::NoSlave { index })?;
        let node_of = |i: usize| {
            config
                .slaves
                .get(i)
                .and_then(SlaveConfig::node)
                .and_then(|n| NodeId::new(n).ok())
        };
        let node = node_of(index).ok_or(SlaveNodeError::NoNodeId { index })?;
        match slave {
            SlaveConfig::Servo(servo) => Ok(Self::from_servo(node, servo)),
            SlaveConfig::Encoder {
                counts_per_rev,
                shaft_speed,
                ..
            } => Ok(Self::encoder(node, *counts_per_rev, *shaft_speed)),
            SlaveConfig::Switches { axis, cams, .. } => {
                if !matches!(config.slaves.get(*axis), Some(SlaveConfig::Servo(_))) {
                    return Err(SlaveNodeError::AxisNotServo { index, axis: *axis });
                }
                let axis_node =
                    node_of(*axis).ok_or(SlaveNodeError::AxisNoNodeId { index, axis: *axis })?;
                let cams: Vec<SwitchCam> = cams.iter().map(|&c| SwitchCam::from(c)).collect();
                Self::switches(node, axis_node, &cams)
                    .map_err(|source| SlaveNodeError::Cams { index, source })
            }
        }
    }
}

/// A slave of a chain description that cannot be a CANopen node.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum SlaveNodeError {
    /// No such slave.
    #[error("slave[{index}] does not exist")]
    NoSlave {
        /// Its position.
        index: usize,
    },
    /// It has no `node = N`.
    #[error("slave[{index}] has no CANopen node id (node = 1..127)")]
    NoNodeId {
        /// Its position.
        index: usize,
    },
    /// A switch-cam module's axis is no servo.
    #[error("slave[{index}].axis = {axis} is not a servo")]
    AxisNotServo {
        /// Its position.
        index: usize,
        /// The axis it names.
        axis: usize,
    },
    /// A switch-cam module's servo has no node id (on CAN the module follows it by id).
    #[error("slave[{index}].axis = {axis}: that servo has no CANopen node id")]
    AxisNoNodeId {
        /// Its position.
        index: usize,
        /// The axis it names.
        axis: usize,
    },
    /// The cams.
    #[error("slave[{index}]: {source}")]
    Cams {
        /// Its position.
        index: usize,
        /// Why.
        source: CamError,
    },
}

/// A node that cannot be built.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum CanNodeError {
    /// The SDO configuration.
    #[error("CANopen node {node}: {source}")]
    Sdo {
        /// The node.
        node: NodeId,
        /// Why.
        source: SdoConfigError,
    },
    /// The switch cams.
    #[error("CANopen node {node}: {source}")]
    Cams {
        /// The node.
        node: NodeId,
        /// Why.
        source: CamError,
    },
    /// A SYNC watchdog margin below one period (or not a number).
    #[error(
        "CANopen {node}: sync_timeout_periods = {periods}: the SYNC watchdog's margin \
         must be at least 1 communication cycle period"
    )]
    SyncTimeout {
        /// The node.
        node: NodeId,
        /// The margin given.
        periods: f64,
    },
    /// A recorder (0x2F00) or scratch (0x2F01) larger than the simulator holds.
    #[error(
        "CANopen node {node}: {key} = {bytes}: the {what} holds at most {max} bytes",
        max = super::dictionary::RECORDER_MAX_BYTES
    )]
    DomainSize {
        /// The node.
        node: NodeId,
        /// The chain file's key.
        key: &'static str,
        /// The object.
        what: &'static str,
        /// The size asked for.
        bytes: usize,
    },
    /// A PDO count the simulator does not offer.
    #[error(
        "CANopen {node}: pdo_count = {count}: a simulated node has 1 to {max} PDOs \
         each way",
        max = MAX_PDO_COUNT
    )]
    PdoCount {
        /// The node.
        node: NodeId,
        /// The count asked for.
        count: u8,
    },
    /// The servo's parameters.
    #[error("CANopen node {node}: servo parameters: {source}")]
    Params {
        /// The node.
        node: NodeId,
        /// Why.
        source: ParamError,
    },
}

/// Frames the node sends, in order; filled by one call, read by the caller.
#[derive(Debug)]
struct Outbox {
    frames: [CanFrame; OUTBOX_FRAMES],
    len: usize,
    dropped: u64,
}

impl Outbox {
    fn new() -> Self {
        Self {
            frames: [Sync::new().emit(); OUTBOX_FRAMES],
            len: 0,
            dropped: 0,
        }
    }

    fn push(&mut self, f: CanFrame) {
        match self.frames.get_mut(self.len) {
            Some(slot) => {
                *slot = f;
                self.len += 1;
            }
            None => self.dropped += 1,
        }
    }

    fn as_slice(&self) -> &[CanFrame] {
        self.frames.get(..self.len).unwrap_or(&[])
    }
}

/// Run-time state of one PDO (not an object: restarts when its parameters change).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct PdoRun {
    /// RPDO: data received since the last SYNC (synchronous), its length.
    pending: Option<([u8; 8], usize)>,
    /// TPDO: SYNCs counted towards the transmission type.
    syncs: u8,
    /// TPDO with a SYNC start value: the start SYNC has come.
    started: bool,
    /// TPDO: last data sent, its length, and when.
    last: Option<([u8; 8], usize, u64)>,
    /// RPDO: when it last came, and whether its deadline (event timer) has passed since.
    received_at: Option<u64>,
    timed_out: bool,
}

/// Counters a test reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeCounters {
    /// SYNCs consumed.
    pub syncs: u64,
    /// Counter byte of the last SYNC (None: it had none).
    pub last_sync_counter: Option<u8>,
    /// RPDOs taken.
    pub rpdos: u64,
    /// TPDOs sent.
    pub tpdos: u64,
    /// EMCYs sent.
    pub emcys: u64,
    /// EMCYs lost: the inhibit time held back more than the queue holds.
    pub emcys_lost: u64,
    /// Heartbeats (and boot-ups) sent.
    pub heartbeats: u64,
    /// SYNCs in a row without a synchronous RPDO while following setpoints.
    pub missed_in_row: u32,
    /// Frames that did not fit one call's outbox.
    pub dropped: u64,
}

/// The CANopen servo node.
#[derive(Debug)]
pub struct CanNode {
    node: NodeId,
    nmt: NmtSlaveState,
    sdo: SdoServer<Box<[u8]>>,
    dict: NodeDictionary,
    out: Outbox,
    rpdo: [PdoRun; MAX_PDO_COUNT],
    tpdo: [PdoRun; MAX_PDO_COUNT],
    last_heartbeat_ns: u64,
    /// Heartbeat consumer: last heartbeat of the monitored node, and whether it timed out.
    consumer_seen_ns: Option<u64>,
    consumer_lost: bool,
    /// A SYNC of the wrong length for 0x1019 was reported (EMCY 0x8240 once, until one
    /// of the right length comes).
    sync_length_error: bool,
    /// SYNC watchdog (0x1006): when the last SYNC came (None: not since it was armed),
    /// and whether it has fired.
    last_sync_ns: Option<u64>,
    sync_lost: bool,
    /// The SYNC watchdog's margin (periods).
    sync_timeout_periods: f64,
    /// When the loops last ran (None: not since power-on).
    last_run_ns: Option<u64>,
    /// The error code the last EMCY reported as active (0: none, or reset sent).
    emcy_active: u16,
    /// EMCYs held back by the inhibit time, oldest first, and when the last went out.
    emcy_queue: [Emergency; EMCY_QUEUE],
    emcy_queue_len: usize,
    last_emcy_ns: Option<u64>,
    /// The time of the call in progress.
    now: u64,
    counters: NodeCounters,
}

impl CanNode {
    /// A node in Initialisation: its first [`CanNode::tick`] (or [`CanNode::receive`])
    /// boots it (boot-up message, Pre-operational).
    pub fn new(config: CanNodeConfig) -> Result<Self, CanNodeError> {
        let node = config.node;
        if !(config.sync_timeout_periods >= 1.0 && config.sync_timeout_periods.is_finite()) {
            return Err(CanNodeError::SyncTimeout {
                node,
                periods: config.sync_timeout_periods,
            });
        }
        config
            .params
            .check()
            .map_err(|source| CanNodeError::Params { node, source })?;
        if !(1..=MAX_PDO_COUNT as u8).contains(&config.pdo_count) {
            return Err(CanNodeError::PdoCount {
                node,
                count: config.pdo_count,
            });
        }
        for (key, what, bytes) in [
            ("recorder_bytes", "recorder 0x2F00", config.recorder_bytes),
            ("scratch_bytes", "scratch 0x2F01", config.scratch_bytes),
        ] {
            if bytes > super::dictionary::RECORDER_MAX_BYTES {
                return Err(CanNodeError::DomainSize {
                    node,
                    key,
                    what,
                    bytes,
                });
            }
        }
        // The SDO server holds an object whole: the recorder and the scratch must fit.
        let sdo_buffer = config
            .sdo_buffer
            .max(config.recorder_bytes)
            .max(config.scratch_bytes);
        let sdo = SdoServer::new(node, config.sdo, vec![0u8; sdo_buffer].into_boxed_slice())
            .map_err(|source| CanNodeError::Sdo { node, source })?;
        let device = match config.device {
            CanDeviceConfig::Servo => CanDevice::Servo(ServoDrive::with_params(
                0,
                0,
                config.start_counts,
                config.params,
            )),
            CanDeviceConfig::Encoder {
                counts_per_rev,
                shaft_speed_rev_s,
            } => CanDevice::Encoder(EncoderDevice::new(counts_per_rev, shaft_speed_rev_s)),
            CanDeviceConfig::Switches { axis, cams } => {
                let cams: Vec<SwitchCam> = cams.iter().flatten().copied().collect();
                CanDevice::Switches(
                    SwitchesDevice::new(axis, &cams)
                        .map_err(|source| CanNodeError::Cams { node, source })?,
                )
            }
        };
        let mut dict = NodeDictionary::new(
            node,
            config.identity,
            config.heartbeat_ms,
            device,
            config.pdo_count,
        );
        dict.set_recorder(config.recorder_bytes);
        dict.set_scratch(config.scratch_bytes);
        Ok(Self {
            node,
            nmt: NmtSlaveState::Initialisation,
            sdo,
            dict,
            out: Outbox::new(),
            rpdo: [PdoRun::default(); MAX_PDO_COUNT],
            tpdo: [PdoRun::default(); MAX_PDO_COUNT],
            last_heartbeat_ns: 0,
            consumer_seen_ns: None,
            consumer_lost: false,
            last_sync_ns: None,
            sync_lost: false,
            sync_timeout_periods: config.sync_timeout_periods,
            sync_length_error: false,
            last_run_ns: None,
            emcy_active: 0,
            emcy_queue: [Emergency {
                node,
                error_code: 0,
                error_register: 0,
                manufacturer: [0; 5],
            }; EMCY_QUEUE],
            emcy_queue_len: 0,
            last_emcy_ns: None,
            now: 0,
            counters: NodeCounters::default(),
        })
    }

    /// The node id.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// The NMT state.
    pub fn nmt_state(&self) -> NmtSlaveState {
        self.nmt
    }

    /// The servo behind the node (None: the node is another device).
    pub fn servo(&self) -> Option<&ServoDrive> {
        match &self.dict.device {
            CanDevice::Servo(s) => Some(s),
            _ => None,
        }
    }

    /// The servo, mutable (a test injects what the wire cannot).
    pub fn servo_mut(&mut self) -> Option<&mut ServoDrive> {
        match &mut self.dict.device {
            CanDevice::Servo(s) => Some(s),
            _ => None,
        }
    }

    /// The device behind the node.
    pub fn device(&self) -> &CanDevice {
        &self.dict.device
    }

    /// The device, mutable (a test turns an encoder's shaft).
    pub fn device_mut(&mut self) -> &mut CanDevice {
        &mut self.dict.device
    }

    /// The position this node reports as its axis' (a servo's position actual value, in
    /// counts), for modules on the same bus that follow it.
    pub fn axis_position(&self) -> Option<i64> {
        self.dict.device.axis_position()
    }

    /// The node whose axis this node's device follows (a switch-cam module's servo).
    pub fn coupled_axis(&self) -> Option<NodeId> {
        self.dict.device.coupled_axis()
    }

    /// The followed axis is at `position` (counts): the bus calls this before it hands
    /// the node a frame or a tick.
    pub fn sense_axis(&mut self, position: i64) {
        self.dict.device.sense_axis(position);
    }

    /// The dictionary.
    pub fn dictionary(&self) -> &NodeDictionary {
        &self.dict
    }

    /// 0x1001 error register.
    pub fn error_register(&self) -> u8 {
        self.dict.error_register
    }

    /// Counters.
    pub fn counters(&self) -> NodeCounters {
        NodeCounters {
            dropped: self.out.dropped,
            ..self.counters
        }
    }

    /// Takes a frame from the bus at `now_ns`; returns the frames the node sends.
    pub fn receive(&mut self, frame: &CanFrame, now_ns: u64) -> &[CanFrame] {
        self.out.len = 0;
        self.advance(now_ns);
        if self.nmt != NmtSlaveState::Initialisation {
            self.dispatch(frame, now_ns);
            self.check_emcy();
        }
        self.out.as_slice()
    }

    /// Lets time pass to `now_ns` (boot, heartbeat, timeouts, event TPDOs, the loops
    /// without SYNC); returns the frames the node sends.
    pub fn tick(&mut self, now_ns: u64) -> &[CanFrame] {
        self.out.len = 0;
        self.advance(now_ns);
        self.check_emcy();
        self.out.as_slice()
    }

    fn advance(&mut self, now: u64) {
        self.now = now;
        if self.nmt == NmtSlaveState::Initialisation {
            self.boot(now);
        }
        // The loops, when no SYNC paces them.
        let last = *self.last_run_ns.get_or_insert(now);
        if now.saturating_sub(last) >= IDLE_RUN_NS {
            self.run_to(now);
        }
        // Heartbeat producer (CiA 301 §7.2.8.3.2.2): every 0x1017 ms.
        let period = u64::from(self.dict.comm.heartbeat_producer_ms) * 1_000_000;
        if period > 0 && self.nmt.heartbeat_allowed() && now >= self.last_heartbeat_ns + period {
            let hb = Heartbeat::new(self.node, self.nmt.heartbeat());
            self.send(hb.emit());
            self.counters.heartbeats += 1;
            // Keep the phase; after a long silence of the caller start again from now.
            self.last_heartbeat_ns = if now - self.last_heartbeat_ns < 2 * period {
                self.last_heartbeat_ns + period
            } else {
                now
            };
        }
        // Heartbeat consumer (§7.2.8.3.2.3): monitoring starts with the first heartbeat.
        if core::mem::take(&mut self.dict.changed.heartbeat_consumer) {
            self.consumer_seen_ns = None;
            self.consumer_lost = false;
        }
        if let (Some((_, ms)), Some(seen)) = (self.dict.comm.consumer(), self.consumer_seen_ns) {
            // No heartbeat within the consumer time: the event (at the time, not after).
            if !self.consumer_lost && now >= seen + u64::from(ms) * 1_000_000 {
                self.consumer_lost = true;
                self.on_heartbeat_lost();
            }
        }
        // SYNC watchdog (0x1006, CiA 301 §7.5.2.6 lets a SYNC consumer detect the loss
        // of SYNC): armed by the first SYNC; no SYNC for 1.5 periods (the margin
        // CANopenNode uses; CiA 301 leaves it open; `sync_timeout_periods`) is a
        // communication error: EMCY
        // 0x8100 and, the drive's setpoints being paced by SYNC, the 0x6007 reaction.
        let period = u64::from(self.dict.comm.cycle_period_us) * 1_000;
        if let (true, Some(last)) = (period > 0, self.last_sync_ns) {
            if !self.sync_lost
                && self.nmt.sync_emcy_allowed()
                && now.saturating_sub(last) as f64 > period as f64 * self.sync_timeout_periods
            {
                self.sync_lost = true;
                self.communication_error(emcy_code::COMMUNICATION);
            }
        }
        // SDO server timeouts.
        if self.nmt.sdo_allowed() {
            self.sdo.poll(now);
            self.drain_sdo();
        }
        self.take_changes();
        self.flush_emcy();
        if self.nmt.pdo_allowed() {
            self.event_tpdos(now);
            self.rpdo_deadlines(now);
        }
    }

    /// RPDO deadline monitoring (CiA 301 §7.5.2.35 sub 5): armed by a reception, an RPDO
    /// that does not come again within its event timer is an RPDO timeout (EMCY 0x8250,
    /// and, its data being the drive's command, the 0x6007 reaction), once until it comes.
    fn rpdo_deadlines(&mut self, now: u64) {
        for n in 0..MAX_PDO_COUNT {
            let Some(p) = self.dict.comm.rpdo.get(n).copied() else {
                continue;
            };
            let timer = u64::from(p.event_timer_ms) * 1_000_000;
            let Some(run) = self.rpdo.get_mut(n) else {
                continue;
            };
            let expired = run
                .received_at
                .is_some_and(|t| now >= t.saturating_add(timer));
            if p.is_valid() && timer > 0 && expired && !run.timed_out {
                run.timed_out = true;
                self.communication_error(emcy_code::RPDO_TIMEOUT);
            }
        }
    }

    /// Ends an SDO transfer in progress without an answer (reset communication, Stopped:
    /// the SDO connection is gone, CiA 301 Table 41): the server is told of a client
    /// abort, which it takes silently.
    fn reset_sdo(&mut self, now: u64) {
        if self.sdo.is_idle() {
            return;
        }
        let abort = ClientCommand::Abort {
            mux: Multiplexer::new(0, 0),
            code: AbortCode::GENERAL_ERROR,
        };
        if let Ok(f) = CanFrame::new(u32::from(CobId::SdoRx(self.node).id()), &abort.emit()) {
            self.sdo.receive(&f, now, &mut self.dict);
        }
        // Nothing is sent for it.
        while self.sdo.transmit().is_some() {}
    }

    /// Initialisation ends: boot-up message (CiA 301 §7.2.8.3.3), Pre-operational.
    fn boot(&mut self, now: u64) {
        self.reset_sdo(now);
        let hb = Heartbeat::new(self.node, NmtSlaveState::Initialisation.heartbeat());
        self.send(hb.emit());
        self.counters.heartbeats += 1;
        self.nmt = NmtSlaveState::PreOperational;
        self.last_heartbeat_ns = now;
        self.rpdo = [PdoRun::default(); MAX_PDO_COUNT];
        self.tpdo = [PdoRun::default(); MAX_PDO_COUNT];
        self.consumer_seen_ns = None;
        self.consumer_lost = false;
        self.last_sync_ns = None;
        self.sync_lost = false;
        self.emcy_queue_len = 0;
        self.last_emcy_ns = None;
        self.counters.missed_in_row = 0;
    }

    fn send(&mut self, f: CanFrame) {
        self.out.push(f);
    }

    fn drain_sdo(&mut self) {
        while let Some(f) = self.sdo.transmit() {
            self.send(f);
        }
    }

    fn dispatch(&mut self, frame: &CanFrame, now: u64) {
        let id = frame.id();
        if id == NMT_COB_ID {
            if let Ok(cmd) = NmtFrame::parse(frame) {
                if cmd.target.addresses(self.node) {
                    self.on_nmt(cmd.command, now);
                }
            }
            return;
        }
        if id == SYNC_COB_ID {
            if self.nmt.sync_emcy_allowed() {
                match Sync::parse(frame) {
                    Ok(s) => {
                        // 0x1019 says which length the SYNC has: 0 bytes when 0, 1 byte
                        // (the counter) otherwise; another is reported once (EMCY 0x8240)
                        // and the SYNC still taken.
                        let expected = self.dict.comm.sync_overflow != 0;
                        if s.counter().is_some() != expected {
                            if !self.sync_length_error {
                                self.sync_length_error = true;
                                self.emcy(emcy_code::SYNC_LENGTH);
                            }
                        } else {
                            self.sync_length_error = false;
                        }
                        self.on_sync(s.counter(), now);
                    }
                    Err(SyncError::Length(_)) => {
                        if !self.sync_length_error {
                            self.sync_length_error = true;
                            self.emcy(emcy_code::SYNC_LENGTH);
                        }
                        self.on_sync(None, now);
                    }
                    // A counter outside 1..=240 or an RTR is no SYNC of CiA 301.
                    Err(_) => {}
                }
            }
            return;
        }
        if id == CobId::SdoRx(self.node).id() {
            if self.nmt.sdo_allowed() {
                self.sdo.receive(frame, now, &mut self.dict);
                self.drain_sdo();
                self.take_changes();
            }
            return;
        }
        if let (Some((node, _)), Ok(hb)) = (self.dict.comm.consumer(), Heartbeat::parse(frame)) {
            if hb.node.get() == node {
                self.consumer_seen_ns = Some(now);
                self.consumer_lost = false;
                self.update_error_register();
            }
            return;
        }
        if self.nmt.pdo_allowed() && !frame.is_remote() {
            let hit = self
                .dict
                .comm
                .rpdo
                .iter()
                .position(|p| p.is_valid() && p.can_id() == id);
            if let Some(n) = hit {
                self.on_rpdo(n, frame, now);
            }
        }
    }

    fn on_nmt(&mut self, cmd: gantry_drives::canopen::nmt::NmtCommand, now: u64) {
        let Some(action) = self.nmt.on_command(cmd) else {
            return;
        };
        match action {
            NmtAction::Enter(s) => {
                if s == NmtSlaveState::Stopped && self.nmt != NmtSlaveState::Stopped {
                    self.connection_abort(emcy_code::COMMUNICATION);
                    self.reset_sdo(now);
                }
                if s != self.nmt {
                    // PDO run-time state restarts on every change (CiA 301: PDOs exist
                    // only in Operational).
                    self.rpdo = [PdoRun::default(); MAX_PDO_COUNT];
                    self.tpdo = [PdoRun::default(); MAX_PDO_COUNT];
                    self.counters.missed_in_row = 0;
                }
                self.nmt = s;
            }
            NmtAction::ResetCommunication => {
                self.connection_abort(emcy_code::COMMUNICATION);
                self.dict.reset_communication();
                self.nmt = NmtSlaveState::Initialisation;
                self.boot(now);
            }
            NmtAction::ResetNode => {
                self.dict.reset_application();
                self.dict.reset_communication();
                self.emcy_active = 0;
                self.nmt = NmtSlaveState::Initialisation;
                self.boot(now);
            }
        }
    }

    /// CiA 402-2 0x6007: the connection is lost (heartbeat, NMT stopped, reset
    /// communication); option 1 faults the drive if its power is on.
    fn connection_abort(&mut self, code: u16) {
        if self.dict.abort_connection_option() == 1 {
            self.dict.device.communication_fault(code);
        }
    }

    /// A communication error with EMCY `code`: the 0x6007 reaction, and one EMCY — the
    /// drive's fault EMCY when it faulted for it, else the error's own.
    fn communication_error(&mut self, code: u16) {
        self.connection_abort(code);
        let faulted = self.dict.device.faulted() && self.dict.device.error_code() == code;
        if faulted && self.emcy_active != code {
            self.check_emcy();
        } else {
            self.emcy(code);
        }
    }

    fn on_heartbeat_lost(&mut self) {
        self.update_error_register();
        self.communication_error(emcy_code::HEARTBEAT);
        // 0x1029:01 (CiA 301 §7.5.2.32): what a communication error does to the NMT state.
        match self.dict.comm.error_behaviour {
            behaviour::PRE_OPERATIONAL if self.nmt == NmtSlaveState::Operational => {
                self.nmt = NmtSlaveState::PreOperational;
            }
            behaviour::STOPPED => self.nmt = NmtSlaveState::Stopped,
            _ => {}
        }
        self.update_error_register();
    }

    fn take_changes(&mut self) {
        let c = core::mem::take(&mut self.dict.changed);
        for (run, changed) in self.rpdo.iter_mut().zip(c.rpdo) {
            if changed {
                *run = PdoRun::default();
            }
        }
        for (run, changed) in self.tpdo.iter_mut().zip(c.tpdo) {
            if changed {
                *run = PdoRun::default();
            }
        }
        if c.heartbeat_consumer {
            self.consumer_seen_ns = None;
            self.consumer_lost = false;
        }
        if c.sync_watchdog {
            self.last_sync_ns = None;
            self.sync_lost = false;
        }
    }

    /// Runs the loops from the last run to `now` on the command taken last.
    fn run_to(&mut self, now: u64) {
        let last = *self.last_run_ns.get_or_insert(now);
        let mut left = now.saturating_sub(last);
        let mut runs = 0;
        while left > 0 && runs < MAX_RUNS {
            let dt = left.min(MAX_RUN_NS);
            self.dict.device.run(dt as f64 * 1e-9);
            left -= dt;
            runs += 1;
        }
        self.last_run_ns = Some(now);
    }

    fn on_sync(&mut self, counter: Option<u8>, now: u64) {
        self.counters.syncs += 1;
        self.last_sync_ns = Some(now);
        self.sync_lost = false;
        self.counters.last_sync_counter = counter;
        // (1) The loops up to the SYNC.
        self.run_to(now);
        if !self.nmt.pdo_allowed() {
            return;
        }
        // (2) Inputs sampled at the SYNC, synchronous TPDOs.
        self.dict
            .device
            .publish_input_image(&mut self.dict.tx_image);
        for n in 0..MAX_PDO_COUNT {
            let Some(p) = self.dict.comm.tpdo.get(n).copied() else {
                continue;
            };
            let Trigger::Sync(every) = p.trigger() else {
                continue;
            };
            if !p.is_valid() {
                continue;
            }
            let (data, len) = self.encode(&p);
            let Some(run) = self.tpdo.get_mut(n) else {
                continue;
            };
            // A start value waits for the SYNC whose counter equals it (§7.5.2.36 sub 6;
            // ignored when the SYNC has no counter).
            if p.sync_start != 0 && !run.started {
                match counter {
                    Some(c) if c == p.sync_start => {
                        run.started = true;
                        run.syncs = every.saturating_sub(1);
                    }
                    Some(_) => continue,
                    None => {}
                }
            }
            let due = if every == 0 {
                // Acyclic: at the SYNC after a change.
                run.last.is_none_or(|(d, l, _)| (d, l) != (data, len))
            } else {
                run.syncs = run.syncs.saturating_add(1);
                if run.syncs >= every {
                    run.syncs = 0;
                    true
                } else {
                    false
                }
            };
            if due {
                run.last = Some((data, len, now));
                self.send_tpdo(&p, data, len);
            }
        }
        // (3) The setpoint: synchronous RPDO data received since the last SYNC.
        let mut any_sync = false;
        let mut got = false;
        for n in 0..MAX_PDO_COUNT {
            let Some(p) = self.dict.comm.rpdo.get(n).copied() else {
                continue;
            };
            if !p.is_valid() || p.trigger() == Trigger::Event {
                continue;
            }
            any_sync = true;
            if let Some((data, len)) = self.rpdo.get_mut(n).and_then(|r| r.pending.take()) {
                self.decode(&p, &data, len);
                got = true;
            }
        }
        if got {
            self.counters.missed_in_row = 0;
            self.counters.rpdos += 1;
            let image = self.dict.rx_image;
            self.dict.device.take_output_image(&image);
        } else if any_sync && self.dict.device.drive_state() == Some(State::OperationEnabled) {
            if let Some(r) = self.dict.device.record_mut() {
                r.missed(1);
            }
            self.counters.missed_in_row = self.counters.missed_in_row.saturating_add(1);
            let limit = u32::from(self.dict.missed_setpoint_limit);
            if limit > 0 && self.counters.missed_in_row >= limit {
                self.dict
                    .device
                    .communication_fault(emcy_code::RPDO_TIMEOUT);
            }
        }
    }

    fn on_rpdo(&mut self, n: usize, frame: &CanFrame, now: u64) {
        let Some(p) = self.dict.comm.rpdo.get(n).copied() else {
            return;
        };
        if let Some(run) = self.rpdo.get_mut(n) {
            run.received_at = Some(now);
            run.timed_out = false;
        }
        let data = frame.data();
        if data.len() < p.len() {
            // CiA 301 §7.2.2.2: fewer bytes than mapped: not processed, EMCY 0x8210.
            self.emcy(emcy_code::PDO_LENGTH);
            return;
        }
        let mut bytes = [0u8; 8];
        for (d, s) in bytes.iter_mut().zip(data) {
            *d = *s;
        }
        match p.trigger() {
            Trigger::Sync(_) => {
                if let Some(run) = self.rpdo.get_mut(n) {
                    // A second RPDO before the SYNC overwrites the first, never taken.
                    if run.pending.replace((bytes, data.len())).is_some()
                        && self.dict.device.drive_state() == Some(State::OperationEnabled)
                    {
                        if let Some(r) = self.dict.device.record_mut() {
                            r.doubled();
                        }
                    }
                }
            }
            Trigger::Event => {
                self.decode(&p, &bytes, data.len());
                self.counters.rpdos += 1;
                let image = self.dict.rx_image;
                self.dict.device.take_output_image(&image);
            }
        }
    }

    /// Copies an RPDO's mapped objects into the full output image.
    fn decode(&mut self, p: &Pdo, data: &[u8; 8], len: usize) {
        let mut at = 0;
        for o in p.mapped() {
            let n = o.kind.size();
            if at + n > len {
                break;
            }
            if let Some(src) = data.get(at..at + n) {
                let offset = self.dict.output_offset(o);
                image_put(&mut self.dict.rx_image, offset, o, src);
            }
            at += n;
        }
    }

    /// A TPDO's data from the full input image.
    fn encode(&self, p: &Pdo) -> ([u8; 8], usize) {
        let mut data = [0u8; 8];
        let mut at = 0;
        for o in p.mapped() {
            let n = o.kind.size();
            let src = self
                .dict
                .input_offset(o)
                .and_then(|i| self.dict.tx_image.get(i..i + n));
            if let (Some(src), Some(dst)) = (src, data.get_mut(at..at + n)) {
                dst.copy_from_slice(src);
            }
            at += n;
        }
        (data, at.min(8))
    }

    fn send_tpdo(&mut self, p: &Pdo, data: [u8; 8], len: usize) {
        if let Ok(f) = CanFrame::new(u32::from(p.can_id()), data.get(..len).unwrap_or(&[])) {
            self.send(f);
            self.counters.tpdos += 1;
        }
    }

    /// Event-driven TPDOs (types 254/255): on a change of a mapped value, no sooner than
    /// the inhibit time (0x1800:03, 100 µs) after the last, and at least every event
    /// timer (0x1800:05, ms) (CiA 301 §7.2.2.2, §7.5.2.36).
    fn event_tpdos(&mut self, now: u64) {
        let mut image = [0u8; IMAGE_BYTES];
        self.dict.device.publish_input_image(&mut image);
        self.dict.tx_image = image;
        for n in 0..MAX_PDO_COUNT {
            let Some(p) = self.dict.comm.tpdo.get(n).copied() else {
                continue;
            };
            if !p.is_valid() || p.trigger() != Trigger::Event {
                continue;
            }
            let (data, len) = self.encode(&p);
            let Some(run) = self.tpdo.get_mut(n) else {
                continue;
            };
            let due = match run.last {
                None => true,
                Some((d, l, at)) => {
                    let inhibit = u64::from(p.inhibit_time) * 100_000;
                    let timer = u64::from(p.event_timer_ms) * 1_000_000;
                    let changed = (d, l) != (data, len) && now >= at + inhibit;
                    let expired = timer > 0 && now >= at + timer;
                    changed || expired
                }
            };
            if due {
                run.last = Some((data, len, now));
                self.send_tpdo(&p, data, len);
            }
        }
    }

    /// The error register from what is active (CiA 301 §7.5.2.2, Table 48).
    fn update_error_register(&mut self) {
        let mut reg = 0u8;
        let fault = self.dict.device.faulted();
        if fault {
            reg |= error_register_bits(self.dict.device.error_code());
        }
        if self.consumer_lost {
            reg |= error_register_bits(emcy_code::HEARTBEAT);
        }
        self.dict.error_register = reg;
    }

    /// Sends an EMCY with `code` and the present error register (Pre-operational and
    /// Operational only, CiA 301 Table 41).
    fn emcy(&mut self, code: u16) {
        self.update_error_register();
        if !self.nmt.sync_emcy_allowed() {
            return;
        }
        let register = self.dict.error_register | error_register_bits(code);
        self.produce_emcy(code, register);
    }

    /// Records `code` in 0x1003 and sends the EMCY on the COB-ID of 0x1014 if it exists,
    /// no sooner than the inhibit time 0x1015 after the previous one (CiA 301 §7.2.7.1,
    /// §7.5.2.14): one that comes sooner waits in a queue of [`EMCY_QUEUE`]; beyond that
    /// it is lost (counted).
    fn produce_emcy(&mut self, code: u16, register: u8) {
        if code != emcy_code::NO_ERROR {
            self.dict.push_error(code);
        }
        if !self.dict.comm.emcy_valid() {
            return;
        }
        let e = Emergency {
            node: self.node,
            error_code: code,
            error_register: register,
            manufacturer: [0; 5],
        };
        if self.emcy_queue_len == 0 && self.emcy_inhibit_passed(self.now) {
            self.send_emcy(&e);
        } else if let Some(slot) = self.emcy_queue.get_mut(self.emcy_queue_len) {
            *slot = e;
            self.emcy_queue_len += 1;
        } else {
            self.counters.emcys_lost += 1;
        }
    }

    fn emcy_inhibit_passed(&self, now: u64) -> bool {
        let inhibit = u64::from(self.dict.comm.emcy_inhibit_100us) * 100_000;
        self.last_emcy_ns
            .is_none_or(|t| now >= t.saturating_add(inhibit))
    }

    fn send_emcy(&mut self, e: &Emergency) {
        let cob = self.dict.comm.emcy_can_id();
        if let Ok(f) = CanFrame::new(u32::from(cob), e.emit().data()) {
            self.send(f);
            self.counters.emcys += 1;
            self.last_emcy_ns = Some(self.now);
        }
    }

    /// Sends the queued EMCYs the inhibit time lets go.
    fn flush_emcy(&mut self) {
        while self.emcy_queue_len > 0
            && self.nmt.sync_emcy_allowed()
            && self.emcy_inhibit_passed(self.now)
        {
            let Some(&e) = self.emcy_queue.first() else {
                break;
            };
            self.emcy_queue.copy_within(1.., 0);
            self.emcy_queue_len -= 1;
            self.send_emcy(&e);
        }
    }

    /// A drive fault is reported once with its 0x603F code; its end with an error reset
    /// EMCY (code 0x0000) (CiA 301 §7.2.7.1).
    fn check_emcy(&mut self) {
        self.update_error_register();
        if !self.nmt.sync_emcy_allowed() {
            return;
        }
        let fault = self.dict.device.faulted();
        let code = if fault {
            self.dict.device.error_code()
        } else {
            emcy_code::NO_ERROR
        };
        if code != self.emcy_active {
            self.emcy_active = code;
            let register = self.dict.error_register;
            self.produce_emcy(code, register);
        }
    }

    /// Access and size of the object at `index`:`sub`, as the SDO server sees it.
    pub fn object_info(&self, index: u16, sub: u8) -> Result<EntryInfo, AbortCode> {
        use gantry_drives::canopen::sdo::ObjectDictionary as _;
        self.dict.entry(Multiplexer::new(index, sub))
    }

    /// The object at `index`:`sub` as the SDO server would read it (for tests and the
    /// EDS writer), or the abort code.
    pub fn read_object(&mut self, index: u16, sub: u8, out: &mut [u8]) -> Result<usize, AbortCode> {
        use gantry_drives::canopen::sdo::ObjectDictionary as _;
        self.dict.read(Multiplexer::new(index, sub), out)
    }
}

/// The error register bits an error code sets (CiA 301 Table 48): bit 0 generic always;
/// bit 1 current (0x2xxx), bit 2 voltage (0x3xxx), bit 3 temperature (0x4xxx), bit 4
/// communication (0x81xx, 0x82xx), bit 7 manufacturer-specific (0xFFxx), bit 5 device
/// profile for the rest (CiA 402's 0x8xxx monitoring codes, e.g. 0x8611 following error).
pub fn error_register_bits(code: u16) -> u8 {
    if code == 0 {
        return 0;
    }
    1 | match code >> 8 {
        0x20..=0x2F => 1 << 1,
        0x30..=0x3F => 1 << 2,
        0x40..=0x4F => 1 << 3,
        0x81 | 0x82 => 1 << 4,
        0xFF => 1 << 7,
        _ => 1 << 5,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_register_bits_of_table_48() {
        assert_eq!(error_register_bits(0), 0);
        assert_eq!(error_register_bits(0x2310), 0x03, "current");
        assert_eq!(error_register_bits(0x3210), 0x05, "voltage");
        assert_eq!(error_register_bits(0x4310), 0x09, "temperature");
        assert_eq!(error_register_bits(0x8130), 0x11, "heartbeat");
        assert_eq!(error_register_bits(0x8250), 0x11, "RPDO timeout");
        assert_eq!(error_register_bits(0x8611), 0x21, "following error");
        assert_eq!(error_register_bits(0xFF01), 0x81, "manufacturer");
    }

    #[test]
    fn boots_on_the_first_call_and_only_once() {
        let mut n = CanNode::new(CanNodeConfig::servo(NodeId::new(12).unwrap())).unwrap();
        assert_eq!(n.nmt_state(), NmtSlaveState::Initialisation);
        let out = n.tick(5).to_vec();
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].id(), 0x70C);
        assert_eq!(out[0].data(), [0]);
        assert_eq!(n.nmt_state(), NmtSlaveState::PreOperational);
        assert!(n.tick(6).is_empty());
    }

    #[test]
    fn built_from_a_chain_description_servo() {
        let text = "[[slave]]\nkind = \"servo\"\nstart_position = 5000\n";
        let c = crate::config::SimConfig::parse(text, "test.toml").unwrap();
        let crate::config::SlaveConfig::Servo(servo) = &c.slaves[0] else {
            panic!("not a servo");
        };
        let mut n =
            CanNode::new(CanNodeConfig::from_servo(NodeId::new(2).unwrap(), servo)).unwrap();
        n.tick(0);
        let mut out = [0u8; 4];
        assert_eq!(n.read_object(0x6064, 0, &mut out), Ok(4));
        assert_eq!(i32::from_le_bytes(out), 5000);
        assert_eq!(n.read_object(0x1018, 1, &mut out), Ok(4));
        assert_eq!(u32::from_le_bytes(out), crate::catalog::VENDOR_ID);
    }

    #[test]
    fn bad_parameters_are_refused_with_the_node_named() {
        let mut c = CanNodeConfig::servo(NodeId::new(12).unwrap());
        c.sdo.block_size = 0;
        let e = CanNode::new(c).unwrap_err().to_string();
        assert!(e.contains("node 12") && e.contains("block size"), "{e}");
        let mut c = CanNodeConfig::servo(NodeId::new(12).unwrap());
        c.params.max_speed_rpm = -1.0;
        let e = CanNode::new(c).unwrap_err().to_string();
        assert!(
            e.contains("node 12") && e.contains("servo parameters"),
            "{e}"
        );
    }
}
