//! `gantry commission AXIS commutation`: the commutation offset measured in the seed's
//! dynamic mode on a running service, through what the axis' drive exposes — the
//! open-loop current-vector mode and its objects, by SDO, and the position actual value.
//!
//! The measurement runs in the cycle thread as a drive procedure
//! ([`crate::runtime::procedure::DriveProcedure::Commutation`], the sequencer
//! `gantry_drives::commutation::CommutationProcedure`): the axis is lent to its drive, the
//! sequencer's SDO accesses go beside the cycle and it reads the rotor in each cycle's
//! position actual value. This module starts it and follows it.
//!
//! The axis must be **disabled** to start: a drive whose commutation is unknown cannot hold
//! its motor in a closed loop (past 90° electrical it turns it the wrong way and runs it
//! away), so it is never enabled in CSP before the offset is known. Lent from Disabled, the
//! drive is enabled by the procedure in the open-loop mode; handed back, it is disabled by
//! its Disabled axis, and 0x6060 is set back to CSP here, with the drive's power off. The
//! axis is left **disabled**, as the seed's `MeasureCommutationOffset` leaves it (`when
//! xAxis1.State.IsDisabled continue`), done, failed or cancelled alike, with the current of
//! the vector off.

use std::time::{Duration, Instant};

use gantry_drives::cia402::objects::{self, ObjectId};
use gantry_drives::cia402::{ModeOfOperation, State};
use gantry_drives::commutation::{
    CommutationConfig, CommutationMeasurement, CommutationObjects, CommutationProcedure, PolePairs,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;

use super::{CommissionError, Context, ProcedureOutcome, POLL};
use crate::runtime::procedure::DriveProcedure;
use crate::runtime::sdo::{SdoData, SdoError, SdoRequest};

/// The procedure's name in messages.
pub const PROCEDURE: &str = "commutation measurement";

/// How long the drive may take to show a mode or a power state it was told.
const SETTLE_TIMEOUT: Duration = Duration::from_secs(2);
/// How often the drive's state is looked at meanwhile.
const SETTLE_POLL: Duration = Duration::from_millis(10);
/// How often a running measurement is looked at (progress, cancel).
const FOLLOW_POLL: Duration = Duration::from_millis(20);

/// The measurement's parameters from the configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommutationSettings {
    /// The axis' drive, by its bus position (for SDO).
    pub drive: usize,
    /// Encoder counts per motor revolution (the axis' scaling).
    pub counts_per_rev: u32,
    /// Current of the vector (per mille of the rated torque's); `None`: the default 300.
    pub current_per_mille: Option<u16>,
    /// Where the drive exposes the objects and the open-loop mode (`[axis.commutation]`).
    pub objects: CommutationObjects,
}

