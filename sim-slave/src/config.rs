//! The simulator's configuration: a TOML file that lists the chain, in wiring order.
//!
//! ```toml
//! # How often the devices' applications run (µs), in real time.
//! cycle_us = 1000
//!
//! [[slave]]
//! kind = "servo"          # a CiA-402 servo drive (CoE, CSP)
//! start_position = 0      # absolute encoder value at power-up, counts
//! bandwidth_hz = 200      # velocity loop bandwidth, Hz
//! dc_drift_ppm = 30       # its distributed clock runs 30 ppm fast (default 0)
//! # The motor and load (defaults: a 400 W servo, 17-bit encoder, load 5x the rotor).
//! counts_per_rev = 131072
//! rated_torque_nm = 1.27
//! peak_torque_nm = 3.8    # the current limit
//! rotor_inertia_kgm2 = 0.26e-4
//! load_inertia_ratio = 5.0
//! coulomb_friction_nm = 0.03
//! viscous_friction_nm_s = 1e-4  # N·m per rad/s
//! max_speed_rpm = 6000    # power-up 0x607F max profile velocity
//! # Power-up values of CiA 402 objects (the master may change them by SDO).
//! following_error_window = 32768      # 0x6065, counts
//! following_error_timeout_ms = 10     # 0x6066
//! quick_stop_deceleration = 131072000 # 0x6085, counts/s²
//! quick_stop_option_code = 2          # 0x605A: quick stop ramp, then switch on disabled
//! fault_reaction_option_code = 2      # 0x605E: quick stop ramp
//!
//! [slave.al]              # its firmware's AL transition times (defaults 2, 10, 5 ms)
//! init_to_preop_ms = 2
//! preop_to_safeop_ms = 10
//! safeop_to_op_ms = 5
//! sync_error_limit = 4    # 0x10F1:02: two SYNC0 periods without outputs leave Op
//!
//! [[slave]]
//! kind = "encoder"        # an incremental encoder module (like an EL5101), no CoE
//! counts_per_rev = 4096   # counts per shaft revolution
//! shaft_speed = 0.5       # rev/s the shaft turns by itself (default 0: it stands)
//!
//! [[slave]]
//! kind = "switches"       # 8 digital inputs (like an EL1008) read from switch cams
//! axis = 0                # chain index of the servo whose position moves the cams
//!
//! [[slave.cam]]           # a reference switch: input 0 high from 10000 to 12000 counts
//! input = 0
//! from = 10000
//! to = 12000
//!
//! [[slave.cam]]           # a positive limit switch, normally closed: input 1 drops
//! input = 1               # from 500000 counts on
//! from = 500000
//! to = 9223372036854775807
//! normally_closed = true
//! ```

use serde::Deserialize;
use thiserror::Error;

use crate::catalog::{self, EncoderOptions, ServoOptions, SwitchesOptions};
use crate::chain::SlaveChain;
use crate::esc::al::{Firmware, TransitionTimes};
use crate::plant::servo::homing::{HomingFaults, MethodSet};
use crate::plant::servo::probe::DriveSwitches;
use crate::plant::servo::ServoParams;
use crate::plant::switches::{check_cams, CamError, SwitchCam};

/// A configuration that cannot be used, with where and why.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The TOML is malformed, has an unknown key or a value of the wrong type.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// 1-based line of the offending key or value.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A value is out of its range.
    #[error("{path}: {key}: {reason}")]
    Invalid {
        /// The file.
        path: String,
        /// The key, e.g. `slave[2].bandwidth_hz`.
        key: String,
        /// What is wrong.
        reason: String,
    },
}

/// The simulator's configuration.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// Period of the devices' applications (µs).
    #[serde(default = "default_cycle_us")]
    pub cycle_us: u32,
    /// The slaves, in wiring order.
    #[serde(rename = "slave", default)]
    pub slaves: Vec<SlaveConfig>,
}

fn default_cycle_us() -> u32 {
    1000
}

/// One slave of the chain.
// Read once at start: the servo's size costs nothing worth a box.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum SlaveConfig {
    /// A CiA-402 servo drive.
    Servo(ServoConfig),
    /// An incremental encoder module.
    Encoder {
        /// CANopen node id (1..=127) on a CAN bus (see [`ServoConfig::node`]).
        #[serde(default)]
        node: Option<u8>,
        /// Counts per shaft revolution.
        #[serde(default = "default_counts_per_rev")]
        counts_per_rev: u32,
        /// Speed at which the shaft turns by itself (rev/s).
        #[serde(default)]
        shaft_speed: f64,
        /// How long its firmware takes for each AL transition (`[slave.al]`).
        #[serde(default)]
        al: AlConfig,
    },
    /// A digital-input module whose inputs are switch cams on a servo's travel.
    Switches {
        /// CANopen node id (1..=127) on a CAN bus (see [`ServoConfig::node`]).
        #[serde(default)]
        node: Option<u8>,
        /// Chain index of the servo.
        axis: usize,
        /// The cams (`[[slave.cam]]`).
        #[serde(rename = "cam", default)]
        cams: Vec<CamConfig>,
    },
}

