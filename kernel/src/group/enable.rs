//! The rules MC_GroupEnable checks against the group's axes as they are, and the rules a
//! group move checks at its start (seed 004, Omron NJ MC_GroupEnable, MC_MoveLinear,
//! MC_MoveCircular2D).
//!
//! Both are functions of views the kernel fills from its axes, so they allocate nothing and
//! can run at command submission. Errors are `Copy` and name the axis (kernel index and
//! logical axis A0..A3) and what is wrong with it.

use super::config::{GroupConfig, MAX_GROUP_AXES};
use crate::axis::state::AxisState;
use crate::axis::AxisKind;
use crate::homing::{LimitSide, SwitchInputs};

/// One kernel axis as MC_GroupEnable sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisView {
    /// Its PLCopen state.
    pub state: AxisState,
    /// Its kind.
    pub kind: AxisKind,
    /// Whether its reference is defined. MC_GroupEnable does not need it (Omron homes the
    /// axes before enabling, but checks homing at each move's start: error 5466); kept so
    /// the kernel fills one view per axis.
    pub homed: bool,
    /// The index of the enabled group it belongs to, if any.
    pub in_enabled_group: Option<usize>,
}

/// Checks MC_GroupEnable's rules for `group` against the kernel's axes (`axes[i]` is kernel
/// axis `i`), each logical axis in order, the first broken rule returned:
///
/// - the axis exists and is of a kind that takes motion (real, simulated, virtual; Omron:
///   "servo axis" or "virtual servo axis", others are error 543D);
/// - it stands still: Disabled or Standstill (Omron: `Status.Disabled` or
///   `Status.Standstill` TRUE), so enabling the group never takes over a moving axis;
/// - it is in no enabled group (Omron: an axis already in an enabled group makes
///   MC_GroupEnable fail), so no two paths drive one axis.
///
/// Called for a group that is Disabled: MC_GroupEnable on an enabled group is a no-op that
/// checks nothing (`state.rs`), so any enabled group an axis is in is another one. The
/// configuration was validated when it was built ([`GroupConfig::validate`]); the count is
/// checked again because enabling a group of no axes would coordinate nothing.
pub fn check_enable(group: &GroupConfig, axes: &[AxisView]) -> Result<(), GroupEnableError> {
    let count = group.axes.len();
    if count == 0 || count > MAX_GROUP_AXES {
        return Err(GroupEnableError::AxisCount { count });
    }
    for (logical, &axis) in group.axes.iter().enumerate() {
        let Some(view) = axes.get(axis) else {
            return Err(GroupEnableError::NoSuchAxis { logical, axis });
        };
        if !view.kind.is_commandable() {
            return Err(GroupEnableError::KindNotSupported {
                logical,
                axis,
                kind: view.kind.name(),
            });
        }
        if !matches!(view.state, AxisState::Disabled | AxisState::Standstill) {
            return Err(GroupEnableError::NotStandingStill {
                logical,
                axis,
                state: view.state,
            });
        }
        if let Some(other) = view.in_enabled_group {
            return Err(GroupEnableError::InOtherGroup {
                logical,
                axis,
                other,
            });
        }
    }
    Ok(())
}

/// Why MC_GroupEnable failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GroupEnableError {
    /// The group has no axes or more than four.
    #[error("MC_GroupEnable: the group has {count} axes; a group has 1 to 4 axes (A0..A3)")]
    AxisCount {
        /// How many it has.
        count: usize,
    },
    /// A logical axis names a kernel axis that does not exist.
    #[error("MC_GroupEnable: A{logical} is axis {axis}, which does not exist")]
    NoSuchAxis {
        /// The logical axis (0 for A0).
        logical: usize,
        /// The kernel axis index.
        axis: usize,
    },
    /// An axis of a kind that takes no motion (Omron error 543D).
    #[error(
        "MC_GroupEnable: A{logical} is axis {axis} of type {kind}; a group takes only real, \
         simulated and virtual axes (Omron 543D: axis type not supported)"
    )]
    KindNotSupported {
        /// The logical axis (0 for A0).
        logical: usize,
        /// The kernel axis.
        axis: usize,
        /// Its kind's name.
        kind: &'static str,
    },
    /// An axis is neither Disabled nor at Standstill.
    #[error(
        "MC_GroupEnable: A{logical} (axis {axis}) is in {state}; every axis of the group must \
         be Disabled or at Standstill",
        state = state.name()
    )]
    NotStandingStill {
        /// The logical axis (0 for A0).
        logical: usize,
        /// The kernel axis.
        axis: usize,
        /// Its state.
        state: AxisState,
    },
    /// An axis already belongs to another enabled group.
    #[error(
        "MC_GroupEnable: A{logical} (axis {axis}) belongs to enabled group {other}; an axis can \
         be in one enabled group only"
    )]
    InOtherGroup {
        /// The logical axis (0 for A0).
        logical: usize,
        /// The kernel axis.
        axis: usize,
        /// The index of the enabled group it is in.
        other: usize,
    },
}

/// One axis of the group as a move sees it at its start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MoveView {
    /// Its kernel index (for the message).
    pub axis: usize,
    /// Whether its reference is defined.
    pub homed: bool,
    /// Its switches this cycle.
    pub switches: SwitchInputs,
}

/// Checks the rules a group move (MC_MoveLinear, MC_MoveCircular2D) checks at its start,
/// over every axis of the group (`axes[n]` is logical axis An); the homing rule is checked
/// on all axes before the limit rule, and the first axis breaking it is named:
///
/// - every axis is homed (Omron error 5466, "command started with the home not defined"):
///   a path is planned in absolute coordinates, which mean nothing on an axis without a
///   reference, and software limits are active only once homed;
/// - no hardware limit switch is active on any axis of the group, not only on the axes the
///   move drives (seed 004 for MC_MoveCircular2D: "any logical axis of the group"; SPEC §7
///   for MC_MoveLinear too): a path cannot move one axis away from its switch while
///   holding the others, so it does not start.
///
/// Modulo axes are refused by MC_MoveCircular2D's own operand check (Omron 544A), not here.
pub fn check_move_start(axes: &[MoveView]) -> Result<(), GroupMoveError> {
    for (logical, view) in axes.iter().enumerate() {
        if !view.homed {
            return Err(GroupMoveError::NotHomed {
                logical,
                axis: view.axis,
            });
        }
    }
    for (logical, view) in axes.iter().enumerate() {
        let side = if view.switches.negative_limit {
            Some(LimitSide::Negative)
        } else if view.switches.positive_limit {
            Some(LimitSide::Positive)
        } else {
            None
        };
        if let Some(side) = side {
            return Err(GroupMoveError::LimitSwitchActive {
                logical,
                axis: view.axis,
                side,
            });
        }
    }
    Ok(())
}

/// Why a group move could not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GroupMoveError {
    /// An axis of the group is not homed (Omron error 5466).
    #[error(
        "A{logical} (axis {axis}) is not homed; a group move needs every axis of the group \
         homed (Omron 5466: command started with the home not defined)"
    )]
    NotHomed {
        /// The logical axis (0 for A0).
        logical: usize,
        /// The kernel axis.
        axis: usize,
    },
    /// A hardware limit switch of an axis of the group is active.
    #[error(
        "A{logical} (axis {axis}): the {side} is active; a group move does not start while a \
         limit input of any axis of the group is on"
    )]
    LimitSwitchActive {
        /// The logical axis (0 for A0).
        logical: usize,
        /// The kernel axis.
        axis: usize,
        /// Which switch.
        side: LimitSide,
    },
}
