//! What is wrong with a cam table; every variant names the point(s) or the count.

use thiserror::Error;

use super::Interpolation;

/// A cam table that cannot be built; every variant names the offending point(s) (0-based
/// indices into the list given) or the count and the limit.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum CamError {
    /// Fewer than two points: a table needs at least one segment.
    #[error("a cam table needs at least 2 points, got {count}")]
    TooFewPoints {
        /// Points given.
        count: usize,
    },
    /// More points than [`super::MAX_POINTS`].
    #[error("a cam table may have at most {max} points, got {count}")]
    TooManyPoints {
        /// Points given.
        count: usize,
        /// The limit.
        max: usize,
    },
    /// A master or slave position that is NaN or infinite.
    #[error("cam point {index} (master {master}, slave {slave}) is not a pair of finite numbers")]
    NotFinite {
        /// Index of the point.
        index: usize,
        /// Its master position.
        master: f64,
        /// Its slave position.
        slave: f64,
    },
    /// Master positions must strictly increase: `master[index] > master[index - 1]`.
    #[error(
        "cam points {} and {index}: master positions must strictly increase, got {previous_master} then {master}",
        index - 1
    )]
    NotIncreasing {
        /// Index of the later point (the earlier one is `index - 1`).
        index: usize,
        /// Master position of point `index - 1`.
        previous_master: f64,
        /// Master position of point `index`.
        master: f64,
    },
    /// A periodic cubic or quintic table needs at least three points (two segments): with
    /// two, the first and the last point are the same point of the period.
    #[error("a periodic {} cam table needs at least 3 points, got {count}", interpolation.name())]
    PeriodicTooFewPoints {
        /// The interpolation asked for.
        interpolation: Interpolation,
        /// Points given.
        count: usize,
    },
    /// The segment between points `index` and `index + 1` has a slope, velocity or
    /// acceleration that is not a finite number: the points are too close together for
    /// the difference of their slave positions (or the values too large).
    #[error(
        "cam segment between points {index} and {} (master {master_from} .. {master_to}) has derivatives that are not finite numbers: points too close for their slave difference",
        index + 1
    )]
    Degenerate {
        /// Index of the segment's first point.
        index: usize,
        /// Master position of point `index`.
        master_from: f64,
        /// Master position of point `index + 1`.
        master_to: f64,
    },
    /// [`super::CamTable::with_derivatives`]: not one derivative pair per point.
    #[error("{derivatives} derivative pairs given for {points} cam points (one per point needed)")]
    DerivativeCount {
        /// Points given.
        points: usize,
        /// Derivative pairs given.
        derivatives: usize,
    },
    /// [`super::CamTable::with_derivatives`]: a d1 or d2 that is NaN or infinite.
    #[error("cam point {index}: derivatives d1 {d1}, d2 {d2} are not finite numbers")]
    DerivativeNotFinite {
        /// Index of the point.
        index: usize,
        /// The d1 given.
        d1: f64,
        /// The d2 given.
        d2: f64,
    },
    /// [`super::CamTable::with_derivatives`], periodic: the last point's d1/d2 must equal
    /// the first point's, or the repetition is not C2.
    #[error(
        "periodic cam table: the last point's d1 {last_d1}, d2 {last_d2} must equal the first point's d1 {first_d1}, d2 {first_d2}"
    )]
    PeriodicDerivativesDiffer {
        /// d1 at the first point.
        first_d1: f64,
        /// d2 at the first point.
        first_d2: f64,
        /// d1 at the last point.
        last_d1: f64,
        /// d2 at the last point.
        last_d2: f64,
    },
}
