//! The bus of simulated axes (SPEC §1: "configured like a real axis but not connected;
//! actual = set"): a bus with no hardware behind it, one CiA-402 drive per axis whose
//! position is the target it was sent. It implements [`CycleBus`], so the one engine
//! ([`crate::runtime::engine::Engine`]) and the one cycle
//! ([`crate::runtime::cycle::Cycle::from_config`]) run on it unchanged: the master codes
//! each drive's CSP process data as it would for a drive on a wire, and each drive
//! decodes it and answers through the same typed view ([`gantry_drives::cia402::image`])
//! at the bytes its PDO layout gives.
//!
//! A drive here answers at once: the power state machine (the shared CiA-402 table,
//! [`DeviceStateMachine`]) takes each exchange's controlword, and in Operation enabled the
//! position actual value is the target position taken in the same exchange, so the
//! master reads next cycle exactly what it sent this cycle (the one cycle any bus takes to
//! bring inputs back). It is still as strict as a drive on the wire:
//!
//! - it follows only in Operation enabled with a controlword that keeps it there (the
//!   all-zero outputs of a master that has not written yet are no setpoint);
//! - it has one mode of operation, CSP (another value of 0x6060 is not taken, as a drive
//!   does not take a mode it does not have; the display 0x6061 keeps 8);
//! - a target further from the last position than the axis' maximum speed allows in one
//!   cycle (plus one count, for rounding both ends) is not taken: the drive faults with
//!   [`SETPOINT_STEP_FAULT`], as the simulated servo does (`gantry-sim`) and real drives
//!   do (Bosch Rexroth IndraDrive F2037 "Excessive position command difference");
//! - its 32-bit position counts as CSP drives count (0x6064 is INTEGER32 and wraps: a
//!   target is taken the short way from the last position);
//! - a fault needs the fault-reset edge (bit 7 of the controlword, CiA 402-2 transition
//!   15) to clear; the drive is then in Switch on disabled and must be enabled again.
//!
//! Nothing can cut a drive off: there is no wire. No exchange is ever lost, no drive is
//! ever unreachable ([`CycleBus::fault`] is always `None`), and a restore finds the drive
//! operational already.

use gantry_drives::cia402::controlword::Command as ControlCommand;
use gantry_drives::cia402::image::{InputImage, OutputImage, PdoMap};
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::cia402::statusword;
use gantry_drives::cia402::{Controlword, DeviceStateMachine, State, Statusword};
use gantry_drives::csp::MODE_CSP;
use gantry_kernel::axis::command::CommandError;
use thiserror::Error;

use crate::config::{AxisSection, AxisType, Config};
use crate::runtime::bus::{BusCounters, CycleBus, Reply, Restored, Unreachable};

/// Error code (0x603F) of a target that stepped further than the axis' maximum speed
/// allows in one cycle (manufacturer-specific, CiA 301 0xFF00…0xFFFF: CiA 402 has no
/// standard code for it; the same code as the simulated servo's).
pub const SETPOINT_STEP_FAULT: u16 = 0xFF01;

/// Why a bus of simulated axes could not be made for a configuration.
#[derive(Debug, Error, PartialEq)]
pub enum SimulatedError {
    /// An axis' configuration does not give a drive (PDO layout, scaling).
    #[error("{path}: axis {axis:?}: {key}: {reason}")]
    Axis {
        /// The configuration file.
        path: String,
        /// The axis.
        axis: String,
        /// The configuration key.
        key: String,
        /// What is wrong with it.
        reason: String,
    },
}

/// The largest target step a drive takes in one cycle: `vmax · T` in counts plus one
/// count, as both ends are rounded to whole counts (`|round(a) − round(b)| ≤ |a − b| + 1`;
/// a relative 1e-12 keeps an exact product of the kernel's f64 path from rounding to one
/// count less than the set values really moved).
pub fn max_step_counts(vmax_counts_per_s: f64, cycle_s: f64) -> u32 {
    let exact = (vmax_counts_per_s * cycle_s).abs() * (1.0 + 1e-12);
    // Saturates: a bound beyond the 32-bit counter bounds nothing.
    (exact.floor() as u32).saturating_add(1)
}

