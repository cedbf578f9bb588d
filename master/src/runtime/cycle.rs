//! One cycle over CSP drives, on any bus: read every axis' drive inputs from the bus,
//! run the kernel, write every drive's outputs back. The same code runs lockstep (demo,
//! tests) and in real time; nothing here allocates after it is built
//! ([`Cycle::from_config`]).

use gantry_kernel::axis::{AxisFeedback, AxisSetpoint};
use gantry_kernel::mechanics::Modulo;
use gantry_kernel::Kernel;
use thiserror::Error;

use super::bus::{CycleBus, DriveError};
use super::encoder_input::{self, EncoderInput};
use crate::config::ModuleInput;
use crate::config::{AxisType, Config};
use crate::drive_axis::AxisChannel;
use gantry_drives::cia402::procedure::ProcedureOutputs;
use gantry_drives::csp::{
    encode_outputs, encode_procedure_outputs, encode_touch_probe, CspChannel, CspInputs,
    FAULT_CODE_NOT_MAPPED,
};

/// Error code fed to the kernel for an axis whose drive the bus cannot reach (CiA 301
/// emergency class 0x81xx, "communication"); the reason is the bus' (see
/// [`CycleBus::fault`]).
pub const COMMUNICATION_FAULT: u16 = 0x8100;

/// What made a step of the set-up fail, kept as the source of a [`SetupError`].
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why the cycle could not be built for a configuration and its bus.
#[derive(Debug, Error)]
pub enum SetupError {
    /// The configuration names a drive that is not on the bus.
    #[error("{path}: axis {axis:?} is on drive {drive}, but the bus has {slaves} slaves")]
    MissingDrive {
        /// The configuration file.
        path: String,
        /// The axis.
        axis: String,
        /// Its drive position.
        drive: usize,
        /// Positions on the bus.
        slaves: usize,
    },
    /// An axis' configuration does not fit its drive (PDO layout, scaling).
    #[error("axis {axis:?}: {key}: {reason}")]
    Axis {
        /// The axis.
        axis: String,
        /// The configuration key.
        key: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The bus carries fewer process data bytes for an axis' drive than its layout has.
    #[error(
        "axis {axis:?}: drive {drive} has {got} {what} bytes on the bus, its PDO layout has {need}"
    )]
    ShortImage {
        /// The axis.
        axis: String,
        /// Its drive position.
        drive: usize,
        /// "input" or "output".
        what: &'static str,
        /// Bytes the bus carries.
        got: usize,
        /// Bytes the layout has.
        need: usize,
    },
    /// The layout does not suit CSP, or the kernel refused the axes.
    #[error("{what}")]
    Setup {
        /// What was being set up.
        what: String,
        /// Why it failed.
        #[source]
        source: Cause,
    },
}

/// A drive's process data does not fit the CSP layout.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum CycleError {
    /// Fewer input bytes than the layout needs.
    #[error("drive {drive}: {got} input bytes, its PDO layout has {need}")]
    ShortInputs {
        /// Drive index.
        drive: usize,
        /// Bytes present.
        got: usize,
        /// Bytes the layout has.
        need: usize,
    },
    /// Fewer output bytes than the layout needs.
    #[error("drive {drive}: {got} output bytes, its PDO layout has {need}")]
    ShortOutputs {
        /// Drive index.
        drive: usize,
        /// Bytes present.
        got: usize,
        /// Bytes the layout has.
        need: usize,
    },
    /// No such drive.
    #[error("drive {0} is not in the cycle")]
    NoDrive(usize),
}

/// The kernel and, per axis, where its actual values come from: a CSP channel on its
/// drive's position on the bus (real axes), an encoder module's counter (external axes),
/// or nothing (simulated and virtual axes: the kernel sets actual = set; shadow axes: the
/// kernel feeds them their source's values). Axes are mapped to bus positions by the
/// configuration, not by index.
#[derive(Debug)]
pub struct Cycle {
    /// The motion kernel.
    pub kernel: Kernel,
    /// Per axis, its drive's channel (`None`: the axis has no drive).
    channels: Vec<Option<CspChannel>>,
    /// Per axis, its encoder module (external axes).
    encoders: Vec<Option<EncoderInput>>,
    inputs: Vec<CspInputs>,
    feedback: Vec<AxisFeedback>,
    setpoints: Vec<AxisSetpoint>,
    /// The bus position of each axis' drive or encoder module (`usize::MAX`: none).
    drives: Vec<usize>,
    /// Drives lent to a procedure: what they get instead of their CSP outputs (see
    /// [`Cycle::set_procedure_outputs`]).
    procedures: Vec<Option<ProcedureOutputs>>,
    /// Per axis, the switches read from I/O modules (negative limit, positive limit,
    /// reference) and their last levels.
    modules: Vec<ModuleSwitches>,
    /// The configuration's cam tables' names, by slot (for the application; the cycle
    /// never reads them).
    cam_names: Vec<(usize, String)>,
}

/// An axis' switches read from I/O modules on the bus, and what they read last.
#[derive(Clone, Copy, Debug, Default)]
struct ModuleSwitches {
    /// Negative limit, positive limit, reference.
    inputs: [Option<ModuleInput>; 3],
    /// Their last levels (active), kept through a cycle whose inputs did not come.
    active: [bool; 3],
}

