//! One drive's share of a cycle in cyclic synchronous position mode: decode its inputs
//! into kernel feedback, and turn the kernel's set values into its outputs — the
//! controlword from the shared CiA-402 table, the target position in counts.
//!
//! Process data of a CSP drive (the mapping the simulated servo has; real drives are
//! mapped to it through CoE in PreOp): outputs `0x6040 controlword: u16, 0x607A target
//! position: i32`; inputs `0x6041 statusword: u16, 0x6064 position actual value: i32`.

use gantry_drives::cia402::{next_command, Controlword, State, Statusword, Target};
use gantry_kernel::axis::{AxisFeedback, AxisSetpoint};
use gantry_kernel::mechanics::Scaling;

/// Error code reported for a faulted drive whose 0x603F error code is not in the process
/// data (CiA 301 generic error 0xFF00 "device specific"); the real code needs an SDO read.
pub const FAULT_CODE_NOT_MAPPED: u16 = 0xFF00;

/// Bytes of a CSP drive's outputs.
pub const OUTPUT_BYTES: usize = 6;
/// Bytes of a CSP drive's inputs.
pub const INPUT_BYTES: usize = 6;

/// Decoded inputs of a CSP drive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CspInputs {
    /// Statusword.
    pub statusword: Statusword,
    /// Position actual value (counts).
    pub position: i32,
}

impl CspInputs {
    /// Decodes the input bytes; `None` when there are too few.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let b = bytes.get(..INPUT_BYTES)?;
        Some(Self {
            statusword: Statusword(u16::from_le_bytes([b[0], b[1]])),
            position: i32::from_le_bytes([b[2], b[3], b[4], b[5]]),
        })
    }
}

/// Encodes outputs; does nothing when the buffer is too short.
pub fn encode_outputs(bytes: &mut [u8], cw: Controlword, target: i32) {
    if let Some(b) = bytes.get_mut(..OUTPUT_BYTES) {
        b[0..2].copy_from_slice(&cw.0.to_le_bytes());
        b[2..6].copy_from_slice(&target.to_le_bytes());
    }
}

/// The master side of one drive.
#[derive(Clone, Debug)]
pub struct CspChannel {
    /// Units ⇄ counts of the axis on this drive.
    pub scaling: Scaling,
    last_cw: Controlword,
}

impl CspChannel {
    /// A channel with the axis' scaling.
    pub fn new(scaling: Scaling) -> Self {
        Self {
            scaling,
            last_cw: Controlword(0),
        }
    }

    /// Kernel feedback from the drive's inputs.
    pub fn feedback(&self, inputs: &CspInputs) -> AxisFeedback {
        let state = inputs.statusword.state();
        AxisFeedback {
            position: self.scaling.counts_to_units(i64::from(inputs.position)),
            velocity: 0.0,
            operation_enabled: state == Some(State::OperationEnabled),
            fault: matches!(state, Some(State::Fault | State::FaultReactionActive))
                .then_some(FAULT_CODE_NOT_MAPPED),
        }
    }

    /// The outputs for this cycle: one step of the power state machine towards what the
    /// kernel wants, and the set position — or the actual position while the drive is not
    /// enabled, so that enabling never jumps.
    pub fn outputs(&mut self, sp: &AxisSetpoint, inputs: &CspInputs) -> (Controlword, i32) {
        let state = inputs
            .statusword
            .state()
            .unwrap_or(State::NotReadyToSwitchOn);
        let target = if sp.enable {
            Target::Enabled
        } else {
            Target::Disabled
        };
        // Fault resets are sent only when the axis asks (its Reset).
        let cmd = next_command(state, target, sp.reset_fault, self.last_cw);
        self.last_cw = Controlword::of(cmd);
        let position = if state == State::OperationEnabled && sp.enable {
            i32::try_from(self.scaling.units_to_counts(sp.position)).unwrap_or(inputs.position)
        } else {
            inputs.position
        };
        (self.last_cw, position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_kernel::mechanics::ScalingConfig;

    fn channel() -> CspChannel {
        CspChannel::new(
            Scaling::new(ScalingConfig {
                counts_per_motor_rev: 10_000,
                motor_revs: 1,
                load_revs: 1,
                units_per_load_rev: 10.0,
                invert: false,
            })
            .unwrap(),
        )
    }

    #[test]
    fn inputs_round_trip_and_short_buffers_are_refused() {
        let mut out = [0u8; 6];
        encode_outputs(&mut out, Controlword(0x0F), -5);
        assert_eq!(out, [0x0F, 0, 0xFB, 0xFF, 0xFF, 0xFF]);
        let i = CspInputs::decode(&[0x37, 0x06, 0x10, 0x27, 0, 0]).unwrap();
        assert_eq!(i.statusword.state(), Some(State::OperationEnabled));
        assert_eq!(i.position, 10_000);
        assert!(CspInputs::decode(&[1, 2, 3]).is_none());
        let fb = channel().feedback(&i);
        assert_eq!(fb.position, 10.0);
        assert!(fb.operation_enabled);
    }

    #[test]
    fn holds_actual_until_enabled_then_follows_the_set_value() {
        let mut ch = channel();
        let sp = AxisSetpoint {
            position: 2.0,
            enable: true,
            ..AxisSetpoint::default()
        };
        let disabled = CspInputs {
            statusword: Statusword(0x0250),
            position: 777,
        };
        assert_eq!(ch.outputs(&sp, &disabled), (Controlword(0x06), 777));
        let enabled = CspInputs {
            statusword: Statusword(0x0637),
            position: 777,
        };
        assert_eq!(ch.outputs(&sp, &enabled), (Controlword(0x0F), 2000));
        let off = AxisSetpoint {
            enable: false,
            ..sp
        };
        assert_eq!(ch.outputs(&off, &enabled).0, Controlword(0x00));
    }
}
