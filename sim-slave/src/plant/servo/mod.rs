//! A CiA-402 servo drive in cyclic synchronous position, velocity and torque modes (CSP,
//! CSV, CST): the device side of the power state machine from `gantry-drives` (the same
//! table the master uses), and a motor and load with inertia, friction and a torque limit,
//! moved by cascaded loops at the drive's own loop rate (see [`motor`]). It is as strict
//! as a real drive:
//!
//! - **Following error** (CiA 402-2 §12.4, objects 0x6065/0x6066): in CSP, when the
//!   position demand and the actual position are further apart than the window for longer
//!   than the time out, the drive faults with 0x8611.
//! - **Setpoint step** (0x607F max profile velocity): a CSP target that moved further since
//!   the last one than the motor can go at 0x607F in that time (plus one count) faults at
//!   once with [`ERROR_SETPOINT_STEP`]. "That time" is since the target last changed, so a
//!   frame the master sent a period late is no fault (the drive counts such misses, it does
//!   not fault on one); the first target after enabling must be within one period of the
//!   load. A jump after a standstill is left to the following error, as on real drives. Real drives have this monitor (Bosch
//!   Rexroth IndraDrive: F2037 "Excessive position command difference") because without it
//!   the loops lunge at peak torque for the whole following-error time out before 0x8611
//!   stops them. The code is manufacturer-specific, as theirs is: CiA 402 has no standard
//!   code for it, and 0x8611 would tell the user the axis could not keep up when the
//!   master asked for the impossible.
//! - **Stops** decelerate as the option codes say (CiA 402-2 §8.4): quick stop 0x605A on
//!   0x6084/0x6085 or at the current limit, staying in Quick stop active (5…8) or going to
//!   Switch on disabled (1…4) once stopped; shutdown 0x605B and disable operation 0x605C
//!   (0: the power stage goes off and the load coasts, 1: slow down on 0x6084 first, the
//!   state changing once stopped); fault reaction 0x605E (the drive shows Fault reaction
//!   active while it brakes, then Fault).
//! - **Actual values** are the model's: velocity 0x606C, torque 0x6077 (per mille of the
//!   rated torque 0x6076, from the current: what accelerates the inertia plus friction),
//!   following error 0x60F4.
//! - **Overspeed** (a velocity supervision every drive has; CiA 402-2 leaves it to the
//!   manufacturer): a motor faster than [`OVERSPEED_FACTOR`] × its top speed faults the
//!   drive with 0x8400 (velocity control error) in any mode, and the power stage goes off
//!   at once, whatever 0x605E says: a motor that overspeeds is not obeying its velocity
//!   loop (a wrong commutation turns it the wrong way), so braking with that loop would
//!   only drive it harder.
//! - **Commutation** (see [`motor`]): the motor is a permanent-magnet synchronous motor
//!   commutated with the drive's setting 0x2100; the true offset is hidden in
//!   [`ServoParams::commutation_offset`]. What a drive exposes to measure it: 0x2101 pole
//!   pairs (ro) and the manufacturer mode [`OPEN_LOOP`] (0x6060 = -1), in which the drive
//!   holds a current vector of amplitude 0x2102 at electrical angle 0x2103 without its
//!   encoder; the master sees the rotor turn only in the position actual value.
//! - **32-bit positions wrap** as CSP drives count: the position actual value is the low
//!   half of the drive's position, and a target is taken the short way from the last one.
//!
//! A CSP target is interpolated linearly over the setpoint period (the time between two
//! setpoints taken), with the velocity feed-forward its slope; a period without a new
//! setpoint continues along the last slope, and after that the demand stays where it got
//! to (a drive starved of setpoints does not run away).
//!
//! Process data follows the PDO layout the master mapped (see `coe::pdo`), read and
//! written through the view the master codes through too (`gantry_drives::cia402::image`);
//! until then the power-up mapping: outputs `0x6040 controlword: u16, 0x607A target position: i32`;
//! inputs `0x6041 statusword: u16, 0x6064 position actual value: i32`.
//!
//! Each application period is three calls, so that the ESC side can sample the outputs
//! at the drive's SYNC0 edge: [`ServoDrive::take_outputs`], [`ServoDrive::run`],
//! [`ServoDrive::publish_inputs`] ([`ServoDrive::step`] does all three).

pub mod crossings;
pub mod homing;
pub mod motor;
pub mod params;
pub mod probe;

use gantry_drives::cia402::controlword::Command;
use gantry_drives::cia402::image::{InputImage, OutputImage, PdoMap};
use gantry_drives::cia402::objects::{self, ObjectId};
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::cia402::state::transition;
use gantry_drives::cia402::statusword;
use gantry_drives::cia402::{Controlword, DeviceStateMachine, State, Statusword};
use gantry_drives::commutation::PolePairs;

use crate::coe::od::ObjectDictionary;
use crate::esc::memory::Memory;
use crate::plant::record::DriveRecord;
use crossings::CrossingLog;
use homing::Homing;
use motor::{Commutation, Drive, Gains, Motor};
pub use params::{ParamError, ServoParams};
use probe::{Edge, Signal, TouchProbe};

/// Most process data bytes per direction the model handles.
const MAX_PDO_BYTES: usize = 64;

/// Error code (0x603F) of a fault by process-data watchdog: CiA 301 0x8700 "sync
/// controller" family, which EtherCAT drives use for a lost SyncManager watchdog.
pub const ERROR_SYNC_WATCHDOG: u16 = 0x8700;
/// Error code of a following error beyond 0x6065 for longer than 0x6066 (CiA 402-2).
pub const ERROR_FOLLOWING: u16 = 0x8611;
/// Error code of a CSP setpoint that stepped further than the motor can move in the
/// setpoint period (manufacturer-specific, CiA 301 0xFF00…0xFFFF; see the module doc).
pub const ERROR_SETPOINT_STEP: u16 = 0xFF01;

/// Error code of an overspeed (CiA 402-2 0x8400 velocity control error).
pub const ERROR_OVERSPEED: u16 = 0x8400;
/// A motor faster than this many times its top speed (`max_speed_rpm`) overspeeds. The
/// velocity command is clipped at the top speed, and the tuned loops overshoot a step to
/// it by a few per cent, so only a motor out of control reaches this.
pub const OVERSPEED_FACTOR: f64 = 1.2;

/// Most loop substeps in one run (bounded work): 100 ms at 16 kHz, the longest
/// application period the simulator allows. A longer run takes longer substeps.
const MAX_SUBSTEPS: usize = 1600;

/// Speed below which a homing drive counts as standing on its home position (counts/s).
const HOMING_STANDSTILL: f64 = 1000.0;

/// Modes of operation: homing (CiA 402-2 §10.4, see [`homing`]), cyclic synchronous
/// position, velocity, torque.
const HM: i8 = 6;
const CSP: i8 = 8;
const CSV: i8 = 9;
const CST: i8 = 10;
/// The manufacturer mode by default: open-loop current vector (0x2102 amplitude at 0x2103
/// angle); `ServoParams::commutation_objects` may put it elsewhere.
pub const OPEN_LOOP: i8 = gantry_drives::cia402::mode::OPEN_LOOP_CURRENT_VECTOR;

/// The CiA 402 modes the drive has, as 0x6060 values (and its maker's open-loop mode).
const MODES: [i8; 4] = [HM, CSP, CSV, CST];

/// How the drive brakes.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Brake {
    /// Power stage off at once; the load coasts.
    Coast,
    /// Along a ramp of this deceleration (counts/s²).
    Ramp(f64),
    /// At the current (torque) limit.
    CurrentLimit,
}

