//! The axis-group requests (`group`, `move_linear`, `move_circular`) as kernel group
//! commands: names resolved, numbers checked. The kernel checks the rest (the group's
//! state, MC_GroupEnable's rules, a move's start checks, MoveCircular2D's rules, the
//! axes' limits) and its refusal reaches the client as the command's error.

use gantry_kernel::group::run::{GroupCmd, GroupMove, GroupPathKind};
use gantry_kernel::path::{CircMode, PathChoice, PathLimits, MAX_AXES};

use super::protocol::{CircularDirection, CircularMode, GroupOp};
use super::server::Refused;

/// A `group` request's command.
pub fn group_op(op: GroupOp) -> GroupCmd {
    match op {
        GroupOp::Enable => GroupCmd::Enable,
        GroupOp::Disable => GroupCmd::Disable,
        GroupOp::Stop => GroupCmd::Stop,
        GroupOp::Release => GroupCmd::Release,
        GroupOp::Reset => GroupCmd::Reset,
    }
}

/// Path dynamics as given: the velocity required and > 0, the rest finite and > 0 when
/// given (left out: the axes' limits decide).
pub fn dynamics(
    velocity: f64,
    acceleration: Option<f64>,
    deceleration: Option<f64>,
    jerk: Option<f64>,
) -> Result<PathLimits, Refused> {
    let check = |field: &'static str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(Refused::GroupOperand {
                field,
                value: v,
                reason: "must be a finite number > 0",
            })
        }
    };
    let opt = |field, v: Option<f64>| v.map_or(Ok(f64::INFINITY), |v| check(field, v));
    Ok(PathLimits {
        v: check("velocity", velocity)?,
        a: opt("acceleration", acceleration)?,
        d: opt("deceleration", deceleration)?,
        j: opt("jerk", jerk)?,
    })
}

/// MC_MoveLinear to `to` (one value per axis of the group, `axes` of them).
pub fn move_linear(
    to: &[f64],
    axes: usize,
    dynamics: PathLimits,
    relative: bool,
    buffered: bool,
) -> Result<GroupCmd, Refused> {
    if to.len() != axes {
        return Err(Refused::GroupOperand {
            field: "to",
            value: to.len() as f64,
            reason: "must give one position per axis of the group",
        });
    }
    let mut target = [0.0; MAX_AXES];
    for (t, &v) in target.iter_mut().zip(to) {
        if !v.is_finite() {
            return Err(Refused::NotFinite {
                field: "to",
                value: v,
            });
        }
        *t = v;
    }
    Ok(GroupCmd::Move(GroupMove {
        path: GroupPathKind::Linear { target },
        relative,
        dynamics,
        buffered,
    }))
}

/// MC_MoveCircular2D.
#[allow(clippy::too_many_arguments)]
pub fn move_circular(
    mode: CircularMode,
    aux: [f64; 2],
    end: [f64; 2],
    direction: CircularDirection,
    circ: [usize; 2],
    dynamics: PathLimits,
    relative: bool,
    buffered: bool,
) -> GroupCmd {
    GroupCmd::Move(GroupMove {
        path: GroupPathKind::Circular {
            circ: (circ[0], circ[1]),
            aux,
            end,
            mode: match mode {
                CircularMode::Border => CircMode::Border,
                CircularMode::Center => CircMode::Center,
                CircularMode::Radius => CircMode::Radius,
            },
            choice: match direction {
                CircularDirection::Ccw => PathChoice::Ccw,
                CircularDirection::Cw => PathChoice::Cw,
            },
        },
        relative,
        dynamics,
        buffered,
    })
}
