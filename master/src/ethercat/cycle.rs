//! One cycle of the EtherCAT master over CSP drives, without the wire: decode every
//! drive's inputs, run the kernel, encode every drive's outputs. The same code runs
//! lockstep (demo, tests) and in real time; nothing here allocates after `new`.

use gantry_kernel::axis::{AxisFeedback, AxisSetpoint};
use gantry_kernel::Kernel;
use thiserror::Error;

use super::cyclic::{encode_outputs, CspChannel, CspInputs};
use super::health::COMMUNICATION_FAULT;

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
    /// A cycle for `kernel`'s axes on these channels.
    pub fn new(kernel: Kernel, channels: Vec<CspChannel>) -> Self {
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
    pub fn channel_mut(&mut self, i: usize) -> Option<&mut CspChannel> {
        self.channels.get_mut(i)
    }

    /// The last decoded inputs of drive `i`.
    pub fn inputs(&self, i: usize) -> Option<&CspInputs> {
        self.inputs.get(i)
    }

    /// Takes drive `i`'s inputs from the process image.
    pub fn read_inputs(&mut self, i: usize, bytes: &[u8]) -> Result<(), CycleError> {
        let channel = self.channels.get(i).ok_or(CycleError::NoDrive(i))?;
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
    /// communication fault at its last known position instead of stale inputs.
    pub fn comm_fault(&mut self, i: usize) -> Result<(), CycleError> {
        let feedback = self.feedback.get_mut(i).ok_or(CycleError::NoDrive(i))?;
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