/// One simulated CiA-402 drive in CSP: its process data (the bytes of its PDO layout, both
/// ways), its power state, and its position.
#[derive(Clone, Debug)]
pub struct SimulatedDrive {
    map: PdoMap,
    outputs: Vec<u8>,
    inputs: Vec<u8>,
    state: DeviceStateMachine,
    /// The controlword of the exchange before, for the commands it makes an edge of.
    last_controlword: Controlword,
    /// 0x6064 Position actual value (the drive's 32-bit counter).
    position: i32,
    /// 0x606C Velocity actual value (counts/s): the last step over the cycle.
    velocity: i32,
    /// 0x603F Error code (0 without a fault).
    error_code: u16,
    /// The largest target step taken in one cycle (counts); `None`: any.
    max_step: Option<u32>,
    /// Exchanges per second, for the velocity actual value.
    cycles_per_s: f64,
    /// Targets taken in Operation enabled (setpoints) since start.
    setpoints: u64,
}

impl SimulatedDrive {
    /// A drive mapped to `layout`, standing at `position` counts, in Switch on disabled
    /// (CiA 402 transitions 0 and 1 are done at power-up), exchanging every `cycle_s`
    /// seconds, taking target steps of at most `max_step` counts (`None`: any).
    pub fn new(layout: &PdoLayout, position: i32, cycle_s: f64, max_step: Option<u32>) -> Self {
        let map = PdoMap::of(layout);
        let mut drive = Self {
            map,
            outputs: vec![0; map.output_bytes],
            inputs: vec![0; map.input_bytes],
            state: DeviceStateMachine::ready(),
            last_controlword: Controlword(0),
            position,
            velocity: 0,
            error_code: 0,
            max_step,
            cycles_per_s: if cycle_s > 0.0 { 1.0 / cycle_s } else { 0.0 },
            setpoints: 0,
        };
        drive.publish();
        drive
    }

    /// Its power state.
    pub fn state(&self) -> State {
        self.state.state()
    }

    /// 0x6064 Position actual value (counts).
    pub fn position(&self) -> i32 {
        self.position
    }

    /// 0x603F Error code (0 without a fault).
    pub fn error_code(&self) -> u16 {
        self.error_code
    }

    /// Targets taken in Operation enabled since start.
    pub fn setpoints(&self) -> u64 {
        self.setpoints
    }

    /// The input bytes it last published.
    pub fn inputs(&self) -> &[u8] {
        &self.inputs
    }

    /// The output bytes the master wrote for the next exchange.
    pub fn outputs(&self) -> &[u8] {
        &self.outputs
    }

    /// The output bytes, to write.
    pub fn outputs_mut(&mut self) -> &mut [u8] {
        &mut self.outputs
    }

    /// A fault raised by the drive itself (what a real drive raises for its own reasons:
    /// over-temperature, an encoder error): CiA 402 transition 13, then 14 at once — the
    /// drive has no load to brake. It keeps its position; the fault stays until the
    /// fault-reset edge.
    pub fn fault(&mut self, code: u16) {
        self.state.fault();
        self.state.fault_reaction_done();
        self.error_code = code;
        self.velocity = 0;
        self.publish();
    }

    /// One exchange: takes the outputs (with `operational`; else, like an EtherCAT slave
    /// in Safe-Operational, it publishes its inputs and takes no outputs), then publishes
    /// its inputs.
    fn exchange(&mut self, operational: bool) {
        if operational {
            self.take_outputs();
        }
        self.publish();
    }

    /// The controlword through the power state machine, then, following, the target.
    fn take_outputs(&mut self) {
        // The buffer is the layout's size: the view is always made.
        let Ok(img) = OutputImage::new_checked(&self.outputs[..], &self.map) else {
            return;
        };
        let cw = img.controlword().unwrap_or_default();
        let target = img.target_position();
        let command = cw.command(self.last_controlword);
        self.last_controlword = cw;
        self.state.control(cw);
        if !matches!(self.state(), State::Fault | State::FaultReactionActive) {
            self.error_code = 0;
        }
        // 0x6060 is not looked at: a mode the drive does not have is not taken, and CSP
        // is its only one.
        let following =
            self.state() == State::OperationEnabled && command == ControlCommand::EnableOperation;
        let Some(target) = target.filter(|_| following) else {
            self.velocity = 0;
            return;
        };
        // The short way from the last position: the counter wraps.
        let step = target.wrapping_sub(self.position);
        if self.max_step.is_some_and(|max| step.unsigned_abs() > max) {
            self.fault(SETPOINT_STEP_FAULT);
            return;
        }
        self.setpoints += 1;
        self.velocity = (f64::from(step) * self.cycles_per_s)
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32;
        self.position = target;
    }

