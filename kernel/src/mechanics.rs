//! Mechanics and units (SPEC §1; seed 000 §3): linear or rotary, normal or modulo,
//! allowed direction, software limits.
//!
//! NOTE for whoever extends this file: `Mechanics`, `Modulo` (with `period()`, `wrap`,
//! `delta_positive`, `delta_negative`, `delta_shortest`, `follow`), `Direction` and
//! `MechanicsError` are used by `axis/`; keep these names and signatures.

use thiserror::Error;

/// Linear or rotary motion (only changes how values are labelled; both can be modulo).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MotionKind {
    /// Straight-line motion (mm, m).
    #[default]
    Linear,
    /// Rotation (°, rev).
    Rotary,
}

/// Directions the mechanics may move in (seed 000 §3.3, §3.4, §3.7, §3.8).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Both directions.
    #[default]
    Both,
    /// Positive direction only.
    PositiveOnly,
    /// Negative direction only.
    NegativeOnly,
}

/// A modulo period: positions are kept in `[0, period)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Modulo {
    period: f64,
}

impl Modulo {
    /// A modulo period; `None` unless `period` is finite and > 0.
    pub fn new(period: f64) -> Option<Self> {
        (period.is_finite() && period > 0.0).then_some(Self { period })
    }

    /// The period (units).
    pub const fn period(&self) -> f64 {
        self.period
    }

    /// `p` wrapped into `[0, period)`; never returns `period` itself.
    pub fn wrap(&self, p: f64) -> f64 {
        let w = p.rem_euclid(self.period);
        if w >= self.period {
            0.0
        } else {
            w
        }
    }

    /// Distance in `[0, period)` from `from` to `to` going positive.
    pub fn delta_positive(&self, from: f64, to: f64) -> f64 {
        self.wrap(to - from)
    }

    /// Distance in `(-period, 0]` from `from` to `to` going negative.
    pub fn delta_negative(&self, from: f64, to: f64) -> f64 {
        let d = self.wrap(to - from);
        if d == 0.0 {
            0.0
        } else {
            d - self.period
        }
    }

    /// Shortest signed distance from `from` to `to` (a tie goes positive).
    pub fn delta_shortest(&self, from: f64, to: f64) -> f64 {
        let d = self.delta_positive(from, to);
        if d > self.period / 2.0 {
            d - self.period
        } else {
            d
        }
    }

    /// `actual` (wrapped) expressed on the same side of the wrap as `set` (unwrapped or
    /// wrapped): set 0 with actual lagging by 2 gives −2, not 358.
    pub fn follow(&self, set: f64, actual: f64) -> f64 {
        set + self.delta_shortest(self.wrap(set), actual)
    }
}

/// Mechanics of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mechanics {
    /// Linear or rotary.
    pub kind: MotionKind,
    /// Modulo period, if the axis is modulo.
    pub modulo: Option<Modulo>,
    /// Allowed direction.
    pub direction: Direction,
    /// Software limits `(min, max)` (units), active once the axis is homed; ignored on
    /// modulo axes.
    pub software_limits: Option<(f64, f64)>,
}

impl Mechanics {
    /// Checks the mechanics for consistency.
    pub fn validate(&self) -> Result<(), MechanicsError> {
        if let Some((min, max)) = self.software_limits {
            if !(min.is_finite() && max.is_finite()) {
                return Err(MechanicsError::LimitNotFinite { min, max });
            }
            if min >= max {
                return Err(MechanicsError::LimitsNotOrdered { min, max });
            }
        }
        Ok(())
    }
}

/// A mechanics configuration mistake.
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
}