/// Why the drive brakes, and what follows once it stands.
#[derive(Clone, Copy, Debug, PartialEq)]
enum StopCause {
    /// Quick stop (transition 11); `stay`: remain in Quick stop active (codes 5…8), else
    /// transition 12 to Switch on disabled.
    QuickStop { stay: bool },
    /// Shutdown or disable operation with a slow-down (transitions 8 and 5, option 1):
    /// the transition completes with this controlword once the load stands.
    Transition(Controlword),
    /// The fault reaction (transition 14 follows).
    FaultReaction,
}

/// A stop in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Braking {
    brake: Brake,
    why: StopCause,
    /// The ramp's velocity (counts/s).
    ramp: f64,
}

/// The SDO-visible settings of the drive (CiA 402 objects), power-up values from
/// [`ServoParams`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct Settings {
    following_error_window: u32,
    following_error_timeout_ms: u16,
    max_profile_velocity: u32,
    profile_deceleration: u32,
    quick_stop_deceleration: u32,
    max_torque: u16,
    quick_stop_option_code: i16,
    shutdown_option_code: i16,
    disable_operation_option_code: i16,
    fault_reaction_option_code: i16,
    /// 0x2102 (per mille of the rated torque's current).
    commutation_current: u16,
    /// 0x2103 (65536 to an electrical revolution).
    commutation_angle: u32,
    /// 0x60D0:1 and :2.
    touch_probe_sources: [i16; 2],
}

impl Settings {
    fn of(p: &ServoParams) -> Self {
        Self {
            following_error_window: p.following_error_window,
            following_error_timeout_ms: p.following_error_timeout_ms,
            max_profile_velocity: p.max_speed_counts().min(f64::from(u32::MAX)) as u32,
            profile_deceleration: p.profile_deceleration,
            quick_stop_deceleration: p.quick_stop_deceleration,
            max_torque: (p.peak_torque_nm / p.rated_torque_nm * 1000.0).round() as u16,
            quick_stop_option_code: p.quick_stop_option_code,
            shutdown_option_code: p.shutdown_option_code,
            disable_operation_option_code: p.disable_operation_option_code,
            fault_reaction_option_code: p.fault_reaction_option_code,
            commutation_current: 0,
            commutation_angle: 0,
            touch_probe_sources: probe::source::DEFAULT,
        }
    }
}

/// A servo drive model.
#[derive(Clone, Debug)]
pub struct ServoDrive {
    /// Where the output process data lies in the ESC's RAM (SM2).
    pub outputs_at: u16,
    /// Where the input process data lies (SM3).
    pub inputs_at: u16,
    /// The motor, load and tuning.
    pub params: ServoParams,
    /// The commutation offset the drive was told (counts); the motor's true one is
    /// `params.commutation_offset`.
    pub commutation_setting: i32,
    settings: Settings,
    state: DeviceStateMachine,
    error_code: u16,
    motor: Motor,
    /// Last controlword taken, and the one before (for the fault reset edge).
    controlword: Controlword,
    last_controlword: Controlword,
    /// Last target position taken (the drive's 32-bit value).
    target: i32,
    target_velocity: i32,
    target_torque: i16,
    mode: i8,
    /// A touch probe function received, not yet applied.
    pending_touch_probe: Option<u16>,
    /// A setpoint was taken since the last run.
    fresh: bool,
    /// Run time since the last setpoint was taken (s).
    since_take: f64,
    /// Run time since the target taken last changed (s), and that time when it changed.
    since_change: f64,
    change_interval: f64,
    /// SYNC0 periods without a setpoint before the one taken last.
    missed_periods: u64,
    /// The setpoint period (s): the time between setpoints.
    setpoint_period: Option<f64>,
    /// The last time between two setpoints taken (s).
    last_interval: Option<f64>,
    /// The last CSP target, unwrapped to the drive's full position (counts).
    target_abs: Option<f64>,
    /// Interpolation segment: start, slope (the velocity feed-forward, counts/s), time in.
    seg_start: f64,
    slope: f64,
    seg_t: f64,
    seg_len: f64,
    /// Position demand value (counts): the interpolated target.
    demand: f64,
    /// Mean torque (N·m) and velocity (counts/s) over the last run: the actual values
    /// reported, as drives average them over the cycle (sampled at the cycle's end they
    /// would show the loops' ripple at the setpoint steps, not the load's torque).
    torque_mean: f64,
    velocity_mean: f64,
    /// How long the following error has been beyond the window (s).
    following_time: f64,
    braking: Option<Braking>,
    /// Where the drive holds the load in Quick stop active once stopped.
    hold: f64,
    /// Touch probes 1 and 2 (0x60B8–0x60BD).
    probe: TouchProbe,
    /// Homing mode (0x6098–0x609A, 0x607C).
    homing: Homing,
    /// The first CSP target of the last sequence (after enabling or a change of mode)
    /// and the position actual value when it was taken.
    takeover: Option<(i32, i32)>,
    /// The position actual value minus the load's raw position (counts): what homing
    /// set (0 until a homing attains; lost at a power-on reset, as an incremental
    /// encoder's reference is).
    shift: i64,
    /// The mode and the controlword's bits 4 and 8 at the last run (for their edges).
    last_mode: i8,
    last_start: bool,
    layout: PdoLayout,
    /// Where `layout` puts each object: the process data is read and written through the
    /// view the master uses too (`gantry_drives::cia402::image`).
    map: PdoMap,
    record: DriveRecord,
    /// Every switch edge and index pulse the load crossed (the simulator's truth for
    /// homing tests).
    crossings: CrossingLog,
}

impl ServoDrive {
    /// The default servo ([`ServoParams::default`]) at position `start_counts` (the
    /// absolute encoder's value at power-up).
    pub fn new(outputs_at: u16, inputs_at: u16, start_counts: i32) -> Self {
        Self::with_params(outputs_at, inputs_at, start_counts, ServoParams::default())
    }

    /// A servo with `params` at position `start_counts`.
    pub fn with_params(
        outputs_at: u16,
        inputs_at: u16,
        start_counts: i32,
        params: ServoParams,
    ) -> Self {
        let p = f64::from(start_counts);
        let layout = PdoLayout::csp_minimal();
        Self {
            outputs_at,
            inputs_at,
            params,
            commutation_setting: 0,
            settings: Settings::of(&params),
            state: DeviceStateMachine::ready(),
            error_code: 0,
            motor: Motor::at(p),
            controlword: Controlword(0),
            last_controlword: Controlword(0),
            target: start_counts,
            target_velocity: 0,
            target_torque: 0,
            mode: CSP,
            pending_touch_probe: None,
            fresh: false,
            since_take: 0.0,
            since_change: 0.0,
            change_interval: 0.0,
            missed_periods: 0,
            setpoint_period: None,
            last_interval: None,
            target_abs: None,
            seg_start: p,
            slope: 0.0,
            seg_t: 0.0,
            seg_len: 0.0,
            demand: p,
            torque_mean: 0.0,
            velocity_mean: 0.0,
            following_time: 0.0,
            braking: None,
            hold: p,
            probe: TouchProbe::default(),
            homing: Homing::idle(p, params.homing_faults),
            takeover: None,
            shift: 0,
            last_mode: CSP,
            last_start: false,
            map: PdoMap::of(&layout),
            layout,
            record: DriveRecord::default(),
            crossings: CrossingLog::default(),
        }
    }

    /// Counts of one electrical revolution.
    fn counts_per_electrical_rev(&self) -> f64 {
        f64::from(self.params.counts_per_rev) / f64::from(self.params.pole_pairs.max(1))
    }

