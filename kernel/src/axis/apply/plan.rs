//! Planning a move from the last set values, guarded against overshoot: when a plan with
//! the command's dynamics would overshoot, its limits are raised just enough.

use crate::axis::command::CommandError;
use crate::axis::motion::MoveParams;
use crate::axis::Axis;
use crate::profile::{KinematicState, Limits, Profile, RampType};

/// Bisection steps when a dynamics change must be softened to avoid overshoot.
const NO_OVERSHOOT_STEPS: usize = 24;

impl Axis {
    /// The state a new move plans from: the last set values, except that an S-curve
    /// following a ramp without jerk limit starts from zero acceleration (those ramps jump
    /// in acceleration anyway; inheriting their acceleration would make the new jerk limit
    /// drag it down slowly and overshoot).
    pub(super) fn start_for(&self, ramp: RampType) -> KinematicState {
        let mut s = self.main;
        let prev = self.motion.map(|m| m.params.ramp);
        if ramp == RampType::SCurve && prev.is_some_and(|r| r != RampType::SCurve) {
            s.a = 0.0;
        }
        s
    }

    pub(super) fn plan_goal(
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
    pub(super) fn acceptable(&self, p: &Profile, start: &KinematicState, goal: Goal) -> bool {
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
    pub(super) fn plan_guarded(
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
}

/// What a plan is for, and what it must not do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Goal {
    /// Reach velocity `v` (slowing down with `decel_jerk`) without overshooting it.
    Velocity {
        /// Target velocity.
        v: f64,
        /// Jerk when slowing down.
        decel_jerk: f64,
    },
    /// Reach `target` at `v_end`; with `no_reverse`, without passing it and coming back.
    Position {
        target: f64,
        v_end: f64,
        no_reverse: bool,
    },
}

/// Whether a profile starting at velocity `v0` ever moves against its initial direction
/// (for a position move: passes the target and comes back).
pub(super) fn reverses(p: &Profile, v0: f64) -> bool {
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
