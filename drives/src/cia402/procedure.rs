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
use super::objects::{self, ObjectId};
use super::{ModeOfOperation, Statusword};

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
    /// The power state machine's Quick stop command instead of Enable operation (CiA
    /// 402-2 transition 11): the drive brakes on its own quick-stop ramp (0x6085, as
    /// 0x605A says) in whatever mode it is in. Cleared, the channel enables it again.
    pub quick_stop: bool,
}

impl ProcedureOutputs {
    /// Mode `mode`, no mode-specific bit set.
    pub const fn idle(mode: ModeOfOperation) -> Self {
        Self {
            mode,
            mode_bits: 0,
            quick_stop: false,
        }
    }

    /// The same with `bits` (within [`MODE_BITS`]) set.
    pub const fn with(self, bits: u16) -> Self {
        Self {
            mode_bits: self.mode_bits | (bits & MODE_BITS),
            ..self
        }
    }

    /// The same with the Quick stop command.
    pub const fn quick_stopping(self) -> Self {
        Self {
            quick_stop: true,
            ..self
        }
    }
}

/// An object access a procedure asks for (the master carries it by SDO beside the cycle).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoAccess {
    /// The object.
    pub object: ObjectId,
    /// `Some(v)`: write `v` (its low bytes, as the object's size); `None`: read it.
    pub write: Option<i64>,
}

/// How an [`SdoAccess`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoOutcome {
    /// Done; the value read (0 for a write).
    Done(i64),
    /// The drive aborted it with this CiA 301 code.
    Aborted(u32),
    /// It failed otherwise (no answer, no SDO channel): why.
    Failed(&'static str),
}

/// What a procedure sees each cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProcedureInputs {
    /// The drive's statusword.
    pub statusword: Statusword,
    /// 0x6061 from the process data, where mapped.
    pub mode_display: Option<i8>,
    /// Whether the process data carries 0x6060 (else the mode goes by SDO).
    pub mode_mapped: bool,
    /// 0x6064 position actual value (counts).
    pub position: i32,
    /// Time (s), monotonic.
    pub now_s: f64,
    /// The outcome of the access asked for last, once (the cycle it arrives).
    pub sdo: Option<SdoOutcome>,
}

/// What a procedure wants this cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProcedureStep {
    /// Outputs in place of the CSP ones (`None`: the CSP outputs).
    pub outputs: Option<ProcedureOutputs>,
    /// An object access to start (one at a time: the next step after its outcome).
    pub sdo: Option<SdoAccess>,
    /// The procedure has ended (the drive is back in CSP, or never left it).
    pub end: Option<Result<(), ProcedureFailure>>,
}

impl ProcedureStep {
    /// Keep sending `outputs`, nothing else.
    pub const fn hold(outputs: Option<ProcedureOutputs>) -> Self {
        Self {
            outputs,
            sdo: None,
            end: None,
        }
    }
}

/// Why a procedure failed (the master names the axis and the procedure).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum ProcedureFailure {
    /// The drive did not report what the procedure waits for in time.
    #[error("did not report {missing} within {timeout_s} s")]
    NotReported {
        /// What ("homing attained").
        missing: &'static str,
        /// How long the procedure waited (s).
        timeout_s: f64,
    },
    /// The drive reported that it failed.
    #[error("the drive reports {what}")]
    DriveReports {
        /// What.
        what: &'static str,
    },
    /// The drive refused a value (SDO abort).
    #[error("the drive refused 0x{:04X}:{:02X} = {value} (SDO abort 0x{code:08X})", .object.index, .object.sub)]
    Refused {
        /// The object.
        object: ObjectId,
        /// The value written.
        value: i64,
        /// CiA 301 abort code.
        code: u32,
    },
    /// An access failed otherwise.
    #[error("0x{:04X}:{:02X}: {what}", .object.index, .object.sub)]
    Sdo {
        /// The object.
        object: ObjectId,
        /// Why.
        what: &'static str,
    },
    /// A command (Stop, QuickStop) cancelled it.
    #[error("cancelled by {by}")]
    Cancelled {
        /// The command.
        by: &'static str,
    },
}

