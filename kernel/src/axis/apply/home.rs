//! Homing commands (Jetter MoveHome and SetReference, Beckhoff MC_StepAbsoluteSwitch) and
//! the hardware limit switches (issue 13 §1–2, SPEC §4).
//!
//! A homing run is a [`MotionKind::Home`] motion whose profile the sequencer
//! ([`crate::homing::sequence`]) replans each time it demands something new — always an
//! S-curve from the last set values, so every homing move is jerk-limited and continuous.
//! The axis is not homed while it runs (as TwinCAT's MC_Home clears "calibrated" at the
//! start) and is homed when the run sets the position (SPEC §1).
//!
//! Limit switches: outside homing, a set velocity into an active limit switch stops the
//! axis with its quick-stop deceleration and puts it in ErrorStop ("positive limit
//! switch"); a move towards an active switch is refused, so after Reset the axis can only
//! move away from it. Homing runs handle the switches themselves (reversal, or the
//! reference in `LimitSwitch`).

use crate::axis::command::{Command, CommandError, PositioningMode};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::{Epoch, Motion, MotionKind, MoveParams};
use crate::axis::state::Event;
use crate::axis::status::AxisFault;
use crate::axis::{AxisFeedback, HomingDynamics};
use crate::homing::sequence::{Demand, Observation, Plan, Sequencer};
use crate::homing::{
    HomingMode, HomingStatus, LimitSide, MoveHomeCall, StepAbsoluteSwitch, SwitchConfig,
};
use crate::profile::{plan_position, plan_velocity, KinematicState, Limits, Profile, RampType};

use super::super::Axis;

/// `value` must be finite and > 0 (or +∞ where `infinite_ok`) and at most `max`.
fn check(
    command: &'static str,
    parameter: &'static str,
    value: f64,
    max: f64,
    infinite_ok: bool,
) -> Result<(), CommandError> {
    let problem = if value.is_nan() || value <= 0.0 {
        Some("must be > 0")
    } else if value.is_infinite() && !infinite_ok {
        Some("must be finite")
    } else if value > max {
        Some("exceeds the axis maximum")
    } else {
        None
    };
    match problem {
        Some(problem) => Err(CommandError::HomingParameter {
            command,
            parameter,
            value,
            problem,
        }),
        None => Ok(()),
    }
}

fn finite(command: &'static str, parameter: &'static str, value: f64) -> Result<(), CommandError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(CommandError::HomingParameter {
            command,
            parameter,
            value,
            problem: "must be finite",
        })
    }
}

impl Axis {
    /// MoveHome: merges the call into the last-used parameters, validates, starts.
    pub(super) fn move_home(
        &mut self,
        call: &MoveHomeCall,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let p = call.merged(&self.move_home);
        let c = "MoveHome";
        let max = self.cfg.max;
        check(
            c,
            "Acceleration",
            p.acceleration,
            max.amax.min(max.dmax),
            false,
        )?;
        check(c, "Jerk", p.jerk, max.jmax, false)?;
        check(
            c,
            "SpeedSwitchSearch",
            p.speed_switch_search,
            max.vmax,
            false,
        )?;
        check(
            c,
            "SpeedReferenceSearch",
            p.speed_reference_search,
            max.vmax,
            false,
        )?;
        let inf = f64::INFINITY;
        check(
            c,
            "MaxDistanceSwitchSearch",
            p.max_distance_switch_search,
            inf,
            true,
        )?;
        check(
            c,
            "MaxDistanceReferenceSearch",
            p.max_distance_reference_search,
            inf,
            true,
        )?;
        finite(c, "ReferenceOffset", p.reference_offset)?;
        finite(c, "NormalPosition", p.normal_position)?;
        if p.switch_config == SwitchConfig::NoSwitch
            && matches!(
                p.mode,
                HomingMode::SwitchingEdge1Phase | HomingMode::SwitchingEdge2Phase
            )
        {
            return Err(CommandError::HomingParameter {
                command: c,
                parameter: "Mode",
                value: f64::NAN,
                problem: "SwitchingEdge needs a switch: SwitchConfig NoSwitch is for ZeroPulse",
            });
        }
        self.check_homing_direction(c, p.direction.sign())?;
        self.move_home = p;
        let dynamics = HomingDynamics {
            acceleration: p.acceleration,
            deceleration: p.acceleration,
            jerk: p.jerk,
            speed: p.speed_switch_search,
        };
        self.start_homing(p.plan(), dynamics, c, h, handles)
    }

