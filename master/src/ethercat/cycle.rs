//! One cycle of the EtherCAT master over CSP drives, without the wire: decode every
//! drive's inputs, run the kernel, encode every drive's outputs. The same code runs
//! lockstep (demo, tests) and in real time; nothing here allocates after `new`.

use gantry_kernel::axis::{AxisFeedback, AxisSetpoint};
use gantry_kernel::Kernel;
use thiserror::Error;

use super::health::COMMUNICATION_FAULT;
use crate::drive_axis::AxisChannel;
use gantry_drives::csp::{encode_outputs, CspChannel, CspInputs};

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

/// The kernel and one CSP channel per axis (axis `i` on drive `i`).
#[derive(Debug)]
pub struct CspCycle {
    /// The motion kernel.
    pub kernel: Kernel,
    channels: Vec<CspChannel>,
    inputs: Vec<CspInputs>,
    feedback: Vec<AxisFeedback>,
    setpoints: Vec<AxisSetpoint>,
}

impl CspCycle {
    /// A cycle for `kernel`'s axes on these channels. Each channel counts its axis'
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
            channels,
            inputs: vec![CspInputs::default(); n],
            feedback: vec![AxisFeedback::default(); n],
            setpoints: vec![AxisSetpoint::default(); n],
        }
    }

    /// Number of drives.
    pub fn len(&self) -> usize {
        self.channels.len()
    }

    /// Whether there is no drive.
    pub fn is_empty(&self) -> bool {
        self.channels.is_empty()
    }

    /// The channel of drive `i`.
    pub fn channel(&self, i: usize) -> Option<&CspChannel> {
        self.channels.get(i)
    }

    /// The channel of drive `i`, to change.
    pub fn channel_mut(&mut self, i: usize) -> Option<&mut CspChannel> {
        self.channels.get_mut(i)
    }

    /// The last decoded inputs of drive `i`.
    pub fn inputs(&self, i: usize) -> Option<&CspInputs> {
        self.inputs.get(i)
    }

    /// Takes drive `i`'s inputs from the process image.
    pub fn read_inputs(&mut self, i: usize, bytes: &[u8]) -> Result<(), CycleError> {
        let channel = self.channels.get_mut(i).ok_or(CycleError::NoDrive(i))?;
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
            .last_target_position();
        let feedback = self.feedback.get_mut(i).ok_or(CycleError::NoDrive(i))?;
        feedback.position = held;
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
            self.channels.get_mut(i).ok_or(CycleError::NoDrive(i))?,
            self.setpoints.get(i).ok_or(CycleError::NoDrive(i))?,
            self.inputs.get(i).ok_or(CycleError::NoDrive(i))?,
        );
        let (cw, target) = channel.outputs(sp, inputs);
        encode_outputs(&channel.offsets, bytes, cw, target);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::csp::COUNT_RANGE_FAULT;
    use gantry_drives::scaling::{Scaling, ScalingConfig};
    use gantry_kernel::axis::command::{Command, MoveDirection, MoveVelocity, PowerCommand};
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
        let mut c = CspCycle::new(kernel, vec![CspChannel::new(scaling)]);
        c.kernel
            .command(0, Command::Power(PowerCommand::Enable))
            .unwrap();
        let mut out = [0u8; 6];
        let cycle = |c: &mut CspCycle, out: &mut [u8; 6]| {
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
        let mut c = CspCycle::new(kernel, vec![CspChannel::new(scaling)]);
        c.kernel
            .command(0, Command::Power(PowerCommand::Enable))
            .unwrap();
        // The drive: enabled, its position actual value two cycles behind its target.
        let mut sent: Vec<i32> = vec![0, 0];
        let mut out = [0u8; 6];
        let mut cycle = |c: &mut CspCycle, inputs: Option<[u8; 6]>, sent: &mut Vec<i32>| {
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
