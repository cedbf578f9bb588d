//! A planned path segment: the path length s(t) as a one-dimensional jerk-limited profile
//! (the axes' planner, [`crate::profile::plan_position`] with [`RampType::SCurve`], from
//! rest at s = 0 to rest at s = length) under the path dynamics of [`super::limits`], and
//! every axis' set values from it through the segment's geometry.
//!
//! Sampling is closed form (the 1-D profile's and the geometry's), allocation-free and
//! never panics, so the cycle may call [`PathProfile::sample`] directly. The end is
//! exact: the 1-D profile pins s = length at its end, and the segment returns its end
//! point to the bit there.

use super::blend::{corner_at, corner_in, Corner, CornerInputs, Junction, Transition};
use super::limits::{path_limits, AxisLimits, PathLimits, PathLimitsError};
use super::segment::{PathSegment, MAX_AXES};
use crate::profile::{
    plan_position, plan_velocity, KinematicState, Limits, PlanError, Profile, RampType,
};
use thiserror::Error;

/// Why a path segment cannot be planned.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum PathPlanError {
    /// The path dynamics cannot be derived.
    #[error(transparent)]
    Limits(#[from] PathLimitsError),
    /// The 1-D profile along the path cannot be planned.
    #[error("planning along the path: {0}")]
    Plan(#[from] PlanError),
}

/// A path segment with its timing: the group's set values at any time.
///
/// The path length over time is up to three pieces: a ramp in from rest (when the segment
/// was blended into: the mirror of the previous segment's ramp out, see [`super::blend`]),
/// the body, and a ramp out to rest at the end (when the next segment is blended in). The
/// body can be planned again from a later state (a blend decided while moving, a stop).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathProfile {
    segment: PathSegment,
    /// The command's dynamics (what `limits` was derived from).
    cmd: PathLimits,
    limits: PathLimits,
    /// The path speed the axes alone allow on this segment.
    axis_speed: f64,
    ramp_in: Option<Profile>,
    /// When the body starts (s after the segment's start).
    body_t0: f64,
    body: Profile,
    ramp_out: Option<Profile>,
}

impl PathProfile {
    /// Plans `segment` from rest to rest: the command `cmd` (its infinite values leave
    /// them to the axes) capped so no axis exceeds its `axes` limits.
    pub fn plan(
        segment: PathSegment,
        axes: &[AxisLimits],
        cmd: &PathLimits,
    ) -> Result<Self, PathPlanError> {
        let limits = path_limits(&segment, axes, cmd)?;
        let axis_speed = path_limits(&segment, axes, &FREE)?.v;
        let mut out = Self {
            segment,
            cmd: *cmd,
            limits,
            axis_speed,
            ramp_in: None,
            body_t0: 0.0,
            body: Profile::new(KinematicState::at_rest(0.0)),
            ramp_out: None,
        };
        // A move to where the group is: nothing to plan (the 1-D planner would still
        // return a sub-millisecond wiggle for a zero distance).
        if segment.length() > 0.0 {
            out.body = out.plan_body(KinematicState::at_rest(0.0), segment.length(), 0.0, axes)?;
        }
        Ok(out)
    }

    /// The body from `start` to `target` arriving at `v_end`, within this segment's
    /// dynamics (its speed raised to `v_end` for a blend faster than the command).
    fn plan_body(
        &self,
        start: KinematicState,
        target: f64,
        v_end: f64,
        axes: &[AxisLimits],
    ) -> Result<Profile, PlanError> {
        let l = self.dynamics_up_to(start.v.abs().max(v_end), axes);
        plan_position(
            RampType::SCurve,
            start,
            target,
            v_end,
            &Limits {
                vmax: self.limits.v.max(v_end),
                ..l
            },
        )
    }

    /// The path acceleration, deceleration and jerk that keep the axes within their limits
    /// at path speeds up to `top`: the segment's own, or — when a blend runs it faster
    /// than its command — those derived again at `top` (an arc's centripetal terms grow
    /// with the speed).
    fn dynamics_up_to(&self, top: f64, axes: &[AxisLimits]) -> Limits {
        let l = if top > self.limits.v {
            path_limits(&self.segment, axes, &PathLimits { v: top, ..self.cmd })
                .unwrap_or(self.limits)
        } else {
            self.limits
        };
        Limits {
            vmax: l.v,
            amax: l.a,
            dmax: l.d,
            jmax: l.j,
        }
    }

