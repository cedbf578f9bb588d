//! Procedures a drive runs by itself, out of CSP, run by the cycle thread: CiA 402 drive
//! homing today; a commissioning measurement in a manufacturer's mode is the next one.
//!
//! The hand-over (see [`gantry_drives::cia402::procedure`]): the engine lends the axis to
//! its drive in the kernel (its set position tracks the drive), steps the procedure's
//! sans-I/O sequencer once per cycle on the drive's inputs, sends the outputs it asks for
//! in place of the CSP ones ([`super::cycle::Cycle::set_procedure_outputs`]), carries its
//! object accesses by SDO beside the cycle (before the application's; one at a time),
//! and when it ends takes the drive back and ends the lending with its outcome. Power off
//! or a drive fault end the lending in the kernel: the drive gets its CSP outputs again at
//! once (and, where 0x6060 is not in the process data, 0x6060 = 8 by SDO). Stop and
//! QuickStop cancel it: the sequencer halts the drive and hands it back.
//!
//! To add a procedure: a sans-I/O sequencer in `gantry_drives` with a
//! `step(&ProcedureInputs) -> ProcedureStep` and a `cancel(by)`, and a variant of
//! [`DriveProcedure`] for it (Copy, fixed size: it crosses to the cycle thread in a
//! request and lives there without allocating).

use gantry_drives::canopen::sdo::abort::AbortCode;
use gantry_drives::cia402::homing::DriveHoming;
use gantry_drives::cia402::procedure::{
    ModeSwitch, ProcedureFailure, ProcedureInputs, ProcedureStep, SdoAccess, SdoOutcome,
};
use gantry_drives::commutation::CommutationProcedure;
use gantry_kernel::axis::lend::{DriveProcedureError, DriveProcedureFailure};

use super::sdo::{SdoBuffer, SdoError, SdoTransfer};

/// A procedure a drive runs by itself.
// Inline on purpose (the commutation measurement carries its samples' sums): boxed, the
// cycle thread would free it.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DriveProcedure {
    /// CiA 402 homing mode.
    Homing(DriveHoming),
    /// The commutation measurement in the manufacturer's open-loop current mode
    /// (`gantry_drives::commutation`).
    Commutation(CommutationProcedure),
}

impl DriveProcedure {
    /// Its name in messages.
    pub const fn name(&self) -> &'static str {
        match self {
            Self::Homing(_) => "drive homing",
            Self::Commutation(_) => "commutation measurement",
        }
    }

    /// Whether it homes the axis (the axis is in Homing meanwhile).
    pub const fn homes(&self) -> bool {
        matches!(self, Self::Homing(_))
    }

    /// Its method, where it has one.
    pub const fn method(&self) -> Option<i16> {
        match self {
            Self::Homing(h) => Some(h.params().method as i16),
            Self::Commutation(_) => None,
        }
    }

    /// What it is doing now.
    pub const fn phase_name(&self) -> &'static str {
        match self {
            Self::Homing(h) => h.phase_name(),
            Self::Commutation(c) => c.phase_name(),
        }
    }

    fn step(&mut self, io: &ProcedureInputs) -> ProcedureStep {
        match self {
            Self::Homing(h) => h.step(io),
            Self::Commutation(c) => c.step(io),
        }
    }

    fn cancel(&mut self, by: &'static str) {
        match self {
            Self::Homing(h) => h.cancel(by),
            Self::Commutation(c) => c.cancel(by),
        }
    }

    /// The kernel's error for `f`.
    pub fn error(&self, f: ProcedureFailure) -> DriveProcedureError {
        let failure = match f {
            ProcedureFailure::NotReported { missing, timeout_s } => {
                DriveProcedureFailure::NotReported { missing, timeout_s }
            }
            ProcedureFailure::DriveReports { what } => DriveProcedureFailure::DriveReports { what },
            ProcedureFailure::Refused {
                object,
                value,
                code,
            } => DriveProcedureFailure::Refused {
                index: object.index,
                sub: object.sub,
                value,
                code,
                text: AbortCode(code).text(),
            },
            ProcedureFailure::Sdo { object, what } => DriveProcedureFailure::Sdo {
                index: object.index,
                sub: object.sub,
                what,
            },
            ProcedureFailure::Cancelled { by } => DriveProcedureFailure::Cancelled { by },
        };
        DriveProcedureError {
            procedure: self.name(),
            method: self.method(),
            failure,
        }
    }
}