impl Cycle {
    /// A cycle for `kernel`'s axes on these channels, axis `i` on the drive at position
    /// `i`. Each channel counts its axis'
    /// modulo period, taken from the kernel's configuration; a channel whose period cannot
    /// be counted faults its axis (check [`CspChannel::set_modulo`] first to refuse such a
    /// configuration with a message).
    pub fn new(kernel: Kernel, mut channels: Vec<CspChannel>) -> Self {
        for (channel, axis) in channels.iter_mut().zip(kernel.axes()) {
            // An error stays in the channel, which faults the axis.
            let _ = channel.set_modulo(axis.config().mechanics.modulo);
        }
        let n = channels.len();
        Self {
            kernel,
            channels: channels.into_iter().map(Some).collect(),
            encoders: vec![None; n],
            inputs: vec![CspInputs::default(); n],
            feedback: vec![AxisFeedback::default(); n],
            setpoints: vec![AxisSetpoint::default(); n],
            drives: (0..n).collect(),
            modules: vec![ModuleSwitches::default(); n],
            procedures: vec![None; n],
            cam_names: Vec::new(),
        }
    }

    /// The cycle of `config` on `bus`, as the service, the demo and the tests run it: the
    /// kernel at the bus' cycle time with the configuration's axes, and one CSP channel
    /// per axis on its drive (layout, scaling, modulo period), checked against what the
    /// bus carries for that drive. Allocates; build it before the drives go operational.
    pub fn from_config(config: &Config, bus: &impl CycleBus) -> Result<Self, SetupError> {
        let mut channels = Vec::with_capacity(config.axes.len());
        let mut encoders = Vec::with_capacity(config.axes.len());
        let mut modules = Vec::with_capacity(config.axes.len());
        let mut drives = Vec::with_capacity(config.axes.len());
        let cycle_s = f64::from(config.bus.cycle_us) * 1e-6;
        for a in &config.axes {
            let axis_error = |(key, reason)| SetupError::Axis {
                axis: a.name.clone(),
                key,
                reason,
            };
            match (a.axis_type, a.encoder_input) {
                (AxisType::Real, _) => {}
                (AxisType::External, Some(e)) => {
                    let bytes = bus.inputs(e.slave).len();
                    if e.slave >= bus.drives() || bytes < encoder_input::INPUT_BYTES {
                        return Err(SetupError::Axis {
                            axis: a.name.clone(),
                            key: "encoder_input.slave".into(),
                            reason: format!(
                                "slave {}: the bus has {} slaves, slave {} {} input bytes (an \
                                 encoder module has at least {}: status, counter value)",
                                e.slave,
                                bus.drives(),
                                e.slave,
                                bytes,
                                encoder_input::INPUT_BYTES
                            ),
                        });
                    }
                    let scaling = a.scaling().map_err(axis_error)?;
                    let input =
                        EncoderInput::new(e.slave, scaling, a.modulo, e.freeze_timeout_ms, cycle_s)
                            .map_err(|err| axis_error(("modulo".into(), err.to_string())))?;
                    channels.push(None);
                    encoders.push(Some(input));
                    modules.push(ModuleSwitches::default());
                    drives.push(e.slave);
                    continue;
                }
                _ => {
                    channels.push(None);
                    encoders.push(None);
                    modules.push(ModuleSwitches::default());
                    drives.push(usize::MAX);
                    continue;
                }
            }
            if a.drive >= bus.drives() {
                return Err(SetupError::MissingDrive {
                    path: config.path.clone(),
                    axis: a.name.clone(),
                    drive: a.drive,
                    slaves: bus.drives(),
                });
            }
            let setup_error = |e: Cause| SetupError::Setup {
                what: format!("axis {:?}", a.name),
                source: e,
            };
            let layout = a.pdo_layout().map_err(axis_error)?;
            let scaling = a.scaling().map_err(axis_error)?;
            let mut channel =
                CspChannel::with_layout(scaling, &layout).map_err(|e| setup_error(e.into()))?;
            channel.set_switch_wiring(a.switches.wiring().map_err(axis_error)?);
            // A modulo period that cannot be counted is refused here, by name (the cycle
            // would fault the axis).
            channel
                .set_modulo(a.modulo.and_then(Modulo::new))
                .map_err(|e| setup_error(e.into()))?;
            let short = |what, got, need| SetupError::ShortImage {
                axis: a.name.clone(),
                drive: a.drive,
                what,
                got,
                need,
            };
            let (inputs, need) = (bus.inputs(a.drive).len(), channel.offsets.input_bytes);
            if inputs < need {
                return Err(short("input", inputs, need));
            }
            let (outputs, need) = (bus.outputs(a.drive).len(), channel.offsets.output_bytes);
            if outputs < need {
                return Err(short("output", outputs, need));
            }
            channels.push(Some(channel));
            encoders.push(None);
            drives.push(a.drive);
            // Switches on I/O modules: the module there, its input in its process data.
            let inputs = a.switches.module_inputs().map_err(axis_error)?;
            let names = ["negative_limit", "positive_limit", "reference"];
            for (name, m) in names.iter().zip(inputs) {
                let Some(m) = m else { continue };
                let bytes = bus.inputs(m.slave).len();
                if m.slave >= bus.drives() || m.active(bus.inputs(m.slave)).is_none() {
                    return Err(SetupError::Axis {
                        axis: a.name.clone(),
                        key: format!("switches.{name}"),
                        reason: format!(
                            "input {} of slave {}: the bus has {} slaves, slave {} {} input \
                             bytes",
                            m.input,
                            m.slave,
                            bus.drives(),
                            m.slave,
                            bytes
                        ),
                    });
                }
            }
            modules.push(ModuleSwitches {
                inputs,
                active: [false; 3],
            });
        }
        let dt = f64::from(config.bus.cycle_us) * 1e-6;
        let mut kernel =
            Kernel::new(dt, config.kernel_axes.clone()).map_err(|e| SetupError::Setup {
                what: "the motion kernel".into(),
                source: e.into(),
            })?;
        // The configuration's cam tables, each into its slot (`[[cam]]` order).
        let mut cam_names = Vec::with_capacity(config.cams.len());
        for cam in &config.cams {
            kernel
                .set_cam_table(cam.slot, Some(cam.table.clone()))
                .map_err(|e| SetupError::Setup {
                    what: format!("{}: cam table {:?} ({})", config.path, cam.name, cam.file),
                    source: e.into(),
                })?;
            cam_names.push((cam.slot, cam.name.clone()));
        }
        // The configuration's axis groups (`[[group]]` order: the kernel's group indices).
        for g in &config.groups {
            kernel.add_group(g.clone()).map_err(|e| SetupError::Setup {
                what: format!("{}: group {:?}", config.path, g.name),
                source: e.into(),
            })?;
        }
        let n = channels.len();
        let mut cycle = Self {
            kernel,
            channels,
            encoders,
            inputs: vec![CspInputs::default(); n],
            feedback: vec![AxisFeedback::default(); n],
            setpoints: vec![AxisSetpoint::default(); n],
            drives,
            modules,
            procedures: vec![None; n],
            cam_names,
        };
        for (channel, axis) in cycle.channels.iter_mut().zip(cycle.kernel.axes()) {
            if let Some(channel) = channel {
                // Checked above (refused by name): cannot fail here.
                let _ = channel.set_modulo(axis.config().mechanics.modulo);
            }
        }
        Ok(cycle)
    }

