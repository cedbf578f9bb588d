//! Jerk-limited, time-optimal S-curve from an arbitrary state. STUB: being written.
use super::{KinematicState, Limits, PlanError, Profile};

/// Plans a position move; see [`super::plan_position`].
pub fn plan_position(
    start: KinematicState,
    target: f64,
    _v_end: f64,
    _lim: &Limits,
) -> Result<Profile, PlanError> {
    Err(PlanError::NoSolution {
        p: start.p,
        v: start.v,
        a: start.a,
        target,
    })
}

/// Plans a velocity change; see [`super::plan_velocity`].
pub fn plan_velocity(
    start: KinematicState,
    v_target: f64,
    _lim: &Limits,
) -> Result<Profile, PlanError> {
    Err(PlanError::NoSolution {
        p: start.p,
        v: start.v,
        a: start.a,
        target: v_target,
    })
}
