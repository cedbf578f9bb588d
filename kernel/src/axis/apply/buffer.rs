//! Buffered and blending moves (PLCopen BufferMode): queueing a move behind the running one,
//! the velocity at which the running one ends, and starting the next one in the cycle the
//! previous one ends.

use crate::axis::command::{BufferMode, CommandError};
use crate::axis::handle::{CommandStatus, HandleTable};
use crate::axis::motion::{Epoch, Motion, MotionKind, Queued, Settle};
use crate::axis::Axis;
use crate::profile::KinematicState;

impl Axis {
    pub(super) fn enqueue(&mut self, q: Queued) -> Result<CommandStatus, CommandError> {
        let was_empty = self.queue.is_empty();
        let blending = !matches!(q.buffer(), BufferMode::Aborting | BufferMode::Buffered);
        if self.queue.push(q).is_err() {
            return Err(CommandError::QueueFull {
                command: match q {
                    Queued::Ptp { .. } => "MovePtp",
                    Queued::Velocity { .. } => "MoveVelocity",
                },
                capacity: crate::axis::motion::QUEUE_CAPACITY,
            });
        }
        if was_empty && blending {
            // The running move must now end at the blend velocity: replan it from here.
            if let Some(mo) = self.motion {
                // A move already settling at its target has ended: nothing to replan (the
                // blending move starts next cycle without waiting for the settling).
                if let MotionKind::Ptp {
                    target,
                    settle: Settle { since: None, .. },
                    ..
                } = mo.kind
                {
                    let v_end = self.blend_velocity(target, mo.params.limits.vmax);
                    if let Ok(p) = self.plan_ptp(self.main, target, v_end, &mo.params) {
                        self.motion = Some(Motion {
                            profile: p,
                            epoch: Epoch::at(self.last_tick),
                            kind: mo.kind,
                            ..mo
                        });
                    }
                }
            }
        }
        Ok(CommandStatus::Busy)
    }

    /// Velocity (signed) at which a PTP to `target` with speed `v1` should end, given the
    /// first queued move (PLCopen blending; 0 when the next move reverses or is buffered).
    pub(super) fn blend_velocity(&self, target: f64, v1: f64) -> f64 {
        let Some(Queued::Ptp { cmd, params, .. }) = self.queue.front() else {
            return 0.0;
        };
        let v2 = params.limits.vmax;
        let speed = match cmd.buffer {
            BufferMode::BlendingLow => v1.min(v2),
            BufferMode::BlendingPrevious => v1,
            BufferMode::BlendingNext => v2,
            BufferMode::BlendingHigh => v1.max(v2),
            BufferMode::Aborting | BufferMode::Buffered => return 0.0,
        };
        let dir1 = self.last_direction;
        let from = KinematicState::at_rest(target);
        let Ok(t2) = self.resolve_target(cmd, &from, Some(target), params) else {
            return 0.0;
        };
        let dir2 = (t2 - target).signum();
        if dir2 == 0.0 || dir2 != dir1 {
            return 0.0;
        }
        dir1 * speed
    }

    /// Starts a queued move at `epoch` from the state `start` the previous move ended in.
    pub(in crate::axis) fn start_queued(
        &mut self,
        q: Queued,
        start: KinematicState,
        epoch: Epoch,
        _dt: f64,
        handles: &mut HandleTable,
    ) -> Result<(), CommandError> {
        match q {
            Queued::Ptp {
                cmd,
                params,
                window,
                handle,
            } => {
                let target = self.resolve_target(&cmd, &start, self.last_target, &params)?;
                // The new move is the running one now; its own successor decides its end.
                self.last_direction = if target != start.p {
                    (target - start.p).signum()
                } else {
                    self.last_direction
                };
                let v_end = self.blend_velocity(target, params.limits.vmax);
                let profile = self.plan_ptp(start, target, v_end, &params)?;
                self.install_ptp(target, window, profile, params, handle, epoch);
                handles.set(handle, CommandStatus::Active);
            }
            Queued::Velocity {
                cmd,
                params,
                handle,
            } => {
                let profile = self.plan_vel(
                    start,
                    cmd.direction.sign() * params.limits.vmax,
                    &params,
                    params.limits.jmax,
                )?;
                self.install_velocity(cmd.direction, profile, params, handle, epoch);
                handles.set(handle, CommandStatus::Active);
            }
        }
        Ok(())
    }
}