    /// The configuration's cam tables' names and slots (none for a cycle made with
    /// [`Cycle::new`]).
    pub fn cam_names(&self) -> &[(usize, String)] {
        &self.cam_names
    }

    /// The bus position of `axis`' drive, or of its encoder module for an external axis
    /// (`usize::MAX` for an axis without either, or no such axis): where its bus faults
    /// and a reset's recovery are.
    pub fn drive_of(&self, axis: usize) -> usize {
        self.drives.get(axis).copied().unwrap_or(usize::MAX)
    }

    /// Decodes every axis' drive inputs from `bus`; an axis whose drive the bus cannot
    /// reach gets a communication fault instead ([`Cycle::comm_fault`]), one whose inputs
    /// did not come with the last exchange keeps what it had.
    pub fn read_from(&mut self, bus: &impl CycleBus) -> Result<(), CycleError> {
        for axis in 0..self.drives.len() {
            let drive = self.drive_of(axis);
            if let Some(e) = self.encoders.get_mut(axis).and_then(Option::as_mut) {
                let unreachable = bus.fault(drive).is_some();
                let fresh = bus.inputs_fresh(drive).then(|| bus.inputs(drive));
                let fb = *e.read(unreachable, fresh);
                if let Some(dst) = self.feedback.get_mut(axis) {
                    *dst = fb;
                }
                continue;
            }
            if self.channels.get(axis).is_none_or(Option::is_none) {
                // No drive: the kernel makes the actual values (or a shadow's source).
                continue;
            }
            if bus.fault(drive).is_some() {
                self.comm_fault(axis)?;
                continue;
            }
            // Inputs that did not come with the last exchange: none decoded, the axis keeps
            // last cycle's feedback, as it does through a lost frame.
            if !bus.inputs_fresh(drive) {
                continue;
            }
            self.read_inputs(axis, bus.inputs(drive))?;
            if let Some(e) = bus.drive_error(drive) {
                self.drive_error(axis, e)?;
            }
        }
        for axis in 0..self.drives.len() {
            self.read_module_switches(axis, bus)?;
        }
        Ok(())
    }

    /// Axis `axis`' switches on I/O modules: each module input's level this cycle (the
    /// last one when the module's inputs did not come), into the axis' feedback; a module
    /// the bus cannot reach gives the axis a communication fault (its limit switches are
    /// not watched any more).
    fn read_module_switches(&mut self, axis: usize, bus: &impl CycleBus) -> Result<(), CycleError> {
        let m = self
            .modules
            .get_mut(axis)
            .ok_or(CycleError::NoDrive(axis))?;
        let mut unreachable = false;
        for (input, active) in m.inputs.iter().zip(m.active.iter_mut()) {
            let Some(input) = input else { continue };
            if bus.fault(input.slave).is_some() {
                unreachable = true;
            } else if bus.inputs_fresh(input.slave) {
                if let Some(a) = input.active(bus.inputs(input.slave)) {
                    *active = a;
                }
            }
        }
        let (inputs, [neg, pos, reference]) = (m.inputs, m.active);
        if unreachable {
            return self.comm_fault(axis);
        }
        let feedback = self
            .feedback
            .get_mut(axis)
            .ok_or(CycleError::NoDrive(axis))?;
        let sw = &mut feedback.switches;
        for (input, (slot, level)) in inputs.iter().zip([
            (&mut sw.negative_limit, neg),
            (&mut sw.positive_limit, pos),
            (&mut sw.reference, reference),
        ]) {
            if input.is_some() {
                *slot = level;
            }
        }
        Ok(())
    }

