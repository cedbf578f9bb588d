//! A follower's cycle: its set values from its master relation, its limits checked
//! against what the master asks, and what happens when the master fails or the relation
//! ends.

use super::handle::{CommandStatus, HandleId, HandleTable};
use super::motion::{Epoch, Motion, MotionKind, MoveParams};
use super::state::Event;
use super::status::{AxisFault, SyncLimit};
use super::{Axis, AxisFeedback, AxisKind, SyncLimitReaction};
use crate::axis::command::MoveDirection;
use crate::cam::CamTable;
use crate::profile::{plan_velocity, KinematicState, Limits};
use crate::sync::{FollowOut, MasterSample, Split};

/// Status bits of a relation in one cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct SyncBits {
    pub in_sync: bool,
    pub end_of_profile: bool,
    pub limit_exceeded: bool,
}

impl Axis {
    /// The master this axis follows and which of its values.
    pub fn following(&self) -> Option<(usize, crate::sync::command::MasterValue)> {
        self.follow.map(|f| (f.master, f.source))
    }

    /// The cam table slot this axis' relation reads, if it cams.
    pub fn cam_table_in_use(&self) -> Option<usize> {
        self.follow.and_then(|f| f.cam_table())
    }

    /// This axis as a master: its set or actual values this cycle.
    pub fn master_sample(&self, source: crate::sync::command::MasterValue) -> MasterSample {
        let s = &self.status;
        let actual =
            source == crate::sync::command::MasterValue::Actual && self.cfg.kind.has_feedback();
        MasterSample {
            at: Split {
                turns: s.turns,
                p: if actual { s.actual_position } else { s.set.p },
            },
            v: if actual { s.actual_velocity } else { s.set.v },
            a: if actual { 0.0 } else { s.set.a },
            available: !(s.state == super::state::AxisState::ErrorStop
                && self.cfg.kind.has_feedback()),
            period: self.period(),
            actual,
        }
    }

    /// The set position as whole periods and the rest.
    pub(crate) fn set_split(&self) -> Split {
        Split {
            turns: self.frame_turns,
            p: self.main.p,
        }
    }

    /// Puts the set position at `at`, moving the frame's whole periods (and the actual
    /// position with them) so both stay small.
    fn set_frame(&mut self, at: Split) {
        if let Some(period) = self.period() {
            let shift = (at.turns - self.frame_turns) as f64 * period;
            self.frame_turns = at.turns;
            self.actual_p -= shift;
        }
        self.main.p = at.p;
    }

    /// Whether a group's path drives the axis, and which group.
    pub fn driven_by_group(&self) -> Option<usize> {
        self.group
    }

    /// The group `g` takes the axis over for a move (from Standstill; the kernel checked).
    pub(crate) fn begin_group_motion(&mut self, g: usize) {
        self.group = Some(g);
        self.enter(Event::SynchronizedMotionStarted);
    }

    /// The axis' group is enabled or disabled.
    pub(crate) fn set_coordinated(&mut self, on: bool) {
        self.coordinated = on;
    }

    /// One cycle under a group: its path's set values. The cycle the path ends, or one
    /// without a path, the axis stands with its group: out of SynchronizedMotion in that
    /// same cycle, so a command sent on the group move's Done finds it standing.
    pub(super) fn group_step(&mut self, path: Option<&super::PathSample>) {
        if let Some(s) = path {
            self.main = s.set;
            if !s.last {
                return;
            }
        }
        self.group = None;
        self.main = KinematicState::at_rest(self.main.p);
        if self.state == super::state::AxisState::SynchronizedMotion {
            self.enter(Event::MotionDone);
        }
    }

    /// One cycle of a follower.
    pub(super) fn follow_step(
        &mut self,
        m: &MasterSample,
        cams: &[Option<CamTable>],
        now: u64,
        dt: f64,
        handles: &mut HandleTable,
    ) {
        let Some(mut f) = self.follow else { return };
        if !m.available {
            self.fault(AxisFault::MasterLost { master: f.master }, handles);
            self.brake_from_last_cycle(now, dt, handles);
            return;
        }
        let out = f.sample(m, self.period(), cams, now, dt);
        self.follow = Some(f);
        if let Some(limit) = self.sync_violation(&out, m) {
            match self.cfg.sync_limit_reaction {
                SyncLimitReaction::ErrorStop => {
                    self.fault(AxisFault::SyncLimit(limit), handles);
                    self.brake_from_last_cycle(now, dt, handles);
                    return;
                }
                SyncLimitReaction::Warning => self.sync_bits.limit_exceeded = true,
            }
        }
        self.set_frame(out.at);
        self.main.j = (out.a - self.main.a) / dt;
        self.main.v = out.v;
        self.main.a = out.a;
        self.sync_bits.in_sync = out.in_sync;
        self.sync_bits.end_of_profile = out.ended || out.wrapped;
        if out.ended {
            handles.set(f.handle, CommandStatus::Done);
            self.follow = None;
            let h = handles.issue(CommandStatus::Active);
            self.continue_at_velocity(h, f.command, Epoch::at(now));
        }
    }

