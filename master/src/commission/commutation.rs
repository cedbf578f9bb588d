//! `gantry commission AXIS commutation`: the commutation offset measured in the seed's
//! dynamic mode (`gantry_drives::commutation`) on a running axis, through what its drive
//! exposes — the open-loop current-vector mode and its objects, by SDO, and the position
//! actual value — then written to the drive.
//!
//! The axis must be **disabled** to start: a drive whose commutation is unknown cannot hold
//! its motor in a closed loop (past 90° electrical it turns it the wrong way and runs it
//! away), so it is never enabled in CSP before the offset is known. The steps: with the
//! power off, the vector's current and angle set to 0 and 0x6060 to the open-loop mode
//! (0x6061 awaited); the axis enabled (the drive energises a vector of no current) and
//! lent to its drive (`Controller::lend_to_drive`: the drive kept in Operation enabled,
//! its target its own position, the kernel's set position tracking it); then the
//! measurement's writes go out one by one by SDO while 0x6064 is read back. At the end —
//! done, failed or cancelled alike — the current is switched off, the lending ended, the
//! axis disabled and 0x6060 set back to CSP: the axis is left **disabled**, as the seed's
//! `MeasureCommutationOffset` leaves it (`when xAxis1.State.IsDisabled continue`), to be
//! enabled again with the offset now in the drive.

use std::time::{Duration, Instant};

use gantry_drives::cia402::mode::OPEN_LOOP_CURRENT_VECTOR;
use gantry_drives::cia402::objects::{self, ObjectId};
use gantry_drives::cia402::procedure::ProcedureOutputs;
use gantry_drives::cia402::{ModeOfOperation, State};
use gantry_drives::commutation::{
    CommutationConfig, CommutationError, CommutationMeasurement, Phase, Step,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::lend::{DriveProcedureError, DriveProcedureFailure};
use gantry_kernel::axis::state::AxisState;

use super::{CommissionError, Context, ProcedureOutcome, POLL};
use crate::runtime::controller::CommandHandle;
use crate::runtime::sdo::{SdoData, SdoError, SdoRequest};

/// What the lending is called in the axis' messages.
pub const PROCEDURE: &str = "commutation measurement";

/// How often the measurement looks at the rotor (and writes the vector's angle at most).
const MEASURE_POLL: Duration = Duration::from_millis(4);

/// How often the drive's power state is looked at while it changes.
const SETTLE_POLL: Duration = Duration::from_millis(10);

/// How long the drive may take to show a mode it was told (0x6061).
const MODE_TIMEOUT: Duration = Duration::from_secs(2);

/// The measurement's parameters from the configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommutationSettings {
    /// The axis' drive, by its bus position (for SDO).
    pub drive: usize,
    /// Encoder counts per motor revolution (the axis' scaling).
    pub counts_per_rev: u32,
    /// Current of the vector (per mille of the rated torque's); `None`: the default 300.
    pub current_per_mille: Option<u16>,
    /// Drive counts per axis unit (signed: negative for an inverted axis), to follow the
    /// rotor in the snapshot's actual position between SDO reads of 0x6064.
    pub counts_per_unit: f64,
}

/// A running measurement's link to its axis.
struct Run<'a> {
    cx: &'a Context,
    s: CommutationSettings,
    lent: Option<CommandHandle>,
    /// The drive was switched to the open-loop mode.
    switched: bool,
}

/// What a cancelled or failed measurement leaves the axis in.
const LEFT: &str = "the axis is disabled, its drive's current off and in CSP again";

