//! Lending an axis to its drive: a procedure the drive runs by itself, out of the cyclic
//! mode the kernel drives it in — CiA 402 homing mode (the drive searches its switches and
//! index pulse and sets its own position), a manufacturer's commissioning mode (a
//! commutation measurement). While the axis is lent:
//!
//! - its set position **tracks the drive's actual position** every cycle (the drive moves
//!   itself; the kernel plans nothing), so that when the axis is handed back the first
//!   set value is where the drive stands and nothing jumps;
//! - it refuses every command but power off, Stop and QuickStop
//!   ([`CommandError::LentToDrive`]): power off ends the lending at once (the handle is
//!   Aborted) and switches the drive off; Stop and QuickStop ask the master to cancel
//!   ([`crate::Kernel::cancel_requested`]): it halts the drive in its mode, hands it back
//!   and ends the lending with an error naming the command;
//! - the hardware limit switch stop is off (a homing method reverses at the switches);
//! - a drive fault ends it in ErrorStop as any fault does, the handle in Error.
//!
//! The kernel knows nothing of the drive's procedure: the master runs it (see the master's
//! `runtime::procedure`) and ends the lending with [`crate::Kernel::end_drive_procedure`],
//! done (for homing: the drive's position is now the axis' reference) or failed with a
//! [`DriveProcedureError`].

use super::command::CommandError;
use super::handle::{CommandStatus, HandleId, HandleTable};
use super::state::{AxisState, Event};
use super::Axis;
use crate::axis::command::Command;
use crate::axis::command::PowerCommand;
use crate::profile::KinematicState;

/// An axis lent to its drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Lent {
    /// The handle that follows the procedure.
    pub handle: HandleId,
    /// What the drive is doing (for messages).
    pub procedure: &'static str,
    /// A homing procedure: the axis is in Homing and not homed while it runs.
    pub homing: bool,
    /// Stop or QuickStop asked to cancel it (the command's name).
    pub cancel: Option<&'static str>,
}

/// Why a procedure the drive ran by itself failed. `Copy`: it lives in the RT status.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("{procedure}{}: {failure}", Method(*.method))]
pub struct DriveProcedureError {
    /// The procedure ("drive homing").
    pub procedure: &'static str,
    /// Its method, where it has one (the CiA 402 homing method).
    pub method: Option<i16>,
    /// What went wrong.
    pub failure: DriveProcedureFailure,
}

/// " method N", or nothing.
struct Method(Option<i16>);

impl core::fmt::Display for Method {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Some(m) => write!(f, " method {m}"),
            None => Ok(()),
        }
    }
}

/// What went wrong in a drive's procedure.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum DriveProcedureFailure {
    /// The drive did not report what the procedure waits for in time.
    #[error("did not report {missing} within {timeout_s} s")]
    NotReported {
        /// What was missing ("homing attained").
        missing: &'static str,
        /// How long the master waited (s).
        timeout_s: f64,
    },
    /// The drive reported that the procedure failed.
    #[error("the drive reports {what}")]
    DriveReports {
        /// What ("a homing error (statusword bit 13)").
        what: &'static str,
    },
    /// The drive refused an object the procedure writes (SDO abort).
    #[error(
        "the drive refused 0x{index:04X}:{sub:02X} = {value} (SDO abort 0x{code:08X}: {text})"
    )]
    Refused {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The value written.
        value: i64,
        /// CiA 301 abort code.
        code: u32,
        /// Its text.
        text: &'static str,
    },
    /// An object could not be read or written for another reason (no answer, no SDO
    /// channel on this bus).
    #[error("0x{index:04X}:{sub:02X}: {what}")]
    Sdo {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        what: &'static str,
    },
    /// A command (Stop, QuickStop) cancelled it; the drive was halted and handed back.
    #[error("cancelled by {by}")]
    Cancelled {
        /// The command.
        by: &'static str,
    },
    /// The procedure was asked of an axis that cannot run it.
    #[error("{what}")]
    Unusable {
        /// Why.
        what: &'static str,
    },
}

impl Axis {
    /// Lends the axis to its drive (see the module doc): from Standstill only, on an axis
    /// with a drive.
    pub(crate) fn lend(
        &mut self,
        procedure: &'static str,
        homing: bool,
        h: HandleId,
    ) -> Result<CommandStatus, CommandError> {
        if !self.cfg.kind.has_feedback() {
            return Err(CommandError::NothingToHomeOn {
                command: procedure,
                kind: self.cfg.kind.name(),
            });
        }
        if let Some(l) = self.lent {
            return Err(CommandError::LentToDrive {
                command: procedure,
                procedure: l.procedure,
            });
        }
        if self.state != AxisState::Standstill || self.motion.is_some() || self.overlay.is_some() {
            return Err(CommandError::NotAllowedInState {
                command: procedure,
                state: self.state,
            });
        }
        if homing {
            self.enter(Event::HomingStarted);
            self.homed = false;
        }
        self.lent = Some(Lent {
            handle: h,
            procedure,
            homing,
            cancel: None,
        });
        self.main = KinematicState::at_rest(self.actual_p);
        Ok(CommandStatus::Active)
    }

