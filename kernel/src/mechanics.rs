//! Mechanics and units (SPEC §1; seed 000 §3): linear or rotary, normal or modulo,
//! allowed direction, software limits.
//!
//! Also units ⇄ drive counts ([`Scaling`], exact over long travel) and the extension of a
//! drive's wrapping 32-bit counter ([`CountExtender`]).

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
    /// A zero in counts per revolution or the gear ratio.
    #[error("counts per revolution and both sides of the gear ratio must be > 0")]
    ZeroScaling,
    /// A feed constant that is not a finite number > 0.
    #[error("feed constant (units per load revolution) {feed} must be a finite number > 0")]
    BadFeed {
        /// The value given.
        feed: f64,
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

/// User units ⇄ drive counts, exact over long travel.
///
/// Counts per load revolution are the rational `counts_per_motor_rev · motor_revs /
/// load_revs`; one load revolution moves `units_per_load_rev` user units. Conversions go
/// through i128 arithmetic on that rational, so a position far from zero converts without
/// drift and round trips are exact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scaling {
    /// Encoder counts per motor revolution.
    pub counts_per_motor_rev: u32,
    /// Gear: motor revolutions …
    pub motor_revs: u32,
    /// … per load revolutions.
    pub load_revs: u32,
    /// Feed constant: user units per load revolution (e.g. 5 mm, 360°).
    pub units_per_load_rev: f64,
    /// Motor positive is mechanics negative.
    pub invert: bool,
}

impl Default for Scaling {
    fn default() -> Self {
        Self {
            counts_per_motor_rev: 1 << 20,
            motor_revs: 1,
            load_revs: 1,
            units_per_load_rev: 360.0,
            invert: false,
        }
    }
}

impl Scaling {
    /// Checks the scaling.
    pub fn validate(&self) -> Result<(), MechanicsError> {
        if self.counts_per_motor_rev == 0 || self.motor_revs == 0 || self.load_revs == 0 {
            return Err(MechanicsError::ZeroScaling);
        }
        if !(self.units_per_load_rev.is_finite() && self.units_per_load_rev > 0.0) {
            return Err(MechanicsError::BadFeed {
                feed: self.units_per_load_rev,
            });
        }
        Ok(())
    }

    /// Counts per load revolution as `(numerator, denominator)`.
    fn counts_per_load_rev(&self) -> (i128, i128) {
        (
            self.counts_per_motor_rev as i128 * self.motor_revs as i128,
            self.load_revs as i128,
        )
    }

    fn sign(&self) -> f64 {
        if self.invert {
            -1.0
        } else {
            1.0
        }
    }

    /// Counts per user unit (for velocities and display; positions use the exact path).
    pub fn counts_per_unit(&self) -> f64 {
        let (n, d) = self.counts_per_load_rev();
        n as f64 / d as f64 / self.units_per_load_rev
    }

    /// Position in user units → counts, rounded to the nearest count. Whole load
    /// revolutions are converted exactly; only the fraction of a revolution goes through
    /// floating point.
    pub fn units_to_counts(&self, p: f64) -> i64 {
        let revs = p / self.units_per_load_rev;
        let whole = revs.floor();
        let frac_units = p - whole * self.units_per_load_rev;
        self.revs_to_counts(whole as i128, frac_units)
    }

    /// `whole` load revolutions plus `frac_units` user units → counts (exact for the
    /// whole revolutions, so modulo axes can pass their turn count here).
    pub fn revs_to_counts(&self, whole: i128, frac_units: f64) -> i64 {
        let (n, d) = self.counts_per_load_rev();
        let frac_counts = frac_units / self.units_per_load_rev * n as f64 / d as f64;
        // whole · n / d = q + r / d exactly; only r / d + the fraction meet floating point.
        let q = (whole * n).div_euclid(d);
        let r = (whole * n).rem_euclid(d) as f64 / d as f64;
        let total = q + (r + frac_counts).round() as i128;
        let counts = i64::try_from(total).unwrap_or(if total < 0 { i64::MIN } else { i64::MAX });
        if self.invert {
            counts.saturating_neg()
        } else {
            counts
        }
    }