impl SlaveConfig {
    /// Its CANopen node id, if it has one.
    pub fn node(&self) -> Option<u8> {
        match self {
            SlaveConfig::Servo(s) => s.node,
            SlaveConfig::Encoder { node, .. } | SlaveConfig::Switches { node, .. } => *node,
        }
    }
}

/// One switch cam of a `switches` slave: the switch on `input` is actuated while the
/// servo's position actual value is in `from..=to` (counts).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct CamConfig {
    /// Input bit (0…7).
    pub input: u8,
    /// First actuated position (counts).
    pub from: i64,
    /// Last actuated position (counts).
    pub to: i64,
    /// A normally closed contact (limit switches).
    #[serde(default)]
    pub normally_closed: bool,
}

impl From<CamConfig> for SwitchCam {
    fn from(c: CamConfig) -> Self {
        SwitchCam {
            input: c.input,
            from: c.from,
            to: c.to,
            normally_closed: c.normally_closed,
        }
    }
}

/// A `kind = "servo"` slave: where it starts, its clock, and its motor, tuning and object
/// power-up values ([`ServoParams`]; every key defaults to the 400 W servo).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct ServoConfig {
    /// CANopen node id (1..=127) when the chain is simulated on a CAN bus; unused on
    /// EtherCAT, where a slave's place in the chain is its address.
    pub node: Option<u8>,
    /// Absolute encoder value at power-up (counts).
    pub start_position: i32,
    /// On a CAN bus: the SYNC watchdog's margin, in communication cycle periods (0x1006):
    /// no SYNC for longer is a communication error (EMCY 0x8100 and the 0x6007
    /// reaction). CiA 301 §7.5.2.6 leaves it to the device; 1.5 (CANopenNode's) by
    /// default. A larger one tolerates a master on a host without real time.
    pub sync_timeout_periods: f64,
    /// On a CAN bus: bytes of the manufacturer DOMAIN 0x2F00 "recorder" (read-only, known
    /// content, for large SDO uploads; 0: the node has none; at most 1 MiB).
    pub recorder_bytes: u32,
    /// On a CAN bus: bytes the manufacturer DOMAIN 0x2F01 "scratch" holds at most
    /// (read-write: an upload reads back what the last download wrote, for large SDO
    /// downloads; 0: the node has none; at most 1 MiB).
    pub scratch_bytes: u32,
    /// On a CAN bus: how long its SDO server waits for the client's next frame before it
    /// aborts the transfer with 0x05040000 (ms; CiA 301 leaves it to the device; 1000 by
    /// default). A longer one serves a slow client (a Python master in an emulated VM
    /// acknowledging a sub-block of 127 segments).
    pub sdo_timeout_ms: u32,
    /// On a CAN bus: receive and transmit PDOs it has, each way (1..=8; 4 by default,
    /// the predefined connection set's, what most CiA 402 drives have). PDOs 5 and up
    /// power up invalid without a COB-ID: the master gives them one.
    pub pdo_count: u8,
    /// How fast its distributed clock's oscillator runs against true time (ppm;
    /// negative: slow). A real quartz is off by tens of ppm: the first DC slave's is
    /// the network's reference, which the master's cycle has to follow.
    pub dc_drift_ppm: f64,
    /// The motor's hidden commutation offset (counts), for commissioning to find.
    pub commutation_offset: i32,
    /// Velocity loop bandwidth (Hz): the figure servo datasheets give as the drive's
    /// "speed response".
    pub bandwidth_hz: f64,
    /// Position loop gain (1/s); default a fifth of the velocity loop's 2π·bandwidth.
    pub position_gain: Option<f64>,
    /// Encoder counts per motor revolution.
    pub counts_per_rev: u32,
    /// Rated torque (N·m).
    pub rated_torque_nm: f64,
    /// Peak torque (N·m), the current limit.
    pub peak_torque_nm: f64,
    /// Rotor inertia (kg·m²).
    pub rotor_inertia_kgm2: f64,
    /// Load inertia as a multiple of the rotor's.
    pub load_inertia_ratio: f64,
    /// Coulomb friction (N·m).
    pub coulomb_friction_nm: f64,
    /// Viscous friction (N·m per rad/s).
    pub viscous_friction_nm_s: f64,
    /// Top motor speed (rpm), the power-up 0x607F.
    pub max_speed_rpm: f64,
    /// Motor pole pairs.
    pub pole_pairs: u32,
    /// Index pulse position in the revolution (counts).
    pub index_at: u32,
    /// The drive's loop rate (Hz).
    pub loop_rate_hz: f64,
    /// Current loop bandwidth (Hz).
    pub current_loop_hz: f64,
    /// 0x6065 Following error window (counts; 4294967295: off).
    pub following_error_window: u32,
    /// 0x6066 Following error time out (ms).
    pub following_error_timeout_ms: u16,
    /// 0x6084 Profile deceleration (counts/s²).
    pub profile_deceleration: u32,
    /// 0x6085 Quick stop deceleration (counts/s²).
    pub quick_stop_deceleration: u32,
    /// 0x605A Quick stop option code (0…8).
    pub quick_stop_option_code: i16,
    /// 0x605B Shutdown option code (0, 1).
    pub shutdown_option_code: i16,
    /// 0x605C Disable operation option code (0, 1).
    pub disable_operation_option_code: i16,
    /// 0x605E Fault reaction option code (0…4).
    pub fault_reaction_option_code: i16,
    /// How long its firmware takes for each AL transition (`[slave.al]`).
    pub al: AlConfig,
    /// Switch cams on its own travel, read by its digital inputs 0x60FD
    /// (`[slave.switches]`).
    pub switches: ServoSwitches,
    /// Faults of its homing mode, to inject (`[slave.homing]`).
    pub homing: ServoHoming,
    /// Where its maker put the commutation objects (`[slave.commutation]`).
    pub commutation: ServoCommutation,
}

