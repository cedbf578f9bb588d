//! Axis groups (PLCopen Motion Control Part 4, "Coordinated Motion"; seed 004, Omron NJ
//! `_sGROUP_REF`): up to four axes moved together along one path.
//!
//! This module holds what a group is before it moves anything: its configuration
//! (`config`), its PLCopen state machine (`state`), the rules MC_GroupEnable and a move's
//! start check against the axes as they are (`enable`), and the timing of a group command's
//! handle and the axes' "coordinated" status (`status`). All of it is pure: functions of
//! the states and views passed in, no allocation after the configuration is built. The group
//! as a set-value source of its axes comes with the path planner.

pub mod config;
pub mod enable;
pub mod run;
pub mod state;
pub mod status;

pub use config::{GroupConfig, GroupConfigError, MAX_GROUP_AXES};
pub use enable::{
    check_enable, check_move_start, AxisView, GroupEnableError, GroupMoveError, MoveView,
};
pub use state::{accepts, GroupCommand, GroupEvent, GroupState};
pub use status::{
    coordinated, enabled_group_of, next_status, start_abort_cause, start_status, AbortCause,
    FbOutputs, GroupCommandError, HandleEvent,
};