    /// An error the drive reported outside its process data (a CANopen EMCY): a new one
    /// faults the axis with its code (ErrorStop with the drive's own code and text, even
    /// if the drive does not fault for it); one in force names the fault of a drive whose
    /// layout does not carry 0x603F ([`FAULT_CODE_NOT_MAPPED`] otherwise).
    fn drive_error(&mut self, axis: usize, e: DriveError) -> Result<(), CycleError> {
        let feedback = self
            .feedback
            .get_mut(axis)
            .ok_or(CycleError::NoDrive(axis))?;
        if e.fresh || feedback.fault == Some(FAULT_CODE_NOT_MAPPED) {
            feedback.fault = Some(e.code);
        }
        Ok(())
    }

    /// Encodes every axis' outputs into its drive's bytes on `bus`.
    pub fn write_to(&mut self, bus: &mut impl CycleBus) -> Result<(), CycleError> {
        for axis in 0..self.drives.len() {
            if self.channels.get(axis).is_none_or(Option::is_none) {
                continue;
            }
            let drive = self.drive_of(axis);
            self.write_outputs(axis, bus.outputs_mut(drive))?;
        }
        Ok(())
    }

    /// Number of axes.
    pub fn len(&self) -> usize {
        self.channels.len()
    }

    /// Whether there is no axis.
    pub fn is_empty(&self) -> bool {
        self.channels.is_empty()
    }

    /// The channel of axis `i`'s drive (`None`: no such axis, or an axis without a drive).
    pub fn channel(&self, i: usize) -> Option<&CspChannel> {
        self.channels.get(i).and_then(Option::as_ref)
    }

    /// The channel of axis `i`'s drive, to change.
    pub fn channel_mut(&mut self, i: usize) -> Option<&mut CspChannel> {
        self.channels.get_mut(i).and_then(Option::as_mut)
    }

    /// The encoder input of external axis `i`.
    pub fn encoder_input(&self, i: usize) -> Option<&EncoderInput> {
        self.encoders.get(i).and_then(Option::as_ref)
    }

    /// The feedback axis `i` gets at the next [`Cycle::step`] (as read so far).
    pub fn feedback(&self, i: usize) -> Option<&AxisFeedback> {
        self.feedback.get(i)
    }

    /// The last decoded inputs of drive `i`.
    pub fn inputs(&self, i: usize) -> Option<&CspInputs> {
        self.inputs.get(i)
    }

    /// Takes drive `i`'s inputs from the process image.
    pub fn read_inputs(&mut self, i: usize, bytes: &[u8]) -> Result<(), CycleError> {
        let channel = self
            .channels
            .get_mut(i)
            .and_then(Option::as_mut)
            .ok_or(CycleError::NoDrive(i))?;
        let decoded = channel.decode(bytes).ok_or(CycleError::ShortInputs {
            drive: i,
            got: bytes.len(),
            need: channel.offsets.input_bytes,
        })?;
        let (inputs, feedback) = (
            self.inputs.get_mut(i).ok_or(CycleError::NoDrive(i))?,
            self.feedback.get_mut(i).ok_or(CycleError::NoDrive(i))?,
        );
        *inputs = decoded;
        *feedback = channel.feedback(&decoded);
        Ok(())
    }

    /// Drive `i` cannot be reached this cycle (see `health`): its axis gets a
    /// communication fault instead of stale inputs, at the position the drive was last
    /// sent ([`CspChannel::last_target_position`]). The kernel takes a faulted drive's
    /// position as its set value; the drive may well be enabled still and taking every
    /// frame (the replies were late, not the frames), so its last position actual value —
    /// as old as the last reply — would step the target back by the path travelled since
    /// (up to one axis unit in one cycle at full speed after three lost frames, measured
    /// over veth) and the drive would fault on the step (0xFF01) or follow it.
    pub fn comm_fault(&mut self, i: usize) -> Result<(), CycleError> {
        let held = self
            .channels
            .get(i)
            .ok_or(CycleError::NoDrive(i))?
            .as_ref()
            .map(CspChannel::last_target_position);
        let feedback = self.feedback.get_mut(i).ok_or(CycleError::NoDrive(i))?;
        if let Some(held) = held {
            feedback.position = held;
        }
        feedback.operation_enabled = false;
        feedback.fault = Some(COMMUNICATION_FAULT);
        Ok(())
    }

    /// Gives axis `i` a fault with `code` this cycle (the cycle thread's own reasons, e.g.
    /// overruns), keeping its last position.
    pub fn force_fault(&mut self, i: usize, code: u16) -> Result<(), CycleError> {
        let feedback = self.feedback.get_mut(i).ok_or(CycleError::NoDrive(i))?;
        feedback.fault = Some(code);
        Ok(())
    }

    /// Sends axis `i`'s drive `outputs` instead of its CSP outputs from the next write on
    /// (`None`: CSP again), for a procedure the drive runs by itself
    /// ([`gantry_drives::cia402::procedure`] says how to use it). The axis must be lent to
    /// the drive in the kernel meanwhile (`Kernel::lend_to_drive`), so that its set
    /// position tracks the drive.
    pub fn set_procedure_outputs(
        &mut self,
        i: usize,
        outputs: Option<ProcedureOutputs>,
    ) -> Result<(), CycleError> {
        *self.procedures.get_mut(i).ok_or(CycleError::NoDrive(i))? = outputs;
        Ok(())
    }

