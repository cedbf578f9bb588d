//! Commissioning procedures (SPEC §5, seed 000 §5.2.6 手动操作): measuring a synchronous
//! motor's commutation offset ([`commutation`]) and the reversing test motion between two
//! positions ([`reversing`]). Each runs on the application side, through the
//! [`Controller`] — axis commands, SDO transfers, the snapshot — never in the cycle thread,
//! on a thread of its own started by [`start`]; a [`ProcedureHandle`] follows it (progress,
//! cancel, outcome).
//!
//! Safety: a procedure that fails or is cancelled leaves its axis stopped (a cancelled one
//! by `Stop`, which locks the axis until `release`; a failed one in whatever the failure
//! left it — ErrorStop after a drive fault), with the drive's current off; it never leaves
//! a move running or a drive in a procedure mode.

pub mod commutation;
pub mod reversing;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use gantry_drives::commutation::CommutationError;
use gantry_kernel::axis::command::{Command, CommandError};
use gantry_kernel::axis::handle::CommandStatus;
use thiserror::Error;

use crate::persist::Saved;
use crate::runtime::controller::{CommandHandle, ControlError, Controller};
use crate::runtime::sdo::SdoError;

pub use commutation::CommutationSettings;
pub use reversing::Reversing;

/// A commissioning procedure and its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Procedure {
    /// Measure the commutation offset and write it to the drive.
    Commutation(CommutationSettings),
    /// Move back and forth between two positions.
    Reversing(Reversing),
}

impl Procedure {
    /// Its name, as the command line says it.
    pub const fn name(&self) -> &'static str {
        match self {
            Self::Commutation(_) => "commutation",
            Self::Reversing(_) => "reversing",
        }
    }
}

/// What a procedure found or did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProcedureOutcome {
    /// The commutation offset, written to the drive.
    Commutation {
        /// The offset (counts), as the drive's 0x2100 reads after the measurement.
        offset_counts: i32,
    },
    /// Reversing cycles run.
    Reversing {
        /// Cycles (there and back) run.
        cycles: u32,
    },
}

/// Why a procedure ended without its outcome. Each names the axis.
#[derive(Debug, Error)]
pub enum CommissionError {
    /// A parameter is out of range.
    #[error("{axis}: {procedure}: {operand} {reason}")]
    Operand {
        /// Axis name.
        axis: String,
        /// The procedure.
        procedure: &'static str,
        /// The operand (the command line's option).
        operand: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// The request did not reach the cycle.
    #[error("{axis}")]
    Control {
        /// Axis name.
        axis: String,
        /// Why.
        #[source]
        source: ControlError,
    },
    /// Cancelled (Ctrl-C, `gantry stop`, or [`ProcedureHandle::cancel`]).
    #[error("{axis}: {procedure} cancelled {when}; {left}")]
    Cancelled {
        /// Axis name.
        axis: String,
        /// The procedure.
        procedure: &'static str,
        /// How far it got.
        when: String,
        /// What it left the axis in.
        left: &'static str,
    },
    /// A command of the procedure failed (the axis' error says why).
    #[error("{axis}: {procedure}: {command} failed")]
    Command {
        /// Axis name.
        axis: String,
        /// The procedure.
        procedure: &'static str,
        /// The command.
        command: &'static str,
        /// Why (boxed: the kernel's error is large).
        #[source]
        source: Box<CommandError>,
    },
    /// An object of the drive could not be read or written.
    #[error("{axis}: {procedure}: {object}")]
    Sdo {
        /// Axis name.
        axis: String,
        /// The procedure.
        procedure: &'static str,
        /// The object ("0x2101 Motor pole pairs").
        object: String,
        /// Why.
        #[source]
        source: SdoError,
    },
    /// The measurement failed.
    #[error("{axis}")]
    Measurement {
        /// Axis name.
        axis: String,
        /// Why.
        #[source]
        source: CommutationError,
    },
    /// The drive was not where the procedure needs it.
    #[error("{axis}: {procedure}: {what}")]
    Drive {
        /// Axis name.
        axis: String,
        /// The procedure.
        procedure: &'static str,
        /// What was wrong.
        what: String,
    },
    /// The procedure's thread ended without an outcome (it panicked).
    #[error("{axis}: {procedure} ended without an outcome")]
    Lost {
        /// Axis name.
        axis: String,
        /// The procedure.
        procedure: &'static str,
    },
}

/// Where a procedure is.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Progress {
    /// The phase, in words ("turning the current vector forwards").
    pub phase: String,
    /// How far, 0 to 1.
    pub fraction: f64,
}

