//! Axis-group paths (seed 004, Omron NJ MC_MoveLinear and MC_MoveCircular2D; SPEC §7):
//! the pure geometry and timing of one coordinated move, before any group state machine.
//!
//! - [`circle`]: MC_MoveCircular2D's rules — border point, center, radius; CW/CCW; full
//!   circles; the cases that become a line or an error.
//! - [`segment`]: a line or a helix in up to four axes, parametrised by path length, with
//!   the derivatives the dynamics need.
//! - [`limits`]: the path speed, acceleration and jerk that keep every axis within its own
//!   limits.
//! - [`profile`]: the planned segment, sampled in closed form at any time.
//! - [`blend`]: two segments joined in motion — the transit speed, and the superimposed
//!   corner that keeps every axis within its limits.

pub mod blend;
pub mod circle;
pub mod limits;
pub mod profile;
pub mod segment;

pub use blend::Transition;
pub use circle::{circular_2d, Arc2, CircMode, CircularError, PathChoice, Segment2};
pub use limits::{path_limits, AxisLimits, PathLimits, PathLimitsError};
pub use profile::{along, PathPlanError, PathProfile};
pub use segment::{CircAxes, PathDerivatives, PathSegment, SegmentError, MAX_AXES};
