//! Braking: MC_Halt (then Standstill), MC_Stop (locks until Release), QuickStop (then
//! power off), and the braking motion they and ErrorStop share.

use crate::axis::command::{positive, CommandError, HaltMode, Operand};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::{Epoch, Motion, MotionKind, MoveParams};
use crate::axis::state::{AxisState, Event};
use crate::axis::Axis;
use crate::profile::{plan_position, plan_velocity, Limits, RampType};

impl Axis {
    pub(super) fn halt(
        &mut self,
        mode: HaltMode,
        deceleration: Option<f64>,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let name = "Halt";
        let running = self.motion.map(|m| m.params).unwrap_or(MoveParams {
            limits: Limits {
                vmax: self.ptp_dynamics.speed,
                amax: self.ptp_dynamics.acceleration,
                dmax: self.ptp_dynamics.deceleration,
                jmax: self.ptp_dynamics.jerk,
            },
            ramp: self.ptp_dynamics.ramp,
        });
        let dec = positive(
            name,
            Operand::Deceleration,
            deceleration.unwrap_or(running.limits.dmax),
            self.cfg.max.dmax,
        )?;
        let halt_position = self.actual_p;
        let mut start = self.main;
        start.p += self.overlay_set.p;
        start.v += self.overlay_set.v;
        start.a += self.overlay_set.a;
        let params = MoveParams {
            limits: Limits {
                dmax: dec,
                vmax: running
                    .limits
                    .vmax
                    .max(start.v.abs())
                    .min(self.cfg.max.vmax),
                ..running.limits
            },
            ramp: running.ramp,
        };
        let (profile, target) = match mode {
            HaltMode::Normal => {
                let p =
                    plan_velocity(params.ramp, start, 0.0, &params.limits).map_err(|error| {
                        CommandError::Plan {
                            command: name,
                            error,
                        }
                    })?;
                let t = p.end_state().p;
                (p, t)
            }
            HaltMode::AtActualPosition => {
                let p = plan_position(params.ramp, start, halt_position, 0.0, &params.limits)
                    .map_err(|error| CommandError::Plan {
                        command: name,
                        error,
                    })?;
                (p, halt_position)
            }
        };
        self.fold_overlay(handles);
        if let Some(old) = self.motion.take() {
            handles.set(old.handle, CommandStatus::Aborted);
        }
        self.queue
            .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
        self.motion = Some(Motion {
            kind: MotionKind::Halt { target },
            profile,
            epoch: Epoch::at(self.last_tick),
            params,
            handle: h,
            command: name,
            decel_jerk: params.limits.jmax,
        });
        self.enter(Event::DiscreteMotionStarted);
        Ok(CommandStatus::Active)
    }

    pub(super) fn stop(
        &mut self,
        deceleration: Option<f64>,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let dec = positive(
            "Stop",
            Operand::Deceleration,
            deceleration.unwrap_or(self.cfg.max.dmax),
            self.cfg.max.dmax,
        )?;
        self.fold_overlay(handles);
        self.abort_all_but_values(handles);
        self.start_stop_motion(MotionKind::Stop, dec, h, "Stop")?;
        self.release_pending = false;
        self.enter(Event::StopStarted);
        Ok(CommandStatus::Active)
    }

    /// Aborts the running commands but keeps the current set values (to brake from them).
    pub(super) fn abort_all_but_values(&mut self, handles: &mut HandleTable) {
        if let Some(m) = self.motion.take() {
            handles.set(m.handle, CommandStatus::Aborted);
        }
        if let Some(f) = self.follow.take() {
            handles.set(f.handle, CommandStatus::Aborted);
        }
        self.queue
            .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
    }

    /// Starts a braking motion from the current set values.
    pub(in crate::axis) fn start_stop_motion(
        &mut self,
        kind: MotionKind,
        decel: f64,
        h: HandleId,
        name: &'static str,
    ) -> Result<(), CommandError> {
        let ramp = match kind {
            MotionKind::QuickStop => RampType::Trapezoid,
            _ => self
                .motion
                .map(|m| m.params.ramp)
                .unwrap_or(self.ptp_dynamics.ramp),
        };
        let max = self.cfg.max;
        let limits = Limits {
            vmax: max.vmax.max(self.main.v.abs()),
            amax: max.amax,
            dmax: decel,
            jmax: max.jmax,
        };
        let profile = plan_velocity(ramp, self.main, 0.0, &limits)
            .or_else(|_| plan_velocity(RampType::Trapezoid, self.main, 0.0, &limits))
            .map_err(|error| CommandError::Plan {
                command: name,
                error,
            })?;
        self.motion = Some(Motion {
            kind,
            profile,
            epoch: Epoch::at(self.last_tick),
            params: MoveParams { limits, ramp },
            handle: h,
            command: name,
            decel_jerk: max.jmax,
        });
        Ok(())
    }

    /// MC_Stop's release: Standstill at once when the stop has ended, else when it ends.
    pub(super) fn release(&mut self) -> Result<CommandStatus, CommandError> {
        if self.motion.is_some_and(|m| m.kind == MotionKind::Stop) {
            self.release_pending = true;
        } else if self.state == AxisState::Stopping {
            self.enter(Event::Released);
        }
        Ok(CommandStatus::Done)
    }

    /// QuickStop: brake with the quick-stop deceleration, then power off.
    pub(super) fn quick_stop(
        &mut self,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        self.fold_overlay(handles);
        self.abort_all_but_values(handles);
        self.start_stop_motion(
            MotionKind::QuickStop,
            self.cfg.quick_stop_deceleration,
            h,
            "QuickStop",
        )?;
        self.enter(Event::StopStarted);
        Ok(CommandStatus::Active)
    }
}
