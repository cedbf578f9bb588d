//! The axis group's state machine (PLCopen Motion Control Part 4, "State diagram for axes
//! groups"; Omron NJ `_sGROUP_REF.Status`: Disabled, Standby, Moving, Stopping, ErrorStop).
//!
//! As for the axis (`axis/state.rs`), two tables say all of it: [`accepts`] which command
//! each state takes, [`GroupState::on`] where each [`GroupEvent`] leads. A transition the
//! table does not list is refused, not taken.
//!
//! Sources, and what was chosen where they are silent:
//! - PLCopen Part 4 (its notes as Beckhoff TF5410 and ABB Automation Builder reproduce
//!   them): GroupDisabled is the initial state, MC_GroupEnable leaves it for GroupStandby;
//!   MC_GroupDisable "can be issued in all states" and leads to GroupDisabled — also from
//!   GroupStopping (it cancels the stop) and from GroupErrorStop; an error of the group or
//!   of one of its axes leads from any enabled state to GroupErrorStop, which only
//!   MC_GroupReset (to GroupStandby) or MC_GroupDisable leave; GroupStopping returns to
//!   GroupStandby when MC_GroupStop is Done and its Execute is FALSE; in GroupStopping
//!   function blocks "can be called but are not executed" except MC_GroupDisable;
//!   MC_GroupHome (the axes' own homing runs, together) leads from GroupStandby to
//!   GroupHoming and back;
//!   MC_GroupReset "has no effect" outside GroupErrorStop; motion function blocks lead from
//!   GroupStandby to GroupMoving and back when the last move is done with nothing buffered.
//! - Seed 004 (Omron): a group error does not put its axes in error (the axes keep their
//!   own states); a move started while the group is in error or while MC_GroupStop runs
//!   ends CommandAborted (see `status.rs`). Omron has no group homing (its axes are homed
//!   one by one before the group is used); PLCopen's MC_GroupHome and GroupHoming are kept
//!   so the state set is PLCopen's.
//! - Chosen: MC_GroupEnable on an enabled group is a no-op in GroupStandby and refused in
//!   the motion states, where its rule (every axis standing still) cannot hold. Moves and
//!   MC_GroupHalt are refused during GroupHoming: the run is defining the reference the path
//!   would be planned in (stop it first). MC_GroupReset is refused in GroupDisabled (there is
//!   no group error to reset there; an axis' own error is reset on the axis). A second
//!   MC_GroupStop during GroupStopping is refused (PLCopen: not executed). Disable from
//!   GroupErrorStop leads to GroupDisabled, as PLCopen says, not to a separate
//!   "error disabled" state (Beckhoff's extension): the group's error does not outlive the
//!   group's enable, since it never faulted the axes.

/// PLCopen Part 4 axis group state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum GroupState {
    /// Not enabled: its axes are free for single-axis commands and other groups.
    #[default]
    Disabled,
    /// Enabled, no group command moves the axes.
    Standby,
    /// A group homing run is in progress.
    Homing,
    /// A group move (linear, circular, halt) controls the axes.
    Moving,
    /// MC_GroupStop is active: the group refuses motion until the stop is released.
    Stopping,
    /// An error stopped the group; only Reset and Disable leave it.
    ErrorStop,
}

impl GroupState {
    /// Every state, in the order of PLCopen's diagram.
    pub const ALL: [GroupState; 6] = [
        GroupState::Disabled,
        GroupState::Standby,
        GroupState::Homing,
        GroupState::Moving,
        GroupState::Stopping,
        GroupState::ErrorStop,
    ];

    /// Whether the group is enabled (its axes are "coordinated"): every state but
    /// Disabled, ErrorStop included — only MC_GroupDisable releases the axes.
    pub const fn is_enabled(self) -> bool {
        !matches!(self, GroupState::Disabled)
    }

    /// Name as PLCopen Part 4 writes it (Omron drops the "Group" prefix).
    pub const fn name(self) -> &'static str {
        match self {
            GroupState::Disabled => "GroupDisabled",
            GroupState::Standby => "GroupStandby",
            GroupState::Homing => "GroupHoming",
            GroupState::Moving => "GroupMoving",
            GroupState::Stopping => "GroupStopping",
            GroupState::ErrorStop => "GroupErrorStop",
        }
    }

    /// The state `event` leads to from this one; `None`: the diagram has no such
    /// transition (the caller keeps the state and refuses what caused the event).
    pub const fn on(self, event: GroupEvent) -> Option<GroupState> {
        use GroupEvent as E;
        use GroupState as S;
        match (self, event) {
            // MC_GroupDisable in all states (PLCopen), cancelling a stop or an error.
            (_, E::Disabled) => Some(S::Disabled),
            (S::Disabled, E::Enabled) => Some(S::Standby),
            (S::Disabled, _) => None,
            (S::ErrorStop, E::Reset) => Some(S::Standby),
            // An error of the group or of one of its axes, from any enabled state; a
            // second error keeps the group there.
            (_, E::Error) => Some(S::ErrorStop),
            // The braking the error started begins and ends inside ErrorStop.
            (S::ErrorStop, E::StopStarted | E::MoveDone) => Some(S::ErrorStop),
            (S::ErrorStop, _) => None,
            // MC_GroupEnable on an enabled, standing group: nothing to do.
            (S::Standby, E::Enabled) => Some(S::Standby),
            (_, E::Enabled) => None,
            // MC_GroupReset outside ErrorStop "has no effect" (PLCopen); Stopping takes
            // nothing but Disable and its own release.
            (S::Standby | S::Homing | S::Moving, E::Reset) => Some(self),
            (_, E::Reset) => None,
            (S::Stopping, E::StopReleased) => Some(S::Standby),
            (_, E::StopReleased) => None,
            (S::Stopping, _) => None,
            (_, E::StopStarted) => Some(S::Stopping),
            // A move from standstill, or one that aborts or follows the running one.
            (S::Standby | S::Moving, E::MoveStarted) => Some(S::Moving),
            (_, E::MoveStarted) => None,
            (S::Moving, E::MoveDone) => Some(S::Standby),
            (_, E::MoveDone) => None,
            (S::Standby, E::HomingStarted) => Some(S::Homing),
            (_, E::HomingStarted) => None,
            (S::Homing, E::HomingDone) => Some(S::Standby),
            (_, E::HomingDone) => None,
        }
    }
}

