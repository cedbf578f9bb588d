//! MC_MoveVelocity and its reversal.

use super::plan::Goal;
use crate::axis::command::{CommandError, MoveDirection, MoveVelocity};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::{Epoch, Motion, MotionKind, MoveParams, Queued};
use crate::axis::state::Event;
use crate::axis::{Axis, Dynamics};
use crate::profile::{plan_velocity, KinematicState, Profile};

impl Axis {
    pub(super) fn velocity_operands(
        &self,
        v: &MoveVelocity,
    ) -> Result<(MoveParams, Dynamics), CommandError> {
        let name = "MoveVelocity";
        let used = self.dynamics_operands(
            name,
            self.vel_dynamics,
            v.speed,
            v.acceleration,
            v.deceleration,
            v.jerk,
            v.ramp,
        )?;
        if !self.direction_allowed(v.direction.sign()) {
            return Err(self.direction_error(name, v.direction.sign()));
        }
        Ok(used)
    }

    pub(super) fn plan_vel(
        &self,
        start: KinematicState,
        v: f64,
        params: &MoveParams,
        decel_jerk: f64,
    ) -> Result<Profile, CommandError> {
        let mut lim = params.limits;
        // Separate jerk for slowing down (Logix MAJ Decel Jerk).
        if v.abs() < start.v.abs() || v * start.v < 0.0 {
            lim.jmax = decel_jerk;
        }
        plan_velocity(params.ramp, start, v, &lim).map_err(|error| CommandError::Plan {
            command: "MoveVelocity",
            error,
        })
    }

    pub(super) fn install_velocity(
        &mut self,
        direction: MoveDirection,
        profile: Profile,
        params: MoveParams,
        h: HandleId,
        epoch: Epoch,
    ) {
        self.last_direction = direction.sign();
        self.motion = Some(Motion {
            kind: MotionKind::Velocity { direction },
            profile,
            epoch,
            params,
            handle: h,
            command: "MoveVelocity",
            decel_jerk: params.limits.jmax,
        });
        self.enter(Event::ContinuousMotionStarted);
    }

    pub(super) fn move_velocity(
        &mut self,
        v: MoveVelocity,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let (params, used) = self.velocity_operands(&v)?;
        let running = self.motion.is_some() || !self.queue.is_empty();
        if v.buffer.is_queued() && running {
            self.vel_dynamics = used;
            return self.enqueue(Queued::Velocity {
                cmd: v,
                params,
                handle: h,
            });
        }
        let goal = Goal::Velocity {
            v: v.direction.sign() * params.limits.vmax,
            decel_jerk: params.limits.jmax,
        };
        let (profile, _, _) = self.plan_guarded(self.start_for(params.ramp), goal, &params)?;
        self.vel_dynamics = used;
        if let Some(old) = self.motion.take() {
            handles.set(old.handle, CommandStatus::Aborted);
        }
        self.queue
            .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
        self.install_velocity(v.direction, profile, params, h, Epoch::at(self.last_tick));
        Ok(CommandStatus::Active)
    }

    pub(super) fn reverse(
        &mut self,
        _handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let Some(m) = self.motion else {
            return Err(CommandError::NothingToChange {
                command: "MoveVelocity.Reverse",
            });
        };
        let MotionKind::Velocity { direction } = m.kind else {
            return Err(CommandError::NothingToChange {
                command: "MoveVelocity.Reverse",
            });
        };
        let dir = direction.reversed();
        if !self.direction_allowed(dir.sign()) {
            return Err(self.direction_error("MoveVelocity.Reverse", dir.sign()));
        }
        let goal = Goal::Velocity {
            v: dir.sign() * m.params.limits.vmax,
            decel_jerk: m.decel_jerk,
        };
        let (profile, _, _) = self.plan_guarded(self.main, goal, &m.params)?;
        self.install_velocity(dir, profile, m.params, m.handle, Epoch::at(self.last_tick));
        Ok(CommandStatus::Done)
    }
}
