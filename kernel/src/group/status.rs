//! A group command's handle over time, and the axes' "coordinated" status.
//!
//! The handle reuses the axis' [`CommandStatus`] (Busy, Active, Done, CommandAborted,
//! Error); what groups add is when each applies, as seed 004's timing charts show for
//! Omron's MC_MoveLinear / MC_MoveCircular2D:
//!
//! | output | TRUE | FALSE |
//! |---|---|---|
//! | Busy | at Execute's rising edge | when Done, Error or CommandAborted turns TRUE |
//! | Active | when the axes begin to move | when Done, Error or CommandAborted turns TRUE |
//! | Done | at the end of the move | with Execute FALSE, or one cycle later if it already is |
//! | CommandAborted | another command aborts it; an error aborts it; started while the group is in error; started while MC_GroupStop runs | as Done |
//! | Error | the start conditions or the inputs are wrong | when the error is cleared |
//!
//! Unlike a single axis' move (which ends in Error when its axis faults), a group move
//! that an error interrupts ends CommandAborted: the error belongs to the group's status,
//! and the group's error does not fault its axes (seed 004).

use super::config::GroupConfig;
use super::enable::{GroupEnableError, GroupMoveError};
use super::state::{accepts, GroupCommand, GroupState};
use crate::axis::handle::CommandStatus;

/// Why a group command failed at its start (its handle's Error).
///
/// `Copy`, as the kernel's other real-time errors. The kernel's handle table holds
/// [`crate::axis::command::CommandError`]; group handles join it when the group is wired
/// into the kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GroupCommandError {
    /// The group's state does not take the command (`state::accepts`).
    #[error("{command} is not allowed in state {state}", state = state.name())]
    NotAllowedInState {
        /// Function block name.
        command: &'static str,
        /// The group's state.
        state: GroupState,
    },
    /// MC_GroupEnable's rules do not hold.
    #[error(transparent)]
    Enable(#[from] GroupEnableError),
    /// A move's start conditions do not hold.
    #[error("{command}: {error}")]
    MoveStart {
        /// Function block name.
        command: &'static str,
        /// Which rule, which axis.
        error: GroupMoveError,
    },
    /// MC_GroupHome: an axis' homing run failed or was taken over.
    #[error("GroupHome: axis {axis}'s homing run ended {how}; the group goes to ErrorStop")]
    HomingFailed {
        /// The axis (kernel index).
        axis: usize,
        /// "in an error" or "aborted".
        how: &'static str,
    },
}

/// Why a group command ended CommandAborted (seed 004's list).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AbortCause {
    /// Another command started in Aborting mode, or MC_GroupHalt, took over.
    Command,
    /// An error of the group or of one of its axes stopped the group.
    GroupError,
    /// MC_GroupStop stopped the group.
    GroupStop,
    /// MC_GroupDisable (or a forced disable) ended the group's enable.
    GroupDisable,
    /// The command was started while the group was in ErrorStop.
    StartedInErrorStop,
    /// The command was started while MC_GroupStop ran (group in Stopping).
    StartedWhileStopping,
}

/// What happens to a running group command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HandleEvent {
    /// The command controls the axes: they begin to move (a buffered move: when the one
    /// before it hands over).
    AxesMoving,
    /// It did what it was asked: the end of the path reached, the group enabled, ...
    Finished,
    /// It ended before that.
    Aborted(AbortCause),
}

/// How a group command starts in `state`: `Ok(Busy)` when the state takes it and
/// `conditions` hold; `Ok(Aborted)` for a motion command started while the group is in
/// ErrorStop or Stopping (seed 004: CommandAborted, not Error); `Err` for any other refusal
/// (the state, MC_GroupEnable's rules, the move's start rules) — the handle's Error.
///
/// `conditions` (the enable or move-start rules the caller picks for the command) runs only
/// when the state takes the command, so a refusal by state is reported as such.
pub fn start_status(
    state: GroupState,
    cmd: GroupCommand,
    conditions: impl FnOnce() -> Result<(), GroupCommandError>,
) -> Result<CommandStatus, GroupCommandError> {
    if !accepts(state, &cmd) {
        return match (state, cmd.is_motion()) {
            (GroupState::ErrorStop | GroupState::Stopping, true) => Ok(CommandStatus::Aborted),
            _ => Err(GroupCommandError::NotAllowedInState {
                command: cmd.name(),
                state,
            }),
        };
    }
    conditions()?;
    Ok(CommandStatus::Busy)
}