    /// cos of the electrical angle by which the commutation setting misses the motor's
    /// true offset: the share of the commanded torque the closed loops get (1 when
    /// commissioned, 0 at 90° electrical, negative beyond: torque the wrong way).
    pub fn torque_efficiency(&self) -> f64 {
        let p = &self.params;
        let error = f64::from(p.commutation_offset) - f64::from(self.commutation_setting);
        let electrical = 2.0 * core::f64::consts::PI * f64::from(p.pole_pairs) * error
            / f64::from(p.counts_per_rev.max(1));
        electrical.cos()
    }

    /// The commutation the loops see: the motor's true offset and the drive's setting.
    pub fn commutation(&self) -> Commutation {
        Commutation::of(&self.params, self.commutation_setting)
    }

    /// The probes and switches see the load move from `from` to `to` (counts): the home
    /// switch's edges and the index pulse, in the order of travel, each latched where it
    /// happened.
    fn watch_travel(&mut self, from: i64, to: i64) {
        if from == to {
            return;
        }
        self.crossings.watch(&self.params, from, to);
        let p = &self.params;
        let index =
            probe::index_crossing(from, to, i64::from(p.index_at), i64::from(p.counts_per_rev));
        let [a, b] = p.switches.home_edges(from, to);
        let [c, d] = p.switches.edges(0, Signal::NegativeLimit, from, to);
        let [e, f] = p.switches.edges(1, Signal::PositiveLimit, from, to);
        let mut events = [a, b, c, d, e, f, index];
        // In the order of travel.
        events.sort_by_key(|e| e.map_or(i64::MAX, |e| (e.at - from).abs()));
        for mut e in events.into_iter().flatten() {
            // Latched as the position actual value counts (what homing set).
            e.at += self.shift;
            self.probe.event(e, self.settings.touch_probe_sources);
        }
    }

    /// The touch probes (0x60B8–0x60BD).
    pub fn touch_probe(&self) -> &TouchProbe {
        &self.probe
    }

    /// 0x60FD Digital inputs now: the switch cams on the drive's travel.
    pub fn digital_inputs(&self) -> u32 {
        self.params.switches.digital_inputs(self.position_counts())
    }

    /// Uses the layout the master mapped (at PreOp → SafeOp).
    pub fn configure(&mut self, layout: PdoLayout) {
        self.map = PdoMap::of(&layout);
        self.layout = layout;
    }

    /// The process data layout in use.
    pub fn layout(&self) -> &PdoLayout {
        &self.layout
    }

    /// Power state.
    pub fn state(&self) -> State {
        self.state.state()
    }

    /// Load position (counts, the drive's full position, not wrapped).
    pub fn position(&self) -> f64 {
        self.motor.position
    }

    /// Load velocity now (counts/s; 0x606C reports its mean over the last period).
    pub fn velocity(&self) -> f64 {
        self.motor.velocity
    }

    /// Torque the motor delivers now (N·m), from its current (0x6077 reports its mean
    /// over the last period).
    pub fn torque_nm(&self) -> f64 {
        self.motor.torque
    }

    /// Position demand value (counts): the interpolated CSP target the loops follow.
    pub fn demand(&self) -> f64 {
        self.demand
    }

    /// Position actual value (0x6064): the load position rounded to whole counts, its
    /// low 32 bits (the value wraps, as CSP drives count).
    pub fn actual_counts(&self) -> i32 {
        round_i64(self.motor.position).wrapping_add(self.shift) as i32
    }

    /// The position actual value minus the raw position (counts): what the last homing
    /// set (0 before any).
    pub fn position_shift(&self) -> i64 {
        self.shift
    }

    /// The mode of operation it is in (0x6061).
    pub fn mode(&self) -> i8 {
        self.mode
    }

    /// The first CSP target the drive took after it was last enabled or switched to CSP,
    /// and its position actual value then (counts): a master that takes a drive over
    /// without a jump sends the latter.
    pub fn takeover(&self) -> Option<(i32, i32)> {
        self.takeover
    }

    /// The homing mode's state and objects.
    pub fn homing(&self) -> &Homing {
        &self.homing
    }

    /// The load position rounded to whole counts, not wrapped (what switch cams on this
    /// axis see).
    pub fn position_counts(&self) -> i64 {
        round_i64(self.motor.position)
    }

    /// The master stopped sending process data: a drive with power on faults and stops
    /// as its fault reaction option code (0x605E) says.
    pub fn on_watchdog(&mut self) {
        if matches!(
            self.state.state(),
            State::OperationEnabled | State::SwitchedOn | State::QuickStopActive
        ) {
            self.fault(ERROR_SYNC_WATCHDOG);
        }
    }

    /// A communication failure the drive must react to (CiA 402-2 0x6007 abort connection
    /// option code 1, "fault signal"): a drive with its power stage on faults with `code`
    /// (the CANopen node passes 0x8130 heartbeat lost, 0x8250 RPDO timeout, 0x8100 NMT
    /// stop or SYNC loss) and stops as 0x605E says; a drive whose power stage is off, or
    /// that is already in Fault, is left as it is: there is nothing to stop.
    pub fn communication_fault(&mut self, code: u16) {
        if matches!(
            self.state.state(),
            State::OperationEnabled | State::SwitchedOn | State::QuickStopActive
        ) {
            self.fault(code);
        }
    }

    /// The application restarts (NMT reset node, CiA 301 §7.3.2.2.1: the application
    /// is set to its power-on state): power stage off, no fault, Switch on disabled, the
    /// command cleared, no setpoint period. The load stays where it is (it is physical) and
    /// the settings are the caller's to restore (the node writes the power-on values of
    /// its objects back and calls [`ServoDrive::take_objects`]). No allocation.
    pub fn power_on_reset(&mut self) {
        let p = self.motor.position;
        self.state = DeviceStateMachine::ready();
        self.error_code = 0;
        self.controlword = Controlword(0);
        self.last_controlword = Controlword(0);
        self.target = wrap32(p);
        self.fresh = false;
        self.since_take = 0.0;
        self.since_change = 0.0;
        self.change_interval = 0.0;
        self.missed_periods = 0;
        self.setpoint_period = None;
        self.last_interval = None;
        self.target_abs = None;
        self.seg_start = p;
        self.slope = 0.0;
        self.seg_t = 0.0;
        self.seg_len = 0.0;
        self.demand = p;
        self.following_time = 0.0;
        self.braking = None;
        self.hold = p;
        self.pending_touch_probe = None;
        self.probe = TouchProbe::default();
        self.homing = Homing::idle(p, self.params.homing_faults);
        self.shift = 0;
        self.last_start = false;
        self.record.disabled();
    }

    /// The switch edges and index pulses the load crossed, where (counts).
    pub fn crossings(&self) -> &CrossingLog {
        &self.crossings
    }

    /// What the drive recorded of the setpoints it took.
    pub fn record(&self) -> &DriveRecord {
        &self.record
    }

    /// The record, mutable: the ESC side counts the setpoints missed and doubled at the
    /// SYNC0 edges (it sees the edges and the SyncManager events, the drive does not).
    pub fn record_mut(&mut self) -> &mut DriveRecord {
        &mut self.record
    }

    /// Last fault's error code (0x603F), 0 when none.
    pub fn error_code(&self) -> u16 {
        self.error_code
    }