/// `[slave.commutation]` of a servo: the indices (sub-index 0) of its manufacturer's
/// commutation objects and its open-loop current-vector mode, as another maker's drive has
/// them elsewhere than gantry-sim's default 0x2100–0x2103 and −1. Types as the default's:
/// offset INTEGER32, pole pairs UNSIGNED8, current and angle UNSIGNED16.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(default, deny_unknown_fields)]
pub struct ServoCommutation {
    /// The open-loop current-vector mode (a negative 0x6060 value).
    pub mode: i8,
    /// The commutation offset setting.
    pub offset: u16,
    /// Its units to an electrical revolution; 0: encoder counts.
    pub offset_units: u32,
    /// The motor's pole pairs (read-only); 0: the drive does not expose them.
    pub pole_pairs: u16,
    /// The vector's amplitude (per mille of the rated current).
    pub current: u16,
    /// The vector's electrical angle.
    pub angle: u16,
    /// Angle units to an electrical revolution.
    pub angle_units: u32,
}

impl Default for ServoCommutation {
    fn default() -> Self {
        let d = gantry_drives::commutation::CommutationObjects::default();
        let pole_pairs = match d.pole_pairs {
            gantry_drives::commutation::PolePairs::Object(o) => o.index,
            gantry_drives::commutation::PolePairs::Fixed(_) => 0,
        };
        Self {
            mode: d.mode,
            offset: d.offset.index,
            offset_units: 0,
            pole_pairs,
            current: d.current.index,
            angle: d.angle.index,
            angle_units: d.angle_units,
        }
    }
}

impl ServoCommutation {
    /// The objects these keys describe (checked by [`ServoParams::check`]).
    pub fn objects(&self, pole_pairs: u32) -> gantry_drives::commutation::CommutationObjects {
        use gantry_drives::cia402::objects::ObjectId;
        use gantry_drives::commutation::{CommutationObjects, OffsetUnits, PolePairs};
        let d = CommutationObjects::default();
        let at = |o: ObjectId, index: u16| ObjectId { index, ..o };
        let pole_pairs = match (d.pole_pairs, self.pole_pairs) {
            (PolePairs::Object(o), index) if index != 0 => PolePairs::Object(at(o, index)),
            _ => PolePairs::Fixed(pole_pairs),
        };
        CommutationObjects {
            mode: self.mode,
            offset: at(d.offset, self.offset),
            offset_units: match self.offset_units {
                0 => OffsetUnits::Counts,
                n => OffsetUnits::PerElectricalRev(n),
            },
            pole_pairs,
            current: at(d.current, self.current),
            angle: at(d.angle, self.angle),
            angle_units: self.angle_units,
        }
    }
}

/// `[slave.homing]` of a servo: homing faults real drives are reported to have.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(default, deny_unknown_fields)]
pub struct ServoHoming {
    /// The drive homes but never sets "homing attained" (statusword bit 12).
    pub never_attains: bool,
    /// Methods it refuses (SDO abort 0x06090030) although CiA 402 defines them, e.g.
    /// `[0]`.
    #[serde(deserialize_with = "method_set")]
    pub refuse_methods: MethodSet,
}

/// A list of homing methods.
fn method_set<'de, D: serde::Deserializer<'de>>(d: D) -> Result<MethodSet, D::Error> {
    let list = Vec::<i8>::deserialize(d)?;
    let mut set = MethodSet::EMPTY;
    for m in list {
        set.insert(m);
    }
    Ok(set)
}

/// `[slave.switches]` of a servo: where on its travel (counts, both ends included) each
/// switch its digital inputs (0x60FD) read is actuated. 0x60FD reports each switch
/// function active (CiA 402: 1 = active), as a drive set up for its contacts' type does,
/// so there is no polarity here; the home switch is also both touch probes' input.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(default, deny_unknown_fields)]
pub struct ServoSwitches {
    /// Bit 0: the negative limit switch.
    pub negative_limit: Option<[i64; 2]>,
    /// Bit 1: the positive limit switch.
    pub positive_limit: Option<[i64; 2]>,
    /// Bit 2: the home (reference) switch.
    pub home: Option<[i64; 2]>,
}