    /// The geometry.
    pub fn segment(&self) -> &PathSegment {
        &self.segment
    }

    /// The path dynamics the profile keeps.
    pub fn limits(&self) -> &PathLimits {
        &self.limits
    }

    /// The path speed the axes alone allow on this segment (a blend may pass faster than
    /// the command, never faster than this).
    pub fn axis_speed(&self) -> f64 {
        self.axis_speed
    }

    /// When the body starts (the end of the ramp in; 0 without one).
    pub fn body_start(&self) -> f64 {
        self.body_t0
    }

    /// When the ramp out starts (the next segment's start), if the segment blends into
    /// the next.
    pub fn ramp_out_start(&self) -> Option<f64> {
        self.ramp_out.map(|_| self.body_t0 + self.body.duration())
    }

    /// Duration (s).
    pub fn duration(&self) -> f64 {
        self.body_t0 + self.body.duration() + self.ramp_out.map_or(0.0, |r| r.duration())
    }

    /// s(t): path length, path speed, acceleration and jerk `t` s after the start.
    pub fn path_at(&self, t: f64) -> KinematicState {
        if let Some(r) = &self.ramp_in {
            if t < self.body_t0 {
                return r.sample(t);
            }
        }
        let tb = t - self.body_t0;
        match &self.ramp_out {
            Some(r) if tb >= self.body.duration() => r.sample(tb - self.body.duration()),
            _ => self.body.sample(tb),
        }
    }

    /// Every axis' position, velocity, acceleration and jerk `t` seconds after the start
    /// (`t <= 0`: the start; past the end: the end at rest). Axes beyond the group's
    /// stand at their start.
    pub fn sample(&self, t: f64) -> [KinematicState; MAX_AXES] {
        along(&self.segment, &self.path_at(t))
    }

    /// Where the body may be planned again from, at the earliest `t`: its time and state
    /// (never inside the ramp in, which mirrors the previous segment's ramp out).
    fn replan_point(&self, t: f64) -> (f64, KinematicState) {
        let t = t.max(self.body_t0);
        let s = self.path_at(t);
        (t, KinematicState { j: 0.0, ..s })
    }

    /// Replaces the body from `t` on (never inside the ramp in) by a brake to rest along
    /// the path with the segment's deceleration and jerk; drops a ramp out.
    pub fn brake_from(&mut self, t: f64, axes: &[AxisLimits]) {
        let (t0, at) = self.replan_point(t);
        let limits = Limits {
            vmax: self.limits.v.max(at.v.abs()),
            ..self.dynamics_up_to(at.v.abs(), axes)
        };
        let brake = plan_velocity(RampType::SCurve, at, 0.0, &limits)
            .or_else(|_| plan_velocity(RampType::Trapezoid, at, 0.0, &limits))
            .unwrap_or_else(|_| Profile::new(KinematicState::at_rest(at.p)));
        self.set_body(t0, brake);
        self.ramp_out = None;
    }

    /// The body from `t0` on (the time before it is the past: never sampled again).
    fn set_body(&mut self, t0: f64, body: Profile) {
        self.body_t0 = t0;
        self.body = body;
    }