    /// Whether the axis is lent to its drive.
    pub(crate) fn is_lent(&self) -> bool {
        self.lent.is_some()
    }

    /// Each cycle while lent, and the first after: the set position is where the drive
    /// stands.
    pub(super) fn track_lent_drive(&mut self) {
        let rejoin = core::mem::take(&mut self.rejoin);
        if self.lent.is_some() {
            self.motion = None;
        }
        if self.lent.is_some() || (rejoin && self.motion.is_none()) {
            self.main = KinematicState::at_rest(self.actual_p);
        }
    }

    /// Ends the lending: `Ok(())` done (a homing procedure homes the axis: the drive's
    /// position is the axis' from now on), or failed. False when the axis was not lent
    /// (it was stopped or faulted meanwhile; the handle already says how).
    pub(crate) fn end_lending(
        &mut self,
        outcome: Result<(), DriveProcedureError>,
        handles: &mut HandleTable,
    ) -> bool {
        let Some(l) = self.lent.take() else {
            return false;
        };
        self.motion = None;
        if l.homing && outcome.is_ok() {
            // The drive set its own position to the reference: the axis frame is the
            // drive's again (no SetPosition offset), and homed.
            self.actual_p -= self.position_offset;
            self.position_offset = 0.0;
            self.homed = true;
        }
        self.main = KinematicState::at_rest(self.actual_p);
        self.rejoin = true;
        if self.state == AxisState::Homing {
            self.enter(Event::MotionDone);
        }
        let status = match outcome {
            Ok(()) => CommandStatus::Done,
            Err(e) => CommandStatus::Error(CommandError::DriveProcedure(e)),
        };
        handles.set(l.handle, status);
        true
    }

    /// A command while lent: `None` when the axis is not lent (the command goes on as
    /// always). Power off ends the lending at once (its handle Aborted) and goes on: the
    /// drive is switched off, whatever mode it is in. Stop and QuickStop ask the master to
    /// cancel the procedure — the drive halts in its mode and is handed back, the lending's
    /// handle ends in Error naming the command — and are Done at once (the axis stands as
    /// far as the kernel plans). Every other command is refused.
    pub(super) fn lent_command(
        &mut self,
        cmd: &Command,
        handles: &mut HandleTable,
    ) -> Option<Result<CommandStatus, CommandError>> {
        let l = self.lent.as_mut()?;
        match cmd {
            Command::Power(PowerCommand::Disable | PowerCommand::DisableForced) => {
                let h = l.handle;
                self.lent = None;
                if self.state == AxisState::Homing {
                    self.enter(Event::MotionDone);
                }
                self.main = KinematicState::at_rest(self.actual_p);
                handles.set(h, CommandStatus::Aborted);
                None
            }
            Command::Stop { .. } | Command::QuickStop => {
                l.cancel.get_or_insert(cmd.name());
                Some(Ok(CommandStatus::Done))
            }
            _ => Some(Err(CommandError::LentToDrive {
                command: cmd.name(),
                procedure: l.procedure,
            })),
        }
    }