impl ServoSwitches {
    /// The cams, each on its 0x60FD bit, named by their key.
    fn cams(&self) -> impl Iterator<Item = (&'static str, SwitchCam)> + '_ {
        [
            ("negative_limit", self.negative_limit),
            ("positive_limit", self.positive_limit),
            ("home", self.home),
        ]
        .into_iter()
        .enumerate()
        .filter_map(|(input, (key, range))| {
            range.map(|[from, to]| {
                (
                    key,
                    SwitchCam {
                        input: input as u8,
                        from,
                        to,
                        normally_closed: false,
                    },
                )
            })
        })
    }

    /// The drive's switches.
    pub fn drive_switches(&self) -> DriveSwitches {
        let cams: Vec<SwitchCam> = self.cams().map(|(_, c)| c).collect();
        DriveSwitches::new(&cams)
    }
}

impl Default for ServoConfig {
    fn default() -> Self {
        let p = ServoParams::default();
        Self {
            node: None,
            start_position: 0,
            sync_timeout_periods: crate::canopen::node::SYNC_TIMEOUT_PERIODS,
            recorder_bytes: 0,
            scratch_bytes: 0,
            sdo_timeout_ms: 1000,
            pdo_count: crate::canopen::pdo::DEFAULT_PDO_COUNT,
            dc_drift_ppm: 0.0,
            commutation_offset: p.commutation_offset,
            bandwidth_hz: p.velocity_loop_hz,
            position_gain: None,
            counts_per_rev: p.counts_per_rev,
            rated_torque_nm: p.rated_torque_nm,
            peak_torque_nm: p.peak_torque_nm,
            rotor_inertia_kgm2: p.rotor_inertia_kgm2,
            load_inertia_ratio: p.load_inertia_ratio,
            coulomb_friction_nm: p.coulomb_friction_nm,
            viscous_friction_nm_s: p.viscous_friction_nm_s,
            max_speed_rpm: p.max_speed_rpm,
            pole_pairs: p.pole_pairs,
            index_at: p.index_at,
            loop_rate_hz: p.loop_rate_hz,
            current_loop_hz: p.current_loop_hz,
            following_error_window: p.following_error_window,
            following_error_timeout_ms: p.following_error_timeout_ms,
            profile_deceleration: p.profile_deceleration,
            quick_stop_deceleration: p.quick_stop_deceleration,
            quick_stop_option_code: p.quick_stop_option_code,
            shutdown_option_code: p.shutdown_option_code,
            disable_operation_option_code: p.disable_operation_option_code,
            fault_reaction_option_code: p.fault_reaction_option_code,
            al: AlConfig::default(),
            switches: ServoSwitches::default(),
            homing: ServoHoming::default(),
            commutation: ServoCommutation::default(),
        }
    }
}

impl ServoConfig {
    /// The servo these keys describe (not checked: see [`ServoParams::check`]).
    pub fn params(&self) -> ServoParams {
        let c = self;
        ServoParams {
            counts_per_rev: c.counts_per_rev,
            rated_torque_nm: c.rated_torque_nm,
            peak_torque_nm: c.peak_torque_nm,
            rotor_inertia_kgm2: c.rotor_inertia_kgm2,
            load_inertia_ratio: c.load_inertia_ratio,
            coulomb_friction_nm: c.coulomb_friction_nm,
            viscous_friction_nm_s: c.viscous_friction_nm_s,
            max_speed_rpm: c.max_speed_rpm,
            pole_pairs: c.pole_pairs,
            index_at: c.index_at,
            switches: c.switches.drive_switches(),
            commutation_offset: c.commutation_offset,
            loop_rate_hz: c.loop_rate_hz,
            current_loop_hz: c.current_loop_hz,
            velocity_loop_hz: c.bandwidth_hz,
            position_gain: c
                .position_gain
                .unwrap_or(2.0 * core::f64::consts::PI * c.bandwidth_hz / 5.0),
            following_error_window: c.following_error_window,
            following_error_timeout_ms: c.following_error_timeout_ms,
            profile_deceleration: c.profile_deceleration,
            quick_stop_deceleration: c.quick_stop_deceleration,
            quick_stop_option_code: c.quick_stop_option_code,
            shutdown_option_code: c.shutdown_option_code,
            disable_operation_option_code: c.disable_operation_option_code,
            fault_reaction_option_code: c.fault_reaction_option_code,
            homing_faults: HomingFaults {
                never_attains: c.homing.never_attains,
                refused: c.homing.refuse_methods,
            },
            commutation_objects: c.commutation.objects(c.pole_pairs),
        }
    }
}

fn default_counts_per_rev() -> u32 {
    4096
}

// AL transition times (`[slave.al]`).

/// How long a device's firmware takes for each upward AL transition (ms); what is not
/// given keeps the device's default (a servo: 2, 10 and 5 ms; an encoder module: 0). A
/// digital-input module has no firmware: its ESC mirrors AL control at once.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AlConfig {
    /// Init → PreOp.
    pub init_to_preop_ms: Option<f64>,
    /// PreOp → SafeOp.
    pub preop_to_safeop_ms: Option<f64>,
    /// SafeOp → Op.
    pub safeop_to_op_ms: Option<f64>,
    /// 0x10F1:02 sync error counter limit (default 4: two SYNC0 periods in a row without
    /// outputs take the drive out of Op with a sync error).
    pub sync_error_limit: Option<u16>,
    /// SafeOp → Op waits for valid outputs (default: a servo does, an I/O module not).
    pub op_needs_outputs: Option<bool>,
    /// How long the firmware takes to answer a mailbox request (ms; default 0: at once).
    pub mailbox_ms: Option<f64>,
}

/// Longest AL transition time accepted (ms): beyond, a master's state-transition timeout
/// (ethercrab: 5 s) has long given up.
const MAX_AL_TRANSITION_MS: f64 = 10_000.0;

