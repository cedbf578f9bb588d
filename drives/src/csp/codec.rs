//! A CSP drive's process data decoded and encoded through the shared view
//! ([`crate::cia402::image`]).

use crate::cia402::image::{ImageError, InputImage, OutputImage};
use crate::cia402::{Controlword, ModeOfOperation, Statusword};

use super::probe::ProbeInputs;
use super::{CspOffsets, MODE_CSP};

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
    /// Digital inputs 0x60FD, when mapped.
    pub digital_inputs: Option<u32>,
    /// Touch probe status and values, when 0x60B9 is mapped.
    pub probe: Option<ProbeInputs>,
    /// Modes of operation display 0x6061, when mapped.
    pub mode_display: Option<i8>,
}

impl CspInputs {
    /// Decodes the input bytes; an error when there are fewer than the layout maps.
    pub fn decode(at: &CspOffsets, bytes: &[u8]) -> Result<Self, ImageError> {
        let img = InputImage::new_checked(bytes, at.map())?;
        // `CspOffsets` guarantees statusword and position actual value are mapped, and
        // the view has their bytes; the defaults are never taken.
        Ok(Self {
            statusword: img.statusword().unwrap_or_default(),
            position: img.position_actual_value().unwrap_or_default(),
            velocity: img.velocity_actual_value(),
            error_code: img.error_code(),
            digital_inputs: img.digital_inputs(),
            mode_display: img.modes_of_operation_display(),
            probe: img.touch_probe_status().map(|status| ProbeInputs {
                status,
                values: [
                    img.touch_probe_pos1_pos_value(),
                    img.touch_probe_pos1_neg_value(),
                    img.touch_probe_pos2_pos_value(),
                    img.touch_probe_pos2_neg_value(),
                ],
            }),
        })
    }
}

/// Encodes the outputs: controlword, target position, and mode CSP where 0x6060 is
/// mapped. Writes nothing when the buffer is shorter than the layout's outputs (the cycle
/// checks [`CspOffsets::output_bytes`] first and reports the drive).
pub fn encode_outputs(at: &CspOffsets, bytes: &mut [u8], cw: Controlword, target: i32) {
    if let Ok(mut img) = OutputImage::new_checked(bytes, at.map()) {
        img.set_controlword(cw);
        img.set_target_position(target);
        img.set_modes_of_operation(MODE_CSP);
    }
}

/// Encodes the outputs of a drive lent to a procedure
/// ([`crate::cia402::procedure::ProcedureOutputs`]): controlword, target position (the
/// drive's own position) and the procedure's mode where 0x6060 is mapped.
pub fn encode_procedure_outputs(
    at: &CspOffsets,
    bytes: &mut [u8],
    cw: Controlword,
    target: i32,
    mode: ModeOfOperation,
) {
    if let Ok(mut img) = OutputImage::new_checked(bytes, at.map()) {
        img.set_controlword(cw);
        img.set_target_position(target);
        img.set_modes_of_operation(mode.raw());
    }
}

/// Encodes 0x60B8 Touch probe function where the layout maps it (see
/// [`super::CspChannel::probe_function`]).
pub fn encode_touch_probe(at: &CspOffsets, bytes: &mut [u8], function: u16) {
    if let Ok(mut img) = OutputImage::new_checked(bytes, at.map()) {
        img.set_touch_probe_function(function);
    }
}