/// How long a drive may take to show a new mode of operation in 0x6061 (s). CiA 402 sets
/// no figure; drives switch within a few cycles.
pub const MODE_SWITCH_TIMEOUT_S: f64 = 1.0;

/// Switching the drive's mode of operation and waiting until 0x6061 shows it: by PDO where
/// 0x6060/0x6061 are mapped, else by SDO (write 0x6060, read 0x6061 until it agrees).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModeSwitch {
    /// The mode wanted.
    pub mode: ModeOfOperation,
    phase: SwitchPhase,
    since: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SwitchPhase {
    /// The SDO write of 0x6060 is to be sent (or the PDO carries it).
    Write,
    /// The write is on its way.
    Writing,
    /// Waiting for the display; `reading`: an SDO read of 0x6061 is on its way.
    Display { reading: bool },
}

/// Where a [`ModeSwitch`] is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Switching {
    /// Still switching: send this.
    Pending(ProcedureStep),
    /// The drive shows the mode.
    Done,
    /// It failed.
    Failed(ProcedureFailure),
}

impl ModeSwitch {
    /// A switch to `mode`.
    pub const fn to(mode: ModeOfOperation) -> Self {
        Self {
            mode,
            phase: SwitchPhase::Write,
            since: None,
        }
    }

    /// One cycle; `bits`: the mode-specific bits to send meanwhile (in the new mode).
    pub fn step(&mut self, io: &ProcedureInputs, bits: u16) -> Switching {
        let since = *self.since.get_or_insert(io.now_s);
        let want = self.mode.raw();
        let mut step = ProcedureStep::hold(Some(ProcedureOutputs::idle(self.mode).with(bits)));
        let mode = objects::MODES_OF_OPERATION;
        match self.phase {
            SwitchPhase::Write if io.mode_mapped => {
                self.phase = SwitchPhase::Display { reading: false };
            }
            SwitchPhase::Write => {
                step.sdo = Some(SdoAccess {
                    object: mode,
                    write: Some(i64::from(want)),
                });
                self.phase = SwitchPhase::Writing;
                return Switching::Pending(step);
            }
            SwitchPhase::Writing => match io.sdo {
                None => return Switching::Pending(step),
                Some(SdoOutcome::Done(_)) => self.phase = SwitchPhase::Display { reading: false },
                Some(SdoOutcome::Aborted(code)) => {
                    return Switching::Failed(ProcedureFailure::Refused {
                        object: mode,
                        value: i64::from(want),
                        code,
                    });
                }
                Some(SdoOutcome::Failed(what)) => {
                    return Switching::Failed(ProcedureFailure::Sdo { object: mode, what });
                }
            },
            SwitchPhase::Display { .. } => {}
        }
        // The display, from the process data or read by SDO.
        let shown = match (io.mode_display, self.phase) {
            (Some(m), _) => Some(m),
            (None, SwitchPhase::Display { reading: true }) => match io.sdo {
                Some(outcome) => {
                    self.phase = SwitchPhase::Display { reading: false };
                    match outcome {
                        SdoOutcome::Done(v) => Some(v as i8),
                        _ => None,
                    }
                }
                None => None,
            },
            (None, _) => None,
        };
        if shown == Some(want) {
            return Switching::Done;
        }
        if io.now_s - since > MODE_SWITCH_TIMEOUT_S {
            return Switching::Failed(ProcedureFailure::NotReported {
                missing: mode_shown(self.mode),
                timeout_s: MODE_SWITCH_TIMEOUT_S,
            });
        }
        if io.mode_display.is_none() && self.phase == (SwitchPhase::Display { reading: false }) {
            step.sdo = Some(SdoAccess {
                object: objects::MODES_OF_OPERATION_DISPLAY,
                write: None,
            });
            self.phase = SwitchPhase::Display { reading: true };
        }
        Switching::Pending(step)
    }
}

/// What a drive that does not switch did not report.
const fn mode_shown(mode: ModeOfOperation) -> &'static str {
    match mode {
        ModeOfOperation::Homing => "mode of operation 6 (homing) in 0x6061",
        ModeOfOperation::CyclicSyncPosition => "mode of operation 8 (CSP) in 0x6061",
        _ => "the mode of operation asked for in 0x6061",
    }
}