    /// Writes the inputs: every object the layout maps that the view knows.
    fn publish(&mut self) {
        let sw = self.statusword();
        let Ok(mut img) = InputImage::new_checked(&mut self.inputs[..], &self.map) else {
            return;
        };
        img.set_statusword(sw);
        img.set_position_actual_value(self.position);
        img.set_velocity_actual_value(self.velocity);
        img.set_torque_actual_value(0);
        // The position is the demand: no following error.
        img.set_following_error_actual_value(0);
        img.set_error_code(self.error_code);
        img.set_modes_of_operation_display(MODE_CSP);
        // No touch probe, no digital inputs wired.
        img.set_touch_probe_status(0);
        img.set_touch_probe_pos1_pos_value(0);
        img.set_digital_inputs(0);
    }

    /// 0x6041: the state, remote (bit 9: the controlword is processed), and bit 12 in
    /// Operation enabled (CSP: the drive follows the command value).
    fn statusword(&self) -> Statusword {
        let mut sw = self.state.statusword().0 | statusword::REMOTE;
        if self.state() == State::OperationEnabled {
            sw |= statusword::MODE_SPECIFIC_12;
        }
        Statusword(sw)
    }
}

/// A bus of simulated drives, one per position (a position without a drive has no
/// process data).
#[derive(Clone, Debug, Default)]
pub struct SimulatedBus {
    drives: Vec<Option<SimulatedDrive>>,
    /// The engine said the cycle is ready for operation: from the next exchange on the
    /// drives take their outputs.
    operational: bool,
    /// A restore finished (at once), waiting to be taken.
    restored: Option<Result<Restored, CommandError>>,
}

impl SimulatedBus {
    /// A bus with these drives, at positions `0..drives.len()`.
    pub fn new(drives: Vec<Option<SimulatedDrive>>) -> Self {
        Self {
            drives,
            ..Self::default()
        }
    }

    /// A drive for each axis of `config`, at its `drive` position, mapped to its `pdo`
    /// layout, standing at 0 counts, taking steps up to the axis' maximum speed at the
    /// configuration's cycle time (`bus.cycle_us`; the `[bus]` section is not otherwise
    /// looked at: there is no wire to configure).
    pub fn of_config(config: &Config) -> Result<Self, SimulatedError> {
        let cycle_s = f64::from(config.bus.cycle_us) * 1e-6;
        // Only real axes have a drive (the others have `drive` unset).
        let real = |a: &&AxisSection| a.axis_type == AxisType::Real;
        let positions = config
            .axes
            .iter()
            .filter(real)
            .map(|a| a.drive.saturating_add(1))
            .max()
            .unwrap_or(0);
        let mut drives = vec![None; positions];
        for (a, k) in config.axes.iter().zip(&config.kernel_axes) {
            if a.axis_type != AxisType::Real {
                continue;
            }
            let axis_error = |(key, reason)| SimulatedError::Axis {
                path: config.path.clone(),
                axis: a.name.clone(),
                key,
                reason,
            };
            let layout = a.pdo_layout().map_err(axis_error)?;
            let scaling = a.scaling().map_err(axis_error)?;
            let max_step = max_step_counts(scaling.velocity_to_counts(k.max.vmax), cycle_s);
            if let Some(slot) = drives.get_mut(a.drive) {
                *slot = Some(SimulatedDrive::new(&layout, 0, cycle_s, Some(max_step)));
            }
        }
        Ok(Self::new(drives))
    }

    /// The drive at `position`, if there is one.
    pub fn drive(&self, position: usize) -> Option<&SimulatedDrive> {
        self.drives.get(position)?.as_ref()
    }

    /// The drive at `position`, to change (e.g. to fault it).
    pub fn drive_mut(&mut self, position: usize) -> Option<&mut SimulatedDrive> {
        self.drives.get_mut(position)?.as_mut()
    }

    /// Whether the drives take their outputs ([`CycleBus::start_operation`] was called).
    pub fn is_operational(&self) -> bool {
        self.operational
    }
}

impl CycleBus for SimulatedBus {
    fn drives(&self) -> usize {
        self.drives.len()
    }

