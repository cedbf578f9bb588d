//! What can go wrong between units and counts; every variant names the value and the
//! field or limit.

use thiserror::Error;

/// A scaling or count mistake.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum ScalingError {
    /// A modulo period that is not a finite number > 0.
    #[error("modulo period {period} must be a finite number > 0")]
    BadPeriod {
        /// The period given.
        period: f64,
    },
    /// A position that is NaN or infinite.
    #[error("{name} = {value} is not a finite number")]
    NotFinite {
        /// Which value.
        name: &'static str,
        /// The value.
        value: f64,
    },
    /// A scaling parameter out of range: gear and counts must be > 0, the feed constant a
    /// finite number > 0 whose counts per unit are a normal `f64`.
    #[error("scaling {field} = {value} must be > 0 (and finite)")]
    BadScaling {
        /// The field of [`super::ScalingConfig`].
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A position whose count does not fit the `i64` range.
    #[error("position {value} is beyond the range of 64-bit drive counts")]
    CountsOutOfRange {
        /// The position (units).
        value: f64,
    },
    /// A modulo period of less than one count, or one whose exact count ratio does not fit
    /// 126 bits.
    #[error(
        "modulo period {period} at {counts_per_unit} counts per unit has no usable count ratio"
    )]
    CountsPerPeriodOutOfRange {
        /// The period (units).
        period: f64,
        /// Counts per unit of the scaling.
        counts_per_unit: f64,
    },
    /// A counter width outside 2..=32 bits.
    #[error("counter width {bits} bits must be between 2 and 32")]
    BadCounterWidth {
        /// The width given.
        bits: u32,
    },
}
