//! One drive's share of a cycle in cyclic synchronous position mode: decode its inputs
//! into kernel feedback, and turn the kernel's set values into its outputs — the
//! controlword from the shared CiA-402 table, the target position in counts.
//!
//! Where each object sits comes from the drive's PDO layout (mapped by SDO in PreOp, see
//! `mapping`); a drive left with its power-up mapping exchanges the minimal CSP set:
//! outputs `0x6040 controlword: u16, 0x607A target position: i32`; inputs `0x6041
//! statusword: u16, 0x6064 position actual value: i32`.

use gantry_drives::cia402::objects;
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::cia402::{next_command, Controlword, State, Statusword, Target};
use gantry_kernel::axis::{AxisFeedback, AxisSetpoint};
use gantry_kernel::mechanics::Scaling;
use thiserror::Error;

/// Error code reported for a faulted drive whose 0x603F error code is not in the process
/// data (CiA 301 generic error 0xFF00 "device specific"); the real code needs an SDO read.
pub const FAULT_CODE_NOT_MAPPED: u16 = 0xFF00;

/// Modes of operation: cyclic synchronous position.
pub const MODE_CSP: i8 = 8;

/// A layout that CSP cannot run on.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
#[error("the PDO layout lacks {object:#06x} {name}, which CSP needs")]
pub struct LayoutError {
    /// The missing object.
    pub object: u16,
    /// Its name.
    pub name: &'static str,
}

/// Byte offsets of the objects CSP uses in one drive's process data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CspOffsets {
    controlword: usize,
    target: usize,
    mode: Option<usize>,
    /// Bytes of the outputs.
    pub output_bytes: usize,
    statusword: usize,
    position: usize,
    velocity: Option<usize>,
    error_code: Option<usize>,
    /// Bytes of the inputs.
    pub input_bytes: usize,
}

impl CspOffsets {
    /// The offsets in `layout`; the four objects CSP cannot do without must be there.
    pub fn of(layout: &PdoLayout) -> Result<Self, LayoutError> {
        let need = |offset: Option<usize>, o: objects::ObjectId| {
            offset.ok_or(LayoutError {
                object: o.index,
                name: o.name,
            })
        };
        Ok(Self {
            controlword: need(layout.output_offset(0x6040), objects::CONTROLWORD)?,
            target: need(layout.output_offset(0x607A), objects::TARGET_POSITION)?,
            mode: layout.output_offset(0x6060),
            output_bytes: layout.output_bytes(),
            statusword: need(layout.input_offset(0x6041), objects::STATUSWORD)?,
            position: need(layout.input_offset(0x6064), objects::POSITION_ACTUAL_VALUE)?,
            velocity: layout.input_offset(0x606C),
            error_code: layout.input_offset(0x603F),
            input_bytes: layout.input_bytes(),
        })
    }

    /// The power-up mapping of a CSP drive.
    pub fn minimal() -> Self {
        Self {
            controlword: 0,
            target: 2,
            mode: None,
            output_bytes: 6,
            statusword: 0,
            position: 2,
            velocity: None,
            error_code: None,
            input_bytes: 6,
        }
    }
}

fn get<const N: usize>(bytes: &[u8], at: usize) -> Option<[u8; N]> {
    bytes.get(at..at + N)?.try_into().ok()
}

fn set(bytes: &mut [u8], at: usize, value: &[u8]) {
    if let Some(dst) = bytes.get_mut(at..at + value.len()) {
        dst.copy_from_slice(value);
    }
}

/// Decoded inputs of a CSP drive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CspInputs {
    /// Statusword.
    pub statusword: Statusword,
    /// Position actual value (counts).
    pub position: i32,
    /// Velocity actual value (counts/s), when mapped.
    pub velocity: Option<i32>,
    /// Error code 0x603F, when mapped.
    pub error_code: Option<u16>,
}

impl CspInputs {
    /// Decodes the input bytes; `None` when there are too few.
    pub fn decode(at: &CspOffsets, bytes: &[u8]) -> Option<Self> {
        if bytes.len() < at.input_bytes {
            return None;
        }
        Some(Self {
            statusword: Statusword(u16::from_le_bytes(get(bytes, at.statusword)?)),
            position: i32::from_le_bytes(get(bytes, at.position)?),
            velocity: at
                .velocity
                .and_then(|o| get(bytes, o))
                .map(i32::from_le_bytes),
            error_code: at
                .error_code
                .and_then(|o| get(bytes, o))
                .map(u16::from_le_bytes),
        })
    }
}