    /// Adds the drive's CiA 402 objects to its dictionary with their access rights
    /// (CiA 402-2): the settings rw within their ranges, the motor's rated torque ro, the
    /// modes of operation limited to those the drive has. Values as they are now.
    pub fn install_objects(&self, od: &mut ObjectDictionary) {
        let max_speed = self.params.max_speed_counts().min(f64::from(u32::MAX)) as i64;
        let u32_max = i64::from(u32::MAX);
        // The modes the drive has, and the homing methods (CiA 402-2 Table 32, §10.4.3):
        // anything else is refused with abort 0x06090030.
        let mut modes = homing::MethodSet::EMPTY;
        for m in MODES {
            modes.insert(m);
        }
        let c = self.params.commutation_objects;
        modes.insert(c.mode);
        let mut methods = homing::MethodSet::EMPTY;
        for m in i8::MIN..=i8::MAX {
            if self.params.homing_faults.accepts(m) {
                methods.insert(m);
            }
        }
        let o = objects::MODES_OF_OPERATION;
        od.insert_set(o.index, o.sub, CSP as u8, modes.bits());
        let o = objects::HOMING_METHOD;
        od.insert_set(o.index, o.sub, 0, methods.bits());
        // 0x6099 is an ARRAY: sub 0 its highest sub-index.
        od.insert(objects::HOMING_SPEED_SWITCH.index, 0, &[2], false);
        let ranged: [(ObjectId, i64, i64); 16] = [
            // A speed of 0 never finds anything; above the motor's top speed it would
            // promise what the motor cannot do.
            (objects::HOMING_SPEED_SWITCH, 1, max_speed),
            (objects::HOMING_SPEED_ZERO, 1, max_speed),
            (objects::HOMING_ACCELERATION, 1, u32_max),
            (
                objects::HOME_OFFSET,
                i64::from(i32::MIN),
                i64::from(i32::MAX),
            ),
            (objects::FOLLOWING_ERROR_WINDOW, 0, u32_max),
            (objects::FOLLOWING_ERROR_TIME_OUT, 0, i64::from(u16::MAX)),
            (objects::MAX_TORQUE, 0, i64::from(u16::MAX)),
            // Above the motor's top speed it would promise what the motor cannot do.
            (objects::MAX_PROFILE_VELOCITY, 0, max_speed),
            // A ramp of 0 would never stop.
            (objects::PROFILE_DECELERATION, 1, u32_max),
            (objects::QUICK_STOP_DECELERATION, 1, u32_max),
            (objects::QUICK_STOP_OPTION_CODE, 0, 8),
            (objects::SHUTDOWN_OPTION_CODE, 0, 1),
            (objects::DISABLE_OPERATION_OPTION_CODE, 0, 1),
            (objects::FAULT_REACTION_OPTION_CODE, 0, 4),
            // At most the power stage's peak (in per mille of the rated torque).
            (c.current, 0, i64::from(self.settings.max_torque)),
            (c.angle, 0, i64::from(c.angle_units) - 1),
        ];
        for (o, min, max) in ranged {
            od.insert_ranged(o.index, o.sub, &vec![0; o.kind.size()], min, max);
        }
        // 0x60D0 touch probe source (ETG.6010): two sub-indices, the values the drive has.
        od.insert(0x60D0, 0, &[2], false);
        for (o, v) in [
            (objects::TOUCH_PROBE_1_SOURCE, probe::source::DEFAULT[0]),
            (objects::TOUCH_PROBE_2_SOURCE, probe::source::DEFAULT[1]),
        ] {
            od.insert_enumerated(o.index, o.sub, &v.to_le_bytes(), &probe::source::ALLOWED);
        }
        // The simulated motor is fixed: its rated torque and pole pairs are read-only here.
        let o = objects::MOTOR_RATED_TORQUE;
        od.insert(o.index, o.sub, &vec![0; o.kind.size()], false);
        if let PolePairs::Object(o) = c.pole_pairs {
            od.insert(o.index, o.sub, &vec![0; o.kind.size()], false);
        }
        // Any offset: the drive takes it modulo an electrical revolution.
        let o = c.offset;
        od.insert(o.index, o.sub, &vec![0; o.kind.size()], true);
        self.publish_objects(od);
    }

    /// Writes the drive's present values into its dictionary (before the master's SDO
    /// request is served, so that an upload reads what the drive has now).
    pub fn publish_objects(&self, od: &mut ObjectDictionary) {
        let s = &self.settings;
        let rated_mnm = (self.params.rated_torque_nm * 1000.0).round() as i64;
        let values: [(ObjectId, i64); 22] = [
            (objects::CONTROLWORD, i64::from(self.controlword.0)),
            (objects::TARGET_POSITION, i64::from(self.target)),
            (objects::TARGET_VELOCITY, i64::from(self.target_velocity)),
            (objects::TARGET_TORQUE, i64::from(self.target_torque)),
            (objects::MODES_OF_OPERATION, i64::from(self.mode)),
            (objects::MODES_OF_OPERATION_DISPLAY, i64::from(self.mode)),
            (objects::STATUSWORD, i64::from(self.statusword())),
            (
                objects::POSITION_ACTUAL_VALUE,
                i64::from(self.actual_counts()),
            ),
            (
                objects::VELOCITY_ACTUAL_VALUE,
                round_i64(self.velocity_mean),
            ),
            (objects::TORQUE_ACTUAL_VALUE, self.torque_per_mille()),
            (objects::ERROR_CODE, i64::from(self.error_code)),
            (
                objects::FOLLOWING_ERROR_ACTUAL_VALUE,
                self.following_error(),
            ),
            (
                objects::FOLLOWING_ERROR_WINDOW,
                i64::from(s.following_error_window),
            ),
            (
                objects::FOLLOWING_ERROR_TIME_OUT,
                i64::from(s.following_error_timeout_ms),
            ),
            (objects::MAX_TORQUE, i64::from(s.max_torque)),
            (objects::MOTOR_RATED_TORQUE, rated_mnm),
            (
                objects::MAX_PROFILE_VELOCITY,
                i64::from(s.max_profile_velocity),
            ),
            (
                objects::PROFILE_DECELERATION,
                i64::from(s.profile_deceleration),
            ),
            (
                objects::QUICK_STOP_DECELERATION,
                i64::from(s.quick_stop_deceleration),
            ),
            (
                objects::QUICK_STOP_OPTION_CODE,
                i64::from(s.quick_stop_option_code),
            ),
            (
                objects::SHUTDOWN_OPTION_CODE,
                i64::from(s.shutdown_option_code),
            ),
            (
                objects::DISABLE_OPERATION_OPTION_CODE,
                i64::from(s.disable_operation_option_code),
            ),
        ];
        let fault_reaction = (
            objects::FAULT_REACTION_OPTION_CODE,
            i64::from(s.fault_reaction_option_code),
        );
        let hs = self.homing.settings();
        let homing_objects = [
            (objects::HOMING_METHOD, i64::from(hs.method)),
            (objects::HOMING_SPEED_SWITCH, i64::from(hs.speed_switch)),
            (objects::HOMING_SPEED_ZERO, i64::from(hs.speed_zero)),
            (objects::HOMING_ACCELERATION, i64::from(hs.acceleration)),
            (objects::HOME_OFFSET, i64::from(hs.home_offset)),
        ];
        let tp = &self.probe;
        let c = self.params.commutation_objects;
        let pole_pairs = match c.pole_pairs {
            PolePairs::Object(o) => Some((o, i64::from(self.params.pole_pairs))),
            PolePairs::Fixed(_) => None,
        };
        let offset = c.offset_to_drive(
            i64::from(self.commutation_setting),
            self.counts_per_electrical_rev(),
        );
        let commutation = [
            (c.offset, offset),
            (c.current, i64::from(s.commutation_current)),
            (c.angle, i64::from(s.commutation_angle)),
        ]
        .into_iter()
        .chain(pole_pairs);
        let io = [
            (objects::TOUCH_PROBE_FUNCTION, i64::from(tp.function())),
            (objects::TOUCH_PROBE_STATUS, i64::from(tp.status())),
            (
                objects::TOUCH_PROBE_POS1_POS_VALUE,
                i64::from(tp.value(0, Edge::Positive)),
            ),
            (
                objects::TOUCH_PROBE_POS1_NEG_VALUE,
                i64::from(tp.value(0, Edge::Negative)),
            ),
            (
                objects::TOUCH_PROBE_POS2_POS_VALUE,
                i64::from(tp.value(1, Edge::Positive)),
            ),
            (
                objects::TOUCH_PROBE_POS2_NEG_VALUE,
                i64::from(tp.value(1, Edge::Negative)),
            ),
            (objects::DIGITAL_INPUTS, i64::from(self.digital_inputs())),
            (
                objects::TOUCH_PROBE_1_SOURCE,
                i64::from(s.touch_probe_sources[0]),
            ),
            (
                objects::TOUCH_PROBE_2_SOURCE,
                i64::from(s.touch_probe_sources[1]),
            ),
        ];
        for (o, v) in values
            .into_iter()
            .chain([fault_reaction])
            .chain(commutation)
            .chain(io)
            .chain(homing_objects)
        {
            let bytes = v.to_le_bytes();
            if let Some(b) = bytes.get(..o.kind.size()) {
                // An object the dictionary does not carry is not the drive's to add.
                let _ = od.set(o.index, o.sub, b);
            }
        }
    }

