//! What is wrong with an axis' mechanics or a move on it; every variant names the value
//! and the limit or field.

use thiserror::Error;

use super::Direction;

/// A mechanics mistake; every variant names the value and the limit or field.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum MechanicsError {
    /// A modulo period that is not a finite number > 0.
    #[error("modulo period {period} must be a finite number > 0")]
    BadPeriod {
        /// The period given.
        period: f64,
    },
    /// A software limit that is not finite.
    #[error("software limits [{min}, {max}] must be finite numbers")]
    LimitNotFinite {
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// Lower software limit not below the upper one.
    #[error("software limit min {min} must be below max {max}")]
    LimitsNotOrdered {
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// A position or velocity that is NaN or infinite.
    #[error("{name} = {value} is not a finite number")]
    NotFinite {
        /// Which value.
        name: &'static str,
        /// The value.
        value: f64,
    },
    /// A target below the lower software limit.
    #[error("target {value} is below the software limit min {min}")]
    BelowSoftwareLimit {
        /// The target.
        value: f64,
        /// The lower limit.
        min: f64,
    },
    /// A target above the upper software limit.
    #[error("target {value} is above the software limit max {max}")]
    AboveSoftwareLimit {
        /// The target.
        value: f64,
        /// The upper limit.
        max: f64,
    },
    /// A move against the allowed direction.
    #[error("a move by {delta} is not allowed: direction is {allowed}")]
    DirectionNotAllowed {
        /// The signed distance of the move.
        delta: f64,
        /// The allowed direction.
        allowed: Direction,
    },
}