    fn inputs(&self, drive: usize) -> &[u8] {
        self.drive(drive).map_or(&[], SimulatedDrive::inputs)
    }

    fn outputs(&self, drive: usize) -> &[u8] {
        self.drive(drive).map_or(&[], SimulatedDrive::outputs)
    }

    fn outputs_mut(&mut self, drive: usize) -> &mut [u8] {
        self.drive_mut(drive)
            .map_or(&mut [], SimulatedDrive::outputs_mut)
    }

    /// Every drive takes its outputs and answers, at once: never lost.
    fn exchange(&mut self, _deadline_ns: u64) -> Reply {
        let operational = self.operational;
        for drive in self.drives.iter_mut().flatten() {
            drive.exchange(operational);
        }
        Reply::Answered
    }

    /// No wire: every drive is always reachable.
    fn fault(&self, _drive: usize) -> Option<&Unreachable> {
        None
    }

    fn any_fault(&self) -> bool {
        false
    }

    fn clear_faults(&mut self) {}

    fn counters(&self) -> BusCounters {
        BusCounters::default()
    }

    fn start_operation(&mut self) {
        self.operational = true;
    }

    /// Nothing ever leaves operation: the restore ends at once (taken with
    /// [`CycleBus::take_restored`]).
    fn start_restore(&mut self, _drive: usize, _now_ns: u64, _timeout_ns: u64) -> bool {
        if self.restored.is_some() {
            return false;
        }
        self.restored = Some(Ok(Restored::WasOperational));
        true
    }

    fn take_restored(&mut self) -> Option<Result<Restored, CommandError>> {
        self.restored.take()
    }

