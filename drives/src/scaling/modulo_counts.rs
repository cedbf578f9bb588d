//! Counts of a modulo axis: whole periods plus a position within the period.

use super::exact::{bits, dyadic, gcd, mul_div_floor, scaled};
use super::{Scaling, ScalingError};

/// Counts of a modulo axis from "whole periods + position within the period", exact
/// however many periods it has turned, even when a period is not a whole number of counts
/// (360° at gear 1:3 with 1000 counts/rev: 333⅓ counts per period).
///
/// Counts per period are kept as the reduced fraction `num / den` (both < 2¹²⁷); the whole
/// periods are converted with 192-bit integer arithmetic and only the two sub-count
/// fractions (of the periods and of the position within) meet floating point, so the error
/// never grows with the number of periods.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModuloCounts {
    scaling: Scaling,
    /// The period (units), finite and > 0.
    period: f64,
    num: u128,
    den: u128,
}

impl ModuloCounts {
    /// Precomputes the exact counts per period of `period` (units) under `scaling`. Fails
    /// when the period is not a finite number > 0, is less than one count, or its ratio
    /// needs more than 126 bits (a period and feed constant some 2⁴⁰ apart).
    ///
    /// The period is a plain number: the kernel's `Modulo` is the same value, checked the
    /// same way, and this crate does not depend on the kernel.
    pub fn new(scaling: Scaling, period: f64) -> Result<Self, ScalingError> {
        if !(period.is_finite() && period > 0.0) {
            return Err(ScalingError::BadPeriod { period });
        }
        let err = ScalingError::CountsPerPeriodOutOfRange {
            period,
            counts_per_unit: scaling.counts_per_unit,
        };
        let (mp, ep) = dyadic(period);
        let mut num = u128::from(mp.unsigned_abs()) * scaling.num;
        let mut den = scaling.den;
        let e = ep + scaling.shift;
        let k = e.unsigned_abs();
        if e >= 0 {
            if bits(num) + k > 126 {
                return Err(err);
            }
            num <<= k;
        } else {
            if bits(den) + k > 126 {
                return Err(err);
            }
            den <<= k;
        }
        let g = gcd(num, den);
        let (num, den) = (num / g, den / g);
        if num < den {
            return Err(err);
        }
        Ok(Self {
            scaling,
            period,
            num,
            den,
        })
    }

    /// Counts per period as the exact reduced fraction `(numerator, denominator)`.
    pub const fn counts_per_period(&self) -> (u128, u128) {
        (self.num, self.den)
    }

    /// The modulo period (units).
    pub const fn period(&self) -> f64 {
        self.period
    }

    /// Counts of `turns` whole periods plus `within` units, rounded half up. Exact when
    /// either part is zero; otherwise only the sum of the two sub-count fractions is
    /// rounded in `f64` (so the result can differ from the exact rounding only when the
    /// exact value lies within ~1e-15 counts of a half count). `within` may lie outside
    /// `[0, period)`.
    pub fn try_to_counts(&self, turns: i64, within: f64) -> Result<i64, ScalingError> {
        if !within.is_finite() {
            return Err(ScalingError::NotFinite {
                name: "position within the period",
                value: within,
            });
        }
        let out = ScalingError::CountsOutOfRange {
            value: turns as f64 * self.period + within,
        };
        let s = self.scaling.sign();
        let periods = mul_div_floor(s * i128::from(turns), self.num, self.den).ok_or(out)?;
        let total = if within == 0.0 {
            periods.round_half_up()
        } else {
            let (m, e) = dyadic(within);
            let n = s * i128::from(m) * self.scaling.num as i128;
            let part = scaled(n, e + self.scaling.shift, self.scaling.den).ok_or(out)?;
            if turns == 0 {
                part.round_half_up()
            } else {
                let f = periods.frac() + part.frac();
                let carry = (f + 0.5).floor() as i128;
                periods
                    .q
                    .checked_add(part.q)
                    .and_then(|q| q.checked_add(carry))
                    .ok_or(out)?
            }
        };
        i64::try_from(total).map_err(|_| out)
    }

    /// Like [`ModuloCounts::try_to_counts`], saturating at the `i64` range (NaN `within`
    /// gives the count of the whole periods alone).
    pub fn to_counts(&self, turns: i64, within: f64) -> i64 {
        let within = if within.is_nan() { 0.0 } else { within };
        match self.try_to_counts(turns, within) {
            Ok(c) => c,
            Err(_) => {
                let up = (turns as f64 * self.period + within) > 0.0;
                if up != self.scaling.cfg.invert {
                    i64::MAX
                } else {
                    i64::MIN
                }
            }
        }
    }

    /// Counts → `(whole periods, position within the period)`, `within` in
    /// `[0, period)` and within a few ulp of the exact value.
    pub fn to_position(&self, counts: i64) -> (i64, f64) {
        let c = self.scaling.sign() * i128::from(counts);
        // periods = c / (num/den) = c · den / num; a ≥ b makes |periods| ≤ |c| + 1.
        let Some(split) = mul_div_floor(c, self.den, self.num) else {
            return (0, 0.0);
        };
        let turns = i64::try_from(split.q).unwrap_or(if split.q < 0 { i64::MIN } else { i64::MAX });
        let within = split.frac() * self.period;
        if within >= self.period {
            (turns.saturating_add(1), 0.0)
        } else {
            (turns, within)
        }
    }
}
