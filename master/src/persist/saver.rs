//! Saving what an axis accepted, whichever way the command came — the control socket or a
//! program on the [`Controller`] API: a controller given the saved parameters
//! ([`Controller::saving_to`]) passes each homing and point-to-point command through
//! [`Saver::prepare`] (what the command leaves out becomes the saved values, seed 000
//! §6.3.2 across restarts) and hands what it is to save to [`Saver::submit`]. A thread of
//! its own waits until the cycle has taken the command and, unless the axis refused it
//! (its parameters are then not the axis' and must not be saved), writes the file — a
//! blocking write with fsync, off the cycle thread and off the caller's; a failure is
//! reported on the service's output and the command goes on.
//!
//! [`Controller`]: crate::runtime::controller::Controller
//! [`Controller::saving_to`]: crate::runtime::controller::Controller::saving_to

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

use gantry_kernel::axis::command::{Command, CommandError};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::homing::{MoveHome, MoveHomeCall, StepAbsoluteSwitch};

use super::{PersistError, PtpParams, Saved};
use crate::error_chain::Chain;
use crate::runtime::controller::CommandHandle;

/// How long the saving thread waits for the cycle to take a command.
const TAKEN_WITHIN: Duration = Duration::from_secs(10);

/// What to save once the axis has taken a command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Save {
    /// A MoveHome call: its whole run (saved when the call `gave` parameters) and
    /// MoveHome as the axis' homing run.
    Home {
        /// The run, every parameter.
        run: MoveHome,
        /// Whether the call gave any parameter.
        gave: bool,
    },
    /// A step-to-absolute-switch call, and step-to-switch as the axis' homing run.
    StepSwitch(StepAbsoluteSwitch),
    /// A move's dynamics, the saved ones completed by those it gave.
    Ptp(PtpParams),
}

impl Save {
    /// For messages: what was not saved.
    pub const fn what(&self) -> &'static str {
        match self {
            Self::Home { .. } => "homing parameters",
            Self::StepSwitch(_) => "step-to-absolute-switch parameters",
            Self::Ptp(_) => "point-to-point parameters",
        }
    }
}

struct Job {
    handle: CommandHandle,
    axis: usize,
    name: String,
    save: Save,
}

/// The saved parameters and the thread that saves what the axes accept.
pub struct Saver {
    saved: Arc<Saved>,
    jobs: mpsc::Sender<Job>,
    pending: Arc<AtomicUsize>,
}

impl std::fmt::Debug for Saver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Saver")
            .field("pending", &self.pending.load(Ordering::Relaxed))
            .finish_non_exhaustive()
    }
}

impl Saver {
    /// Saves into `saved`, on a thread of its own (it ends when the last controller
    /// holding this saver is gone and nothing is left to save).
    pub fn new(saved: Arc<Saved>) -> std::io::Result<Arc<Self>> {
        let (jobs, queue) = mpsc::channel::<Job>();
        let pending = Arc::new(AtomicUsize::new(0));
        let worker = (saved.clone(), pending.clone());
        std::thread::Builder::new()
            .name("gantry-save".into())
            .spawn(move || {
                let (saved, pending) = worker;
                while let Ok(job) = queue.recv() {
                    run(&saved, job);
                    pending.fetch_sub(1, Ordering::AcqRel);
                }
            })?;
        Ok(Arc::new(Self {
            saved,
            jobs,
            pending,
        }))
    }

    /// The saved parameters.
    pub fn saved(&self) -> &Arc<Saved> {
        &self.saved
    }

    /// `command` for axis `axis` as the axis is to get it — a move's left-out dynamics and
    /// a MoveHome call's left-out parameters filled in from the saved ones — and what to
    /// save once the axis has taken it (nothing for other commands).
    pub fn prepare(&self, axis: usize, command: Command) -> (Command, Option<Save>) {
        match command {
            Command::MovePtp(mut m) => {
                let given = PtpParams {
                    speed: m.speed,
                    acceleration: m.acceleration,
                    deceleration: m.deceleration,
                    jerk: m.jerk,
                };
                let used = self.saved.ptp_used(axis, given);
                m.speed = used.speed;
                m.acceleration = used.acceleration;
                m.deceleration = used.deceleration;
                m.jerk = used.jerk;
                let save = (given != PtpParams::default()).then_some(Save::Ptp(used));
                (Command::MovePtp(m), save)
            }
            Command::MoveHome(call) => match self.saved.home_run(axis, &call) {
                Some(run) => (
                    Command::MoveHome(MoveHomeCall::all(run)),
                    Some(Save::Home {
                        run,
                        gave: call != MoveHomeCall::default(),
                    }),
                ),
                None => (command, None),
            },
            Command::StepAbsoluteSwitch(p) => (command, Some(Save::StepSwitch(p))),
            other => (other, None),
        }
    }

    /// Saves `save` for axis `axis` (named `name`) once the cycle has taken the command
    /// of `handle`, unless the axis refused it.
    pub fn submit(&self, handle: CommandHandle, axis: usize, name: String, save: Save) {
        self.pending.fetch_add(1, Ordering::AcqRel);
        let job = Job {
            handle,
            axis,
            name,
            save,
        };
        if self.jobs.send(job).is_err() {
            // The thread is gone (it panicked): nothing will be saved.
            self.pending.fetch_sub(1, Ordering::AcqRel);
        }
    }

    /// Waits until every submitted save is done (or refused, or given up), `timeout` at
    /// most; whether none is left.
    pub fn settle(&self, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while self.pending.load(Ordering::Acquire) > 0 {
            if Instant::now() >= end {
                return false;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        true
    }
}

/// One job: waits for the command's status, then saves unless it was refused.
fn run(saved: &Saved, job: Job) {
    let end = Instant::now() + TAKEN_WITHIN;
    let status = loop {
        if let Some(s) = job.handle.status() {
            break s;
        }
        if Instant::now() >= end {
            return;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    match status {
        CommandStatus::Error(e) if !failed_after_start(&e) => return,
        CommandStatus::Expired => return,
        _ => {}
    }
    let axis = job.axis;
    let written: Result<Option<PathBuf>, PersistError> = match job.save {
        Save::Home { run, gave } => saved.home_accepted(axis, run, gave),
        Save::StepSwitch(run) => saved.step_switch_accepted(axis, run),
        Save::Ptp(used) => saved.ptp_accepted(axis, used),
    };
    if let Err(e) = written {
        let _ = writeln!(
            std::io::stdout(),
            "gantry: axis {}: {} not saved: {}",
            job.name,
            job.save.what(),
            Chain(&e)
        );
    }
}

/// Whether a command's error came after the axis took it (its parameters were then the
/// axis', and are saved): the run failed — a homing search, a limit switch, a fault, the
/// target not reached — as opposed to the command being refused at once.
fn failed_after_start(e: &CommandError) -> bool {
    matches!(
        e,
        CommandError::Homing(_)
            | CommandError::LimitSwitch { .. }
            | CommandError::AxisFault { .. }
            | CommandError::TargetNotReached { .. }
    )
}
