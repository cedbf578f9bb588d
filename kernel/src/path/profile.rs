//! A planned path segment: the path length s(t) as a one-dimensional jerk-limited profile
//! (the axes' planner, [`crate::profile::plan_position`] with [`RampType::SCurve`], from
//! rest at s = 0 to rest at s = length) under the path dynamics of [`super::limits`], and
//! every axis' set values from it through the segment's geometry.
//!
//! Sampling is closed form (the 1-D profile's and the geometry's), allocation-free and
//! never panics, so the cycle may call [`PathProfile::sample`] directly. The end is
//! exact: the 1-D profile pins s = length at its end, and the segment returns its end
//! point to the bit there.

use super::limits::{path_limits, AxisLimits, PathLimits, PathLimitsError};
use super::segment::{PathSegment, MAX_AXES};
use crate::profile::{plan_position, KinematicState, Limits, PlanError, Profile, RampType};
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
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathProfile {
    segment: PathSegment,
    limits: PathLimits,
    path: Profile,
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
        // A move to where the group is: nothing to plan (the 1-D planner would still
        // return a sub-millisecond wiggle for a zero distance).
        if segment.length() <= 0.0 {
            return Ok(Self {
                segment,
                limits,
                path: Profile::new(KinematicState::at_rest(0.0)),
            });
        }
        let path = plan_position(
            RampType::SCurve,
            KinematicState::at_rest(0.0),
            segment.length(),
            0.0,
            &Limits {
                vmax: limits.v,
                amax: limits.a,
                dmax: limits.d,
                jmax: limits.j,
            },
        )?;
        Ok(Self {
            segment,
            limits,
            path,
        })
    }

    /// The geometry.
    pub fn segment(&self) -> &PathSegment {
        &self.segment
    }

    /// The path dynamics the profile keeps.
    pub fn limits(&self) -> &PathLimits {
        &self.limits
    }

    /// s(t): path length, path speed, acceleration and jerk over time.
    pub fn path(&self) -> &Profile {
        &self.path
    }

    /// Duration (s).
    pub fn duration(&self) -> f64 {
        self.path.duration()
    }

    /// Every axis' position, velocity, acceleration and jerk `t` seconds after the start
    /// (`t <= 0`: the start at rest; past the end: the end at rest). Axes beyond the
    /// group's stand at their start.
    pub fn sample(&self, t: f64) -> [KinematicState; MAX_AXES] {
        along(&self.segment, &self.path.sample(t))
    }
}

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