/// What makes a group change its state (the arcs of PLCopen Part 4's diagram).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GroupEvent {
    /// MC_GroupEnable succeeded (its rules held, see `enable.rs`).
    Enabled,
    /// MC_GroupDisable, or a forced disable (Omron: program mode, MC test run).
    Disabled,
    /// A group move (linear, circular, halt) takes control of the axes.
    MoveStarted,
    /// The last group move is done and nothing waits behind it.
    MoveDone,
    /// MC_GroupStop starts braking and locks the group.
    StopStarted,
    /// MC_GroupStop is Done and its Execute is FALSE.
    StopReleased,
    /// A group homing run starts.
    HomingStarted,
    /// The group homing run is done.
    HomingDone,
    /// An error of the group or of one of its axes.
    Error,
    /// MC_GroupReset acknowledged the error.
    Reset,
}

impl GroupEvent {
    /// Every event.
    pub const ALL: [GroupEvent; 10] = [
        GroupEvent::Enabled,
        GroupEvent::Disabled,
        GroupEvent::MoveStarted,
        GroupEvent::MoveDone,
        GroupEvent::StopStarted,
        GroupEvent::StopReleased,
        GroupEvent::HomingStarted,
        GroupEvent::HomingDone,
        GroupEvent::Error,
        GroupEvent::Reset,
    ];
}

/// A command to a group. The moves are markers here; their operands come with the path
/// planner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GroupCommand {
    /// MC_GroupEnable.
    Enable,
    /// MC_GroupDisable.
    Disable,
    /// MC_MoveLinear (Omron; PLCopen MC_MoveLinearAbsolute/Relative).
    MoveLinear,
    /// MC_MoveCircular2D (Omron; PLCopen MC_MoveCircularAbsolute/Relative).
    MoveCircular2D,
    /// MC_GroupStop: brake and lock the group until released.
    Stop,
    /// MC_GroupHalt: brake to standstill without locking (a move with an end).
    Halt,
    /// MC_GroupHome: every axis of the group runs its homing.
    Home,
    /// MC_GroupReset.
    Reset,
    /// MC_GroupStop's Execute fell: the group may leave Stopping once the stop is done
    /// (the axis' `Command::Release`; PLCopen's "Done AND NOT Execute").
    Release,
}

impl GroupCommand {
    /// Every command.
    pub const ALL: [GroupCommand; 9] = [
        GroupCommand::Enable,
        GroupCommand::Disable,
        GroupCommand::MoveLinear,
        GroupCommand::MoveCircular2D,
        GroupCommand::Stop,
        GroupCommand::Halt,
        GroupCommand::Home,
        GroupCommand::Reset,
        GroupCommand::Release,
    ];

    /// Function block name, for messages.
    pub const fn name(self) -> &'static str {
        match self {
            GroupCommand::Enable => "MC_GroupEnable",
            GroupCommand::Disable => "MC_GroupDisable",
            GroupCommand::MoveLinear => "MC_MoveLinear",
            GroupCommand::MoveCircular2D => "MC_MoveCircular2D",
            GroupCommand::Stop => "MC_GroupStop",
            GroupCommand::Halt => "MC_GroupHalt",
            GroupCommand::Home => "MC_GroupHome",
            GroupCommand::Reset => "MC_GroupReset",
            GroupCommand::Release => "MC_GroupStop release",
        }
    }

    /// Whether it is a motion function block (PLCopen Part 4 divides them from the
    /// administrative ones): these end CommandAborted, not Error, when started while the
    /// group is in ErrorStop or Stopping (seed 004's timing chart).
    pub const fn is_motion(self) -> bool {
        matches!(
            self,
            GroupCommand::MoveLinear
                | GroupCommand::MoveCircular2D
                | GroupCommand::Stop
                | GroupCommand::Halt
                | GroupCommand::Home
        )
    }
}

/// Whether `state` accepts `cmd` (PLCopen Part 4's diagram and the choices in the module
/// documentation; unlisted pairs are refused).
///
/// Disabled takes Enable and Disable (a no-op); ErrorStop only Reset and Disable; Stopping
/// only Disable and the stop's release; Homing no move or halt.
pub const fn accepts(state: GroupState, cmd: &GroupCommand) -> bool {
    use GroupCommand as C;
    use GroupState as S;
    match (state, cmd) {
        (_, C::Disable) => true,
        (S::Disabled | S::Standby, C::Enable) => true,
        (_, C::Enable) => false,
        (S::Disabled, _) => false,
        (S::ErrorStop, C::Reset) => true,
        (S::ErrorStop, _) => false,
        (S::Stopping, C::Release) => true,
        (S::Stopping, _) => false,
        (_, C::Release) => false,
        // Outside ErrorStop MC_GroupReset has no effect (PLCopen).
        (_, C::Reset) => true,
        (_, C::Stop) => true,
        (S::Homing, C::MoveLinear | C::MoveCircular2D | C::Halt) => false,
        (S::Standby | S::Moving, C::MoveLinear | C::MoveCircular2D | C::Halt) => true,
        (S::Standby, C::Home) => true,
        (S::Homing | S::Moving, C::Home) => false,
    }
}