    /// Counts → position in user units.
    pub fn counts_to_units(&self, c: i64) -> f64 {
        let c = if self.invert { -(c as i128) } else { c as i128 };
        let (n, d) = self.counts_per_load_rev();
        // c counts = c·d / n load revolutions: split into whole revolutions and a rest.
        let scaled = c * d;
        let whole = scaled.div_euclid(n);
        let rest = scaled.rem_euclid(n) as f64 / n as f64;
        (whole as f64 + rest) * self.units_per_load_rev
    }

    /// Velocity in user units/s → counts/s.
    pub fn velocity_to_counts(&self, v: f64) -> f64 {
        self.sign() * v * self.counts_per_unit()
    }

    /// Velocity in counts/s → user units/s.
    pub fn velocity_to_units(&self, v: f64) -> f64 {
        self.sign() * v / self.counts_per_unit()
    }
}

/// Extends a drive's wrapping 32-bit position counter to 64 bits (the drive counts from
/// −2³¹ to 2³¹−1 and wraps; the master keeps the full count).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CountExtender {
    last: Option<i32>,
    total: i64,
}

impl CountExtender {
    /// Takes the next raw counter value; returns the extended count. The first value is
    /// taken as is. Consecutive values must differ by less than 2³¹ counts.
    pub fn update(&mut self, raw: i32) -> i64 {
        match self.last {
            None => self.total = raw as i64,
            Some(prev) => self.total += raw.wrapping_sub(prev) as i64,
        }
        self.last = Some(raw);
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn deg() -> Modulo {
        Modulo::new(360.0).unwrap()
    }

    #[test]
    fn seed_modulo_distances() {
        let m = deg();
        assert_eq!(m.delta_positive(50.0, 40.0), 350.0);
        assert_eq!(m.delta_negative(40.0, 50.0), -350.0);
        assert_eq!(m.delta_shortest(40.0, 50.0), 10.0);
        assert_eq!(m.delta_positive(50.0, 20.0), 330.0);
        assert_eq!(m.delta_positive(40.0, 40.0), 0.0);
        assert_eq!(m.delta_negative(40.0, 40.0), 0.0);
    }

    #[test]
    fn actual_is_reported_on_the_side_of_set() {
        assert_eq!(deg().follow(0.0, 358.0), -2.0);
        assert_eq!(deg().follow(359.0, 1.0), 361.0);
    }

    #[test]
    fn wrap_never_returns_the_period() {
        let m = deg();
        assert_eq!(m.wrap(-1e-18), 0.0);
        assert_eq!(m.wrap(360.0), 0.0);
        assert_eq!(m.wrap(-10.0), 350.0);
        assert!(Modulo::new(0.0).is_none() && Modulo::new(f64::NAN).is_none());
    }

    #[test]
    fn mechanics_validation_names_the_problem() {
        let mut m = Mechanics {
            software_limits: Some((5.0, -5.0)),
            ..Mechanics::default()
        };
        assert_eq!(
            m.validate(),
            Err(MechanicsError::LimitsNotOrdered {
                min: 5.0,
                max: -5.0
            })
        );
        m.software_limits = Some((f64::NEG_INFINITY, 5.0));
        assert!(m.validate().is_err());
    }

    #[test]
    fn count_extender_rides_through_wraps() {
        let mut e = CountExtender::default();
        assert_eq!(e.update(i32::MAX - 10), (i32::MAX - 10) as i64);
        assert_eq!(e.update(i32::MIN + 9), i32::MAX as i64 + 10);
        let mut raw = i32::MIN + 9;
        let mut expected = i32::MAX as i64 + 10;
        for _ in 0..10_000 {
            raw = raw.wrapping_add(1_000_000);
            expected += 1_000_000;
            assert_eq!(e.update(raw), expected);
        }
        assert!(expected > 10_000_000_000, "many wraps: {expected}");
        for _ in 0..20_000 {
            raw = raw.wrapping_sub(1_000_000);
            expected -= 1_000_000;
            assert_eq!(e.update(raw), expected);
        }
    }

    #[test]
    fn scaling_is_exact_far_from_zero() {
        // 5 mm ball screw, 2:1 gear, 2^17 counts: 52428.8 counts per mm.
        let s = Scaling {
            counts_per_motor_rev: 1 << 17,
            motor_revs: 2,
            load_revs: 1,
            units_per_load_rev: 5.0,
            invert: false,
        };
        s.validate().unwrap();
        for c in [0i64, 1, -1, 1_000_000_000, -1_000_000_007, 123_456_789_012] {
            assert_eq!(s.units_to_counts(s.counts_to_units(c)), c, "round trip {c}");
        }
        // Moving by whole millimetres 10^6 times lands on the exact count.
        let mut p = 0.0;
        for _ in 0..1_000_000 {
            p += 1.0;
        }
        assert_eq!(s.units_to_counts(p), 52_428_800_000);
    }

    #[test]
    fn modulo_turns_convert_without_accumulated_error() {
        // 360° per load rev, gear 3:1, 1000 counts per motor rev: 3000 counts per turn, but
        // with gear 1:3 it is 333.33… counts per turn — not an integer.
        let s = Scaling {
            counts_per_motor_rev: 1000,
            motor_revs: 1,
            load_revs: 3,
            units_per_load_rev: 360.0,
            invert: false,
        };
        let turns: i128 = 1_000_000;
        // 10^6 turns · 1000/3 counts = 333_333_333.33… → 333_333_333.
        assert_eq!(s.revs_to_counts(turns, 0.0), 333_333_333);
        assert_eq!(s.revs_to_counts(turns + 1, 0.0), 333_333_667);
        assert_eq!(s.revs_to_counts(-turns, 0.0), -333_333_333);
        assert_eq!(s.revs_to_counts(turns, 180.0), 333_333_500);
    }

    #[test]
    fn inverted_scaling_flips_counts() {
        let s = Scaling {
            invert: true,
            ..Scaling::default()
        };
        assert_eq!(s.units_to_counts(360.0), -(1 << 20));
        assert_eq!(s.counts_to_units(-(1 << 20)), 360.0);
        assert_eq!(s.velocity_to_counts(360.0), -((1 << 20) as f64));
        assert!(Scaling { motor_revs: 0, ..s }.validate().is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 500, rng_seed: proptest::test_runner::RngSeed::Fixed(11), failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn counts_round_trip_exactly(
            c in -4_000_000_000_000i64..4_000_000_000_000,
            cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100, feed in 0.1..1000.0f64,
        ) {
            let s = Scaling { counts_per_motor_rev: cpr, motor_revs: mr, load_revs: lr, units_per_load_rev: feed, invert: false };
            // One count must be resolvable in f64 at this distance for the test to mean anything.
            let units = s.counts_to_units(c);
            prop_assume!(units.abs() / s.counts_per_unit().recip() < 1e14);
            prop_assert_eq!(s.units_to_counts(units), c);
        }

        #[test]
        fn shortest_delta_is_at_most_half_a_period(a in -1e6..1e6f64, b in -1e6..1e6f64) {
            let m = deg();
            let d = m.delta_shortest(m.wrap(a), m.wrap(b));
            prop_assert!(d.abs() <= 180.0 + 1e-9);
            prop_assert!((m.wrap(m.wrap(a) + d) - m.wrap(b)).abs() < 1e-6 || (m.wrap(m.wrap(a) + d) - m.wrap(b)).abs() > 360.0 - 1e-6);
        }
    }
}
