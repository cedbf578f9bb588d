//! Ramps without a jerk limit: trapezoid (linear), Sine and Linear/Sine (seed 000 §6.1.1).
//! STUB: being written.
use super::{KinematicState, Limits, PlanError, Profile};

/// Shape of the speeding-up and slowing-down ramps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RampShape {
    /// Constant acceleration and deceleration (trapezoid velocity).
    Linear,
    /// Sine acceleration, sine² deceleration.
    Sine,
    /// Linear acceleration, sine deceleration.
    LinearSine,
}

/// Plans a position move; see [`super::plan_position`].
pub fn plan_position(
    _shape: RampShape,
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
    _shape: RampShape,
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