    /// Takes what the master wrote by SDO into the drive's command and settings (after
    /// its request was served). The dictionary checked access and ranges.
    pub fn take_objects(&mut self, od: &ObjectDictionary) {
        let get = |o: ObjectId| {
            od.read(o.index, o.sub).ok().map(|b| {
                let n = o.kind.size().min(b.len());
                let signed = matches!(
                    o.kind,
                    objects::DataType::I8 | objects::DataType::I16 | objects::DataType::I32
                );
                let v = field(b, 0, n);
                if signed || n == 0 {
                    v
                } else {
                    v & ((1i64 << (8 * n)) - 1)
                }
            })
        };
        if let Some(v) = get(objects::MODES_OF_OPERATION) {
            self.take_mode(v as i8);
        }
        let s = &mut self.settings;
        if let Some(v) = get(objects::CONTROLWORD) {
            self.controlword = Controlword(v as u16);
        }
        if let Some(v) = get(objects::TARGET_POSITION) {
            self.target = v as i32;
        }
        if let Some(v) = get(objects::TARGET_VELOCITY) {
            self.target_velocity = v as i32;
        }
        if let Some(v) = get(objects::TARGET_TORQUE) {
            self.target_torque = v as i16;
        }
        if let Some(v) = get(objects::TOUCH_PROBE_FUNCTION) {
            if v as u16 != self.probe.function() {
                self.pending_touch_probe = Some(v as u16);
            }
        }
        let c = self.params.commutation_objects;
        let e = f64::from(self.params.counts_per_rev) / f64::from(self.params.pole_pairs.max(1));
        if let Some(v) = get(c.offset) {
            self.commutation_setting = c.offset_to_counts(v, e) as i32;
        }
        if let Some(v) = get(c.current) {
            s.commutation_current = v as u16;
        }
        if let Some(v) = get(c.angle) {
            s.commutation_angle = v as u32;
        }
        for (i, o) in [objects::TOUCH_PROBE_1_SOURCE, objects::TOUCH_PROBE_2_SOURCE]
            .into_iter()
            .enumerate()
        {
            if let (Some(v), Some(slot)) = (get(o), s.touch_probe_sources.get_mut(i)) {
                *slot = v as i16;
            }
        }
        let hs = self.homing.settings_mut();
        if let Some(v) = get(objects::HOMING_METHOD) {
            hs.method = v as i8;
        }
        if let Some(v) = get(objects::HOMING_SPEED_SWITCH) {
            hs.speed_switch = v as u32;
        }
        if let Some(v) = get(objects::HOMING_SPEED_ZERO) {
            hs.speed_zero = v as u32;
        }
        if let Some(v) = get(objects::HOMING_ACCELERATION) {
            hs.acceleration = (v as u32).max(1);
        }
        if let Some(v) = get(objects::HOME_OFFSET) {
            hs.home_offset = v as i32;
        }
        if let Some(v) = get(objects::FOLLOWING_ERROR_WINDOW) {
            s.following_error_window = v as u32;
        }
        if let Some(v) = get(objects::FOLLOWING_ERROR_TIME_OUT) {
            s.following_error_timeout_ms = v as u16;
        }
        if let Some(v) = get(objects::MAX_TORQUE) {
            s.max_torque = v as u16;
        }
        if let Some(v) = get(objects::MAX_PROFILE_VELOCITY) {
            s.max_profile_velocity = v as u32;
        }
        if let Some(v) = get(objects::PROFILE_DECELERATION) {
            s.profile_deceleration = (v as u32).max(1);
        }
        if let Some(v) = get(objects::QUICK_STOP_DECELERATION) {
            s.quick_stop_deceleration = (v as u32).max(1);
        }
        let code = |v: Option<i64>, hi: i16, old: i16| {
            v.map(|v| v as i16)
                .filter(|c| (0..=hi).contains(c))
                .unwrap_or(old)
        };
        s.quick_stop_option_code = code(
            get(objects::QUICK_STOP_OPTION_CODE),
            8,
            s.quick_stop_option_code,
        );
        s.shutdown_option_code = code(
            get(objects::SHUTDOWN_OPTION_CODE),
            1,
            s.shutdown_option_code,
        );
        s.disable_operation_option_code = code(
            get(objects::DISABLE_OPERATION_OPTION_CODE),
            1,
            s.disable_operation_option_code,
        );
        s.fault_reaction_option_code = code(
            get(objects::FAULT_REACTION_OPTION_CODE),
            4,
            s.fault_reaction_option_code,
        );
    }

    /// One cycle: take the outputs, run the drive for `dt_s`, publish the inputs.
    pub fn step(&mut self, mem: &mut Memory, dt_s: f64) {
        self.take_outputs(mem);
        self.run(dt_s);
        self.publish_inputs(mem);
    }

    /// (a) Takes the outputs: reads the process data the master wrote (SM2's buffer in the
    /// ESC RAM) into the drive's command: controlword, target values, mode, touch probe
    /// function. A real drive does this at its SYNC0 edge (DC) or when the frame has
    /// written SM2 (free run); the target taken is what [`DriveRecord`] judges the master
    /// by. Call it once per new setpoint: a run without one is a missed setpoint, and the
    /// time between two calls is the setpoint period the target is interpolated over.
    pub fn take_outputs(&mut self, mem: &Memory) {
        let mut out = [0u8; MAX_PDO_BYTES];
        let n_out = self.map.output_bytes.min(MAX_PDO_BYTES);
        if let Some(o) = out.get_mut(..n_out) {
            mem.ecat_read(self.outputs_at, o, false);
        }
        self.take_output_image(&out);
    }