    /// What axis `i`'s drive is sent in place of its CSP outputs, if it is lent.
    pub fn procedure_outputs(&self, i: usize) -> Option<ProcedureOutputs> {
        self.procedures.get(i).copied().flatten()
    }

    /// Runs the kernel on the feedback read so far.
    pub fn step(&mut self) {
        let sps = self.kernel.step(&self.feedback);
        for (dst, src) in self.setpoints.iter_mut().zip(sps) {
            *dst = *src;
        }
    }

    /// Writes drive `i`'s outputs into the process image.
    pub fn write_outputs(&mut self, i: usize, bytes: &mut [u8]) -> Result<(), CycleError> {
        let need = self
            .channels
            .get(i)
            .and_then(Option::as_ref)
            .ok_or(CycleError::NoDrive(i))?
            .offsets
            .output_bytes;
        if bytes.len() < need {
            return Err(CycleError::ShortOutputs {
                drive: i,
                got: bytes.len(),
                need,
            });
        }
        let (channel, sp, inputs) = (
            self.channels
                .get_mut(i)
                .and_then(Option::as_mut)
                .ok_or(CycleError::NoDrive(i))?,
            self.setpoints.get(i).ok_or(CycleError::NoDrive(i))?,
            self.inputs.get(i).ok_or(CycleError::NoDrive(i))?,
        );
        match self.procedures.get(i).copied().flatten() {
            Some(p) => {
                let (cw, target) = channel.procedure_outputs(&p, inputs);
                encode_procedure_outputs(&channel.offsets, bytes, cw, target, p.mode);
            }
            None => {
                let (cw, target) = channel.outputs(sp, inputs);
                encode_outputs(&channel.offsets, bytes, cw, target);
            }
        }
        if let Some(f) = channel.probe_function() {
            encode_touch_probe(&channel.offsets, bytes, f);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::csp::COUNT_RANGE_FAULT;
    use gantry_drives::scaling::{Scaling, ScalingConfig};
    use gantry_kernel::axis::command::{Command, MoveDirection, MoveVelocity, PowerCommand};
    use gantry_kernel::axis::handle::CommandStatus;
    use gantry_kernel::axis::state::AxisState;
    use gantry_kernel::axis::status::AxisFault;
    use gantry_kernel::{AxisConfig, AxisKind};

    /// A drive that is Operation enabled at `position` counts (minimal mapping).
    fn enabled_at(position: i32) -> [u8; 6] {
        let mut b = [0u8; 6];
        b[0..2].copy_from_slice(&0x0637u16.to_le_bytes());
        b[2..6].copy_from_slice(&position.to_le_bytes());
        b
    }

    /// An axis whose counts overflow 64 bits within a second of motion (2^62 counts per
    /// unit: 2 units is beyond `i64`) faults with [`COUNT_RANGE_FAULT`] through the
    /// drive-fault path: ErrorStop, the reason readable, and the drive's target is never
    /// a substitute — it stays where the last representable set position put it.
    #[test]
    fn a_set_position_beyond_64_bit_counts_stops_the_axis_with_its_reason() {
        let mut cfg = AxisConfig::new("w", AxisKind::Real);
        cfg.homing_required = false;
        cfg.max.vmax = 4.0;
        cfg.defaults.speed = 4.0;
        let kernel = Kernel::new(1e-3, vec![cfg]).unwrap();
        let scaling = Scaling::new(ScalingConfig {
            counts_per_motor_rev: 1 << 31,
            motor_revs: 1 << 31,
            load_revs: 1,
            units_per_load_rev: 1.0,
            invert: false,
        })
        .unwrap();
        let mut c = Cycle::new(kernel, vec![CspChannel::new(scaling)]);
        c.kernel
            .command(0, Command::Power(PowerCommand::Enable))
            .unwrap();
        let mut out = [0u8; 6];
        let cycle = |c: &mut Cycle, out: &mut [u8; 6]| {
            c.read_inputs(0, &enabled_at(0)).unwrap();
            c.step();
            c.write_outputs(0, out).unwrap();
            i32::from_le_bytes([out[2], out[3], out[4], out[5]])
        };
        for _ in 0..3 {
            cycle(&mut c, &mut out);
        }
        c.kernel
            .command(
                0,
                Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 4.0)),
            )
            .unwrap();
        let mut sent = Vec::new();
        for _ in 0..2000 {
            sent.push(cycle(&mut c, &mut out));
            if c.kernel.axis_status(0).unwrap().state == AxisState::ErrorStop {
                break;
            }
        }
        let status = *c.kernel.axis_status(0).unwrap();
        assert_eq!(status.state, AxisState::ErrorStop, "{status:?}");
        assert_eq!(
            status.error,
            Some(AxisFault::Drive {
                code: COUNT_RANGE_FAULT
            })
        );
        assert_eq!(
            crate::axis_fault::describe_fault(&status.error.unwrap()),
            "drive fault 0x6320: parameter error (gantry stops the axis: its set position has \
             no 64-bit drive count; check the scaling and the travel)"
        );
        // The cycle that could not count repeated the last target; then the axis holds
        // where the drive stands (its actual, 0).
        let n = sent.len();
        assert!(n > 10, "moved a while first: {n} cycles");
        assert_eq!(sent[n - 2], sent[n - 3], "held, not substituted");
    }