/// The abort cause of a refused start, when it is one (see [`start_status`]).
pub const fn start_abort_cause(state: GroupState, cmd: GroupCommand) -> Option<AbortCause> {
    if accepts(state, &cmd) || !cmd.is_motion() {
        return None;
    }
    match state {
        GroupState::ErrorStop => Some(AbortCause::StartedInErrorStop),
        GroupState::Stopping => Some(AbortCause::StartedWhileStopping),
        _ => None,
    }
}

/// The handle's status after `event` (one table, as the state machines): Busy becomes
/// Active when the axes move, Busy or Active become Done or CommandAborted; a final status
/// never changes (as `HandleTable::set`), so a Done move is never aborted later.
pub const fn next_status(status: CommandStatus, event: HandleEvent) -> CommandStatus {
    use CommandStatus as S;
    match (status, event) {
        (S::Done | S::Aborted | S::Error(_) | S::Expired, _) => status,
        (S::Busy | S::Active, HandleEvent::AxesMoving) => S::Active,
        (S::Busy | S::Active, HandleEvent::Finished) => S::Done,
        (S::Busy | S::Active, HandleEvent::Aborted(_)) => S::Aborted,
    }
}

/// A function block's output bits for a handle's status (seed 004's timing chart).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FbOutputs {
    /// Busy: from the start until a final status.
    pub busy: bool,
    /// Active: while the command controls the axes.
    pub active: bool,
    /// Done.
    pub done: bool,
    /// CommandAborted.
    pub command_aborted: bool,
    /// Error: until the error is cleared (the handle leaves Error).
    pub error: bool,
}

impl FbOutputs {
    /// The outputs for `status`, with the function block's Execute input and the number of
    /// whole cycles since the status became final (0 in the cycle it did). Done and
    /// CommandAborted stay TRUE while Execute is TRUE; with Execute FALSE they are TRUE for
    /// the one cycle in which they arrive.
    pub const fn of(status: &CommandStatus, execute: bool, cycles_since_final: u64) -> Self {
        let shown = execute || cycles_since_final == 0;
        match status {
            CommandStatus::Busy => Self {
                busy: true,
                ..Self::none()
            },
            CommandStatus::Active => Self {
                busy: true,
                active: true,
                ..Self::none()
            },
            CommandStatus::Done => Self {
                done: shown,
                ..Self::none()
            },
            CommandStatus::Aborted => Self {
                command_aborted: shown,
                ..Self::none()
            },
            CommandStatus::Error(_) => Self {
                error: true,
                ..Self::none()
            },
            CommandStatus::Expired => Self::none(),
        }
    }

    const fn none() -> Self {
        Self {
            busy: false,
            active: false,
            done: false,
            command_aborted: false,
            error: false,
        }
    }
}

/// The index (in `groups`' order) of the enabled group kernel axis `axis` belongs to: what
/// [`super::AxisView::in_enabled_group`] holds. At most one exists, as MC_GroupEnable's
/// rules keep it so; the first is returned.
pub fn enabled_group_of<'a>(
    axis: usize,
    groups: impl IntoIterator<Item = (&'a GroupConfig, GroupState)>,
) -> Option<usize> {
    groups
        .into_iter()
        .position(|(cfg, state)| state.is_enabled() && cfg.axes.contains(&axis))
}

/// An axis' "coordinated" status bit (Omron `Status.Coordinated`): TRUE from the moment its
/// group is enabled until it is disabled — in every group state but Disabled, ErrorStop
/// included, whether or not the group moves. The kernel sets it from this each cycle; while
/// it is TRUE the axis belongs to the group and no other group may take it.
pub fn coordinated<'a>(
    axis: usize,
    groups: impl IntoIterator<Item = (&'a GroupConfig, GroupState)>,
) -> bool {
    enabled_group_of(axis, groups).is_some()
}
