//! Operands shared by the move commands: dynamics resolved against the last-used values,
//! and the direction check.

use crate::axis::command::{positive, CommandError, Operand};
use crate::axis::motion::MoveParams;
use crate::axis::{Axis, Dynamics};
use crate::profile::{Limits, RampType};

impl Axis {
    /// Speed, acceleration, deceleration, jerk and ramp of a move, each given or taken
    /// from the last-used values `d`, validated against the axis maxima.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn dynamics_operands(
        &self,
        name: &'static str,
        d: Dynamics,
        speed: Option<f64>,
        acceleration: Option<f64>,
        deceleration: Option<f64>,
        jerk: Option<f64>,
        ramp: Option<RampType>,
    ) -> Result<(MoveParams, Dynamics), CommandError> {
        let max = self.cfg.max;
        let speed = positive(name, Operand::Speed, speed.unwrap_or(d.speed), max.vmax)?;
        let acc = positive(
            name,
            Operand::Acceleration,
            acceleration.unwrap_or(d.acceleration),
            max.amax,
        )?;
        let dec = positive(
            name,
            Operand::Deceleration,
            deceleration.unwrap_or(d.deceleration),
            max.dmax,
        )?;
        let jerk = positive(name, Operand::Jerk, jerk.unwrap_or(d.jerk), max.jmax)?;
        let ramp = ramp.unwrap_or(d.ramp);
        Ok((
            MoveParams {
                limits: Limits {
                    vmax: speed,
                    amax: acc,
                    dmax: dec,
                    jmax: jerk,
                },
                ramp,
            },
            Dynamics {
                speed,
                acceleration: acc,
                deceleration: dec,
                jerk,
                ramp,
                target_window: d.target_window,
            },
        ))
    }

    pub(super) fn direction_error(&self, command: &'static str, wanted: f64) -> CommandError {
        let word = |s: f64| if s >= 0.0 { "positive" } else { "negative" };
        CommandError::DirectionNotAllowed {
            command,
            allowed: word(-wanted),
            wanted: word(wanted),
        }
    }
}