    /// A drive lent to a procedure (homing mode, bit 4 set) moves by itself: it gets the
    /// procedure's controlword bits and its own position as the target, the kernel's set
    /// position tracks it, and the first CSP target after the hand-back is where the
    /// drive stands (no jump), on the drive's own position (homing done).
    #[test]
    fn a_drive_lent_to_a_procedure_is_handed_back_where_it_stands() {
        use gantry_drives::cia402::procedure::ProcedureOutputs;
        use gantry_drives::cia402::ModeOfOperation;
        let mut cfg = AxisConfig::new("x", AxisKind::Real);
        cfg.homing_required = false;
        let kernel = Kernel::new(1e-3, vec![cfg]).unwrap();
        let scaling = Scaling::new(ScalingConfig {
            counts_per_motor_rev: 10_000,
            motor_revs: 1,
            load_revs: 1,
            units_per_load_rev: 10.0,
            invert: false,
        })
        .unwrap();
        let mut c = Cycle::new(kernel, vec![CspChannel::new(scaling)]);
        c.kernel
            .command(0, Command::Power(PowerCommand::Enable))
            .unwrap();
        let mut out = [0u8; 6];
        let mut cycle = |c: &mut Cycle, at: i32| {
            c.read_inputs(0, &enabled_at(at)).unwrap();
            c.step();
            c.write_outputs(0, &mut out).unwrap();
            (
                u16::from_le_bytes([out[0], out[1]]),
                i32::from_le_bytes([out[2], out[3], out[4], out[5]]),
            )
        };
        for _ in 0..3 {
            assert_eq!(cycle(&mut c, 700), (0x0F, 700));
        }
        let h = c.kernel.lend_to_drive(0, "drive homing", true).unwrap();
        let homing = ProcedureOutputs::idle(ModeOfOperation::Homing).with(0x10);
        c.set_procedure_outputs(0, Some(homing)).unwrap();
        for k in 0..50 {
            let at = 700 - 100 * k;
            assert_eq!(
                cycle(&mut c, at),
                (0x1F, at),
                "bit 4 set, the target is the drive's"
            );
        }
        // Homing done: the drive stands at -4300 counts (its new reference frame).
        c.set_procedure_outputs(0, None).unwrap();
        assert!(c.kernel.end_drive_procedure(0, Ok(())));
        assert_eq!(c.kernel.command_status(h), CommandStatus::Done);
        for _ in 0..3 {
            assert_eq!(
                cycle(&mut c, -4300),
                (0x0F, -4300),
                "no jump at the hand-back"
            );
        }
        let st = c.kernel.axis_status(0).unwrap();
        assert_eq!(st.state, AxisState::Standstill);
        assert!(st.bits.homed);
        assert!(
            (st.actual_position + 4.3).abs() < 1e-9,
            "{}",
            st.actual_position
        );
    }

    /// Replies lost while an axis runs at full speed (a stall of the slave's host: the
    /// frames arrived and the drive took them, the replies came too late), until the bus
    /// faults the axis: every target the still-enabled drive takes is within the axis'
    /// speed of the one before, before, during and after the fault — the set value is not
    /// taken from the drive's last reported position, which is older by the lost replies
    /// (the step measured over veth before: 26 214 counts, one unit). And once the bus is
    /// reachable again with the axis still in ErrorStop (another axis' reset cleared the
    /// bus faults), the drive is held where it was last sent.
    #[test]
    fn a_communication_fault_holds_the_drive_where_it_was_last_sent() {
        let mut cfg = AxisConfig::new("x", AxisKind::Real);
        cfg.homing_required = false;
        let vmax = cfg.max.vmax;
        let kernel = Kernel::new(1e-3, vec![cfg]).unwrap();
        // 1000 counts per unit: at most vmax · T · 1000 counts (+1 for rounding) a cycle.
        let scaling = Scaling::new(ScalingConfig {
            counts_per_motor_rev: 10_000,
            motor_revs: 1,
            load_revs: 1,
            units_per_load_rev: 10.0,
            invert: false,
        })
        .unwrap();
        let limit = (vmax * 1e-3 * 1000.0) as i32 + 1;
        let mut c = Cycle::new(kernel, vec![CspChannel::new(scaling)]);
        c.kernel
            .command(0, Command::Power(PowerCommand::Enable))
            .unwrap();
        // The drive: enabled, its position actual value two cycles behind its target.
        let mut sent: Vec<i32> = vec![0, 0];
        let mut out = [0u8; 6];
        let mut cycle = |c: &mut Cycle, inputs: Option<[u8; 6]>, sent: &mut Vec<i32>| {
            match inputs {
                Some(bytes) => c.read_inputs(0, &bytes).unwrap(),
                None => c.comm_fault(0).unwrap(),
            }
            c.step();
            c.write_outputs(0, &mut out).unwrap();
            sent.push(i32::from_le_bytes([out[2], out[3], out[4], out[5]]));
        };
        let lagging = |sent: &Vec<i32>| enabled_at(sent[sent.len() - 2]);
        for _ in 0..3 {
            let i = lagging(&sent);
            cycle(&mut c, Some(i), &mut sent);
        }
        c.kernel
            .command(
                0,
                Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, vmax)),
            )
            .unwrap();
        for _ in 0..500 {
            let i = lagging(&sent);
            cycle(&mut c, Some(i), &mut sent);
        }
        let n = sent.len();
        assert!(
            sent[n - 1] - sent[n - 2] >= limit - 2,
            "at full speed: {:?}",
            &sent[n - 3..]
        );
        // Three replies lost: the image keeps the last inputs; then the bus faults.
        let stale = lagging(&sent);
        for _ in 0..3 {
            cycle(&mut c, Some(stale), &mut sent);
        }
        let before_fault = sent.len();
        for _ in 0..20 {
            cycle(&mut c, None, &mut sent);
        }
        let status = *c.kernel.axis_status(0).unwrap();
        assert_eq!(status.state, AxisState::ErrorStop, "{status:?}");
        assert_eq!(
            status.error,
            Some(AxisFault::Drive {
                code: COMMUNICATION_FAULT
            })
        );
        let held = sent[before_fault - 1];
        assert!(
            sent[before_fault..].iter().all(|&t| t == held),
            "held where it was last sent ({held}): {:?}",
            &sent[before_fault - 3..before_fault + 3]
        );
        // Reachable again, the drive standing where it was sent, the axis in ErrorStop.
        for _ in 0..20 {
            cycle(&mut c, Some(enabled_at(held)), &mut sent);
        }
        assert!(sent[sent.len() - 20..].iter().all(|&t| t == held));
        let worst = sent.windows(2).map(|w| (w[1] - w[0]).abs()).max().unwrap();
        assert!(
            worst <= limit,
            "largest target step {worst} counts, vmax · T + 1 is {limit}"
        );
    }
}