    /// MC_StepAbsoluteSwitch: validates and starts.
    pub(super) fn step_absolute_switch(
        &mut self,
        p: &StepAbsoluteSwitch,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let c = "StepAbsoluteSwitch";
        let max = self.cfg.max;
        check(c, "Velocity", p.velocity, max.vmax, false)?;
        check(c, "Acceleration", p.acceleration, max.amax, false)?;
        check(c, "Deceleration", p.deceleration, max.dmax, false)?;
        check(c, "Jerk", p.jerk, max.jmax, false)?;
        check(c, "DistanceLimit", p.distance_limit, f64::INFINITY, true)?;
        finite(c, "Position", p.position)?;
        self.check_homing_direction(c, p.direction.sign())?;
        let dynamics = HomingDynamics {
            acceleration: p.acceleration,
            deceleration: p.deceleration,
            jerk: p.jerk,
            speed: p.velocity,
        };
        self.start_homing(p.plan(), dynamics, c, h, handles)
    }

    /// Homing searches both ways: an axis allowed one direction only cannot home.
    fn check_homing_direction(&self, command: &'static str, d: f64) -> Result<(), CommandError> {
        if self.direction_allowed(d) && self.direction_allowed(-d) {
            Ok(())
        } else {
            Err(CommandError::DirectionNotAllowed {
                command,
                allowed: if self.direction_allowed(1.0) {
                    "positive"
                } else {
                    "negative"
                },
                wanted: "both ways (homing searches and reverses)",
            })
        }
    }

    /// A search for a switch's edge takes the edge's position from the drive's touch
    /// probe only (never from the cycle-sampled position): a plan that needs the edge of
    /// a switch the probe cannot latch — a limit switch without the drive's probe source
    /// (0x60D0), a switch read from an I/O module — is refused before anything moves.
    fn check_latchable(&self, plan: &Plan, command: &'static str) -> Result<(), CommandError> {
        use crate::homing::sequence::{Goal, Signal};
        let parameter = if command == "MoveHome" {
            "SwitchConfig"
        } else {
            "SwitchMode"
        };
        for s in plan.searches.iter().flatten() {
            let Goal::Edge { signal, .. } = s.goal else {
                continue;
            };
            let problem = match signal {
                Signal::Limit(_) if !self.cfg.limit_edges_latched => {
                    "needs the limit switch's edge from the drive's touch probe, which this \
                     axis cannot route to its limit switches (configure [axis.switches] \
                     probe_source, 0x60D0)"
                }
                Signal::Reference if !self.cfg.reference_edges_latched => {
                    "needs the reference switch's edge from the drive's touch probe, which \
                     cannot latch this axis' reference switch (read from an I/O module, or \
                     the probe not mapped): wire it to the drive's probe input"
                }
                _ => continue,
            };
            return Err(CommandError::HomingParameter {
                command,
                parameter,
                value: f64::NAN,
                problem,
            });
        }
        Ok(())
    }