    /// A drive comes back at once.
    fn restore_timeout_ns(&self) -> u64 {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::cia402::image::InputImage;

    /// One drive mapped to the full CSP layout, at `position`, 1 ms cycles, steps of at
    /// most 1000 counts.
    fn bus_at(position: i32) -> SimulatedBus {
        let drive = SimulatedDrive::new(&PdoLayout::csp(), position, 1e-3, Some(1000));
        SimulatedBus::new(vec![Some(drive)])
    }

    /// Writes `cw` and `target` as the master does, exchanges, and decodes the inputs:
    /// (statusword, position, velocity, error code, mode display).
    fn exchange(bus: &mut SimulatedBus, cw: u16, target: i32) -> (Statusword, i32, i32, u16, i8) {
        let map = PdoMap::of(&PdoLayout::csp());
        let mut out = OutputImage::new_checked(bus.outputs_mut(0), &map).unwrap();
        out.set_controlword(Controlword(cw));
        out.set_target_position(target);
        out.set_modes_of_operation(MODE_CSP);
        assert_eq!(bus.exchange(0), Reply::Answered);
        let inp = InputImage::new_checked(bus.inputs(0), &map).unwrap();
        (
            inp.statusword().unwrap(),
            inp.position_actual_value().unwrap(),
            inp.velocity_actual_value().unwrap(),
            inp.error_code().unwrap(),
            inp.modes_of_operation_display().unwrap(),
        )
    }

    fn enable(bus: &mut SimulatedBus, at: i32) {
        for cw in [0x06, 0x07, 0x0F] {
            exchange(bus, cw, at);
        }
        assert_eq!(bus.drive(0).unwrap().state(), State::OperationEnabled);
    }

    #[test]
    fn the_power_sequence_answers_at_once_and_only_in_operation() {
        let mut bus = bus_at(500);
        // Not operational yet (the bus came up, the cycle not ready): outputs not taken.
        let (sw, pos, ..) = exchange(&mut bus, 0x06, 9999);
        assert_eq!(sw.state(), Some(State::SwitchOnDisabled));
        assert_eq!(sw.0, 0x0240, "switch on disabled, remote");
        assert_eq!(pos, 500);
        bus.start_operation();
        assert!(bus.is_operational());
        // CiA 402-2 transitions 2, 3, 4: one a cycle, the state in the same exchange.
        let expect = [
            (0x06, State::ReadyToSwitchOn, 0x0231),
            (0x07, State::SwitchedOn, 0x0233),
            (0x0F, State::OperationEnabled, 0x1237),
        ];
        for (cw, state, raw) in expect {
            let (sw, pos, _, code, mode) = exchange(&mut bus, cw, 500);
            assert_eq!(
                (sw.state(), sw.0),
                (Some(state), raw),
                "controlword {cw:#06x}"
            );
            assert_eq!((pos, code, mode), (500, 0, MODE_CSP));
        }
        // Disable voltage (transition 9): the drive keeps its position, takes no target.
        let (sw, pos, ..) = exchange(&mut bus, 0x00, 700);
        assert_eq!((sw.state(), pos), (Some(State::SwitchOnDisabled), 500));
        // The enabling controlword straight from Switch on disabled does nothing there.
        let (sw, ..) = exchange(&mut bus, 0x0F, 700);
        assert_eq!(sw.state(), Some(State::SwitchOnDisabled));
        assert_eq!(bus.drive(0).unwrap().setpoints(), 1, "the one at enabling");
    }

    #[test]
    fn in_operation_enabled_the_position_is_the_target_sent_the_same_cycle() {
        let mut bus = bus_at(i32::MAX - 1500);
        bus.start_operation();
        enable(&mut bus, i32::MAX - 1500);
        // Across the 32-bit wrap, the short way: +1000 counts a cycle.
        let mut target = i32::MAX - 1500;
        for _ in 0..4 {
            target = target.wrapping_add(1000);
            let (sw, pos, vel, ..) = exchange(&mut bus, 0x0F, target);
            assert_eq!(sw.state(), Some(State::OperationEnabled));
            assert!(sw.has(statusword::MODE_SPECIFIC_12), "follows");
            assert_eq!(pos, target);
            assert_eq!(vel, 1_000_000, "1000 counts in 1 ms");
        }
        assert!(target < 0, "went across the wrap: {target}");
        // Standing: velocity 0.
        let (_, pos, vel, ..) = exchange(&mut bus, 0x0F, target);
        assert_eq!((pos, vel), (target, 0));
        // Another mode of operation is not taken: still CSP, still following.
        let map = PdoMap::of(&PdoLayout::csp());
        let mut out = OutputImage::new_checked(bus.outputs_mut(0), &map).unwrap();
        out.set_target_position(target - 10);
        out.set_modes_of_operation(9);
        bus.exchange(0);
        let inp = InputImage::new_checked(bus.inputs(0), &map).unwrap();
        assert_eq!(inp.modes_of_operation_display(), Some(MODE_CSP));
        assert_eq!(inp.position_actual_value(), Some(target - 10));
    }

    #[test]
    fn a_step_beyond_the_axis_speed_faults_the_drive_until_the_reset_edge() {
        let mut bus = bus_at(0);
        bus.start_operation();
        enable(&mut bus, 0);
        exchange(&mut bus, 0x0F, 1000);
        // 1001 counts in a cycle: beyond the bound; the target is not taken.
        let (sw, pos, vel, code, _) = exchange(&mut bus, 0x0F, 2001);
        assert_eq!(sw.state(), Some(State::Fault));
        assert_eq!((pos, vel, code), (1000, 0, SETPOINT_STEP_FAULT));
        // Faulted, it follows nothing, and bit 7 held high is no reset.
        let (sw, pos, ..) = exchange(&mut bus, 0x0F, 1001);
        assert_eq!((sw.state(), pos), (Some(State::Fault), 1000));
        exchange(&mut bus, 0x80, 1000);
        let (sw, _, _, code, _) = exchange(&mut bus, 0x80, 1000);
        assert_eq!(
            sw.state(),
            Some(State::SwitchOnDisabled),
            "the edge reset it"
        );
        assert_eq!(code, 0);
        let (sw, ..) = exchange(&mut bus, 0x00, 1000);
        assert_eq!(sw.state(), Some(State::SwitchOnDisabled));
        // A fault of the drive's own (over-temperature, say), and back again.
        enable(&mut bus, 1000);
        bus.drive_mut(0).unwrap().fault(0x4310);
        let (sw, _, _, code, _) = exchange(&mut bus, 0x0F, 1000);
        assert_eq!((sw.state(), code), (Some(State::Fault), 0x4310));
        exchange(&mut bus, 0x00, 1000);
        exchange(&mut bus, 0x80, 1000);
        enable(&mut bus, 1000);
        let (_, pos, ..) = exchange(&mut bus, 0x0F, 1900);
        assert_eq!(pos, 1900);
    }

    #[test]
    fn nothing_is_ever_unreachable_or_lost() {
        let mut bus = bus_at(0);
        bus.start_operation();
        enable(&mut bus, 0);
        bus.drive_mut(0).unwrap().fault(0x4310);
        bus.exchange(0);
        // A drive fault is the drive's, in its inputs: the bus reaches it.
        assert!(bus.fault(0).is_none() && !bus.any_fault());
        assert_eq!(bus.counters(), BusCounters::default());
        assert!(bus.inputs_fresh(0));
        assert!(bus.start_restore(0, 0, 0));
        assert!(!bus.start_restore(0, 0, 0), "one at a time");
        assert_eq!(bus.take_restored(), Some(Ok(Restored::WasOperational)));
        assert_eq!(bus.take_restored(), None);
        // A position without a drive has no process data.
        let bus = SimulatedBus::new(vec![None]);
        assert_eq!((bus.drives(), bus.inputs(0).len()), (1, 0));
        assert_eq!(bus.inputs(7).len(), 0);
    }

    #[test]
    fn the_bound_is_vmax_times_the_cycle_plus_one_count() {
        assert_eq!(max_step_counts(1_000_000.0, 1e-3), 1001);
        assert_eq!(max_step_counts(-2_621_440.0, 1e-3), 2622);
        assert_eq!(max_step_counts(f64::INFINITY, 1e-3), u32::MAX);
    }
}

/// The engine on simulated axes, as `gantry demo --bus none` runs it: the configuration,
/// [`crate::runtime::cycle::Cycle::from_config`], the [`crate::runtime::engine::Engine`]
/// on a [`crate::runtime::clock::StepClock`], requests through a
/// [`crate::runtime::controller::Controller`].
#[cfg(test)]
mod on_the_engine {
    use super::*;
    use crate::runtime::clock::StepClock;
    use crate::runtime::controller::{CommandHandle, Controller};
    use crate::runtime::cycle::Cycle;
    use crate::runtime::engine::Engine;
    use gantry_drives::csp::CspInputs;
    use gantry_kernel::axis::command::{Command, MoveDirection, MoveVelocity, PowerCommand};
    use gantry_kernel::axis::handle::CommandStatus;
    use gantry_kernel::axis::state::AxisState;
    use gantry_kernel::axis::status::AxisFault;

