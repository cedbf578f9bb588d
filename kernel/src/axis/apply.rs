//! Applying commands to an axis: operand validation, how a new command joins the running
//! one (aborting, buffered, blending, ramp break), and planning from the last set values.
//!
//! Everything here runs between two cycles with the state of the last cycle, so a new
//! profile starts exactly where the old one was: no jump in position or velocity (nor in
//! acceleration for S-curves).

use super::command::{
    non_negative, percent, position, positive, rate, BufferMode, Command, CommandError,
    DynamicsChange, HaltMode, JerkUnits, Jog, JogProfile, MergeSpeed, MoveDirection, MovePtp,
    MoveVelocity, Operand, PositioningMode, PowerCommand, RampBreakMode, RangeProblem,
};
use super::handle::{CommandStatus, HandleId, HandleTable};
use super::motion::{Epoch, Motion, MotionKind, MoveParams, Queued};
use super::state::{accepts, AxisState};
use super::status::SlopeState;
use super::{Axis, AxisKind, Dynamics};
use crate::profile::{
    plan_position, plan_velocity, KinematicState, Limits, PlanError, Profile, RampType,
};

/// Bisection steps when a dynamics change must be softened to avoid overshoot.
const NO_OVERSHOOT_STEPS: usize = 24;

impl Axis {
    /// Applies `cmd` with handle `h`. Returns the handle's initial status, or the error
    /// that refused the command (the axis then goes on unchanged).
    pub(crate) fn apply(
        &mut self,
        cmd: &Command,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let name = cmd.name();
        let bookkeeping = matches!(cmd, Command::SetPosition { .. } | Command::SetHomed(_));
        if !self.cfg.kind.is_commandable() && !bookkeeping {
            return Err(CommandError::NotCommandable {
                command: name,
                kind: self.cfg.kind.name(),
            });
        }
        if !accepts(self.state, cmd) {
            return Err(CommandError::NotAllowedInState {
                command: name,
                state: self.state,
            });
        }
        match *cmd {
            Command::Power(p) => self.power(p, h, handles),
            Command::Reset => self.reset(h),
            Command::MovePtp(m) => self.move_ptp(m, h, handles),
            Command::MoveVelocity(v) => self.move_velocity(v, h, handles),
            Command::Reverse => self.reverse(handles),
            Command::Jog(j) => self.jog(&j, h, handles),
            Command::Change(what, value) => self.change(what, value),
            Command::Halt { mode, deceleration } => self.halt(mode, deceleration, h, handles),
            Command::Stop { deceleration } => self.stop(deceleration, h, handles),
            Command::Release => {
                if self.motion.is_some_and(|m| m.kind == MotionKind::Stop) {
                    self.release_pending = true;
                } else if self.state == AxisState::Stopping {
                    self.state = AxisState::Standstill;
                }
                Ok(CommandStatus::Done)
            }
            Command::QuickStop => {
                self.fold_overlay(handles);
                self.abort_all_but_values(handles);
                self.start_stop_motion(
                    MotionKind::QuickStop,
                    self.cfg.quick_stop_deceleration,
                    h,
                    name,
                )?;
                self.state = AxisState::Stopping;
                Ok(CommandStatus::Active)
            }
            Command::SetPosition {
                position: value,
                relative,
            } => {
                let v = position(name, Operand::Position, value)?;
                let mut new_p = if relative { self.main.p + v } else { v };
                if let Some(m) = self.cfg.mechanics.modulo {
                    // The position within the period; whole turns are not the user's to set.
                    new_p = self.main.p + m.delta_positive(m.wrap(self.main.p), m.wrap(new_p));
                }
                let shift = new_p - self.main.p;
                self.main.p = new_p;
                self.actual_p += shift;
                self.position_offset += shift;
                if let Some(t) = self.last_target.as_mut() {
                    *t += shift;
                }
                if !relative {
                    self.homed = true;
                }
                self.normalise_frame();
                self.refresh_status();
                Ok(CommandStatus::Done)
            }
            Command::SetHomed(b) => {
                self.homed = b;
                self.refresh_status();
                Ok(CommandStatus::Done)
            }
        }
    }

