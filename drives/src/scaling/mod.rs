//! User units ⇄ drive counts (SPEC §1: counts per unit, gear ratio, feed constant), for
//! the master's drive channels and anything else that talks counts to a drive. The kernel
//! works in user units and never counts; this is where units meet the wire.
//!
//! # Why the unit conversions use exact arithmetic
//!
//! A drive counts integers; an axis may run for years in one direction. Counts per user
//! unit are a rational number (`counts_per_motor_rev · motor_revs / (load_revs ·
//! units_per_load_rev)`, e.g. 25/3 counts per degree) that `f64` cannot hold, and
//! multiplying a large position by a rounded factor drifts: after 10⁹ units a relative
//! error of 10⁻¹⁶ is already 10⁻⁷ units, and errors pile up when whole modulo periods are
//! added. So [`Scaling`] keeps the factor as an exact fraction of integers times a power of
//! two (every finite `f64` is an integer times a power of two) and converts positions with
//! `i128` arithmetic, rounding once, half up (`⌊x + ½⌋`, so shifting a position by whole
//! counts never changes how it rounds). [`ModuloCounts`] does the same for "`n` whole
//! periods plus a position within the period", so a modulo axis that has turned 10⁶ times
//! maps position 0 to exactly the rounded rational count. [`CountExtender`] extends the
//! drive's wrapping 32-bit counter to the 64-bit counts these work in.

mod count_extender;
mod error;
mod exact;
mod modulo_counts;
#[cfg(test)]
mod tests;

pub use count_extender::CountExtender;
pub use error::ScalingError;
pub use modulo_counts::ModuloCounts;

use exact::{dyadic, gcd, scale2, scaled};

/// Scaling parameters as configured (SPEC §1: counts per unit, gear ratio, feed
/// constant): plain data, checked by [`Scaling::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScalingConfig {
    /// Encoder counts per motor revolution.
    pub counts_per_motor_rev: u32,
    /// Gear: motor revolutions …
    pub motor_revs: u32,
    /// … per `load_revs` load revolutions.
    pub load_revs: u32,
    /// Feed constant: user units per load revolution (e.g. 5 mm for a ball screw, 360°).
    pub units_per_load_rev: f64,
    /// Motor positive is mechanics negative (the motor is mounted the other way round).
    pub invert: bool,
}

impl Default for ScalingConfig {
    /// A 20-bit encoder on a direct-drive rotary axis in degrees.
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

/// User units ⇄ drive counts, exact over long travel (see the module doc).
///
/// Counts per unit are kept as `num / den · 2^shift` with `num < 2⁶⁴`, `den < 2⁸⁵`
/// coprime: `num` is the reduced `counts_per_motor_rev · motor_revs`, `den` the reduced
/// `load_revs` times the odd mantissa of the feed constant, `shift` minus its binary
/// exponent. Built only through [`Scaling::new`], so every conversion is panic-free.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scaling {
    cfg: ScalingConfig,
    num: u128,
    den: u128,
    shift: i32,
    counts_per_unit: f64,
}

impl Default for Scaling {
    fn default() -> Self {
        // What `Scaling::new(ScalingConfig::default())` computes: 2^20 counts per 360
        // units, 360 = 45 · 2^3, so num = 2^20, den = 45, shift = −3.
        Self {
            cfg: ScalingConfig::default(),
            num: 1 << 20,
            den: 45,
            shift: -3,
            counts_per_unit: scale2((1u32 << 20) as f64 / 45.0, -3),
        }
    }
}

