//! gantry's motion kernel.
//!
//! Pure and deterministic: no I/O, no clocks (time is cycle ticks passed in), and no
//! heap allocation in [`Kernel::step`]. Positions are `f64` in user units; the drive layer
//! converts them to integer counts (`gantry_drives::scaling`, not a dependency of this crate).
#![deny(missing_docs)]
// The RT path must not panic: no unwrap, expect, panics or unchecked indexing outside tests.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::indexing_slicing,
        clippy::panic
    )
)]

pub mod axis;
pub mod cam;
pub mod group;
pub mod homing;
pub mod kernel;
pub mod mechanics;
pub mod path;
pub mod profile;
pub mod sync;

pub use axis::{Axis, AxisConfig, AxisKind};
pub use kernel::Kernel;
