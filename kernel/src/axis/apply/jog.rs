//! Jog (Logix MAJ): as the axis' own motion, merged, or superimposed on a running move.

use super::plan::Goal;
use crate::axis::command::{
    percent, positive, rate, CommandError, JerkUnits, Jog, JogProfile, MergeSpeed, Operand,
    RangeProblem,
};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::{Epoch, Motion, MotionKind, MoveParams};
use crate::axis::state::Event;
use crate::axis::Axis;
use crate::profile::{Limits, RampType};

impl Axis {
    /// A jog's operands in units/s^n (Logix MAJ units resolved).
    pub(super) fn jog_params(
        &self,
        j: &Jog,
        current_speed: f64,
    ) -> Result<(f64, MoveParams, f64), CommandError> {
        let name = "Jog";
        let max = self.cfg.max;
        let programmed = rate(name, Operand::Speed, j.speed, j.speed_units, max.vmax)?;
        let speed = if j.merge && j.merge_speed == MergeSpeed::Current {
            // Merging at the current speed of an axis at rest would jog at zero speed.
            let v = current_speed.min(max.vmax);
            if v < 1e-9 * max.vmax {
                return Err(CommandError::OperandOutOfRange {
                    command: name,
                    operand: Operand::Speed,
                    value: v,
                    problem: RangeProblem::NotPositive,
                    limit: max.vmax,
                });
            }
            v
        } else {
            programmed
        };
        let acc = rate(
            name,
            Operand::Acceleration,
            j.accel,
            j.accel_units,
            max.amax,
        )?;
        let dec = rate(
            name,
            Operand::Deceleration,
            j.decel,
            j.decel_units,
            max.dmax,
        )?;
        let dv_accel = (speed - current_speed)
            .abs()
            .max(1e-9 * max.vmax)
            .max(f64::MIN_POSITIVE);
        let dv_decel = speed.max(1e-9 * max.vmax).max(f64::MIN_POSITIVE);
        let jerk_of = |operand, value, a: f64, dv: f64| -> Result<f64, CommandError> {
            match j.jerk_units {
                JerkUnits::PerSecond3 => positive(name, operand, value, max.jmax),
                JerkUnits::PercentOfMax => {
                    percent(name, operand, value).map(|p| p / 100.0 * max.jmax)
                }
                JerkUnits::PercentOfTime => percent(name, operand, value).map(|p| {
                    // Jerk phases take fraction f of the ramp time T = Δv / (a (1 − f/2)),
                    // so j = 2a / (f T) = 2a² (1 − f/2) / (f Δv).
                    let f = p / 100.0;
                    (2.0 * a * a * (1.0 - f / 2.0) / (f * dv)).min(max.jmax)
                }),
            }
        };
        let accel_jerk = jerk_of(Operand::Jerk, j.accel_jerk, acc, dv_accel)?;
        let decel_jerk = jerk_of(Operand::DecelJerk, j.decel_jerk, dec, dv_decel)?;
        if !self.direction_allowed(j.direction.sign()) {
            return Err(self.direction_error(name, j.direction.sign()));
        }
        let ramp = match j.profile {
            JogProfile::Trapezoid => RampType::Trapezoid,
            JogProfile::SCurve => RampType::SCurve,
        };
        Ok((
            speed,
            MoveParams {
                limits: Limits {
                    vmax: speed,
                    amax: acc,
                    dmax: dec,
                    jmax: accel_jerk,
                },
                ramp,
            },
            decel_jerk,
        ))
    }

    pub(super) fn jog(
        &mut self,
        j: &Jog,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let total_v = self.main.v + self.overlay_set.v;
        let own_motion = match self.motion {
            None => true,
            Some(m) => matches!(m.kind, MotionKind::Jog),
        };
        if j.merge || own_motion {
            let current = if j.merge {
                total_v.abs()
            } else {
                self.main.v.abs()
            };
            let (speed, params, decel_jerk) = self.jog_params(j, current)?;
            let mut start = self.start_for(params.ramp);
            if j.merge {
                start.p += self.overlay_set.p;
                start.v += self.overlay_set.v;
                start.a += self.overlay_set.a;
            }
            let goal = Goal::Velocity {
                v: j.direction.sign() * speed,
                decel_jerk,
            };
            let (profile, _, _) = self.plan_guarded(start, goal, &params)?;
            if j.merge {
                self.fold_overlay(handles);
            }
            if let Some(old) = self.motion.take() {
                handles.set(old.handle, CommandStatus::Aborted);
            }
            self.queue
                .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
            self.last_direction = j.direction.sign();
            self.motion = Some(Motion {
                kind: MotionKind::Jog,
                profile,
                epoch: Epoch::at(self.last_tick),
                params,
                handle: h,
                command: "Jog",
                decel_jerk,
            });
            self.enter(Event::ContinuousMotionStarted);
        } else {
            // Merge disabled while another move runs: the jog is superimposed on it.
            let (speed, params, decel_jerk) = self.jog_params(j, self.overlay_set.v.abs())?;
            let goal = Goal::Velocity {
                v: j.direction.sign() * speed,
                decel_jerk,
            };
            let (profile, _, _) = self.plan_guarded(self.overlay_set, goal, &params)?;
            if let Some(old) = self.overlay.take() {
                handles.set(old.handle, CommandStatus::Aborted);
            }
            self.overlay = Some(Motion {
                kind: MotionKind::Jog,
                profile,
                epoch: Epoch::at(self.last_tick),
                params,
                handle: h,
                command: "Jog",
                decel_jerk,
            });
        }
        Ok(CommandStatus::Active)
    }

    /// Ends a superimposed jog, folding its displacement into the axis' own set values.
    pub(super) fn fold_overlay(&mut self, handles: &mut HandleTable) {
        if let Some(o) = self.overlay.take() {
            handles.set(o.handle, CommandStatus::Aborted);
            self.fold_overlay_values();
        }
    }
}