impl AlConfig {
    /// The times, with `defaults` for what is not given.
    pub fn times(&self, defaults: TransitionTimes) -> TransitionTimes {
        let ns = |ms: Option<f64>, default: u64| ms.map_or(default, |ms| (ms * 1e6).round() as u64);
        TransitionTimes {
            init_to_preop_ns: ns(self.init_to_preop_ms, defaults.init_to_preop_ns),
            preop_to_safeop_ns: ns(self.preop_to_safeop_ms, defaults.preop_to_safeop_ns),
            safeop_to_op_ns: ns(self.safeop_to_op_ms, defaults.safeop_to_op_ns),
        }
    }

    /// The first key out of range, as `al.<key>`.
    fn invalid_key(&self) -> Option<&'static str> {
        [
            ("al.init_to_preop_ms", self.init_to_preop_ms),
            ("al.preop_to_safeop_ms", self.preop_to_safeop_ms),
            ("al.safeop_to_op_ms", self.safeop_to_op_ms),
            ("al.mailbox_ms", self.mailbox_ms),
        ]
        .into_iter()
        .find(|(_, v)| {
            v.is_some_and(|v| !(v.is_finite() && (0.0..=MAX_AL_TRANSITION_MS).contains(&v)))
        })
        .map(|(k, _)| k)
    }

    /// The firmware `base` with these settings.
    pub fn firmware(&self, base: Firmware) -> Firmware {
        Firmware {
            times: self.times(base.times),
            sync_error_limit: self.sync_error_limit.unwrap_or(base.sync_error_limit),
            op_needs_outputs: self.op_needs_outputs.unwrap_or(base.op_needs_outputs),
            mailbox_response_ns: self
                .mailbox_ms
                .map_or(base.mailbox_response_ns, |ms| (ms * 1e6).round() as u64),
            ..base
        }
    }
}

/// Largest oscillator error of a simulated DC clock (ppm); real ones are within ±100.
const MAX_DC_DRIFT_PPM: f64 = 1000.0;

/// Highest shaft speed of an encoder (rev/s).
const MAX_SHAFT_SPEED: f64 = 1000.0;

/// The line an error points at. For an unknown key inside a tagged table, TOML's span
/// covers the whole table; the line of the key itself is what the user needs.
fn error_line(text: &str, e: &toml::de::Error) -> usize {
    let start = e.span().map_or(0, |s| s.start);
    let line_of = |offset: usize| text.get(..offset).unwrap_or("").lines().count().max(1);
    let unknown = e
        .message()
        .strip_prefix("unknown field `")
        .and_then(|m| m.split('`').next());
    if let Some(key) = unknown {
        let mut offset = start;
        for line in text.get(start..).unwrap_or("").split_inclusive('\n') {
            let rest = line.trim_start().strip_prefix(key).unwrap_or("#");
            if rest.trim_start().starts_with('=') {
                return line_of(offset + 1);
            }
            offset += line.len();
        }
    }
    line_of(start)
}