impl Run<'_> {
    fn sdo_error(&self, o: ObjectId, source: SdoError) -> CommissionError {
        CommissionError::Sdo {
            axis: self.cx.name.clone(),
            procedure: PROCEDURE,
            object: format!("0x{:04X}:{:02X} {}", o.index, o.sub, o.name),
            source,
        }
    }

    /// One SDO transfer, waited for (a transfer already on the bus is waited out).
    fn transfer(&self, o: ObjectId, request: SdoRequest) -> Result<SdoData, CommissionError> {
        let end = Instant::now() + Duration::from_secs(10);
        loop {
            let h = self.cx.ctl.sdo(request).map_err(|e| self.cx.control(e))?;
            let r = h
                .wait(Duration::from_secs(5))
                .map_err(|e| self.cx.control(e))?;
            match r {
                Err(SdoError::Busy) if Instant::now() < end => std::thread::sleep(POLL),
                Err(e) => return Err(self.sdo_error(o, e)),
                Ok(d) => return Ok(d),
            }
        }
    }

    fn write(&self, o: ObjectId, value: i64) -> Result<(), CommissionError> {
        let bytes = value.to_le_bytes();
        let data = bytes
            .get(..o.kind.size())
            .and_then(SdoData::new)
            .unwrap_or_default();
        self.transfer(o, SdoRequest::download(self.s.drive, o.index, o.sub, data))?;
        Ok(())
    }

    fn read(&self, o: ObjectId) -> Result<i64, CommissionError> {
        let d = self.transfer(o, SdoRequest::upload(self.s.drive, o.index, o.sub))?;
        let b = d.as_slice();
        let mut raw = [0u8; 8];
        let n = b.len().min(o.kind.size()).min(8);
        if let (Some(dst), Some(src)) = (raw.get_mut(..n), b.get(..n)) {
            dst.copy_from_slice(src);
        }
        let v = i64::from_le_bytes(raw);
        let signed = matches!(
            o.kind,
            objects::DataType::I8 | objects::DataType::I16 | objects::DataType::I32
        );
        Ok(if signed && n > 0 && n < 8 {
            let shift = 64 - 8 * n as u32;
            (v << shift) >> shift
        } else {
            v
        })
    }

    /// The lending still holds: not ended by a Stop, a power off or a fault.
    fn still_lent(&self) -> Result<(), CommissionError> {
        let Some(h) = &self.lent else {
            return Ok(());
        };
        match h.status() {
            Some(CommandStatus::Error(source)) => Err(CommissionError::Command {
                axis: self.cx.name.clone(),
                procedure: PROCEDURE,
                command: PROCEDURE,
                source: Box::new(source),
            }),
            Some(CommandStatus::Aborted) | Some(CommandStatus::Expired) => Err(self
                .cx
                .cancelled_error("by a stop of the axis".into(), LEFT)),
            _ => Ok(()),
        }
    }

    /// Sets the mode by SDO and waits for 0x6061 to show it.
    fn mode(&self, mode: ModeOfOperation) -> Result<(), CommissionError> {
        self.write(objects::MODES_OF_OPERATION, i64::from(mode.raw()))?;
        let end = Instant::now() + MODE_TIMEOUT;
        loop {
            let shown = self.read(objects::MODES_OF_OPERATION_DISPLAY)?;
            if shown == i64::from(mode.raw()) {
                return Ok(());
            }
            if Instant::now() >= end {
                return Err(CommissionError::Drive {
                    axis: self.cx.name.clone(),
                    procedure: PROCEDURE,
                    what: format!(
                        "the drive shows mode {shown} (0x6061), not {} ({}), after {} s",
                        mode.raw(),
                        mode.short(),
                        MODE_TIMEOUT.as_secs()
                    ),
                });
            }
            std::thread::sleep(POLL);
        }
    }

    /// The measurement proper, between lending and handing back.
    fn measure(&mut self) -> Result<ProcedureOutcome, CommissionError> {
        let cx = self.cx;
        let pole_pairs = self.read(objects::MOTOR_POLE_PAIRS)?;
        let mut config = CommutationConfig::new(self.s.counts_per_rev, pole_pairs as u32);
        if let Some(c) = self.s.current_per_mille {
            config.current_per_mille = c;
        }
        let mut m =
            CommutationMeasurement::new(config).map_err(|source| CommissionError::Measurement {
                axis: cx.name.clone(),
                source,
            })?;
        let state = cx
            .ctl
            .snapshot()
            .axes
            .get(cx.axis)
            .map(|a| a.state)
            .unwrap_or(AxisState::ErrorStop);
        if state != AxisState::Disabled {
            return Err(CommissionError::Drive {
                axis: cx.name.clone(),
                procedure: PROCEDURE,
                what: format!(
                    "the axis must be disabled, it is {} (a drive whose commutation is not \
                     known cannot hold the motor; `gantry disable {}` first)",
                    state.name(),
                    cx.name
                ),
            });
        }
        cx.progress("switching the drive to its open-loop current mode", 0.0);
        self.write(objects::COMMUTATION_CURRENT, 0)?;
        self.write(objects::COMMUTATION_ANGLE, 0)?;
        // Lent from Disabled: the channel enables the drive itself, in the open-loop mode
        // (sent by PDO where 0x6060 is mapped; by SDO here for where it is not).
        let lent = cx
            .ctl
            .lend_to_drive(
                cx.axis,
                PROCEDURE,
                ProcedureOutputs::idle(ModeOfOperation::Other(OPEN_LOOP_CURRENT_VECTOR)),
            )
            .map_err(|e| cx.control(e))?;
        loop {
            match lent.status() {
                Some(CommandStatus::Active) | Some(CommandStatus::Busy) => break,
                Some(CommandStatus::Error(source)) => {
                    return Err(CommissionError::Command {
                        axis: cx.name.clone(),
                        procedure: PROCEDURE,
                        command: PROCEDURE,
                        source: Box::new(source),
                    })
                }
                Some(s) if s.is_final() => {
                    return Err(cx.cancelled_error("before it started".into(), LEFT))
                }
                _ => std::thread::sleep(POLL),
            }
        }
        self.lent = Some(lent);
        self.switched = true;
        self.mode(ModeOfOperation::Other(OPEN_LOOP_CURRENT_VECTOR))?;
        cx.progress("enabling the drive (no current yet)", 0.0);
        self.drive_enabled(true)?;
        // Where the rotor is: 0x6064 read once, at rest (no current yet), and from then on
        // the axis' actual position from the snapshot (what the drive reports each cycle,
        // scaled), so that the SDO channel carries only the measurement's writes — a
        // transfer a cycle beside the process data would load a cycle without real time.
        let origin_counts = self.read(objects::POSITION_ACTUAL_VALUE)?;
        let origin_units = self.actual_units();
        let t0 = Instant::now();
        loop {
            if cx.cancelled() {
                return Err(cx.cancelled_error(format!("while {}", phase_words(m.phase())), LEFT));
            }
            self.still_lent()?;
            let moved = (self.actual_units() - origin_units) * self.s.counts_per_unit;
            let position = (origin_counts + moved.round() as i64) as i32;
            let now = t0.elapsed().as_secs_f64();
            cx.progress(phase_words(m.phase()), m.progress(now));
            match m.poll(now, position) {
                Ok(Step::Write(o, v)) => self.write(o, v)?,
                Ok(Step::Wait) => std::thread::sleep(MEASURE_POLL),
                Ok(Step::Done(r)) => return Ok(ProcedureOutcome::Commutation(r)),
                Err(source) => {
                    return Err(CommissionError::Measurement {
                        axis: cx.name.clone(),
                        source,
                    })
                }
            }
        }
    }

    /// The axis' actual position in the latest snapshot (units).
    fn actual_units(&self) -> f64 {
        self.cx
            .ctl
            .snapshot()
            .axes
            .get(self.cx.axis)
            .map_or(0.0, |a| a.actual_position)
    }

    /// Waits until the drive's power state is Operation enabled (`true`) or not.
    fn drive_enabled(&self, enabled: bool) -> Result<(), CommissionError> {
        let end = Instant::now() + MODE_TIMEOUT;
        loop {
            self.still_lent()
                .or_else(|e| if enabled { Err(e) } else { Ok(()) })?;
            let state = self
                .cx
                .ctl
                .snapshot()
                .drives
                .get(self.cx.axis)
                .and_then(|d| d.state);
            if (state == Some(State::OperationEnabled)) == enabled {
                return Ok(());
            }
            std::thread::sleep(SETTLE_POLL);
            if Instant::now() >= end {
                return Err(CommissionError::Drive {
                    axis: self.cx.name.clone(),
                    procedure: PROCEDURE,
                    what: format!(
                        "the drive is {} after {} s, not {}",
                        state.map_or("not reporting", State::name),
                        MODE_TIMEOUT.as_secs(),
                        if enabled { "enabled" } else { "disabled" }
                    ),
                });
            }
            std::thread::sleep(POLL);
        }
    }

    /// Current off, the lending ended (`failure`: its handle ends in Error with it), the
    /// axis disabled, CSP again. Best effort: each step is tried whatever the last did.
    fn hand_back(&mut self, failure: Option<DriveProcedureFailure>) -> Result<(), CommissionError> {
        let cx = self.cx;
        cx.progress("switching the current off and the drive back to CSP", 1.0);
        let off = self.write(objects::COMMUTATION_CURRENT, 0);
        if self.lent.take().is_some() {
            let outcome = match failure {
                None => Ok(()),
                Some(failure) => Err(DriveProcedureError {
                    procedure: PROCEDURE,
                    method: None,
                    failure,
                }),
            };
            let _ = cx.ctl.end_drive_procedure(cx.axis, outcome);
        }
        // The axis was Disabled all along: handed back, the channel disables the drive.
        let disabled = self.drive_enabled(false);
        let csp = if self.switched {
            self.mode(ModeOfOperation::CyclicSyncPosition)
        } else {
            Ok(())
        };
        off.and(disabled).and(csp)
    }
}