/// Encodes outputs; does nothing when the buffer is too short.
pub fn encode_outputs(at: &CspOffsets, bytes: &mut [u8], cw: Controlword, target: i32) {
    if bytes.len() < at.output_bytes {
        return;
    }
    set(bytes, at.controlword, &cw.0.to_le_bytes());
    set(bytes, at.target, &target.to_le_bytes());
    if let Some(m) = at.mode {
        set(bytes, m, &MODE_CSP.to_le_bytes());
    }
}

/// The master side of one drive.
#[derive(Clone, Debug)]
pub struct CspChannel {
    /// Units ⇄ counts of the axis on this drive.
    pub scaling: Scaling,
    /// Where the objects sit in the drive's process data.
    pub offsets: CspOffsets,
    last_cw: Controlword,
}

impl CspChannel {
    /// A channel with the axis' scaling, for a drive with its power-up mapping.
    pub fn new(scaling: Scaling) -> Self {
        Self {
            scaling,
            offsets: CspOffsets::minimal(),
            last_cw: Controlword(0),
        }
    }

    /// A channel for a drive mapped to `layout`.
    pub fn with_layout(scaling: Scaling, layout: &PdoLayout) -> Result<Self, LayoutError> {
        Ok(Self {
            offsets: CspOffsets::of(layout)?,
            ..Self::new(scaling)
        })
    }

    /// Decodes this drive's inputs.
    pub fn decode(&self, bytes: &[u8]) -> Option<CspInputs> {
        CspInputs::decode(&self.offsets, bytes)
    }

    /// Kernel feedback from the drive's inputs.
    pub fn feedback(&self, inputs: &CspInputs) -> AxisFeedback {
        let state = inputs.statusword.state();
        AxisFeedback {
            position: self.scaling.counts_to_units(i64::from(inputs.position)),
            velocity: inputs.velocity.map_or(0.0, |v| {
                self.scaling.counts_to_units(i64::from(v)) - self.scaling.counts_to_units(0)
            }),
            operation_enabled: state == Some(State::OperationEnabled),
            fault: matches!(state, Some(State::Fault | State::FaultReactionActive)).then_some(
                inputs
                    .error_code
                    .filter(|c| *c != 0)
                    .unwrap_or(FAULT_CODE_NOT_MAPPED),
            ),
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
        let min = CspOffsets::minimal();
        let mut out = [0u8; 6];
        encode_outputs(&min, &mut out, Controlword(0x0F), -5);
        assert_eq!(out, [0x0F, 0, 0xFB, 0xFF, 0xFF, 0xFF]);
        let i = CspInputs::decode(&min, &[0x37, 0x06, 0x10, 0x27, 0, 0]).unwrap();
        assert_eq!(i.statusword.state(), Some(State::OperationEnabled));
        assert_eq!(i.position, 10_000);
        assert!(CspInputs::decode(&min, &[1, 2, 3]).is_none());
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
            ..CspInputs::default()
        };
        assert_eq!(ch.outputs(&sp, &disabled), (Controlword(0x06), 777));
        let enabled = CspInputs {
            statusword: Statusword(0x0637),
            position: 777,
            ..CspInputs::default()
        };
        assert_eq!(ch.outputs(&sp, &enabled), (Controlword(0x0F), 2000));
        let off = AxisSetpoint {
            enable: false,
            ..sp
        };
        assert_eq!(ch.outputs(&off, &enabled).0, Controlword(0x00));
    }

    #[test]
    fn a_full_layout_carries_mode_velocity_and_the_error_code() {
        let layout = PdoLayout::csp();
        let ch = CspChannel::with_layout(channel().scaling, &layout).unwrap();
        let mut out = [0u8; 7];
        encode_outputs(&ch.offsets, &mut out, Controlword(0x0F), 1);
        assert_eq!(out, [0x0F, 0, 1, 0, 0, 0, 8], "mode CSP in the last byte");
        // statusword Fault, position 0, velocity 1000 counts/s, torque, error 0x8700, mode.
        let mut inp = [0u8; 15];
        inp[0..2].copy_from_slice(&0x0218u16.to_le_bytes());
        inp[6..10].copy_from_slice(&1000i32.to_le_bytes());
        inp[12..14].copy_from_slice(&0x8700u16.to_le_bytes());
        let i = ch.decode(&inp).unwrap();
        let fb = ch.feedback(&i);
        assert_eq!(fb.fault, Some(0x8700));
        assert!(
            (fb.velocity - 1.0).abs() < 1e-12,
            "1000 counts/s = 1 unit/s"
        );
        let no_target = PdoLayout {
            outputs: vec![objects::CONTROLWORD],
            inputs: layout.inputs.clone(),
        };
        assert_eq!(
            CspChannel::with_layout(channel().scaling, &no_target)
                .unwrap_err()
                .to_string(),
            "the PDO layout lacks 0x607a Target position, which CSP needs"
        );
    }
}