    fn power(
        &mut self,
        p: PowerCommand,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        match p {
            PowerCommand::Enable => {
                if self.powered && self.state != AxisState::Disabled {
                    return Ok(CommandStatus::Done);
                }
                self.powered = true;
                // Take over at the actual position: no jump when the drive switches on.
                self.main = KinematicState::at_rest(self.actual_p);
                if self.cfg.kind == AxisKind::Real {
                    self.enable_handle = Some(h);
                    return Ok(CommandStatus::Busy);
                }
                if self.state == AxisState::Disabled {
                    self.state = AxisState::Standstill;
                }
                Ok(CommandStatus::Done)
            }
            PowerCommand::DisableForced => {
                self.power_off(handles);
                Ok(CommandStatus::Done)
            }
            PowerCommand::Disable => {
                if self.motion.is_none() && self.overlay.is_none() {
                    self.power_off(handles);
                    return Ok(CommandStatus::Done);
                }
                let decel = self
                    .motion
                    .map(|m| m.params.limits.dmax)
                    .unwrap_or(self.ptp_dynamics.deceleration);
                self.fold_overlay(handles);
                self.abort_all_but_values(handles);
                self.start_stop_motion(MotionKind::Disable, decel, h, "Power.Disable")?;
                self.state = AxisState::Stopping;
                Ok(CommandStatus::Active)
            }
        }
    }

    fn reset(&mut self, h: HandleId) -> Result<CommandStatus, CommandError> {
        if self.state != AxisState::ErrorStop {
            return Ok(CommandStatus::Done);
        }
        if self.drive_fault {
            // The drive must clear its fault first (fault reset on the bus).
            self.reset_pending = Some((h, self.last_tick));
            return Ok(CommandStatus::Busy);
        }
        if self.motion.is_some() {
            // Still braking after the error: reset once it stands.
            return Err(CommandError::NotAllowedInState {
                command: "Reset",
                state: AxisState::ErrorStop,
            });
        }
        self.state = if self.powered {
            AxisState::Standstill
        } else {
            AxisState::Disabled
        };
        self.status.error = None;
        self.refresh_status();
        Ok(CommandStatus::Done)
    }

