//! gantry's motion kernel.
//!
//! Pure and deterministic: no I/O, no clocks (time is cycle ticks passed in), and no
//! heap allocation in [`Kernel::step`]. Positions are `f64` in user units; the drive layer
//! converts them to integer counts with [`mechanics::Scaling`].
#![deny(missing_docs)]

pub mod axis;
pub mod kernel;
pub mod mechanics;
pub mod profile;

pub use axis::{Axis, AxisConfig, AxisKind};
pub use kernel::Kernel;