impl SimConfig {
    /// Reads and checks `path`.
    pub fn load(path: &str) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.into(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses and checks `text`; `path` names it in errors.
    pub fn parse(text: &str, path: &str) -> Result<Self, ConfigError> {
        let config: SimConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.into(),
            line: error_line(text, &e),
            message: e.message().to_string(),
        })?;
        config.check(path)?;
        Ok(config)
    }

    fn check(&self, path: &str) -> Result<(), ConfigError> {
        let invalid = |key: String, reason: &str| ConfigError::Invalid {
            path: path.into(),
            key,
            reason: reason.into(),
        };
        // CiA 301 §7.3.2: node ids 1..=127, each at most once on a bus.
        let mut seen = [false; 128];
        for (i, s) in self.slaves.iter().enumerate() {
            let Some(node) = s.node() else { continue };
            if !(1..=127).contains(&node) {
                return Err(invalid(
                    format!("slave[{i}].node"),
                    "a CANopen node id must be 1 to 127",
                ));
            }
            if seen
                .get_mut(usize::from(node))
                .is_some_and(|s| std::mem::replace(s, true))
            {
                return Err(invalid(
                    format!("slave[{i}].node"),
                    &format!("node id {node} is already used by another slave"),
                ));
            }
        }
        if !(100..=100_000).contains(&self.cycle_us) {
            return Err(invalid("cycle_us".into(), "must be 100 to 100000 µs"));
        }
        if self.slaves.is_empty() {
            return Err(invalid("slave".into(), "the chain has no slave"));
        }
        for (i, s) in self.slaves.iter().enumerate() {
            match s {
                SlaveConfig::Servo(servo) => {
                    if let Some(key) = servo.al.invalid_key() {
                        return Err(invalid(
                            format!("slave[{i}].{key}"),
                            "must be 0 to 10000 ms",
                        ));
                    }
                    if servo.al.sync_error_limit == Some(0) {
                        return Err(invalid(
                            format!("slave[{i}].al.sync_error_limit"),
                            "must be at least 1",
                        ));
                    }
                    if let Err(e) = servo.params().check() {
                        // The TOML key of the velocity loop is `bandwidth_hz`.
                        let name = match e.name {
                            "velocity_loop_hz" => "bandwidth_hz",
                            n => n,
                        };
                        return Err(invalid(format!("slave[{i}].{name}"), &e.reason));
                    }
                    for (key, cam) in servo.switches.cams() {
                        if cam.from > cam.to {
                            return Err(invalid(
                                format!("slave[{i}].switches.{key}"),
                                &format!("from {} is above to {}", cam.from, cam.to),
                            ));
                        }
                    }
                    if !(servo.dc_drift_ppm.is_finite()
                        && servo.dc_drift_ppm.abs() <= MAX_DC_DRIFT_PPM)
                    {
                        return Err(invalid(
                            format!("slave[{i}].dc_drift_ppm"),
                            "must be -1000 to 1000 ppm",
                        ));
                    }
                }
                SlaveConfig::Encoder {
                    counts_per_rev,
                    shaft_speed,
                    al,
                    ..
                } => {
                    if let Some(key) = al.invalid_key() {
                        return Err(invalid(
                            format!("slave[{i}].{key}"),
                            "must be 0 to 10000 ms",
                        ));
                    }
                    if al.sync_error_limit == Some(0) {
                        return Err(invalid(
                            format!("slave[{i}].al.sync_error_limit"),
                            "must be at least 1",
                        ));
                    }
                    if *counts_per_rev == 0 {
                        return Err(invalid(
                            format!("slave[{i}].counts_per_rev"),
                            "must be at least 1",
                        ));
                    }
                    if !(shaft_speed.is_finite() && shaft_speed.abs() <= MAX_SHAFT_SPEED) {
                        return Err(invalid(
                            format!("slave[{i}].shaft_speed"),
                            "must be -1000 to 1000 rev/s",
                        ));
                    }
                }
                SlaveConfig::Switches { axis, cams, .. } => {
                    match self.slaves.get(*axis) {
                        None => {
                            let n = self.slaves.len();
                            return Err(invalid(
                                format!("slave[{i}].axis"),
                                &format!("there is no slave {axis} (the chain has {n})"),
                            ));
                        }
                        Some(SlaveConfig::Servo(_)) => {}
                        Some(_) => {
                            return Err(invalid(
                                format!("slave[{i}].axis"),
                                &format!("slave {axis} is not a servo"),
                            ));
                        }
                    }
                    let cams: Vec<SwitchCam> = cams.iter().map(|&c| c.into()).collect();
                    if let Err(e) = check_cams(&cams) {
                        let (cam, field, reason) = match e {
                            CamError::NoSuchInput { cam, .. } => {
                                (cam, "input", "must be 0 to 7".to_string())
                            }
                            CamError::EmptyRange { cam, from, to } => {
                                (cam, "from", format!("{from} is above to = {to}"))
                            }
                            CamError::InputTaken { cam, input, first } => (
                                cam,
                                "input",
                                format!("input {input} already has cam {first}"),
                            ),
                        };
                        return Err(invalid(format!("slave[{i}].cam[{cam}].{field}"), &reason));
                    }
                }
            }
        }
        Ok(())
    }

    /// The chain this configuration describes. Only a configuration built by hand, not
    /// one [`SimConfig::parse`] checked, can have cams that cannot be wired.
    pub fn chain(&self) -> Result<SlaveChain, CamError> {
        let slaves = self
            .slaves
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let serial = i as u32 + 1;
                Ok(match s {
                    SlaveConfig::Servo(servo) => catalog::servo(ServoOptions {
                        serial,
                        start_counts: servo.start_position,
                        params: servo.params(),
                        firmware: servo.al.firmware(Firmware::SERVO),
                    })
                    .with_dc_drift_ppm(servo.dc_drift_ppm),
                    SlaveConfig::Encoder {
                        counts_per_rev,
                        shaft_speed,
                        al,
                        ..
                    } => catalog::encoder(EncoderOptions {
                        serial,
                        counts_per_rev: *counts_per_rev,
                        shaft_speed_rev_s: *shaft_speed,
                    })
                    .with_firmware(al.firmware(Firmware::SIMPLE)),
                    SlaveConfig::Switches { axis, cams, .. } => {
                        catalog::switches(SwitchesOptions {
                            serial,
                            axis: *axis,
                            cams: cams.iter().map(|&c| c.into()).collect(),
                        })?
                    }
                })
            })
            .collect::<Result<Vec<_>, CamError>>()?;
        Ok(SlaveChain::new(slaves))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::DeviceModel;

    #[test]
    fn parses_a_chain_with_defaults() {
        let c = SimConfig::parse(
            "cycle_us = 500\n[[slave]]\nkind = \"servo\"\n[[slave]]\nkind = \"servo\"\nstart_position = -7\n",
            "sim.toml",
        )
        .unwrap();
        assert_eq!(c.cycle_us, 500);
        assert_eq!(
            c.slaves[1],
            SlaveConfig::Servo(ServoConfig {
                start_position: -7,
                ..ServoConfig::default()
            })
        );
        assert_eq!(
            ServoConfig::default().params(),
            ServoParams::default(),
            "the keys' defaults are the 400 W servo's"
        );
        let chain = c.chain().unwrap();
        assert_eq!(chain.slaves().len(), 2);
        assert_eq!(chain.slaves()[0].firmware().times, TransitionTimes::SERVO);
    }

    #[test]
    fn al_transition_times_are_per_device_with_defaults() {
        let c = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\n[slave.al]\nsafeop_to_op_ms = 20\ninit_to_preop_ms = 0\n\
             [[slave]]\nkind = \"encoder\"\n[slave.al]\npreop_to_safeop_ms = 1.5\n\
             [[slave]]\nkind = \"servo\"\n",
            "sim.toml",
        )
        .unwrap();
        let chain = c.chain().unwrap();
        let times = |i: usize| chain.slaves()[i].firmware().times;
        assert_eq!(
            times(0),
            TransitionTimes {
                init_to_preop_ns: 0,
                preop_to_safeop_ns: 10_000_000,
                safeop_to_op_ns: 20_000_000,
            }
        );
        assert_eq!(
            times(1),
            TransitionTimes {
                preop_to_safeop_ns: 1_500_000,
                ..TransitionTimes::INSTANT
            }
        );
        assert_eq!(times(2), TransitionTimes::SERVO);
        assert!(chain.slaves()[0].firmware().op_needs_outputs);
        assert!(!chain.slaves()[1].firmware().op_needs_outputs);
        let e = |text: &str| SimConfig::parse(text, "sim.toml").unwrap_err().to_string();
        assert_eq!(
            e("[[slave]]\nkind = \"servo\"\n[slave.al]\nsafeop_to_op_ms = -1\n"),
            "sim.toml: slave[0].al.safeop_to_op_ms: must be 0 to 10000 ms"
        );
        assert_eq!(
            e("[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = 0\n"),
            "sim.toml: slave[0].al.sync_error_limit: must be at least 1"
        );
        let limit = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = 40\n",
            "sim.toml",
        )
        .unwrap();
        let chain = limit.chain().unwrap();
        assert_eq!(chain.slaves()[0].firmware().sync_error_limit, 40);
        assert!(
            chain.slaves()[0].firmware().op_needs_outputs,
            "a servo's default"
        );
        let unknown = e("[[slave]]\nkind = \"servo\"\n[slave.al]\nsafeop_op_ms = 1\n");
        assert!(unknown.contains("safeop_op_ms"), "{unknown}");
    }

    #[test]
    fn mistakes_name_file_line_and_key() {
        let e = |text: &str| SimConfig::parse(text, "sim.toml").unwrap_err().to_string();
        let unknown = e("[[slave]]\nkind = \"servo\"\nbandwith_hz = 3\n");
        assert!(unknown.starts_with("sim.toml:3:"), "{unknown}");
        assert!(unknown.contains("bandwith_hz"), "{unknown}");
        let kind = e("[[slave]]\nkind = \"robot\"\n");
        assert!(
            kind.starts_with("sim.toml:1:") || kind.starts_with("sim.toml:2:"),
            "{kind}"
        );
        assert!(kind.contains("robot"), "{kind}");
        let ty = e("cycle_us = \"fast\"\n[[slave]]\nkind = \"servo\"\n");
        assert!(ty.starts_with("sim.toml:1:"), "{ty}");
        assert_eq!(
            e("[[slave]]\nkind = \"servo\"\nbandwidth_hz = -1\n"),
            "sim.toml: slave[0].bandwidth_hz: -1 is not within 1 to 800"
        );
        assert_eq!(
            e("[[slave]]\nkind = \"servo\"\ndc_drift_ppm = 5000\n"),
            "sim.toml: slave[0].dc_drift_ppm: must be -1000 to 1000 ppm"
        );
        assert_eq!(
            e("cycle_us = 1000\n"),
            "sim.toml: slave: the chain has no slave"
        );
    }

    #[test]
    fn the_example_in_the_module_doc_parses() {
        let source = include_str!("config.rs");
        let example: String = source
            .lines()
            .skip_while(|l| !l.starts_with("//! ```toml"))
            .skip(1)
            .take_while(|l| !l.starts_with("//! ```"))
            .map(|l| format!("{}\n", l.trim_start_matches("//!").trim_start_matches(' ')))
            .collect();
        let c = SimConfig::parse(&example, "doc").unwrap();
        assert_eq!(c.slaves.len(), 3);
        assert_eq!(c.chain().unwrap().slaves().len(), 3);
    }

    #[test]
    fn a_servo_s_switch_cams() {
        let c = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\n[slave.switches]\nhome = [100, 200]\npositive_limit = [5000, 9000]\n",
            "sim.toml",
        )
        .unwrap();
        let SlaveConfig::Servo(servo) = &c.slaves[0] else {
            panic!("{:?}", c.slaves[0]);
        };
        let switches = servo.params().switches;
        assert_eq!(switches.digital_inputs(150), 0b100);
        assert_eq!(switches.digital_inputs(6000), 0b010);
        assert_eq!(switches.digital_inputs(-6000), 0);
        let e = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\n[slave.switches]\nhome = [300, 200]\n",
            "sim.toml",
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "sim.toml: slave[0].switches.home: from 300 is above to 200"
        );
        let e = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\n[slave.switches]\nreference = [1, 2]\n",
            "sim.toml",
        )
        .unwrap_err();
        assert!(e.to_string().contains("unknown field `reference`"), "{e}");
    }

    #[test]
    fn node_ids_are_checked() {
        let c = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\nnode = 5\n[[slave]]\nkind = \"encoder\"\nnode = 6\n",
            "sim.toml",
        )
        .unwrap();
        assert_eq!(c.slaves[0].node(), Some(5));
        assert_eq!(c.slaves[1].node(), Some(6));
        let e =
            SimConfig::parse("[[slave]]\nkind = \"servo\"\nnode = 0\n", "sim.toml").unwrap_err();
        assert_eq!(
            e.to_string(),
            "sim.toml: slave[0].node: a CANopen node id must be 1 to 127"
        );
        let e = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\nnode = 9\n[[slave]]\nkind = \"servo\"\nnode = 9\n",
            "sim.toml",
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "sim.toml: slave[1].node: node id 9 is already used by another slave"
        );
    }

    #[test]
    fn parses_encoder_and_switches_with_cams() {
        let c = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\n\
             [[slave]]\nkind = \"encoder\"\ncounts_per_rev = 1024\nshaft_speed = -2.5\n\
             [[slave]]\nkind = \"switches\"\naxis = 0\n\
             [[slave.cam]]\ninput = 3\nfrom = -10\nto = 10\n\
             [[slave.cam]]\ninput = 4\nfrom = 100\nto = 200\nnormally_closed = true\n\
             [[slave]]\nkind = \"encoder\"\n",
            "sim.toml",
        )
        .unwrap();
        assert_eq!(
            c.slaves[1],
            SlaveConfig::Encoder {
                node: None,
                counts_per_rev: 1024,
                shaft_speed: -2.5,
                al: AlConfig::default(),
            }
        );
        assert_eq!(
            c.slaves[3],
            SlaveConfig::Encoder {
                node: None,
                counts_per_rev: 4096,
                shaft_speed: 0.0,
                al: AlConfig::default(),
            }
        );
        let SlaveConfig::Switches { axis, cams, .. } = &c.slaves[2] else {
            panic!("{:?}", c.slaves[2]);
        };
        assert_eq!(*axis, 0);
        assert_eq!(
            cams[1],
            CamConfig {
                input: 4,
                from: 100,
                to: 200,
                normally_closed: true
            }
        );
        assert!(!cams[0].normally_closed);
        let chain = c.chain().unwrap();
        let d = |i: usize| chain.slaves()[i].device();
        assert!(
            matches!(d(1), DeviceModel::Encoder(e) if e.counts_per_rev == 1024 && e.shaft_speed_rev_s == -2.5)
        );
        assert!(matches!(d(2), DeviceModel::Switches(s) if s.axis == 0 && s.cams().len() == 2));
        assert_eq!(
            chain.slaves()[2].description().product_code,
            catalog::SWITCHES_PRODUCT
        );
    }

    #[test]
    fn encoder_and_switches_mistakes_name_the_key() {
        let e = |text: &str| SimConfig::parse(text, "sim.toml").unwrap_err().to_string();
        let servo = "[[slave]]\nkind = \"servo\"\n";
        let encoder = "[[slave]]\nkind = \"encoder\"\n";
        let switches = |axis: usize| format!("[[slave]]\nkind = \"switches\"\naxis = {axis}\n");
        let cam = |input: u8, from: i64, to: i64| {
            format!("[[slave.cam]]\ninput = {input}\nfrom = {from}\nto = {to}\n")
        };
        assert_eq!(
            e(&format!("{servo}{encoder}{}", switches(1))),
            "sim.toml: slave[2].axis: slave 1 is not a servo"
        );
        assert_eq!(
            e(&format!("{servo}{}", switches(5))),
            "sim.toml: slave[1].axis: there is no slave 5 (the chain has 2)"
        );
        assert_eq!(
            e(&format!("{servo}{}{}", switches(0), cam(8, 0, 1))),
            "sim.toml: slave[1].cam[0].input: must be 0 to 7"
        );
        assert_eq!(
            e(&format!(
                "{servo}{}{}{}",
                switches(0),
                cam(0, 0, 1),
                cam(1, 9, 2)
            )),
            "sim.toml: slave[1].cam[1].from: 9 is above to = 2"
        );
        assert_eq!(
            e(&format!(
                "{servo}{}{}{}",
                switches(0),
                cam(2, 0, 1),
                cam(2, 5, 6)
            )),
            "sim.toml: slave[1].cam[1].input: input 2 already has cam 0"
        );
        assert_eq!(
            e(&format!("{encoder}counts_per_rev = 0\n")),
            "sim.toml: slave[0].counts_per_rev: must be at least 1"
        );
        assert_eq!(
            e(&format!("{encoder}shaft_speed = 1e9\n")),
            "sim.toml: slave[0].shaft_speed: must be -1000 to 1000 rev/s"
        );
        // Serde's own checks: a missing axis, an unknown key in a cam (with its line).
        let missing = e(&format!("{servo}[[slave]]\nkind = \"switches\"\n"));
        assert!(missing.contains("axis"), "{missing}");
        let unknown = e(&format!(
            "{servo}{}[[slave.cam]]\ninput = 0\nfrom = 1\nto = 2\nclosed = true\n",
            switches(0)
        ));
        assert!(unknown.starts_with("sim.toml:10:"), "{unknown}");
        assert!(unknown.contains("closed"), "{unknown}");
    }
}
