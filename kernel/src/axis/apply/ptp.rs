//! MC_MoveAbsolute / MC_MoveRelative (one MovePtp with a positioning mode): resolving the
//! target, ramp break during deceleration, and installing the move.

use super::plan::{reverses, Goal};
use crate::axis::command::{
    non_negative, position, BufferMode, CommandError, MovePtp, Operand, PositioningMode,
    RampBreakMode, RangeProblem,
};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::{Epoch, Motion, MotionKind, MoveParams, Queued, Settle};
use crate::axis::state::Event;
use crate::axis::status::SlopeState;
use crate::axis::{Axis, Dynamics};
use crate::profile::{plan_position, plan_velocity, KinematicState, Profile};

impl Axis {
    /// Operands of a PTP move resolved against the last-used values, validated.
    pub(super) fn ptp_operands(
        &self,
        m: &MovePtp,
    ) -> Result<(MoveParams, f64, Dynamics), CommandError> {
        let name = "MovePtp";
        let d = self.ptp_dynamics;
        let (params, mut used) = self.dynamics_operands(
            name,
            d,
            m.speed,
            m.acceleration,
            m.deceleration,
            m.jerk,
            m.ramp,
        )?;
        let window = non_negative(
            name,
            Operand::TargetWindow,
            m.target_window.unwrap_or(d.target_window),
        )?;
        position(name, Operand::Target, m.target)?;
        used.target_window = window;
        Ok((params, window, used))
    }

    /// Checks that the mode fits the axis and that absolute moves have a reference.
    pub(super) fn check_mode(&self, mode: PositioningMode) -> Result<(), CommandError> {
        let name = "MovePtp";
        let modulo = self.cfg.mechanics.modulo.is_some();
        if mode.is_modulo() && !modulo {
            return Err(CommandError::ModuloModeOnNormalAxis {
                command: name,
                mode,
            });
        }
        if mode == PositioningMode::AbsNormal && modulo {
            return Err(CommandError::AbsNormalOnModuloAxis { command: name });
        }
        if mode.is_absolute() && self.cfg.homing_required && !self.homed {
            return Err(CommandError::NotHomed { command: name });
        }
        if mode == PositioningMode::AbsModuloNeg && !self.direction_allowed(-1.0)
            || mode == PositioningMode::AbsModuloPos && !self.direction_allowed(1.0)
        {
            return Err(self.direction_error(
                name,
                if mode == PositioningMode::AbsModuloPos {
                    1.0
                } else {
                    -1.0
                },
            ));
        }
        Ok(())
    }

    /// The target of a PTP move in the axis frame, starting from state `from` (moving or
    /// not) with the previous target `prev_target`.
    pub(super) fn resolve_target(
        &self,
        m: &MovePtp,
        from: &KinematicState,
        prev_target: Option<f64>,
        params: &MoveParams,
    ) -> Result<f64, CommandError> {
        let name = "MovePtp";
        let target = match m.mode {
            PositioningMode::AbsNormal => m.target,
            PositioningMode::RelTarget => prev_target.unwrap_or(from.p) + m.target,
            PositioningMode::RelActual => self.actual_p + m.target,
            mode => {
                let Some(modulo) = self.cfg.mechanics.modulo else {
                    return Err(CommandError::ModuloModeOnNormalAxis {
                        command: name,
                        mode,
                    });
                };
                let period = modulo.period();
                if !(m.target >= 0.0 && m.target < period) {
                    return Err(CommandError::OperandOutOfRange {
                        command: name,
                        operand: Operand::Target,
                        value: m.target,
                        problem: RangeProblem::OutsidePeriod,
                        limit: period,
                    });
                }
                let here = modulo.wrap(from.p);
                let dir = match mode {
                    PositioningMode::AbsModuloPos => 1.0,
                    PositioningMode::AbsModuloNeg => -1.0,
                    PositioningMode::AbsModuloKeepDirection => self.last_direction,
                    _ => 0.0,
                };
                let dir = match self.cfg.mechanics.direction {
                    crate::mechanics::Direction::PositiveOnly => 1.0,
                    crate::mechanics::Direction::NegativeOnly => -1.0,
                    crate::mechanics::Direction::Both => dir,
                };
                let mut delta = if dir > 0.0 {
                    modulo.delta_positive(here, m.target)
                } else if dir < 0.0 {
                    modulo.delta_negative(here, m.target)
                } else {
                    modulo.delta_shortest(here, m.target)
                };
                // A moving axis that must keep its direction goes round once more
                // rather than reverse when the target is inside its stopping distance.
                if dir != 0.0 && from.v * dir > 0.0 {
                    let stop = self.stop_distance(from, params) * dir;
                    let mut n = 0;
                    while delta * dir < stop && n < 1_000 {
                        delta += dir * period;
                        n += 1;
                    }
                }
                from.p + delta
            }
        };
        position(name, Operand::Target, target)?;
        if let (Some((min, max)), true, None) = (
            self.cfg.mechanics.software_limits,
            self.homed,
            self.cfg.mechanics.modulo,
        ) {
            if target < min || target > max {
                return Err(CommandError::OutsideSoftwareLimits {
                    command: name,
                    target,
                    min,
                    max,
                });
            }
        }
        let delta = target - from.p;
        if delta != 0.0 && !self.direction_allowed(delta.signum()) {
            return Err(self.direction_error(name, delta.signum()));
        }
        Ok(target)
    }