struct Shared {
    progress: Mutex<Progress>,
    cancel: AtomicBool,
    /// The canceller stopped the axis itself (`gantry stop`): the procedure gives no Stop
    /// of its own, which would abort that one.
    stop_given: AtomicBool,
    outcome: Mutex<Option<Result<ProcedureOutcome, Arc<CommissionError>>>>,
    /// Where a measured commutation offset was saved, or why it was not.
    saved: Mutex<Option<String>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A procedure on its way. Cheap to clone.
#[derive(Clone)]
pub struct ProcedureHandle {
    axis: usize,
    name: &'static str,
    shared: Arc<Shared>,
}

impl ProcedureHandle {
    /// The axis it runs on.
    pub fn axis(&self) -> usize {
        self.axis
    }

    /// The procedure's name.
    pub fn name(&self) -> &'static str {
        self.name
    }

    /// Where it is.
    pub fn progress(&self) -> Progress {
        lock(&self.shared.progress).clone()
    }

    /// Asks it to stop: it stops the axis, switches the drive's current off and ends with
    /// [`CommissionError::Cancelled`].
    pub fn cancel(&self) {
        self.shared.cancel.store(true, Ordering::Relaxed);
    }

    /// Cancels it after the caller gave the axis a Stop itself (`gantry stop AXIS`): as
    /// [`ProcedureHandle::cancel`], without a second Stop.
    pub fn cancel_stopped(&self) {
        self.shared.stop_given.store(true, Ordering::Relaxed);
        self.cancel();
    }

    /// How it ended, once it has.
    pub fn outcome(&self) -> Option<Result<ProcedureOutcome, Arc<CommissionError>>> {
        lock(&self.shared.outcome).clone()
    }

    /// Where a measured commutation offset was saved (its file), or why it was not; set
    /// before the outcome.
    pub fn saved(&self) -> Option<String> {
        lock(&self.shared.saved).clone()
    }

