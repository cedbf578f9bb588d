//! Changing the speed, acceleration, deceleration or jerk of the running move on the fly.

use super::plan::Goal;
use crate::axis::command::{positive, Command, CommandError, DynamicsChange, Operand};
use crate::axis::handle::CommandStatus;
use crate::axis::motion::{Epoch, Motion, MotionKind};
use crate::axis::{Axis, Dynamics};
use crate::profile::PlanError;

impl Axis {
    pub(super) fn change(
        &mut self,
        what: DynamicsChange,
        value: f64,
    ) -> Result<CommandStatus, CommandError> {
        let name = Command::Change(what, value).name();
        let Some(m) = self.motion else {
            return Err(CommandError::NothingToChange { command: name });
        };
        let max = self.cfg.max;
        let mut params = m.params;
        match what {
            DynamicsChange::Speed => {
                params.limits.vmax = positive(name, Operand::Speed, value, max.vmax)?
            }
            DynamicsChange::Acceleration => {
                params.limits.amax = positive(name, Operand::Acceleration, value, max.amax)?
            }
            DynamicsChange::Deceleration => {
                params.limits.dmax = positive(name, Operand::Deceleration, value, max.dmax)?
            }
            DynamicsChange::Jerk => {
                params.limits.jmax = positive(name, Operand::Jerk, value, max.jmax)?
            }
        }
        let (profile, params, decel_jerk) = match m.kind {
            MotionKind::Ptp { target, .. } => {
                let v_end = self.blend_velocity(target, params.limits.vmax);
                let goal = Goal::Position {
                    target,
                    v_end,
                    no_reverse: true,
                };
                let (p, used, ok) = self.plan_guarded(self.main, goal, &params)?;
                if !ok {
                    // Not even the axis maximum stops in time: keep the running profile.
                    return Err(CommandError::Plan {
                        command: name,
                        error: PlanError::NoSolution {
                            p: self.main.p,
                            v: self.main.v,
                            a: self.main.a,
                            target,
                        },
                    });
                }
                self.ptp_dynamics = Dynamics {
                    speed: params.limits.vmax,
                    acceleration: params.limits.amax,
                    deceleration: params.limits.dmax,
                    jerk: params.limits.jmax,
                    ..self.ptp_dynamics
                };
                (p, used, used.limits.jmax)
            }
            MotionKind::Velocity { direction } => {
                let goal = Goal::Velocity {
                    v: direction.sign() * params.limits.vmax,
                    decel_jerk: params.limits.jmax,
                };
                let (p, _, _) = self.plan_guarded(self.main, goal, &params)?;
                self.vel_dynamics = Dynamics {
                    speed: params.limits.vmax,
                    acceleration: params.limits.amax,
                    deceleration: params.limits.dmax,
                    jerk: params.limits.jmax,
                    ..self.vel_dynamics
                };
                (p, params, params.limits.jmax)
            }
            MotionKind::Jog => {
                let dir = if self.last_direction >= 0.0 {
                    1.0
                } else {
                    -1.0
                };
                let dj = if what == DynamicsChange::Jerk {
                    params.limits.jmax
                } else {
                    m.decel_jerk
                };
                let goal = Goal::Velocity {
                    v: dir * params.limits.vmax,
                    decel_jerk: dj,
                };
                let (p, _, _) = self.plan_guarded(self.main, goal, &params)?;
                (p, params, dj)
            }
            _ => return Err(CommandError::NothingToChange { command: name }),
        };
        self.motion = Some(Motion {
            profile,
            params,
            decel_jerk,
            epoch: Epoch::at(self.last_tick),
            ..m
        });
        Ok(CommandStatus::Done)
    }
}
