//! Taking a drive out of cyclic synchronous position for a procedure it runs by itself,
//! then handing it back: CiA 402 homing mode (6), or a manufacturer's mode (negative
//! values, CiA 402-2 Table 32) for a commissioning measurement.
//!
//! How to use it (the master's `runtime::procedure` does this for drive homing; a new
//! procedure follows the same steps):
//!
//! 1. Lend the axis to its drive (`gantry_kernel::Kernel::lend_to_drive`): the kernel's
//!    set position then tracks the drive's actual position and the axis takes no motion.
//! 2. Write the procedure's parameters by SDO (while the drive is still in CSP).
//! 3. Each cycle, send [`ProcedureOutputs`] instead of the CSP outputs
//!    (`CspChannel::procedure_outputs`): the controlword keeps the drive in Operation
//!    enabled with the procedure's mode-specific bits (4–6, 8 halt, 9) or-ed in, the
//!    target position is the drive's own actual position, and 0x6060 carries the
//!    procedure's mode where the PDO layout maps it (else write 0x6060 by SDO). Wait for
//!    0x6061 (the display, by PDO or SDO) to show the mode before setting bits that start
//!    anything: a drive takes mode-specific bits in the mode it is in (CiA 402-2 §8.4.3).
//! 4. Follow the statusword; end with the mode-specific bits cleared, mode 8 again (PDO or
//!    SDO), and the display showing CSP; then stop sending [`ProcedureOutputs`] and end
//!    the lending (`gantry_kernel::Kernel::end_drive_procedure`). The channel takes the
//!    drive over again as at enabling: the first CSP target is the drive's actual
//!    position, so nothing jumps (the kernel tracked it all along).

use super::controlword::{HALT, MODE_SPECIFIC_4};
use super::ModeOfOperation;

/// Controlword bits whose meaning depends on the mode of operation (CiA 402-2 §8.4.3:
/// 4, 5, 6 operation mode specific, 8 halt, 9 operation mode specific). Everything else
/// in the controlword belongs to the power state machine and stays the channel's.
pub const MODE_BITS: u16 = MODE_SPECIFIC_4 | (1 << 5) | (1 << 6) | HALT | (1 << 9);

/// What the master sends a drive lent to a procedure, in place of its CSP outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProcedureOutputs {
    /// Mode of operation (0x6060), sent by PDO where the layout maps it.
    pub mode: ModeOfOperation,
    /// Mode-specific controlword bits (only [`MODE_BITS`] are taken).
    pub mode_bits: u16,
}

impl ProcedureOutputs {
    /// Mode `mode`, no mode-specific bit set.
    pub const fn idle(mode: ModeOfOperation) -> Self {
        Self { mode, mode_bits: 0 }
    }

    /// The same with `bits` (within [`MODE_BITS`]) set.
    pub const fn with(self, bits: u16) -> Self {
        Self {
            mode: self.mode,
            mode_bits: self.mode_bits | (bits & MODE_BITS),
        }
    }
}