    /// Blocks until it ends or `timeout` passes (`None` then).
    pub fn wait(
        &self,
        timeout: Duration,
    ) -> Option<Result<ProcedureOutcome, Arc<CommissionError>>> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(o) = self.outcome() {
                return Some(o);
            }
            if Instant::now() >= end {
                return None;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

/// What a running procedure uses: the controller, its axis, progress and the cancel flag.
pub(crate) struct Context {
    pub ctl: Controller,
    pub axis: usize,
    pub name: String,
    pub procedure: &'static str,
    shared: Arc<Shared>,
}

/// What a cancelled motion leaves the axis in.
pub(crate) const STOPPED: &str = "the axis is stopped (release it to move it again)";

/// How often a procedure looks at the cycle's snapshot and its handles.
pub(crate) const POLL: Duration = Duration::from_millis(1);

impl Context {
    /// Publishes progress.
    pub fn progress(&self, phase: &str, fraction: f64) {
        let mut p = lock(&self.shared.progress);
        if p.phase != phase {
            p.phase = phase.to_string();
        }
        p.fraction = fraction.clamp(0.0, 1.0);
    }

    /// Whether the canceller stopped the axis itself.
    pub fn stop_given(&self) -> bool {
        self.shared.stop_given.load(Ordering::Relaxed)
    }

    /// Whether it was asked to stop.
    pub fn cancelled(&self) -> bool {
        self.shared.cancel.load(Ordering::Relaxed)
    }

    /// An error of the controller, for this axis.
    pub fn control(&self, source: ControlError) -> CommissionError {
        CommissionError::Control {
            axis: self.name.clone(),
            source,
        }
    }

    /// Sends `command` to the axis.
    pub fn command(&self, command: Command) -> Result<CommandHandle, CommissionError> {
        self.ctl
            .command(self.axis, command)
            .map_err(|e| self.control(e))
    }

    /// Stops the axis (the cancel path): `Stop`, waited for briefly; nothing when the
    /// canceller stopped it already.
    pub fn stop(&self) {
        if self.shared.stop_given.load(Ordering::Relaxed) {
            return;
        }
        if let Ok(h) = self
            .ctl
            .command(self.axis, Command::Stop { deceleration: None })
        {
            let _ = h.wait(Duration::from_secs(10));
        }
    }

    /// The cancelled error, `when` saying how far it got, `left` what it left the axis in.
    pub fn cancelled_error(&self, when: String, left: &'static str) -> CommissionError {
        CommissionError::Cancelled {
            axis: self.name.clone(),
            procedure: self.procedure,
            when,
            left,
        }
    }

    /// Waits for `handle` to be done; a cancel stops the axis. Aborted (a `stop` from
    /// elsewhere) is a cancel too.
    pub fn follow(
        &self,
        handle: &CommandHandle,
        command: &'static str,
        when: impl Fn() -> String,
        mut progress: impl FnMut(&Self),
    ) -> Result<(), CommissionError> {
        loop {
            if self.cancelled() {
                self.stop();
                return Err(self.cancelled_error(when(), STOPPED));
            }
            match handle.status() {
                Some(CommandStatus::Done) => return Ok(()),
                // Another command took the axis (a Stop, a power off): it is left to it.
                Some(CommandStatus::Aborted) | Some(CommandStatus::Expired) => {
                    return Err(self.cancelled_error(when(), STOPPED));
                }
                Some(CommandStatus::Error(source)) => {
                    return Err(CommissionError::Command {
                        axis: self.name.clone(),
                        procedure: self.procedure,
                        command,
                        source: Box::new(source),
                    })
                }
                _ => {}
            }
            if self.ctl.snapshot().ended {
                return Err(self.control(ControlError::Ended));
            }
            progress(self);
            std::thread::sleep(POLL);
        }
    }
}

/// Starts `procedure` on axis `axis` on a thread of its own. A measured commutation
/// offset is saved in `saved` (the axis' parameter file) before the outcome is given, so
/// the next start writes it back to the drive.
pub fn start(
    ctl: &Controller,
    axis: usize,
    procedure: Procedure,
    saved: Arc<Saved>,
) -> Result<ProcedureHandle, ControlError> {
    let name = ctl
        .axes()
        .get(axis)
        .cloned()
        .ok_or_else(|| ControlError::NoAxis(format!("#{axis}")))?;
    let shared = Arc::new(Shared {
        progress: Mutex::new(Progress {
            phase: "starting".into(),
            fraction: 0.0,
        }),
        cancel: AtomicBool::new(false),
        stop_given: AtomicBool::new(false),
        outcome: Mutex::new(None),
        saved: Mutex::new(None),
    });
    let context = Context {
        ctl: ctl.clone(),
        axis,
        name: name.clone(),
        procedure: procedure.name(),
        shared: shared.clone(),
    };
    let handle = ProcedureHandle {
        axis,
        name: procedure.name(),
        shared: shared.clone(),
    };
    let spawned = std::thread::Builder::new()
        .name(format!("commission-{name}"))
        .spawn(move || {
            let result =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match procedure {
                    Procedure::Commutation(s) => commutation::run(&context, s),
                    Procedure::Reversing(r) => reversing::run(&context, r),
                }));
            let result = result.unwrap_or_else(|_| {
                Err(CommissionError::Lost {
                    axis: context.name.clone(),
                    procedure: context.procedure,
                })
            });
            if let Ok(ProcedureOutcome::Commutation { offset_counts }) = &result {
                let offset_counts = *offset_counts;
                let note = match saved.save_commutation_offset(axis, offset_counts) {
                    Ok(Some(path)) => format!("saved in {}", path.display()),
                    Ok(None) => "not saved: no state directory ([service] state_dir or \
                                 systemd's StateDirectory=)"
                        .to_string(),
                    Err(e) => format!("NOT saved: {}", crate::error_chain::Chain(&e)),
                };
                *lock(&context.shared.saved) = Some(note);
            }
            *lock(&context.shared.outcome) = Some(result.map_err(Arc::new));
        });
    if spawned.is_err() {
        return Err(ControlError::QueueFull);
    }
    Ok(handle)
}