    /// The braking motion a fault started plans from the last cycle's set values (the
    /// relation's values of this cycle were not taken): it starts at the last cycle, so
    /// this cycle's set value is already one cycle into it.
    fn brake_from_last_cycle(&mut self, now: u64, dt: f64, handles: &mut HandleTable) {
        if let Some(m) = self.motion.as_mut() {
            m.epoch = Epoch::at(now.saturating_sub(1));
        }
        self.advance(now, dt, handles);
    }

    /// What of the follower's limits the relation's values break, if any. With the
    /// reaction ErrorStop the speed is judged where a brake from here would take it (the
    /// acceleration cannot drop to 0 faster than the jerk allows), so the follower never
    /// exceeds its maximum speed, not even while it brakes.
    fn sync_violation(&self, out: &FollowOut, m: &MasterSample) -> Option<SyncLimit> {
        let max = self.cfg.max;
        let tol = 1.0 + 1e-9;
        let peak = match self.cfg.sync_limit_reaction {
            SyncLimitReaction::ErrorStop if out.a * out.v > 0.0 && !m.actual => {
                out.v + out.a * out.a.abs() / (2.0 * max.jmax)
            }
            _ => out.v,
        };
        if peak.abs() > max.vmax * tol {
            return Some(SyncLimit {
                quantity: "speed",
                value: peak,
                max: max.vmax,
            });
        }
        let eps_v = 1e-9 * max.vmax;
        if out.v.abs() > eps_v && !self.direction_allowed(out.v.signum()) {
            return Some(SyncLimit {
                quantity: "direction",
                value: out.v,
                max: 0.0,
            });
        }
        if m.actual {
            // An encoder's velocity differences are noise: no acceleration is judged.
            return None;
        }
        let (quantity, lim) = if out.a * out.v < 0.0 {
            ("deceleration", max.dmax)
        } else {
            ("acceleration", max.amax)
        };
        (out.a.abs() > lim * (1.0 + 1e-6)).then_some(SyncLimit {
            quantity,
            value: out.a,
            max: lim,
        })
    }

    /// After a relation (GearOut, CamOut, the end of a non-periodic cam): the axis goes on
    /// at its velocity (PLCopen: ContinuousMotion), or stands if it stood.
    pub(super) fn continue_at_velocity(&mut self, h: HandleId, command: &'static str, at: Epoch) {
        let max = self.cfg.max;
        let s = self.main;
        if s.v.abs() <= 1e-9 * max.vmax && s.a.abs() <= 1e-9 * max.amax {
            self.main = KinematicState::at_rest(s.p);
            self.enter(Event::MotionDone);
            return;
        }
        let d = self.vel_dynamics;
        let limits = Limits {
            vmax: max.vmax.max(s.v.abs()),
            amax: d.acceleration,
            dmax: d.deceleration,
            jmax: d.jerk,
        };
        let v = s.v.clamp(-max.vmax, max.vmax);
        let Ok(profile) = plan_velocity(d.ramp, s, v, &limits) else {
            self.main = KinematicState::at_rest(s.p);
            self.enter(Event::MotionDone);
            return;
        };
        let direction = if v >= 0.0 {
            MoveDirection::Positive
        } else {
            MoveDirection::Negative
        };
        self.last_direction = direction.sign();
        self.motion = Some(Motion {
            kind: MotionKind::Velocity { direction },
            profile,
            epoch: at,
            params: MoveParams {
                limits,
                ramp: d.ramp,
            },
            handle: h,
            command,
            decel_jerk: d.jerk,
        });
        self.enter(Event::ContinuousMotionStarted);
    }

    /// An external axis: an encoder whose module reports a failure (a fault code in the
    /// feedback) goes to ErrorStop; Reset brings it back once the failure is gone.
    pub(super) fn take_encoder_fault(&mut self, fb: &AxisFeedback, handles: &mut HandleTable) {
        debug_assert_eq!(self.cfg.kind, AxisKind::External);
        self.drive_fault = fb.fault.is_some();
        if let Some((h, since)) = self.reset_pending {
            if fb.fault.is_none() {
                self.reset_pending = None;
                self.enter(Event::Reset { powered: false });
                self.status.error = None;
                handles.set(h, CommandStatus::Done);
            } else if self.last_tick.saturating_sub(since) > super::DRIVE_RESET_TICKS {
                self.reset_pending = None;
                handles.set(
                    h,
                    CommandStatus::Error(super::command::CommandError::DriveResetFailed {
                        code: fb.fault.unwrap_or(0),
                    }),
                );
            }
        }
        if let Some(code) = fb.fault {
            if self.state != super::state::AxisState::ErrorStop {
                self.fault(AxisFault::Encoder { code }, handles);
            }
        }
    }
}