/// A procedure running on one axis' drive, in the engine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Running {
    pub procedure: DriveProcedure,
    /// The access the sequencer asked for, not yet started.
    pub wanted: Option<SdoAccess>,
    /// The access on the bus.
    pub active: Option<SdoAccess>,
    /// The outcome of the last access, for the next step.
    pub outcome: Option<SdoOutcome>,
    /// The kernel ended the lending (power off, a fault): only the return to CSP by SDO
    /// is left, if any.
    pub ended: bool,
    /// That return.
    pub restore: Option<ModeSwitch>,
}

impl Running {
    pub fn new(procedure: DriveProcedure) -> Self {
        Self {
            procedure,
            wanted: None,
            active: None,
            outcome: None,
            ended: false,
            restore: None,
        }
    }

    /// One cycle of the procedure.
    pub fn step(&mut self, io: &ProcedureInputs, cancel: Option<&'static str>) -> ProcedureStep {
        if let Some(by) = cancel {
            self.procedure.cancel(by);
        }
        let step = self.procedure.step(io);
        self.wanted = step.sdo;
        step
    }

    /// One cycle of the return to CSP by SDO after the kernel ended the lending; true
    /// once it is over (done or failed: the drive is the kernel's either way).
    pub fn restore_step(&mut self, io: &ProcedureInputs) -> bool {
        use gantry_drives::cia402::procedure::Switching;
        let Some(switch) = self.restore.as_mut() else {
            return true;
        };
        match switch.step(io, 0) {
            Switching::Pending(step) => {
                self.wanted = step.sdo;
                false
            }
            Switching::Done | Switching::Failed(_) => true,
        }
    }
}

/// Bytes of the buffer the engine lends the procedures' transfers (their objects are
/// numbers of up to 8 bytes; an object that turns out larger is refused as such).
pub(crate) const SDO_BYTES: usize = 256;

/// The SDO transfer for `access` on drive `drive`, its data put in `buffer`.
pub(crate) fn transfer(drive: usize, access: &SdoAccess, buffer: &mut SdoBuffer) -> SdoTransfer {
    let o = access.object;
    match access.write {
        Some(v) => {
            let bytes = v.to_le_bytes();
            if !buffer.fill(bytes.get(..o.kind.size()).unwrap_or_default()) {
                buffer.clear();
            }
            SdoTransfer::download(drive, o.index, o.sub)
        }
        None => {
            buffer.clear();
            SdoTransfer::upload(drive, o.index, o.sub)
        }
    }
}

/// The outcome of `access` from the transfer's result (the bytes uploaded).
pub(crate) fn outcome(access: &SdoAccess, result: Result<&[u8], SdoError>) -> SdoOutcome {
    match result {
        Ok(got) => {
            let size = access.object.kind.size();
            let mut b = [0u8; 8];
            let n = got.len().min(size).min(8);
            if let (Some(dst), Some(src)) = (b.get_mut(..n), got.get(..n)) {
                dst.copy_from_slice(src);
            }
            let shift = 64 - 8 * (n.max(1) as u32);
            let signed = matches!(
                access.object.kind,
                gantry_drives::cia402::objects::DataType::I8
                    | gantry_drives::cia402::objects::DataType::I16
                    | gantry_drives::cia402::objects::DataType::I32
            );
            let raw = i64::from_le_bytes(b);
            let v = if signed { (raw << shift) >> shift } else { raw };
            SdoOutcome::Done(v)
        }
        Err(e) => failure(&e),
    }
}

/// An SDO error as a procedure sees it.
pub(crate) fn failure(e: &SdoError) -> SdoOutcome {
    match e {
        SdoError::Aborted { code, .. } => SdoOutcome::Aborted(code.0),
        SdoError::NotSupported => {
            SdoOutcome::Failed("this bus does not carry SDO transfers while the cycle runs")
        }
        SdoError::Busy => SdoOutcome::Failed("another SDO transfer is running"),
        SdoError::NoDrive { .. } => SdoOutcome::Failed("no drive at that bus position"),
        SdoError::NoChannel { .. } => {
            SdoOutcome::Failed("the drive has no SDO channel (EtherCAT: no CoE mailbox)")
        }
        SdoError::TimedOut { .. } => SdoOutcome::Failed("the drive did not answer the SDO in time"),
        SdoError::TooLarge { .. } => SdoOutcome::Failed("the object is larger than expected"),
        SdoError::Protocol { what, .. } => SdoOutcome::Failed(what),
    }
}