    /// The command that asked to cancel the procedure (Stop, QuickStop), if one did.
    pub(crate) fn cancel_requested(&self) -> Option<&'static str> {
        self.lent.and_then(|l| l.cancel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::command::{MovePtp, PositioningMode};
    use crate::axis::status::AxisStatus;
    use crate::axis::{AxisConfig, AxisFeedback, AxisKind};
    use crate::Kernel;

    fn enabled_at(k: &mut Kernel, p: f64) -> AxisFeedback {
        let fb = AxisFeedback {
            position: p,
            operation_enabled: true,
            ..Default::default()
        };
        let h = k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
        for _ in 0..3 {
            k.step(&[fb]);
        }
        assert_eq!(k.command_status(h), CommandStatus::Done);
        fb
    }

    fn status(k: &Kernel) -> AxisStatus {
        *k.axis_status(0).unwrap()
    }

    /// The drive moves itself while lent: the set position tracks it, so the first set
    /// value after the hand-back is where the drive stands; homing done homes the axis
    /// on the drive's own position (the SetPosition offset gone).
    #[test]
    fn a_lent_axis_tracks_its_drive_and_is_handed_back_without_a_jump() {
        let mut k = Kernel::new(1e-3, vec![AxisConfig::new("x", AxisKind::Real)]).unwrap();
        let mut fb = enabled_at(&mut k, 5.0);
        // An offset: axis 105 where the drive stands at 5.
        k.command(
            0,
            Command::SetPosition {
                position: 105.0,
                relative: false,
            },
        )
        .unwrap();
        k.step(&[fb]);
        assert!(status(&k).bits.homed);
        let h = k.lend_to_drive(0, "drive homing", true).unwrap();
        assert_eq!(k.command_status(h), CommandStatus::Active);
        assert!(k.is_lent(0));
        assert_eq!(status(&k).state, AxisState::Homing);
        assert!(!status(&k).bits.homed, "not homed while the drive homes");
        // Anything but a stop is refused.
        let e = k
            .command(
                0,
                Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 0.0)),
            )
            .unwrap_err();
        assert!(matches!(e, CommandError::LentToDrive { .. }), "{e:?}");
        assert!(
            e.to_string().contains("lent to its drive for drive homing"),
            "{e}"
        );
        // The drive runs off by itself and sets its position to 0 at the reference.
        for i in 0..100 {
            fb.position = 5.0 - 0.1 * f64::from(i);
            let sp = k.step(&[fb])[0];
            // The offset added and taken off again: equal within rounding.
            assert!((sp.position - fb.position).abs() < 1e-9, "tracks the drive");
        }
        fb.position = 0.25;
        k.step(&[fb]);
        assert!(k.end_drive_procedure(0, Ok(())));
        assert_eq!(k.command_status(h), CommandStatus::Done);
        let sp = k.step(&[fb])[0];
        assert_eq!(sp.position, 0.25, "first set value is the drive's position");
        let st = status(&k);
        assert_eq!(st.state, AxisState::Standstill);
        assert!(st.bits.homed);
        assert_eq!(st.actual_position, 0.25, "the drive's position, no offset");
        assert!(!k.is_lent(0));
        assert!(!k.end_drive_procedure(0, Ok(())), "not lent any more");
    }

    #[test]
    fn a_stop_ends_the_lending_and_a_failure_leaves_the_axis_not_homed() {
        let mut k = Kernel::new(1e-3, vec![AxisConfig::new("x", AxisKind::Real)]).unwrap();
        let fb = enabled_at(&mut k, 1.0);
        let h = k.lend_to_drive(0, "drive homing", true).unwrap();
        k.step(&[fb]);
        // QuickStop asks the master to cancel: still lent (tracking) until it has.
        let q = k.command(0, Command::QuickStop).unwrap();
        assert_eq!(k.command_status(q), CommandStatus::Done);
        assert_eq!(k.cancel_requested(0), Some("QuickStop"));
        assert!(k.is_lent(0));
        // Power off ends it at once.
        k.command(0, Command::Power(PowerCommand::Disable)).unwrap();
        assert_eq!(k.command_status(h), CommandStatus::Aborted);
        assert!(!k.is_lent(0));
        assert_eq!(k.cancel_requested(0), None);
        let mut k = Kernel::new(1e-3, vec![AxisConfig::new("x", AxisKind::Real)]).unwrap();
        let fb = enabled_at(&mut k, 1.0);
        let h = k.lend_to_drive(0, "commutation", false).unwrap();
        assert_eq!(status(&k).state, AxisState::Standstill);
        let again = k.lend_to_drive(0, "drive homing", true).unwrap_err();
        assert!(matches!(
            again,
            CommandError::LentToDrive {
                procedure: "commutation",
                ..
            }
        ));
        k.step(&[fb]);
        let e = DriveProcedureError {
            procedure: "drive homing",
            method: Some(19),
            failure: DriveProcedureFailure::NotReported {
                missing: "homing attained",
                timeout_s: 30.0,
            },
        };
        assert_eq!(
            e.to_string(),
            "drive homing method 19: did not report homing attained within 30 s"
        );
        assert!(k.end_drive_procedure(0, Err(e)));
        assert_eq!(
            k.command_status(h),
            CommandStatus::Error(CommandError::DriveProcedure(e))
        );
        assert_eq!(status(&k).state, AxisState::Standstill);
        // A drive fault while lent: ErrorStop, the handle in Error.
        let h = k.lend_to_drive(0, "commutation", false).unwrap();
        k.step(&[AxisFeedback {
            fault: Some(0x8611),
            ..fb
        }]);
        assert!(matches!(k.command_status(h), CommandStatus::Error(_)));
        assert_eq!(status(&k).state, AxisState::ErrorStop);
        assert!(!k.is_lent(0));
    }
}