    fn start_homing(
        &mut self,
        plan: Plan,
        dynamics: HomingDynamics,
        command: &'static str,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        self.check_latchable(&plan, command)?;
        if !self.cfg.kind.has_feedback() {
            // Without feedback there are no switches or latches: the run would search forever.
            return Err(CommandError::NothingToHomeOn {
                command,
                kind: self.cfg.kind.name(),
            });
        }
        if let Some(m) = self.motion.take() {
            // Accepted only in Standstill, so nothing runs; keep the books straight anyway.
            handles.set(m.handle, CommandStatus::Aborted);
        }
        self.homing_dynamics = dynamics;
        let start = KinematicState::at_rest(self.main.p);
        self.main = start;
        self.motion = Some(Motion {
            kind: MotionKind::Home,
            profile: Profile::new(start),
            epoch: Epoch::at(self.last_tick),
            params: MoveParams {
                limits: self.homing_limits(dynamics.speed),
                ramp: RampType::SCurve,
            },
            handle: h,
            command,
            decel_jerk: dynamics.jerk,
        });
        let seq = Sequencer::new(plan);
        self.home_status = seq.status();
        self.homing = Some((seq, h));
        self.homed = false;
        self.enter(Event::HomingStarted);
        self.refresh_status();
        Ok(CommandStatus::Busy)
    }

    fn homing_limits(&self, speed: f64) -> Limits {
        let d = self.homing_dynamics;
        Limits {
            vmax: speed,
            amax: d.acceleration,
            dmax: d.deceleration,
            jmax: d.jerk,
        }
    }

    /// SetReference: the position becomes `value` without moving; homed, "reference set".
    pub(super) fn set_reference(&mut self, value: f64) -> Result<CommandStatus, CommandError> {
        finite("MoveHome.SetReference", "position", value)?;
        let r = self.set_position(value, false)?;
        self.home_status = HomingStatus {
            reference_set: true,
            ..HomingStatus::default()
        };
        self.refresh_status();
        Ok(r)
    }

    /// Switches and latches of this cycle (latches into the axis frame).
    pub(in crate::axis) fn take_switches(&mut self, fb: &AxisFeedback) {
        self.switches = fb.switches;
        let mut l = fb.probe.shifted(self.position_offset);
        if let Some(m) = self.cfg.mechanics.modulo {
            for latch in [&mut l.rising, &mut l.falling, &mut l.index] {
                latch.position = m.follow(self.main.p, latch.position);
            }
        }
        self.latches = l;
    }

    /// A move `cmd` towards an active limit switch is refused.
    pub(super) fn check_towards_limit(&self, cmd: &Command) -> Result<(), CommandError> {
        if !(self.switches.negative_limit || self.switches.positive_limit) {
            return Ok(());
        }
        let towards = match cmd {
            Command::MovePtp(m) => match m.mode {
                PositioningMode::AbsNormal => m.target - self.main.p,
                PositioningMode::RelTarget => {
                    self.last_target.unwrap_or(self.main.p) + m.target - self.main.p
                }
                PositioningMode::RelActual => m.target,
                // Modulo modes: a rotary axis has no travel ends to guard.
                _ => 0.0,
            },
            Command::MoveVelocity(v) => v.direction.sign(),
            Command::Jog(j) => j.direction.sign(),
            _ => 0.0,
        };
        if towards != 0.0 && self.switches.limit_towards(towards) {
            return Err(CommandError::TowardsLimitSwitch {
                command: cmd.name(),
                side: LimitSide::towards(towards),
            });
        }
        Ok(())
    }

    /// Outside homing: moving into an active limit switch is a quick stop into ErrorStop.
    pub(in crate::axis) fn check_limit_switches(&mut self, handles: &mut HandleTable) {
        use crate::axis::state::AxisState;
        // A drive homing by itself reverses at the switches as its method says.
        if self.homing.is_some()
            || self.lent.is_some()
            || matches!(self.state, AxisState::ErrorStop | AxisState::Disabled)
        {
            return;
        }
        let v = self.main.v + self.overlay_set.v;
        let eps = 1e-9 * self.cfg.max.vmax;
        if v.abs() <= eps || !self.switches.limit_towards(v) {
            return;
        }
        let side = LimitSide::towards(v);
        self.fault(AxisFault::LimitSwitch { side }, handles);
        // The hardware limit brakes with the quick-stop deceleration (issue 13 §1).
        let _ = self.start_stop_motion(
            MotionKind::Stop,
            self.cfg.quick_stop_deceleration,
            HandleId(u64::MAX),
            "ErrorStop",
        );
    }