/// The app side of one measurement.
struct Run<'a> {
    cx: &'a Context,
    s: CommutationSettings,
}

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
            let h = self
                .cx
                .ctl
                .sdo(request.clone())
                .map_err(|e| self.cx.control(e))?;
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
        let data = SdoData::new(bytes.get(..o.kind.size()).unwrap_or_default());
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

    fn drive_error(&self, what: String) -> CommissionError {
        CommissionError::Drive {
            axis: self.cx.name.clone(),
            procedure: PROCEDURE,
            what,
        }
    }

    /// Waits until the drive's power stage is off (the axis disabled it).
    fn drive_off(&self) -> Result<(), CommissionError> {
        let end = Instant::now() + SETTLE_TIMEOUT;
        loop {
            let state = self
                .cx
                .ctl
                .snapshot()
                .drives
                .get(self.cx.axis)
                .and_then(|d| d.state);
            if !matches!(
                state,
                Some(State::OperationEnabled | State::QuickStopActive)
            ) {
                return Ok(());
            }
            if Instant::now() >= end {
                return Err(self.drive_error(format!(
                    "the drive is still {} {} s after the hand-back",
                    state.map_or("?", State::name),
                    SETTLE_TIMEOUT.as_secs()
                )));
            }
            std::thread::sleep(SETTLE_POLL);
        }
    }

    /// 0x6060 = CSP by SDO (with the power off), 0x6061 awaited.
    fn back_to_csp(&self) -> Result<(), CommissionError> {
        let csp = ModeOfOperation::CyclicSyncPosition.raw();
        self.write(objects::MODES_OF_OPERATION, i64::from(csp))?;
        let end = Instant::now() + SETTLE_TIMEOUT;
        loop {
            let shown = self.read(objects::MODES_OF_OPERATION_DISPLAY)?;
            if shown == i64::from(csp) {
                return Ok(());
            }
            if Instant::now() >= end {
                return Err(self.drive_error(format!(
                    "the drive shows mode {shown} (0x6061), not 8 (CSP), after {} s",
                    SETTLE_TIMEOUT.as_secs()
                )));
            }
            std::thread::sleep(SETTLE_POLL);
        }
    }

    /// The motor's pole pairs: configured, or read from the drive.
    fn pole_pairs(&self) -> Result<u32, CommissionError> {
        match self.s.objects.pole_pairs {
            PolePairs::Fixed(n) => Ok(n),
            PolePairs::Object(o) => {
                let n = self.read(o)?;
                u32::try_from(n)
                    .ok()
                    .filter(|n| (1..=64).contains(n))
                    .ok_or_else(|| {
                        self.drive_error(format!(
                            "the drive reports {n} pole pairs (0x{:04X}:{:02X} {}): not 1 to 64",
                            o.index, o.sub, o.name
                        ))
                    })
            }
        }
    }

    /// Starts the procedure and follows it to its end.
    fn measure(&self, pole_pairs: u32) -> Result<(), CommissionError> {
        let cx = self.cx;
        let mut config = CommutationConfig::new(self.s.counts_per_rev, pole_pairs);
        config.objects = self.s.objects;
        if let Some(c) = self.s.current_per_mille {
            config.current_per_mille = c;
        }
        let m =
            CommutationMeasurement::new(config).map_err(|source| CommissionError::Measurement {
                axis: cx.name.clone(),
                source,
            })?;
        let total_s = 2.0 * config.ramp_s + 2.0 * config.turn_s;
        let h = cx
            .ctl
            .drive_procedure(
                cx.axis,
                DriveProcedure::Commutation(CommutationProcedure::new(m)),
            )
            .map_err(|e| cx.control(e))?;
        let t0 = Instant::now();
        let mut cancelled = false;
        loop {
            if cx.cancelled() && !cancelled {
                // The axis is Disabled: a power off ends the lending (a Stop is for a
                // powered axis). `gantry stop` gave it already.
                cancelled = true;
                if !cx.stop_given() {
                    let _ = cx.command(gantry_kernel::axis::command::Command::Power(
                        gantry_kernel::axis::command::PowerCommand::Disable,
                    ));
                }
            }
            match h.status() {
                Some(CommandStatus::Done) => return Ok(()),
                Some(CommandStatus::Error(source)) => {
                    return Err(CommissionError::Command {
                        axis: cx.name.clone(),
                        procedure: PROCEDURE,
                        command: PROCEDURE,
                        source: Box::new(source),
                    })
                }
                Some(CommandStatus::Aborted) | Some(CommandStatus::Expired) => {
                    return Err(cx.cancelled_error("by a stop of the axis".into(), LEFT))
                }
                _ => {}
            }
            let snap = cx.ctl.snapshot();
            if snap.ended {
                return Err(cx.control(crate::runtime::controller::ControlError::Ended));
            }
            let phase = snap
                .drives
                .get(cx.axis)
                .and_then(|d| d.procedure)
                .map_or("starting", |p| p.phase);
            cx.progress(phase, t0.elapsed().as_secs_f64() / total_s);
            std::thread::sleep(FOLLOW_POLL);
        }
    }
}

/// What a cancelled or failed measurement leaves the axis in.
const LEFT: &str = "the axis is disabled, its drive's current off and in CSP again";

/// Runs it (see the module doc).
pub(crate) fn run(
    cx: &Context,
    s: CommutationSettings,
) -> Result<ProcedureOutcome, CommissionError> {
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
                "the axis must be disabled, it is {} (a drive whose commutation is not known \
                 cannot hold the motor; `gantry disable {}` first)",
                state.name(),
                cx.name
            ),
        });
    }
    let run = Run { cx, s };
    let pole_pairs = run.pole_pairs()?;
    let result = run.measure(pole_pairs);
    // Handed back: the power off, then the current off and CSP again, whatever happened.
    cx.progress("switching the drive back to CSP", 1.0);
    let off = run
        .drive_off()
        .and_then(|()| run.write(s.objects.current, 0))
        .and_then(|()| run.back_to_csp());
    let result = result.and(off);
    match result {
        Ok(()) => {
            let wire = run.read(s.objects.offset)?;
            let e = f64::from(s.counts_per_rev) / f64::from(pole_pairs);
            let offset = s.objects.offset_to_counts(wire, e);
            cx.progress("done", 1.0);
            Ok(ProcedureOutcome::Commutation {
                offset_counts: offset as i32,
            })
        }
        Err(CommissionError::Command { source, .. })
            if matches!(
                *source,
                gantry_kernel::axis::command::CommandError::DriveProcedure(
                    gantry_kernel::axis::lend::DriveProcedureError {
                        failure: gantry_kernel::axis::lend::DriveProcedureFailure::Cancelled { .. },
                        ..
                    }
                )
            ) =>
        {
            Err(cx.cancelled_error("by a stop of the axis".into(), LEFT))
        }
        Err(e) => Err(e),
    }
}