    /// Distance (≥ 0) the axis needs to stop from `from` with `params`.
    pub(super) fn stop_distance(&self, from: &KinematicState, params: &MoveParams) -> f64 {
        match plan_velocity(params.ramp, *from, 0.0, &params.limits) {
            Ok(p) => (p.end_state().p - from.p).abs(),
            Err(_) => 0.0,
        }
    }

    pub(super) fn move_ptp(
        &mut self,
        m: MovePtp,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let (params, window, used) = self.ptp_operands(&m)?;
        self.check_mode(m.mode)?;
        let running = self.motion.is_some() || !self.queue.is_empty();
        let decelerating_ptp = self
            .motion
            .is_some_and(|mo| matches!(mo.kind, MotionKind::Ptp { .. }))
            && SlopeState::of(&self.main, 1e-12, 1e-12) == SlopeState::Decelerating;

        if m.buffer.is_queued() && running {
            self.validate_queued_ptp(&m, &params)?;
            self.ptp_dynamics = used;
            return self.enqueue(Queued::Ptp {
                cmd: m,
                params,
                window,
                handle: h,
            });
        }

        let start = self.start_for(params.ramp);
        let target = self.resolve_target(&m, &start, self.last_target, &params)?;
        let goal = Goal::Position {
            target,
            v_end: 0.0,
            no_reverse: false,
        };
        let (planned, _, _) = self.plan_guarded(start, goal, &params)?;

        if decelerating_ptp {
            // Seed 000 §6.1.2: with None, and with Immediate when the distance does not
            // allow it, the first target is reached first and the second follows directly.
            let reverses = reverses(&planned, self.main.v);
            if self.cfg.ramp_break == RampBreakMode::None || reverses {
                self.validate_queued_ptp(&m, &params)?;
                self.ptp_dynamics = used;
                self.queue
                    .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
                let queued = MovePtp {
                    buffer: BufferMode::Buffered,
                    ..m
                };
                return self.enqueue(Queued::Ptp {
                    cmd: queued,
                    params,
                    window,
                    handle: h,
                });
            }
        }

        self.ptp_dynamics = used;
        if self.overlay.is_some() {
            // A new move takes over the axis; the superimposed jog stays.
        }
        if let Some(old) = self.motion.take() {
            handles.set(old.handle, CommandStatus::Aborted);
        }
        self.queue
            .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
        self.install_ptp(
            target,
            window,
            planned,
            params,
            h,
            Epoch::at(self.last_tick),
        );
        Ok(CommandStatus::Active)
    }

    /// Validates a PTP that will start where the queued moves end.
    pub(super) fn validate_queued_ptp(
        &self,
        m: &MovePtp,
        params: &MoveParams,
    ) -> Result<(), CommandError> {
        let (start_p, prev_target) = self.predicted_start();
        let start = KinematicState::at_rest(start_p);
        self.resolve_target(m, &start, prev_target, params)
            .map(|_| ())
    }

    /// Where the last queued (or running) move ends, and its target.
    pub(super) fn predicted_start(&self) -> (f64, Option<f64>) {
        let mut p = self
            .motion
            .map(|m| m.profile.end_state().p)
            .unwrap_or(self.main.p);
        let mut target = self.last_target;
        // Queued PTPs: simulate their resolution at rest.
        let mut q = self.queue;
        while let Some(item) = q.pop() {
            if let Queued::Ptp { cmd, params, .. } = item {
                let from = KinematicState::at_rest(p);
                if let Ok(t) = self.resolve_target(&cmd, &from, target, &params) {
                    p = t;
                    target = Some(t);
                }
            }
        }
        (p, target)
    }

    /// Plans a PTP move; moves with no jerk limit take an infinite jerk.
    pub(super) fn plan_ptp(
        &self,
        start: KinematicState,
        target: f64,
        v_end: f64,
        params: &MoveParams,
    ) -> Result<Profile, CommandError> {
        plan_position(params.ramp, start, target, v_end, &params.limits).map_err(|error| {
            CommandError::Plan {
                command: "MovePtp",
                error,
            }
        })
    }

    pub(super) fn install_ptp(
        &mut self,
        target: f64,
        window: f64,
        profile: Profile,
        params: MoveParams,
        h: HandleId,
        epoch: Epoch,
    ) {
        let dir = (target - profile.start_state().p).signum();
        if dir != 0.0 {
            self.last_direction = dir;
        }
        self.last_target = Some(target);
        self.last_window = window;
        self.motion = Some(Motion {
            kind: MotionKind::Ptp {
                target,
                window,
                settle: Settle::default(),
            },
            profile,
            epoch,
            params,
            handle: h,
            command: "MovePtp",
            decel_jerk: params.limits.jmax,
        });
        self.enter(Event::DiscreteMotionStarted);
    }
}