impl Scaling {
    /// Checks `cfg` and precomputes the exact count ratio.
    pub fn new(cfg: ScalingConfig) -> Result<Self, ScalingError> {
        for (field, value) in [
            ("counts_per_motor_rev", cfg.counts_per_motor_rev),
            ("motor_revs", cfg.motor_revs),
            ("load_revs", cfg.load_revs),
        ] {
            if value == 0 {
                return Err(ScalingError::BadScaling { field, value: 0.0 });
            }
        }
        let feed = cfg.units_per_load_rev;
        let bad_feed = ScalingError::BadScaling {
            field: "units_per_load_rev",
            value: feed,
        };
        if !(feed.is_finite() && feed > 0.0) {
            return Err(bad_feed);
        }
        let (mf, ef) = dyadic(feed);
        let num = u128::from(cfg.counts_per_motor_rev) * u128::from(cfg.motor_revs);
        let den = u128::from(cfg.load_revs) * u128::from(mf.unsigned_abs());
        let g = gcd(num, den);
        let (num, den) = (num / g, den / g);
        let shift = -ef;
        let counts_per_unit = scale2(num as f64 / den as f64, shift);
        if !(counts_per_unit.is_normal() && (1.0 / counts_per_unit).is_normal()) {
            return Err(bad_feed);
        }
        Ok(Self {
            cfg,
            num,
            den,
            shift,
            counts_per_unit,
        })
    }

    /// The configuration this scaling was built from.
    pub const fn config(&self) -> ScalingConfig {
        self.cfg
    }

    /// Counts per user unit (rounded to `f64`; for velocities, accelerations and display —
    /// positions use the exact path).
    pub const fn counts_per_unit(&self) -> f64 {
        self.counts_per_unit
    }

    fn sign(&self) -> i128 {
        if self.cfg.invert {
            -1
        } else {
            1
        }
    }

    /// Position (units) → counts, rounded to the nearest count (half up), computed
    /// exactly. Errors on NaN/infinite positions and counts beyond `i64`.
    pub fn try_units_to_counts(&self, p: f64) -> Result<i64, ScalingError> {
        if !p.is_finite() {
            return Err(ScalingError::NotFinite {
                name: "position",
                value: p,
            });
        }
        let (m, e) = dyadic(p);
        // |m| < 2^53, num < 2^64: the product fits i128 with room to spare.
        let n = self.sign() * i128::from(m) * self.num as i128;
        scaled(n, e + self.shift, self.den)
            .map(|s| s.round_half_up())
            .and_then(|c| i64::try_from(c).ok())
            .ok_or(ScalingError::CountsOutOfRange { value: p })
    }

    /// Position (units) → counts like [`Scaling::try_units_to_counts`], saturating at the
    /// `i64` range, NaN giving 0: for the cyclic path, whose positions the kernel has
    /// already checked (finite, within ±1e9 units).
    pub fn units_to_counts(&self, p: f64) -> i64 {
        match self.try_units_to_counts(p) {
            Ok(c) => c,
            Err(_) if p.is_nan() => 0,
            Err(_) if p > 0.0 => {
                if self.cfg.invert {
                    i64::MIN
                } else {
                    i64::MAX
                }
            }
            Err(_) => {
                if self.cfg.invert {
                    i64::MAX
                } else {
                    i64::MIN
                }
            }
        }
    }

    /// Counts → position (units), within about 2 ulp of the exact value, so that
    /// `units_to_counts(counts_to_units(c)) == c` for `|c| <= 2⁵⁰` (one count is then
    /// still many ulps wide).
    pub fn counts_to_units(&self, c: i64) -> f64 {
        let c = self.sign() * i128::from(c);
        // units = c · den / num · 2^-shift; c · den fits i128 unless den is huge.
        let q = match c.checked_mul(self.den as i128) {
            Some(x) => x as f64 / self.num as f64,
            None => c as f64 * (self.den as f64 / self.num as f64),
        };
        scale2(q, -self.shift)
    }

    /// Velocity (units/s) → counts/s (also for accelerations: units/s² → counts/s²).
    pub fn velocity_to_counts(&self, v: f64) -> f64 {
        self.sign() as f64 * v * self.counts_per_unit
    }

    /// Velocity (counts/s) → units/s (also for accelerations).
    pub fn velocity_to_units(&self, v: f64) -> f64 {
        self.sign() as f64 * v / self.counts_per_unit
    }
}