/// [`Cycle::from_config`] and the cycle's reads and writes on a bus that is no EtherCAT:
/// a plain image per bus position, as a second bus (CANopen) would hand them over.
#[cfg(test)]
mod on_a_bus {
    use super::*;
    use crate::runtime::bus::{BusCounters, Reply, Restored, Unreachable};
    use gantry_kernel::axis::command::{Command, CommandError, PowerCommand};
    use gantry_kernel::axis::status::AxisFault;

    /// Bytes per position, and a fault per position.
    struct Image {
        inputs: Vec<Vec<u8>>,
        outputs: Vec<Vec<u8>>,
        faults: Vec<Option<Unreachable>>,
    }

    impl Image {
        /// `n` positions of `bytes` input and output bytes.
        fn new(n: usize, bytes: usize) -> Self {
            Self {
                inputs: vec![vec![0; bytes]; n],
                outputs: vec![vec![0; bytes]; n],
                faults: vec![None; n],
            }
        }
    }

    impl CycleBus for Image {
        fn drives(&self) -> usize {
            self.inputs.len()
        }
        fn inputs(&self, drive: usize) -> &[u8] {
            self.inputs.get(drive).map_or(&[], Vec::as_slice)
        }
        fn outputs(&self, drive: usize) -> &[u8] {
            self.outputs.get(drive).map_or(&[], Vec::as_slice)
        }
        fn outputs_mut(&mut self, drive: usize) -> &mut [u8] {
            self.outputs
                .get_mut(drive)
                .map_or(&mut [], Vec::as_mut_slice)
        }
        fn exchange(&mut self, _deadline_ns: u64) -> Reply {
            Reply::Answered
        }
        fn fault(&self, drive: usize) -> Option<&Unreachable> {
            self.faults.get(drive)?.as_ref()
        }
        fn any_fault(&self) -> bool {
            self.faults.iter().any(Option::is_some)
        }
        fn clear_faults(&mut self) {
            self.faults.iter_mut().for_each(|f| *f = None);
        }
        fn counters(&self) -> BusCounters {
            BusCounters::default()
        }
        fn start_operation(&mut self) {}
        fn start_restore(&mut self, _drive: usize, _now_ns: u64, _timeout_ns: u64) -> bool {
            false
        }
        fn take_restored(&mut self) -> Option<Result<Restored, CommandError>> {
            None
        }
        fn restore_timeout_ns(&self) -> u64 {
            0
        }
    }

    /// Axis "a" on drive 2 and "b" on drive 0, both with the minimal CSP mapping
    /// (statusword + position actual value in, controlword + target position out: 6 bytes
    /// each way).
    fn config() -> Config {
        let axis = |name: &str, drive: usize| {
            format!(
                "[[axis]]\nname = \"{name}\"\ndrive = {drive}\npdo = \"csp-minimal\"\n\
                 homing_required = false\n\
                 scaling = {{ counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }}\n\
                 max = {{ speed = 10.0, acceleration = 100.0, jerk = 1000.0 }}\n"
            )
        };
        let text = format!(
            "[bus]\nkind = \"ethercat\"\ninterface = \"none\"\ncycle_us = 1000\n{}{}",
            axis("a", 2),
            axis("b", 0)
        );
        Config::parse(&text, "g.toml").unwrap()
    }

    /// Inputs of a drive in Operation enabled at `position` counts.
    fn enabled_at(position: i32) -> Vec<u8> {
        let mut b = vec![0u8; 6];
        b[0..2].copy_from_slice(&0x0637u16.to_le_bytes());
        b[2..6].copy_from_slice(&position.to_le_bytes());
        b
    }