    /// Speed, acceleration, deceleration, jerk and ramp of a move, each given or taken
    /// from the last-used values `d`, validated against the axis maxima.
    #[allow(clippy::too_many_arguments)]
    fn dynamics_operands(
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

    /// Operands of a PTP move resolved against the last-used values, validated.
    fn ptp_operands(&self, m: &MovePtp) -> Result<(MoveParams, f64, Dynamics), CommandError> {
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
    fn check_mode(&self, mode: PositioningMode) -> Result<(), CommandError> {
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

    fn direction_error(&self, command: &'static str, wanted: f64) -> CommandError {
        let word = |s: f64| if s >= 0.0 { "positive" } else { "negative" };
        CommandError::DirectionNotAllowed {
            command,
            allowed: word(-wanted),
            wanted: word(wanted),
        }
    }

    /// The target of a PTP move in the axis frame, starting from state `from` (moving or
    /// not) with the previous target `prev_target`.
    fn resolve_target(
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
    fn stop_distance(&self, from: &KinematicState, params: &MoveParams) -> f64 {
        match plan_velocity(params.ramp, *from, 0.0, &params.limits) {
            Ok(p) => (p.end_state().p - from.p).abs(),
            Err(_) => 0.0,
        }
    }

    fn move_ptp(
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
    fn validate_queued_ptp(&self, m: &MovePtp, params: &MoveParams) -> Result<(), CommandError> {
        let (start_p, prev_target) = self.predicted_start();
        let start = KinematicState::at_rest(start_p);
        self.resolve_target(m, &start, prev_target, params)
            .map(|_| ())
    }

    /// Where the last queued (or running) move ends, and its target.
    fn predicted_start(&self) -> (f64, Option<f64>) {
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

    fn enqueue(&mut self, q: Queued) -> Result<CommandStatus, CommandError> {
        let was_empty = self.queue.is_empty();
        let blending = !matches!(q.buffer(), BufferMode::Aborting | BufferMode::Buffered);
        if self.queue.push(q).is_err() {
            return Err(CommandError::QueueFull {
                command: match q {
                    Queued::Ptp { .. } => "MovePtp",
                    Queued::Velocity { .. } => "MoveVelocity",
                },
                capacity: super::motion::QUEUE_CAPACITY,
            });
        }
        if was_empty && blending {
            // The running move must now end at the blend velocity: replan it from here.
            if let Some(mo) = self.motion {
                if let MotionKind::Ptp { target, window } = mo.kind {
                    let v_end = self.blend_velocity(target, mo.params.limits.vmax);
                    if let Ok(p) = self.plan_ptp(self.main, target, v_end, &mo.params) {
                        self.motion = Some(Motion {
                            profile: p,
                            epoch: Epoch::at(self.last_tick),
                            kind: MotionKind::Ptp { target, window },
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
    fn blend_velocity(&self, target: f64, v1: f64) -> f64 {
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

    /// Plans a PTP move; moves with no jerk limit take an infinite jerk.
    fn plan_ptp(
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

    fn install_ptp(
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
            kind: MotionKind::Ptp { target, window },
            profile,
            epoch,
            params,
            handle: h,
            command: "MovePtp",
            decel_jerk: params.limits.jmax,
        });
        if self.state != AxisState::ErrorStop {
            self.state = AxisState::DiscreteMotion;
        }
    }

    /// Starts a queued move at `epoch` from the state `start` the previous move ended in.
    pub(super) fn start_queued(
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

    fn velocity_operands(&self, v: &MoveVelocity) -> Result<(MoveParams, Dynamics), CommandError> {
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

    fn plan_vel(
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

    fn install_velocity(
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
        if self.state != AxisState::ErrorStop {
            self.state = AxisState::ContinuousMotion;
        }
    }

    fn move_velocity(
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

    fn reverse(&mut self, _handles: &mut HandleTable) -> Result<CommandStatus, CommandError> {
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

    /// A jog's operands in units/s^n (Logix MAJ units resolved).
    fn jog_params(
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

    fn jog(
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
            self.state = AxisState::ContinuousMotion;
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
    fn fold_overlay(&mut self, handles: &mut HandleTable) {
        if let Some(o) = self.overlay.take() {
            handles.set(o.handle, CommandStatus::Aborted);
            self.fold_overlay_values();
        }
    }

    /// The state a new move plans from: the last set values, except that an S-curve
    /// following a ramp without jerk limit starts from zero acceleration (those ramps jump
    /// in acceleration anyway; inheriting their acceleration would make the new jerk limit
    /// drag it down slowly and overshoot).
    fn start_for(&self, ramp: RampType) -> KinematicState {
        let mut s = self.main;
        let prev = self.motion.map(|m| m.params.ramp);
        if ramp == RampType::SCurve && prev.is_some_and(|r| r != RampType::SCurve) {
            s.a = 0.0;
        }
        s
    }

    fn plan_goal(
        &self,
        start: KinematicState,
        goal: Goal,
        params: &MoveParams,
    ) -> Result<Profile, CommandError> {
        match goal {
            Goal::Velocity { v, decel_jerk } => self.plan_vel(start, v, params, decel_jerk),
            Goal::Position { target, v_end, .. } => self.plan_ptp(start, target, v_end, params),
        }
    }

    /// Whether a plan keeps within the axis maximum speed (unless the start is already
    /// beyond it) and, for the goal, neither overshoots the target velocity nor passes the
    /// target position and comes back.
    fn acceptable(&self, p: &Profile, start: &KinematicState, goal: Goal) -> bool {
        let (lo, hi) = velocity_range(p);
        let vlim = self.cfg.max.vmax.max(start.v.abs()) * (1.0 + 1e-9);
        if lo < -vlim || hi > vlim {
            return false;
        }
        match goal {
            Goal::Velocity { v, .. } => !overshoots_velocity(p, start.v, v),
            Goal::Position { no_reverse, .. } => !(no_reverse && reverses(p, start.v)),
        }
    }

    /// Plans `goal`; when the plan is not [`Axis::acceptable`] (Logix warns that lowering
    /// jerk or deceleration while ramping overshoots), raises acceleration, deceleration
    /// and jerk just enough, up to the axis maximum. Returns the plan, the parameters it
    /// used, and whether it is acceptable (false: not even the axis maximum suffices).
    fn plan_guarded(
        &self,
        start: KinematicState,
        goal: Goal,
        params: &MoveParams,
    ) -> Result<(Profile, MoveParams, bool), CommandError> {
        let first = self.plan_goal(start, goal, params)?;
        if self.acceptable(&first, &start, goal) {
            return Ok((first, *params, true));
        }
        let max = self.cfg.max;
        // λ = 0: the command's limits; λ = 1: every limit at the axis maximum (geometric
        // in between, so each limit rises in proportion to its own headroom).
        let raise = |v: f64, top: f64, lambda: f64| {
            if top > v {
                v * (top / v).powf(lambda)
            } else {
                v
            }
        };
        let scaled = |lambda: f64| {
            let mut g = goal;
            if let Goal::Velocity { decel_jerk, .. } = &mut g {
                *decel_jerk = raise(*decel_jerk, max.jmax, lambda);
            }
            let l = params.limits;
            let p = MoveParams {
                limits: Limits {
                    amax: raise(l.amax, max.amax, lambda),
                    dmax: raise(l.dmax, max.dmax, lambda),
                    jmax: raise(l.jmax, max.jmax, lambda),
                    ..l
                },
                ..*params
            };
            (g, p)
        };
        let (g_top, p_top) = scaled(1.0);
        let best = match self.plan_goal(start, g_top, &p_top) {
            Ok(b) if self.acceptable(&b, &start, goal) => b,
            // Not even the axis maximum avoids it: the maximum comes closest.
            Ok(b) => return Ok((b, p_top, false)),
            Err(_) => return Ok((first, *params, false)),
        };
        let (mut lo, mut hi) = (0.0, 1.0);
        let mut found = (best, p_top);
        for _ in 0..NO_OVERSHOOT_STEPS {
            let mid = 0.5 * (lo + hi);
            let (g, p) = scaled(mid);
            match self.plan_goal(start, g, &p) {
                Ok(pl) if self.acceptable(&pl, &start, goal) => {
                    hi = mid;
                    found = (pl, p);
                }
                _ => lo = mid,
            }
        }
        Ok((found.0, found.1, true))
    }

    fn change(&mut self, what: DynamicsChange, value: f64) -> Result<CommandStatus, CommandError> {
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

    fn halt(
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
        self.state = AxisState::DiscreteMotion;
        Ok(CommandStatus::Active)
    }

    fn stop(
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
        self.state = AxisState::Stopping;
        Ok(CommandStatus::Active)
    }

    /// Aborts the running commands but keeps the current set values (to brake from them).
    fn abort_all_but_values(&mut self, handles: &mut HandleTable) {
        if let Some(m) = self.motion.take() {
            handles.set(m.handle, CommandStatus::Aborted);
        }
        self.queue
            .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
    }

    /// Starts a braking motion from the current set values.
    pub(super) fn start_stop_motion(
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
}

/// What a plan is for, and what it must not do.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Goal {
    /// Reach velocity `v` (slowing down with `decel_jerk`) without overshooting it.
    Velocity { v: f64, decel_jerk: f64 },
    /// Reach `target` at `v_end`; with `no_reverse`, without passing it and coming back.
    Position {
        target: f64,
        v_end: f64,
        no_reverse: bool,
    },
}

/// Whether a profile starting at velocity `v0` ever moves against its initial direction
/// (for a position move: passes the target and comes back).
fn reverses(p: &Profile, v0: f64) -> bool {
    let dir = if v0 != 0.0 {
        v0.signum()
    } else {
        (p.end_state().p - p.start_state().p).signum()
    };
    if dir == 0.0 {
        return false;
    }
    let (lo, hi) = velocity_range(p);
    let tol = 1e-9 * (lo.abs().max(hi.abs()).max(1e-12));
    if dir > 0.0 {
        lo < -tol
    } else {
        hi > tol
    }
}

/// Whether a velocity profile from `v0` to `v` goes beyond `v` on the way.
fn overshoots_velocity(p: &Profile, v0: f64, v: f64) -> bool {
    let (lo, hi) = velocity_range(p);
    let tol = 1e-9 * v.abs().max(v0.abs()).max(1e-12);
    if v >= v0 {
        hi > v + tol
    } else {
        lo < v - tol
    }
}

/// Lowest and highest velocity over a profile (segment ends and interior extrema).
fn velocity_range(p: &Profile) -> (f64, f64) {
    let s = p.start_state();
    let (mut lo, mut hi) = (s.v, s.v);
    let mut note = |v: f64| {
        lo = lo.min(v);
        hi = hi.max(v);
    };
    for seg in p.segments() {
        note(seg.end().v);
        if let crate::profile::Shape::Jerk(j) = seg.shape {
            if j != 0.0 {
                let tau = -seg.start.a / j;
                if tau > 0.0 && tau < seg.duration {
                    note(seg.sample(tau).v);
                }
            }
        }
    }
    note(p.end_state().v);
    (lo, hi)
}
