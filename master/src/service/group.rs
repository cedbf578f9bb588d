//! The axis-group requests (`group`, `move_linear`, `move_circular`) as kernel group
//! commands: names resolved, numbers checked. The kernel checks the rest (the group's
//! state, MC_GroupEnable's rules, a move's start checks, MoveCircular2D's rules, the
//! axes' limits) and its refusal reaches the client as the command's error.

use gantry_kernel::group::run::{BufferMode, GroupCmd, GroupMove, GroupPathKind, Transition};
use gantry_kernel::path::{CircMode, PathChoice, PathLimits, MAX_AXES};

use super::protocol::{self, CircularDirection, CircularMode, GroupOp, TransitionMode};
use super::server::Refused;

/// How a group move joins the one running when it is given (PLCopen BufferMode,
/// TransitionMode and the allowed corner deviation), checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Junction {
    /// Aborting, Buffered or one of the Blending modes.
    pub buffer: BufferMode,
    /// None or CornerSuperimposed.
    pub transition: Transition,
    /// With CornerSuperimposed: how far the path may pass from the corner (units;
    /// infinite: the axes' limits alone decide).
    pub corner_deviation: f64,
}

/// The junction a request asks for: `corner_deviation` finite and > 0 when given, else
/// `default` (the group's `[[group]] corner_deviation`, infinite when it has none).
pub fn junction(
    buffer: protocol::BufferMode,
    transition: TransitionMode,
    corner_deviation: Option<f64>,
    default: f64,
) -> Result<Junction, Refused> {
    let corner_deviation = match corner_deviation {
        None => default,
        Some(v) if v.is_finite() && v > 0.0 => v,
        Some(v) => {
            return Err(Refused::GroupOperand {
                field: "corner_deviation",
                value: v,
                reason: "must be a finite number > 0",
            })
        }
    };
    Ok(Junction {
        buffer: buffer.into(),
        transition: match transition {
            TransitionMode::None => Transition::None,
            TransitionMode::CornerSuperimposed => Transition::CornerSuperimposed,
        },
        corner_deviation,
    })
}

/// A `group` request's command.
pub fn group_op(op: GroupOp) -> GroupCmd {
    match op {
        GroupOp::Enable => GroupCmd::Enable,
        GroupOp::Disable => GroupCmd::Disable,
        GroupOp::Stop => GroupCmd::Stop,
        GroupOp::Halt => GroupCmd::Halt,
        GroupOp::Home => GroupCmd::Home,
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
    junction: Junction,
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
        buffer: junction.buffer,
        transition: junction.transition,
        corner_deviation: junction.corner_deviation,
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
    junction: Junction,
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
        buffer: junction.buffer,
        transition: junction.transition,
        corner_deviation: junction.corner_deviation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_junction_takes_the_buffer_words_and_a_corner_deviation_given_or_the_groups() {
        let j = junction(
            protocol::BufferMode::BlendingNext,
            TransitionMode::CornerSuperimposed,
            Some(0.5),
            2.0,
        )
        .unwrap();
        assert_eq!(
            j,
            Junction {
                buffer: BufferMode::BlendingNext,
                transition: Transition::CornerSuperimposed,
                corner_deviation: 0.5,
            }
        );
        // Left out: the group's default, infinite when it has none.
        let j = junction(
            protocol::BufferMode::default(),
            TransitionMode::default(),
            None,
            f64::INFINITY,
        )
        .unwrap();
        assert_eq!(
            (j.buffer, j.transition, j.corner_deviation),
            (BufferMode::Aborting, Transition::None, f64::INFINITY)
        );
        let j = junction(
            protocol::BufferMode::Buffered,
            TransitionMode::CornerSuperimposed,
            None,
            0.25,
        )
        .unwrap();
        assert_eq!(j.corner_deviation, 0.25);
        // Refused, naming the field, whatever the group's default.
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = junction(
                protocol::BufferMode::BlendingLow,
                TransitionMode::CornerSuperimposed,
                Some(bad),
                0.5,
            )
            .unwrap_err();
            assert_eq!(
                e.to_string(),
                format!("corner_deviation = {bad} must be a finite number > 0")
            );
        }
    }

    #[test]
    fn a_move_carries_its_junction_to_the_kernel() {
        let j = Junction {
            buffer: BufferMode::BlendingHigh,
            transition: Transition::CornerSuperimposed,
            corner_deviation: 0.1,
        };
        let d = dynamics(10.0, None, None, None).unwrap();
        let GroupCmd::Move(m) = move_linear(&[1.0, 2.0], 2, d, false, j).unwrap() else {
            panic!("not a move");
        };
        assert_eq!(
            (m.buffer, m.transition, m.corner_deviation),
            (j.buffer, j.transition, j.corner_deviation)
        );
        let GroupCmd::Move(m) = move_circular(
            CircularMode::Center,
            [0.0, 1.0],
            [1.0, 1.0],
            CircularDirection::Cw,
            [0, 1],
            d,
            true,
            j,
        ) else {
            panic!("not a move");
        };
        assert_eq!(
            (m.buffer, m.transition, m.corner_deviation),
            (j.buffer, j.transition, j.corner_deviation)
        );
    }
}