    /// Half a count of "c": 360° are 1 310 720 counts.
    const HALF_COUNT_DEG: f64 = 360.0 / 1_310_720.0 / 2.0 * (1.0 + 1e-9);

    /// "x" linear on drive 1 (full CSP mapping), "c" a rotary table modulo 360° through a
    /// 10:1 gear on drive 0 (minimal mapping).
    fn config() -> Config {
        let text = "[bus]\nkind = \"ethercat\"\ninterface = \"none\"\ncycle_us = 1000\n\
            [[axis]]\nname = \"x\"\ndrive = 1\n\
            scaling = { counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }\n\
            max = { speed = 200.0, acceleration = 2000.0, jerk = 20000.0 }\n\
            [[axis]]\nname = \"c\"\ndrive = 0\nkind = \"rotary\"\nmodulo = 360.0\n\
            pdo = \"csp-minimal\"\n\
            scaling = { counts_per_motor_rev = 131072, motor_revs = 10, units_per_load_rev = 360.0 }\n\
            max = { speed = 720.0, acceleration = 3600.0, jerk = 36000.0 }\n";
        Config::parse(text, "sim.toml").unwrap()
    }

    struct Rig {
        engine: Engine<SimulatedBus>,
        ctl: Controller,
        clock: StepClock<fn(u64)>,
    }

    impl Rig {
        fn new() -> Self {
            let config = config();
            let bus = SimulatedBus::of_config(&config).unwrap();
            let cycle = Cycle::from_config(&config, &bus).unwrap();
            let (engine, ends) = Engine::new(bus, cycle, 10, 16);
            let ctl = Controller::new(ends, vec!["x".into(), "c".into()]);
            let nothing: fn(u64) = |_| {};
            Self {
                engine,
                ctl,
                clock: StepClock::new(1_000_000, 0, nothing),
            }
        }

        fn cycle(&mut self) {
            assert!(self.engine.cycle(&mut self.clock));
        }

        /// Cycles until `h` is final (at most `limit`); its status.
        fn finish(&mut self, h: &CommandHandle, limit: u32) -> CommandStatus {
            for _ in 0..limit {
                if let Some(s) = h.status().filter(CommandStatus::is_final) {
                    return s;
                }
                self.cycle();
            }
            panic!("not final in {limit} cycles: {:?}", h.status());
        }