    /// One cycle of the running homing run.
    pub(in crate::axis) fn run_homing(&mut self, now: u64, dt: f64, handles: &mut HandleTable) {
        let Some((mut seq, h)) = self.homing else {
            return;
        };
        let Some(m) = self
            .motion
            .filter(|m| m.handle == h && m.kind == MotionKind::Home)
        else {
            // Another command took the axis over (it aborted our handle).
            self.homing = None;
            return;
        };
        let o = Observation {
            actual_p: self.actual_p,
            actual_v: self.actual_v,
            set_p: self.main.p,
            set_v: self.main.v,
            settled: m.ended(now, dt),
            inputs: self.switches,
            latches: self.latches,
        };
        let demand = seq.step(&o);
        self.home_status = seq.status();
        self.homing = Some((seq, h));
        let planned = match demand {
            Demand::Keep => return,
            Demand::Velocity(v) => {
                // vmax only caps the profile; the run's speed keeps it > 0 when stopping.
                let vmax = v
                    .abs()
                    .max(self.main.v.abs())
                    .max(self.homing_dynamics.speed);
                let lim = self.homing_limits(vmax);
                plan_velocity(RampType::SCurve, self.main, v, &lim)
            }
            Demand::MoveTo(target) => {
                let speed = self.homing_dynamics.speed;
                let lim = self.homing_limits(speed.max(self.main.v.abs()));
                plan_position(RampType::SCurve, self.main, target, 0.0, &lim)
            }
            Demand::SetPosition(p) => {
                self.motion = None;
                self.homing = None;
                self.main.v = 0.0;
                self.main.a = 0.0;
                self.main.j = 0.0;
                let _ = self.set_position(p, false);
                self.home_status = HomingStatus {
                    reference_set: true,
                    ..seq.status()
                };
                handles.set(h, CommandStatus::Done);
                self.enter(Event::MotionDone);
                return;
            }
            Demand::Fail(e) => {
                let fault = match e {
                    crate::homing::HomingError::LimitSwitch { side, .. } => {
                        AxisFault::LimitSwitch { side }
                    }
                    e => AxisFault::Command(CommandError::Homing(e)),
                };
                let limit = matches!(fault, AxisFault::LimitSwitch { .. });
                if limit {
                    handles.set(h, CommandStatus::Error(CommandError::Homing(e)));
                    self.motion = None;
                }
                self.fault(fault, handles);
                if limit {
                    let _ = self.start_stop_motion(
                        MotionKind::Stop,
                        self.cfg.quick_stop_deceleration,
                        HandleId(u64::MAX),
                        "ErrorStop",
                    );
                }
                return;
            }
        };
        match planned {
            Ok(profile) => {
                if let Some(m) = self.motion.as_mut() {
                    m.profile = profile;
                    m.epoch = Epoch::at(now);
                }
            }
            Err(error) => {
                let e = CommandError::Plan {
                    command: m.command,
                    error,
                };
                self.fault(AxisFault::Command(e), handles);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::homing::MoveHome;

    #[test]
    fn parameters_are_checked_by_name() {
        let e = check("MoveHome", "SpeedSwitchSearch", 0.0, 10.0, false).unwrap_err();
        assert_eq!(
            e.to_string(),
            "MoveHome: parameter SpeedSwitchSearch = 0 must be > 0"
        );
        assert!(check(
            "MoveHome",
            "MaxDistanceSwitchSearch",
            f64::INFINITY,
            f64::INFINITY,
            true
        )
        .is_ok());
        assert!(check("MoveHome", "Jerk", 11.0, 10.0, false).is_err());
    }

    #[test]
    fn move_home_defaults_are_inside_the_maxima() {
        let p = MoveHome::defaults(100.0, 1000.0, 10_000.0);
        assert!(p.speed_switch_search <= 100.0 && p.speed_reference_search < p.speed_switch_search);
        assert!(p.acceleration <= 1000.0 && p.jerk <= 10_000.0);
    }
}