    #[test]
    fn each_axis_reads_and_writes_its_own_drive_by_its_position() {
        let mut bus = Image::new(3, 6);
        let mut cycle = Cycle::from_config(&config(), &bus).unwrap();
        assert_eq!((cycle.drive_of(0), cycle.drive_of(1)), (2, 0));
        assert_eq!(cycle.drive_of(2), usize::MAX, "no such axis");
        bus.inputs[2] = enabled_at(1500);
        bus.inputs[0] = enabled_at(-250);
        cycle.read_from(&bus).unwrap();
        assert_eq!(cycle.inputs(0).unwrap().position, 1500);
        assert_eq!(cycle.inputs(1).unwrap().position, -250);
        cycle.step();
        cycle.write_to(&mut bus).unwrap();
        // Each drive is held where it stands; position 1 has no axis and is not touched.
        let target = |b: &[u8]| i32::from_le_bytes([b[2], b[3], b[4], b[5]]);
        assert_eq!(target(&bus.outputs[2]), 1500);
        assert_eq!(target(&bus.outputs[0]), -250);
        assert_eq!(bus.outputs[1], vec![0; 6]);
        let status = cycle.kernel.axis_status(0).unwrap();
        assert!((status.actual_position - 1.5).abs() < 1e-12, "{status:?}");
    }

    #[test]
    fn an_axis_whose_drive_the_bus_cannot_reach_gets_the_communication_fault() {
        let mut bus = Image::new(3, 6);
        let mut cycle = Cycle::from_config(&config(), &bus).unwrap();
        bus.inputs = vec![enabled_at(0); 3];
        for axis in 0..2 {
            cycle
                .kernel
                .command(axis, Command::Power(PowerCommand::Enable))
                .unwrap();
        }
        for _ in 0..3 {
            cycle.read_from(&bus).unwrap();
            cycle.step();
            cycle.write_to(&mut bus).unwrap();
        }
        bus.faults[2] = Some(Unreachable::new(&"gone"));
        cycle.read_from(&bus).unwrap();
        cycle.step();
        let error = |axis| cycle.kernel.axis_status(axis).unwrap().error;
        assert_eq!(
            error(0),
            Some(AxisFault::Drive {
                code: COMMUNICATION_FAULT
            })
        );
        assert_eq!(error(1), None, "the other drive is reachable");
    }

    /// Axis "a" (drive 0) with its positive limit switch on input 11 of the module at
    /// position 1 (normally closed) and its reference on input 0.
    fn module_config() -> Config {
        let text = "[bus]\nkind = \"ethercat\"\ninterface = \"none\"\ncycle_us = 1000\n\
             [[axis]]\nname = \"a\"\ndrive = 0\npdo = \"csp-minimal\"\n\
             homing_required = false\n\
             scaling = { counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }\n\
             max = { speed = 10.0, acceleration = 100.0, jerk = 1000.0 }\n\
             [axis.switches]\ntouch_probe = false\n\
             positive_limit = { from = \"module\", slave = 1, input = 11, normally_closed = true }\n\
             reference = { from = \"module\", slave = 1, input = 0 }\n";
        Config::parse(text, "g.toml").unwrap()
    }

    #[test]
    fn switches_on_a_module_reach_the_axis_with_their_polarity() {
        let mut bus = Image::new(2, 6);
        let mut cycle = Cycle::from_config(&module_config(), &bus).unwrap();
        bus.inputs[0] = enabled_at(0);
        let switches = |c: &Cycle| c.kernel.axis_status(0).unwrap().switches;
        // Input 11 (byte 1, bit 3) high: the closed contact, not actuated; input 0 low.
        bus.inputs[1] = vec![0, 0b1000, 0, 0, 0, 0];
        cycle.read_from(&bus).unwrap();
        cycle.step();
        let s = switches(&cycle);
        assert!(
            !s.positive_limit && !s.reference && !s.negative_limit,
            "{s:?}"
        );
        // Input 11 drops (actuated), input 0 high.
        bus.inputs[1] = vec![1, 0, 0, 0, 0, 0];
        cycle.read_from(&bus).unwrap();
        cycle.step();
        let s = switches(&cycle);
        assert!(
            s.positive_limit && s.reference && !s.negative_limit,
            "{s:?}"
        );
        // The module unreachable: its axis stops with the communication fault.
        bus.faults[1] = Some(Unreachable::new(&"gone"));
        cycle.read_from(&bus).unwrap();
        cycle.step();
        assert_eq!(
            cycle.kernel.axis_status(0).unwrap().error,
            Some(AxisFault::Drive {
                code: COMMUNICATION_FAULT
            })
        );
        // An input the module does not have, a module the bus does not have.
        let mut short = Image::new(2, 6);
        short.inputs[1] = vec![0];
        let e = Cycle::from_config(&module_config(), &short).unwrap_err();
        assert_eq!(
            e.to_string(),
            "axis \"a\": switches.positive_limit: input 11 of slave 1: the bus has 2 slaves, \
             slave 1 1 input bytes"
        );
        assert!(Cycle::from_config(&module_config(), &Image::new(1, 6)).is_err());
    }

    #[test]
    fn a_configuration_that_does_not_fit_its_bus_is_refused_naming_the_axis() {
        let e = Cycle::from_config(&config(), &Image::new(2, 6)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "g.toml: axis \"a\" is on drive 2, but the bus has 2 slaves"
        );
        let mut bus = Image::new(3, 6);
        bus.inputs[2] = vec![0; 4];
        let e = Cycle::from_config(&config(), &bus).unwrap_err();
        assert_eq!(
            e.to_string(),
            "axis \"a\": drive 2 has 4 input bytes on the bus, its PDO layout has 6"
        );
        let mut bus = Image::new(3, 6);
        bus.outputs[0] = vec![0; 5];
        let e = Cycle::from_config(&config(), &bus).unwrap_err();
        assert_eq!(
            e.to_string(),
            "axis \"b\": drive 0 has 5 output bytes on the bus, its PDO layout has 6"
        );
    }
}