    /// (a) without an ESC: takes the outputs from `out`, a process image laid out as the
    /// configured [`PdoLayout`] (the CANopen node assembles it from its RPDOs at SYNC).
    /// Same rules as [`ServoDrive::take_outputs`]: once per new setpoint.
    pub fn take_output_image(&mut self, out: &[u8]) {
        // A setpoint taken before the drive ran since the previous one (the simulator
        // caught up after a stall of its own, passing SYNC0 edges without running the
        // periods between them): the previous one is judged and interpolated first, as
        // the drive did at its own edge. Judged only with the last, two steps in a row
        // would count as one over a single period.
        if core::mem::take(&mut self.fresh) && self.following() && self.mode == CSP {
            self.new_setpoint(self.setpoint_period.unwrap_or(0.0));
        }
        let previous = self.target;
        // The mapping rules allow at most 10 entries of at most 4 bytes, so the mapped
        // outputs always fit the buffer; an object not mapped keeps its last value.
        if let Ok(img) = OutputImage::new_checked(out, &self.map) {
            if let Some(cw) = img.controlword() {
                self.controlword = cw;
            }
            if let Some(t) = img.target_position() {
                self.target = t;
            }
            if let Some(v) = img.target_velocity() {
                self.target_velocity = v;
            }
            if let Some(t) = img.target_torque() {
                self.target_torque = t;
            }
            if let Some(f) = img.touch_probe_function() {
                self.pending_touch_probe = Some(f);
            }
            if let Some(m) = img.modes_of_operation() {
                self.take_mode(m);
            }
        }
        // The setpoint period: the time between two setpoints once two intervals in a
        // row agree (within half), so that the gap of a missed setpoint, a doubled one or
        // a pause is not taken for the cycle, as a drive that knows its SYNC0 cycle keeps
        // interpolating over the cycle; a lone gap can also not lock it out.
        let t = self.since_take;
        if t > 0.0 {
            let agrees = self
                .last_interval
                .is_some_and(|last| t >= 0.5 * last && t <= 1.5 * last);
            if agrees || self.setpoint_period.is_none() {
                self.setpoint_period = Some(t);
            }
            self.last_interval = Some(t);
        }
        if self.target != previous {
            self.change_interval = self.since_change;
            self.since_change = 0.0;
        }
        // SYNC0 periods that brought no setpoint since the last (the ESC side counts
        // them): the step covers them too, however little of that time the simulator ran.
        self.missed_periods = self.record.missed_since_target();
        self.since_take = 0.0;
        self.fresh = true;
        // A setpoint is a target taken in Operation enabled with a controlword that keeps
        // it there (the all-zero safe outputs of a slave leaving Op are none).
        let enabling = self.controlword.command(self.last_controlword) == Command::EnableOperation;
        if self.following() && self.mode == CSP && enabling {
            self.record.target(self.target);
        }
    }

    /// A mode of operation commanded: taken if the drive has it (else the display keeps
    /// the old). A change while enabled starts the new mode where the load is, as at
    /// enabling: drives re-initialise their position demand to the actual position on a
    /// mode switch, so a CSP that follows another mode does not chase a stale demand.
    fn take_mode(&mut self, m: i8) {
        let has = MODES.contains(&m) || m == self.params.commutation_objects.mode;
        if !has || m == self.mode {
            return;
        }
        self.mode = m;
        if self.state.state() == State::OperationEnabled && self.braking.is_none() {
            self.on_enable();
        }
    }

    /// Whether the drive follows its command values (Operation enabled, not braking).
    fn following(&self) -> bool {
        self.state.state() == State::OperationEnabled && self.braking.is_none()
    }

    /// (b) Runs the drive for `dt_s` seconds on the command last taken: the power state
    /// machine, then the loops and the plant at the drive's loop rate. Call it once per
    /// application period (the simulator allows at most 100 ms): a longer run takes
    /// longer substeps, beyond what the loops are tuned for.
    pub fn run(&mut self, dt_s: f64) {
        let dt = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        if let Some(f) = self.pending_touch_probe.take() {
            self.probe.set_function(f);
        }
        self.apply_controlword();
        if !matches!(
            self.state.state(),
            State::Fault | State::FaultReactionActive
        ) {
            self.error_code = 0;
        }
        self.apply_mode();
        let fresh = core::mem::take(&mut self.fresh);
        if fresh && self.following() && self.mode == CSP {
            self.new_setpoint(dt);
        }
        if self.state.state() != State::OperationEnabled {
            self.record.disabled();
        }
        let before = self.motor.position;
        if dt > 0.0 {
            let n = ((dt * self.params.loop_rate_hz).ceil() as usize).clamp(1, MAX_SUBSTEPS);
            let g = Gains::of(&self.params, dt / n as f64);
            let limit = self.torque_limit();
            let commutation = self.commutation();
            let mut torque = 0.0;
            let homing = self.mode == HM && self.following();
            for _ in 0..n {
                let from = self.position_counts();
                self.substep(&g, limit, &commutation);
                let to = self.position_counts();
                self.watch_travel(from, to);
                if homing {
                    let p = &self.params;
                    let (index_at, rev) = (i64::from(p.index_at), i64::from(p.counts_per_rev));
                    self.homing.observe(from, to, &p.switches, index_at, rev);
                }
                torque += self.motor.torque;
            }
            if homing {
                // On the home position and still: within a count, slower than a count per
                // millisecond (the loops have settled, friction holds nothing off it).
                let standing = self.motor.velocity.abs() < HOMING_STANDSTILL;
                if let Some(set) = self.homing.take_position_set(self.motor.position, standing) {
                    // The home position reads as minus the home offset from now on.
                    self.shift = set.value - set.home;
                }
            }
            self.torque_mean = torque / n as f64;
            self.velocity_mean = (self.motor.position - before) / dt;
        }
        if self.following() && self.mode == CSP && fresh && (self.seg_t - self.seg_len).abs() < 1e-9
        {
            // The segment is done: the demand is the target, without rounding residue.
            if let Some(t) = self.target_abs {
                self.demand = t;
            }
        }
        self.since_take += dt;
        self.since_change += dt;
    }

    /// The controlword taken acts on the state machine: transitions that stop the motor
    /// first brake as their option codes say (CiA 402-2 §8.4.4 ff.).
    fn apply_controlword(&mut self) {
        let cw = self.controlword;
        if let Some(Braking {
            why: StopCause::Transition(started),
            ..
        }) = self.braking
        {
            if cw == started {
                return;
            }
            // The master changed its mind while the drive slowed down: take the new
            // command from Operation enabled.
            self.braking = None;
        }
        let from = self.state.state();
        if from == State::OperationEnabled {
            let cmd = cw.command(self.last_controlword);
            let slow = match transition(from, cmd) {
                State::SwitchedOn => self.settings.disable_operation_option_code == 1,
                State::ReadyToSwitchOn => self.settings.shutdown_option_code == 1,
                _ => false,
            };
            if slow {
                self.last_controlword = cw;
                let decel = f64::from(self.settings.profile_deceleration);
                self.start_braking(Brake::Ramp(decel), StopCause::Transition(cw));
                return;
            }
        }
        self.state.control(cw);
        self.last_controlword = cw;
        let to = self.state.state();
        if from == State::OperationEnabled && to == State::QuickStopActive {
            let code = self.settings.quick_stop_option_code;
            let brake = match code {
                0 => Brake::Coast,
                1 | 5 => Brake::Ramp(f64::from(self.settings.profile_deceleration)),
                2 | 6 => Brake::Ramp(f64::from(self.settings.quick_stop_deceleration)),
                // 3, 7: current limit; 4, 8 (voltage limit) brake as hard: the model has
                // no DC link to limit.
                _ => Brake::CurrentLimit,
            };
            self.start_braking(brake, StopCause::QuickStop { stay: code >= 5 });
        }
        if to != State::QuickStopActive && from == State::QuickStopActive {
            // Transition 12 by the master: the power stage goes off.
            self.braking = None;
        }
        if to == State::OperationEnabled && from != State::OperationEnabled {
            self.on_enable();
        }
    }