    /// Blends `next` (planned from rest at this segment's end) into this segment from
    /// time `t` on: the fastest corner at most `wanted` (see [`super::blend`]) whose
    /// ramps fit both segments and which this segment can still reach from its state at
    /// `t`. On success this segment ends with the ramp out and `next` starts with the
    /// ramp in; `None` (nothing changed) when the junction must be passed at rest.
    pub fn blend_into(
        &mut self,
        next: &mut PathProfile,
        t: f64,
        wanted: f64,
        axes: &[AxisLimits],
        transition: Transition,
        max_deviation: f64,
    ) -> Option<Corner> {
        if self.ramp_out.is_some() || next.ramp_in.is_some() {
            return None;
        }
        let wanted = wanted.min(self.axis_speed).min(next.axis_speed);
        // The next segment brakes with what its axes allow at the speed it comes in with.
        let stop = next.dynamics_up_to(wanted, axes);
        let inputs = CornerInputs {
            first: &self.segment,
            second: &next.segment,
            axes,
            accel: self.limits.d.min(next.limits.a),
            jerk: self.limits.j.min(next.limits.j),
            transition,
            max_deviation,
            stop_decel: stop.dmax,
            stop_jerk: stop.jmax,
        };
        let junction = Junction::new(&inputs);
        let cap = corner_in(&inputs, &junction, wanted)?;
        let (t0, at) = self.replan_point(t);
        let len = self.segment.length();
        // The fastest corner this segment still reaches; slower ones when it is too late.
        // The pieces for corner `c`; when this segment cannot reach its speed, the speed
        // it reaches instead (a corner that slow fits: its ramp is shorter, the body
        // longer).
        type Pieces = (Profile, Profile, Profile, Profile);
        let attempt = |c: &Corner| -> Result<Pieces, Option<f64>> {
            let target = len - c.distance;
            if target < at.p {
                return Err(None);
            }
            let body = self
                .plan_body(at, target, c.speed, axes)
                .map_err(|_| None)?;
            let end = body.end_state();
            if body.lowest_velocity() < -1e-9 * c.speed {
                return Err(None);
            }
            if end.v < c.speed * (1.0 - 1e-9) {
                return Err(Some(end.v * (1.0 - 1e-9)));
            }
            let lim = Limits {
                vmax: c.speed,
                amax: c.accel,
                dmax: c.accel,
                jmax: c.jerk,
            };
            let out = plan_velocity(RampType::SCurve, end, 0.0, &lim).map_err(|_| None)?;
            let ramp = plan_velocity(
                RampType::SCurve,
                KinematicState::at_rest(0.0),
                c.speed,
                &lim,
            )
            .map_err(|_| None)?;
            let next_body = next
                .plan_body(ramp.end_state(), next.segment.length(), 0.0, axes)
                .map_err(|_| None)?;
            if next_body.lowest_velocity() < -1e-9 * c.speed {
                return Err(None);
            }
            Ok((body, out, ramp, next_body))
        };
        let mut found = None;
        match attempt(&cap) {
            Ok(p) => found = Some((cap, p)),
            Err(hint) => {
                // Every bound of the corner itself holds below `cap` (they tighten with
                // the speed): only the running segment's reach is searched, first at the
                // speed it reaches, then by halving.
                let at_speed = |v: f64| {
                    corner_at(&inputs, &junction, v).and_then(|c| attempt(&c).ok().map(|p| (c, p)))
                };
                if let Some(v) = hint.filter(|v| *v > 0.0 && *v < cap.speed) {
                    found = at_speed(v);
                }
                if found.is_none() {
                    let (mut lo, mut hi) = (0.0, cap.speed);
                    for _ in 0..BODY_SEARCH_STEPS {
                        let mid = 0.5 * (lo + hi);
                        match at_speed(mid) {
                            Some(f) => {
                                lo = mid;
                                found = Some(f);
                            }
                            None => hi = mid,
                        }
                    }
                }
            }
        }
        let (c, (body, out, ramp, next_body)) = found?;
        self.set_body(t0, body);
        self.ramp_out = Some(out);
        next.body_t0 = ramp.duration();
        next.ramp_in = Some(ramp);
        next.body = next_body;
        Some(c)
    }
}

/// Iterations of the search for a corner the running segment still reaches.
const BODY_SEARCH_STEPS: usize = 10;

const FREE: PathLimits = PathLimits {
    v: f64::INFINITY,
    a: f64::INFINITY,
    d: f64::INFINITY,
    j: f64::INFINITY,
};

/// Every axis' position, velocity, acceleration and jerk where the path parameter is `s`
/// (s, ṡ, s̈, s⃛): the chain rule through the segment's geometry. Also what a group that
/// brakes along its path (MC_GroupStop) samples, with a braking profile of its own.
pub fn along(segment: &PathSegment, s: &KinematicState) -> [KinematicState; MAX_AXES] {
    let g = segment.derivatives_at(s.p);
    let mut out = [KinematicState::default(); MAX_AXES];
    for (i, k) in out.iter_mut().enumerate() {
        let at = |a: &[f64; MAX_AXES]| a.get(i).copied().unwrap_or(0.0);
        let (p, d1, d2, d3) = (at(&g.p), at(&g.d1), at(&g.d2), at(&g.d3));
        *k = KinematicState {
            p,
            v: d1 * s.v,
            a: d2 * s.v * s.v + d1 * s.a,
            j: d3 * s.v * s.v * s.v + 3.0 * d2 * s.v * s.a + d1 * s.j,
        };
    }
    out
}