/// A phase in words, for the progress line.
fn phase_words(p: Phase) -> &'static str {
    match p {
        Phase::Start => "starting",
        Phase::Align => "aligning the rotor with the current vector",
        Phase::Forward => "turning the current vector forwards",
        Phase::Backward => "turning the current vector back",
        Phase::WriteOffset => "writing the offset",
        Phase::Release | Phase::Done => "switching the current off",
    }
}

/// What the kernel is told of a failed measurement (the commission error has the detail).
fn failure_of(e: &CommissionError) -> Option<DriveProcedureFailure> {
    match e {
        CommissionError::Cancelled { .. } => None,
        CommissionError::Measurement {
            source: CommutationError::NotFollowing { .. },
            ..
        } => Some(DriveProcedureFailure::Unusable {
            what: "the rotor did not follow the current vector",
        }),
        CommissionError::Measurement { .. } => Some(DriveProcedureFailure::Unusable {
            what: "the measurement failed",
        }),
        CommissionError::Sdo { .. } => Some(DriveProcedureFailure::Unusable {
            what: "an object of the drive could not be read or written",
        }),
        _ => Some(DriveProcedureFailure::Unusable {
            what: "the measurement did not finish",
        }),
    }
}

/// Runs it (see the module doc).
pub(crate) fn run(
    cx: &Context,
    s: CommutationSettings,
) -> Result<ProcedureOutcome, CommissionError> {
    let mut run = Run {
        cx,
        s,
        lent: None,
        switched: false,
    };
    let result = run.measure();
    let refused_at_start = matches!(result, Err(CommissionError::Drive { .. })) && !run.switched;
    let back = if refused_at_start {
        Ok(())
    } else {
        run.hand_back(result.as_ref().err().and_then(failure_of))
    };
    match (result, back) {
        (Ok(o), Ok(())) => {
            cx.progress("done", 1.0);
            Ok(o)
        }
        (Ok(_), Err(e)) | (Err(e), _) => Err(e),
    }
}