    /// The mode of operation and the homing bits taken (CiA 402-2 §10.4.1): a change of
    /// mode in Operation enabled starts the new one where the load is (CSP: the next
    /// target is judged from there; HM: holding, not started); bit 4's rising edge starts
    /// homing, its falling edge or the halt bit interrupt it.
    fn apply_mode(&mut self) {
        let cw = self.controlword.0;
        let start = cw & (1 << 4) != 0;
        let halt = cw & (1 << 8) != 0;
        let mode_changed = self.mode != self.last_mode;
        self.last_mode = self.mode;
        if mode_changed {
            // Targets in another mode are no CSP setpoints: a new sequence starts.
            self.record.disabled();
        }
        if mode_changed && self.following() {
            self.on_enable();
        }
        if self.mode != HM || !self.following() {
            if self.homing.running() {
                self.homing.interrupt();
            }
            self.last_start = start;
            return;
        }
        if start && !self.last_start && !halt {
            let (p, v) = (self.motor.position, self.motor.velocity);
            self.homing.start(p, v, &self.params.switches);
        } else if (!start || halt) && self.homing.running() {
            self.homing.interrupt();
        }
        self.last_start = start;
    }

    /// Operation enabled was entered: the demand starts where the load is.
    fn on_enable(&mut self) {
        let p = self.motor.position;
        self.homing.hold(p);
        self.demand = p;
        self.seg_start = p;
        self.slope = 0.0;
        self.seg_t = 0.0;
        self.seg_len = 0.0;
        self.target_abs = None;
        self.following_time = 0.0;
        self.motor.reset_loops();
    }

    fn start_braking(&mut self, brake: Brake, why: StopCause) {
        self.braking = Some(Braking {
            brake,
            why,
            ramp: self.motor.velocity,
        });
        if brake == Brake::Coast {
            self.finish_braking();
        }
    }

    /// The load stands (or coasts, for option 0): the stop's transition follows.
    fn finish_braking(&mut self) {
        let Some(b) = self.braking.take() else {
            return;
        };
        match b.why {
            StopCause::QuickStop { stay: true } if b.brake != Brake::Coast => {
                self.hold = self.motor.position;
            }
            // Transition 12 by the drive itself: Switch on disabled. (A controlword
            // "disable voltage" is the table's way there; the fault-reset edge it clears
            // does not matter outside Fault.)
            StopCause::QuickStop { .. } => {
                self.state.control(Controlword::of(Command::DisableVoltage));
            }
            StopCause::Transition(cw) => {
                self.state.control(cw);
            }
            StopCause::FaultReaction => self.state.fault_reaction_done(),
        }
    }

    /// A fault: Fault reaction active, braking as 0x605E says, then Fault.
    fn fault(&mut self, code: u16) {
        let s = self.state.state();
        if matches!(s, State::Fault | State::FaultReactionActive) {
            return;
        }
        let moving = matches!(s, State::OperationEnabled | State::QuickStopActive);
        self.state.fault();
        self.error_code = code;
        self.record.fault(code);
        if code == ERROR_FOLLOWING {
            self.record.following_error_faults += 1;
        }
        self.braking = None;
        if moving {
            let brake = match self.settings.fault_reaction_option_code {
                0 => Brake::Coast,
                1 => Brake::Ramp(f64::from(self.settings.profile_deceleration)),
                2 => Brake::Ramp(f64::from(self.settings.quick_stop_deceleration)),
                _ => Brake::CurrentLimit,
            };
            self.start_braking(brake, StopCause::FaultReaction);
        } else {
            self.state.fault_reaction_done();
        }
    }

    /// A new CSP setpoint: unwrapped the short way from the last one, checked against
    /// what the motor can move in the setpoint period, and interpolated over it.
    fn new_setpoint(&mut self, dt: f64) {
        let period = self.setpoint_period.filter(|p| *p > 0.0).unwrap_or(dt);
        // The time the motor had for the step: since the target last changed, so that a
        // setpoint the master sent late (its frame missed a period: the same target taken
        // twice) is judged over the periods it covers, as a drive that counts its missed
        // SM events does. The first target after enabling must be within one period's
        // move of where the load is.
        let interval = match self.target_abs {
            Some(_) => period
                .max(self.change_interval)
                .max(period * (1.0 + self.missed_periods as f64)),
            None => period,
        };
        if self.target_abs.is_none() {
            self.takeover = Some((self.target, self.actual_counts()));
        }
        let reference = self.target_abs.unwrap_or(self.demand);
        // The target counts as the position actual value does (raw + what homing set).
        let shift = self.shift as f64;
        let r = round_i64(reference + shift);
        let t = r as f64 + f64::from(self.target.wrapping_sub(r as i32)) - shift;
        let step = (t - reference).abs();
        let limit = f64::from(self.settings.max_profile_velocity) * interval + 1.0;
        if step > limit {
            self.fault(ERROR_SETPOINT_STEP);
            return;
        }
        self.target_abs = Some(t);
        self.seg_start = self.demand;
        self.seg_t = 0.0;
        self.seg_len = period;
        if period > 0.0 {
            self.slope = (t - self.demand) / period;
        } else {
            self.slope = 0.0;
            self.demand = t;
            self.seg_start = t;
        }
    }

    /// Torque limit (N·m): the power stage's peak, or 0x6072 Max torque if lower.
    fn torque_limit(&self) -> f64 {
        let p = &self.params;
        (f64::from(self.settings.max_torque) / 1000.0 * p.rated_torque_nm).min(p.peak_torque_nm)
    }

    /// Speed at which a stop counts as done (counts/s): 0.1 % of the top speed.
    fn standstill(&self) -> f64 {
        0.001 * self.params.max_speed_counts()
    }

    /// One period of the drive's loops, with the torque limit (N·m) and the motor's
    /// commutation.
    fn substep(&mut self, g: &Gains, limit: f64, commutation: &Commutation) {
        let kp = self.params.position_gain;
        let vmax = self.params.max_speed_counts();
        let drive = if let Some(b) = self.braking.as_mut() {
            match b.brake {
                Brake::Coast => Drive::Off,
                Brake::Ramp(d) => {
                    let dv = d * g.h;
                    b.ramp = if b.ramp.abs() <= dv {
                        0.0
                    } else {
                        b.ramp - dv * b.ramp.signum()
                    };
                    Drive::Velocity(b.ramp)
                }
                Brake::CurrentLimit => Drive::Velocity(0.0),
            }
        } else {
            match self.state.state() {
                State::OperationEnabled => match self.mode {
                    CSP => {
                        // The loop compares the demand and the position of the same
                        // instant, the substep's start; the demand then moves on with it.
                        // Without a new setpoint the demand goes on along the last slope
                        // for one more setpoint period (a single missed setpoint), then
                        // stays where it got to.
                        let end = 2.0 * self.seg_len;
                        let at = |t: f64| {
                            let t = if end > 0.0 { t.min(end) } else { t };
                            self.seg_start + self.slope * t
                        };
                        let now = at(self.seg_t);
                        let feed_forward = if end > 0.0 && self.seg_t >= end {
                            0.0
                        } else {
                            self.slope
                        };
                        self.seg_t += g.h;
                        self.demand = at(self.seg_t);
                        let v = kp * (now - self.motor.position) + feed_forward;
                        Drive::Velocity(v.clamp(-vmax, vmax))
                    }
                    CSV => {
                        let v = f64::from(self.target_velocity);
                        let limit = f64::from(self.settings.max_profile_velocity).min(vmax);
                        Drive::Velocity(v.clamp(-limit, limit))
                    }
                    CST => Drive::Torque(
                        f64::from(self.target_torque) / 1000.0 * self.params.rated_torque_nm,
                    ),
                    m if m == self.params.commutation_objects.mode => Drive::Vector {
                        current: f64::from(self.settings.commutation_current) / 1000.0
                            * self.params.rated_torque_nm,
                        angle: f64::from(self.settings.commutation_angle)
                            / f64::from(self.params.commutation_objects.angle_units)
                            * 2.0
                            * core::f64::consts::PI,
                    },
                    HM => Drive::Velocity(self.homing.command(g.h, kp, self.motor.position, vmax)),
                    _ => Drive::Off,
                },
                State::QuickStopActive => {
                    Drive::Velocity((kp * (self.hold - self.motor.position)).clamp(-vmax, vmax))
                }
                _ => Drive::Off,
            }
        };
        self.motor.substep(g, drive, limit, commutation);
        if self.motor.velocity.abs() > OVERSPEED_FACTOR * vmax && self.power_on() {
            self.overspeed();
            return;
        }
        if let Some(b) = self.braking {
            let ramp_done = !matches!(b.brake, Brake::Ramp(_)) || b.ramp == 0.0;
            if ramp_done && self.motor.velocity.abs() < self.standstill() {
                self.finish_braking();
            }
        } else if self.following() && self.mode == CSP {
            self.watch_following_error(g.h);
        }
    }