        fn axis(&self, i: usize) -> gantry_kernel::axis::status::AxisStatus {
            *self.engine.cycle.kernel.axis_status(i).unwrap()
        }

        /// The target the master sent drive `d` and the position it reports.
        fn drive(&self, d: usize, layout: &PdoLayout) -> (i32, i32) {
            let map = PdoMap::of(layout);
            let out = OutputImage::new_checked(self.engine.bus.outputs(d), &map).unwrap();
            let inputs = CspInputs::decode(
                &gantry_drives::csp::CspOffsets::of(layout).unwrap(),
                self.engine.bus.inputs(d),
            )
            .unwrap();
            (out.target_position().unwrap(), inputs.position)
        }
    }

    fn enable_both(rig: &mut Rig) {
        for axis in 0..2 {
            let h = rig
                .ctl
                .command(axis, Command::Power(PowerCommand::Enable))
                .unwrap();
            assert_eq!(rig.finish(&h, 100), CommandStatus::Done);
        }
    }

    #[test]
    fn a_modulo_axis_turns_across_its_wrap_its_actual_the_set_value_sent() {
        let mut rig = Rig::new();
        enable_both(&mut rig);
        let h = rig
            .ctl
            .command(
                1,
                Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 720.0)),
            )
            .unwrap();
        // Status comes with the snapshot, every 10 cycles.
        for _ in 0..10 {
            rig.cycle();
        }
        assert!(
            h.status().is_some_and(|s| !s.is_final()),
            "{:?}",
            h.status()
        );
        let mut last_set = rig.axis(1).set.p;
        let (mut wraps, mut counted) = (0, 0);
        for _ in 0..2000 {
            rig.cycle();
            let c = rig.axis(1);
            assert_eq!(c.state, AxisState::ContinuousMotion, "{c:?}");
            // The drive stands at the target it was sent, in the same exchange...
            let (target, position) = rig.drive(0, &PdoLayout::csp_minimal());
            assert_eq!(position, target);
            // ...so the actual the kernel read this cycle is the set value of the last,
            // rounded to the count sent, across the wrap too.
            let lag = (c.actual_position - last_set + 180.0).rem_euclid(360.0) - 180.0;
            assert!(
                lag.abs() <= HALF_COUNT_DEG,
                "actual {} set before {last_set}",
                c.actual_position
            );
            if c.set.p < last_set - 180.0 {
                wraps += 1;
            }
            last_set = c.set.p;
            counted += 1;
        }
        // 2 s at up to 720°/s from rest (3600°/s²): over three turns.
        assert!(wraps >= 3, "{wraps} wraps in {counted} cycles");
        assert_eq!(rig.engine.bus.drive(0).unwrap().error_code(), 0);
        assert!(rig.engine.bus.drive(0).unwrap().setpoints() >= 2000);
    }

    /// A program on the controller API, not the control socket: what the axes accept is
    /// saved all the same, what they refuse is not.
    #[test]
    fn commands_sent_on_the_controller_save_what_the_axes_accept() {
        use crate::persist::{Saved, Store};
        use gantry_kernel::axis::command::{MovePtp, PositioningMode};
        use gantry_kernel::homing::{HomeDirection, StepAbsoluteSwitch, SwitchMode};
        use std::sync::Arc;
        use std::time::Duration;
        let dir = std::env::temp_dir().join(format!("gantry-ctl-saves-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let store = Arc::new(Store::open(&dir).unwrap());
        let saved = Arc::new(Saved::load(Some(store.clone()), &config()).unwrap());
        let mut rig = Rig::new();
        rig.ctl = rig.ctl.clone().saving_to(saved.clone()).unwrap();
        enable_both(&mut rig);
        // Off the cam (this axis has no reference switch: its level is off), `Off` ends
        // the run at once where the axis stands: homed there at SetPosition.
        let run = StepAbsoluteSwitch {
            direction: HomeDirection::Positive,
            switch_mode: SwitchMode::Off,
            position: 5.0,
            velocity: 10.0,
            acceleration: 100.0,
            deceleration: 100.0,
            jerk: 1000.0,
            distance_limit: 50.0,
        };
        // Refused (a velocity over the axis' 200 mm/s): nothing to save.
        let too_fast = StepAbsoluteSwitch {
            velocity: 1000.0,
            ..run
        };
        let h = rig
            .ctl
            .command(0, Command::StepAbsoluteSwitch(too_fast))
            .unwrap();
        assert!(
            matches!(rig.finish(&h, 100), CommandStatus::Error(_)),
            "{:?}",
            h.status()
        );
        let h = rig
            .ctl
            .command(0, Command::StepAbsoluteSwitch(run))
            .unwrap();
        assert_eq!(rig.finish(&h, 1000), CommandStatus::Done);
        let x = rig.axis(0);
        assert!(
            x.bits.homed && (x.actual_position - 5.0).abs() < 1e-6,
            "{x:?}"
        );
        let mut m = MovePtp::new(PositioningMode::AbsNormal, 6.0);
        m.speed = Some(7.5);
        let h = rig.ctl.command(0, Command::MovePtp(m)).unwrap();
        assert_eq!(rig.finish(&h, 5000), CommandStatus::Done);
        // The saving thread follows the snapshots: cycle until it is done.
        let saver = rig.ctl.saver().unwrap().clone();
        let mut cycles = 0;
        while !saver.settle(Duration::ZERO) {
            assert!(cycles < 20_000, "the saves never finished");
            rig.cycle();
            cycles += 1;
            std::thread::sleep(Duration::from_micros(200));
        }
        let file = store.load("x").unwrap().unwrap();
        assert_eq!(
            file.step_switch,
            Some(crate::service::protocol::StepSwitchParams::from(run))
        );
        assert_eq!(
            file.home_method,
            Some(crate::service::protocol::HomeMethod::StepToSwitch)
        );
        assert_eq!(file.ptp.and_then(|p| p.speed), Some(7.5));
        assert_eq!(store.load("c").unwrap(), None, "c was sent nothing to save");
        // A move that leaves its speed out runs at the saved one.
        assert_eq!(
            saver
                .prepare(
                    0,
                    Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 1.0))
                )
                .0,
            Command::MovePtp(MovePtp {
                speed: Some(7.5),
                ..MovePtp::new(PositioningMode::AbsNormal, 1.0)
            })
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_drive_fault_stops_its_axis_and_a_reset_brings_it_back() {
        let mut rig = Rig::new();
        enable_both(&mut rig);
        let h = rig
            .ctl
            .command(
                0,
                Command::SetPosition {
                    position: 0.0,
                    relative: false,
                },
            )
            .unwrap();
        assert_eq!(rig.finish(&h, 100), CommandStatus::Done);
        rig.engine.bus.drive_mut(1).unwrap().fault(0x4310);
        for _ in 0..3 {
            rig.cycle();
        }
        let x = rig.axis(0);
        assert_eq!(x.state, AxisState::ErrorStop);
        assert_eq!(x.error, Some(AxisFault::Drive { code: 0x4310 }));
        assert_eq!(
            rig.axis(1).state,
            AxisState::Standstill,
            "the other axis runs on"
        );
        let h = rig.ctl.reset(0).unwrap();
        assert_eq!(rig.finish(&h, 100), CommandStatus::Done);
        // CiA 402 leaves a reset drive in Switch on disabled: the axis is Disabled.
        for _ in 0..3 {
            rig.cycle();
        }
        assert_eq!(rig.axis(0).state, AxisState::Disabled, "{:?}", rig.axis(0));
        assert_eq!(
            rig.engine.bus.drive(1).unwrap().state(),
            State::SwitchOnDisabled
        );
        let h = rig
            .ctl
            .command(0, Command::Power(PowerCommand::Enable))
            .unwrap();
        assert_eq!(rig.finish(&h, 100), CommandStatus::Done);
        let h = rig
            .ctl
            .command(
                0,
                Command::MovePtp(gantry_kernel::axis::command::MovePtp::new(
                    gantry_kernel::axis::command::PositioningMode::AbsNormal,
                    10.0,
                )),
            )
            .unwrap();
        assert_eq!(rig.finish(&h, 5000), CommandStatus::Done);
        let x = rig.axis(0);
        assert!((x.actual_position - 10.0).abs() < 1e-6, "{x:?}");
        let (target, position) = rig.drive(1, &PdoLayout::csp());
        assert_eq!(position, target);
        assert_eq!(position, 262_144, "10 mm at 131 072 counts per 5 mm");
    }
}