    /// Whether the power stage is on (the loops drive the motor).
    fn power_on(&self) -> bool {
        matches!(
            self.state.state(),
            State::OperationEnabled | State::QuickStopActive | State::FaultReactionActive
        ) && !matches!(
            self.braking,
            Some(Braking {
                brake: Brake::Coast,
                ..
            })
        )
    }

    /// The motor overspeeds: fault 0x8400 (unless already faulting) and the power stage
    /// off at once, the load coasting (see the module doc).
    fn overspeed(&mut self) {
        self.fault(ERROR_OVERSPEED);
        if self.state.state() == State::FaultReactionActive {
            self.braking = Some(Braking {
                brake: Brake::Coast,
                why: StopCause::FaultReaction,
                ramp: 0.0,
            });
            self.finish_braking();
        }
    }

    /// 0x6065/0x6066: a following error beyond the window for longer than the time out
    /// faults the drive (CiA 402-2 §12.4.3; `u32::MAX` switches the check off).
    fn watch_following_error(&mut self, h: f64) {
        let window = self.settings.following_error_window;
        if window == u32::MAX {
            self.following_time = 0.0;
            return;
        }
        if (self.demand - self.motor.position).abs() <= f64::from(window) {
            self.following_time = 0.0;
            return;
        }
        self.following_time += h;
        let timeout = f64::from(self.settings.following_error_timeout_ms) * 1e-3;
        if self.following_time > timeout + 1e-12 {
            self.fault(ERROR_FOLLOWING);
        }
    }

    /// (c) Publishes the inputs: writes the mapped input objects into SM3's buffer.
    pub fn publish_inputs(&self, mem: &mut Memory) {
        let mut inp = [0u8; MAX_PDO_BYTES];
        let n_in = self.map.input_bytes.min(MAX_PDO_BYTES);
        let Some(buf) = inp.get_mut(..n_in) else {
            return;
        };
        self.publish_input_image(buf);
        mem.pdi_write(self.inputs_at, buf);
    }

    /// (c) without an ESC: writes the mapped input objects into `buf`, a process image
    /// laid out as the configured [`PdoLayout`] (the CANopen node cuts its TPDOs from it).
    pub fn publish_input_image(&self, buf: &mut [u8]) {
        // Always fits (see `take_outputs`); objects not mapped are not written. Values
        // wider than their object are sent as their low bytes, as the registers wrap.
        if let Ok(mut img) = InputImage::new_checked(&mut *buf, &self.map) {
            img.set_statusword(Statusword(self.statusword()));
            img.set_position_actual_value(self.actual_counts());
            img.set_velocity_actual_value(round_i64(self.velocity_mean) as i32);
            img.set_torque_actual_value(self.torque_per_mille() as i16);
            img.set_error_code(self.error_code);
            img.set_modes_of_operation_display(self.mode);
            img.set_following_error_actual_value(self.following_error() as i32);
            let tp = &self.probe;
            img.set_touch_probe_status(tp.status());
            img.set_touch_probe_pos1_pos_value(tp.value(0, Edge::Positive));
            img.set_touch_probe_pos1_neg_value(tp.value(0, Edge::Negative));
            img.set_touch_probe_pos2_pos_value(tp.value(1, Edge::Positive));
            img.set_touch_probe_pos2_neg_value(tp.value(1, Edge::Negative));
            img.set_digital_inputs(self.digital_inputs());
        }
    }

    /// 0x6041: the state, remote, bit 12 (CSP/CSV/CST: the drive follows the command
    /// value), bit 11 (internal limit active: the torque limit clips) and bit 13 (CSP:
    /// following error).
    fn statusword(&self) -> u16 {
        let mut sw = self.state.statusword().0 | statusword::REMOTE;
        if self.mode == HM {
            // Bits 10, 12, 13 as the homing mode says (CiA 402-2 §10.4.2).
            let standing = self.motor.velocity.abs() < HOMING_STANDSTILL;
            let halted = self.controlword.0 & (1 << 8) != 0;
            sw |= self.homing.status_bits(standing, halted);
        } else if self.following() {
            sw |= statusword::MODE_SPECIFIC_12;
        }
        if self.motor.limited && self.state.state() != State::SwitchOnDisabled {
            sw |= statusword::INTERNAL_LIMIT_ACTIVE;
        }
        // Bit 13 in CSP: the following error is beyond the window (its time out running),
        // or it faulted the drive.
        let faulted = matches!(
            self.state.state(),
            State::FaultReactionActive | State::Fault
        ) && self.error_code == ERROR_FOLLOWING;
        if self.mode == CSP && (self.following_time > 0.0 || faulted) {
            sw |= statusword::MODE_SPECIFIC_13;
        }
        sw
    }

    /// 0x60F4: position demand less position actual (CSP; 0 in the other modes).
    fn following_error(&self) -> i64 {
        if self.mode == CSP && self.state.state() == State::OperationEnabled {
            round_i64(self.demand - self.motor.position)
        } else {
            0
        }
    }

    /// 0x6077: torque actual in per mille of the rated torque.
    fn torque_per_mille(&self) -> i64 {
        round_i64(self.torque_mean / self.params.rated_torque_nm * 1000.0)
    }
}

/// `x` rounded to a whole count (saturating far beyond any real position).
fn round_i64(x: f64) -> i64 {
    x.round() as i64
}

/// The low 32 bits of `x` rounded: a 32-bit position register that wraps.
fn wrap32(x: f64) -> i32 {
    round_i64(x) as i32
}

/// A little-endian value of `size` bytes at `at` (an SDO-written object), sign-extended.
fn field(buf: &[u8], at: usize, size: usize) -> i64 {
    let mut b = [0u8; 8];
    if let (Some(dst), Some(src)) = (b.get_mut(..size), buf.get(at..at + size)) {
        dst.copy_from_slice(src);
    }
    let shift = 64 - 8 * size.clamp(1, 8) as u32;
    (i64::from_le_bytes(b) << shift) >> shift
}

#[cfg(test)]
mod tests;
