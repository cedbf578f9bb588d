//! Mechanics and units (SPEC §1; seed 000 §3): linear or rotary, normal or modulo,
//! allowed direction, software limits, and user units ⇄ drive counts.
//!
//! NOTE for whoever extends this file: `Mechanics`, `Modulo` (with `period()`, `wrap`,
//! `delta_positive`, `delta_negative`, `delta_shortest`, `follow`), `Direction` and
//! `MechanicsError` are used by `axis/`; keep these names and signatures.
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
//! maps position 0 to exactly the rounded rational count.

use core::fmt;

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

/// Directions the mechanics may move in (seed 000 §3.3, §3.4, §3.7, §3.8): a conveyor or
/// a ratchet may only turn one way. Allowed on normal axes too.
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

impl Direction {
    /// The name used in messages and configuration files.
    pub const fn name(self) -> &'static str {
        match self {
            Direction::Both => "both",
            Direction::PositiveOnly => "positive only",
            Direction::NegativeOnly => "negative only",
        }
    }

    /// Whether a move by `delta` (units, signed) is allowed; a zero move always is. NaN
    /// is refused on one-way axes.
    pub fn allows(self, delta: f64) -> bool {
        match self {
            Direction::Both => true,
            Direction::PositiveOnly => delta >= 0.0,
            Direction::NegativeOnly => delta <= 0.0,
        }
    }
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A modulo period: positions are kept in `[0, period)` (seed 000 §3.5: rotary tables,
/// conveyors). The period is finite and > 0 by construction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Modulo {
    period: f64,
}

impl Modulo {
    /// A modulo period; `None` unless `period` is finite and > 0.
    pub fn new(period: f64) -> Option<Self> {
        (period.is_finite() && period > 0.0).then_some(Self { period })
    }

    /// A modulo period, or an error naming the bad value.
    pub fn try_new(period: f64) -> Result<Self, MechanicsError> {
        Self::new(period).ok_or(MechanicsError::BadPeriod { period })
    }

    /// The period (units).
    pub const fn period(&self) -> f64 {
        self.period
    }

    /// `p` wrapped into `[0, period)`; never returns `period` itself.
    ///
    /// `%` on `f64` is exact, so only the final `+ period` of a negative remainder rounds;
    /// when a tiny negative `p` rounds up to `period` the result is `0` (the same position,
    /// and the nearest representable one in range). `-0.0` becomes `0.0`.
    pub fn wrap(&self, p: f64) -> f64 {
        let w = p.rem_euclid(self.period);
        if w >= self.period {
            0.0
        } else {
            w + 0.0
        }
    }

    /// `p` as whole periods and a position within the period: `p ≈ turns · period +
    /// within`, `within` in `[0, period)`. `turns` saturates at the `i64` range.
    pub fn split(&self, p: f64) -> (i64, f64) {
        let within = self.wrap(p);
        let turns = ((p - within) / self.period).round();
        // `as` saturates (and maps NaN to 0).
        (turns as i64, within)
    }

    /// Distance in `[0, period)` from `from` to `to` going positive (AbsModuloPos: at 50°,
    /// going to 40° travels +350°).
    pub fn delta_positive(&self, from: f64, to: f64) -> f64 {
        self.wrap(to - from)
    }

    /// Distance in `(-period, 0]` from `from` to `to` going negative (AbsModuloNeg: at
    /// 40°, going to 50° travels −350°).
    pub fn delta_negative(&self, from: f64, to: f64) -> f64 {
        -self.wrap(from - to) + 0.0
    }

    /// Shortest signed distance from `from` to `to`, in `(-period/2, period/2]`; a tie
    /// (exactly half a period) goes positive (AbsModuloAuto: 40° to 50° travels +10°).
    pub fn delta_shortest(&self, from: f64, to: f64) -> f64 {
        let d = self.delta_positive(from, to);
        if d > self.period / 2.0 {
            d - self.period
        } else {
            d
        }
    }

    /// Distance keeping the direction of the last move (AbsModuloKeepDirection):
    /// `last_dir > 0` goes positive, `< 0` negative, `0` (no move yet) the shortest way.
    /// At 40° after a positive move, going to 20° travels +340°.
    pub fn delta_keep(&self, from: f64, to: f64, last_dir: f64) -> f64 {
        if last_dir > 0.0 {
            self.delta_positive(from, to)
        } else if last_dir < 0.0 {
            self.delta_negative(from, to)
        } else {
            self.delta_shortest(from, to)
        }
    }

    /// `actual` (wrapped or not) expressed on the same side of the wrap as `set`
    /// (unwrapped or wrapped): `set + ` the shortest signed difference, so set 0 with the
    /// actual value lagging by 2 gives −2, not 358 (SPEC §1).
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
    /// modulo axes (a modulo position has no end).
    pub software_limits: Option<(f64, f64)>,
}

impl Mechanics {
    /// Checks the mechanics for consistency: a finite period > 0, finite software limits
    /// with `min < max`. A one-way direction on a normal axis is allowed (a conveyor
    /// belt's absolute position may just grow).
    pub fn validate(&self) -> Result<(), MechanicsError> {
        if let Some(m) = self.modulo {
            Modulo::try_new(m.period())?;
        }
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

    /// Checks a target position (units, axis frame): finite, and inside the software
    /// limits on a normal axis that has them. The caller decides whether the limits are
    /// active yet (they are once the axis is homed).
    pub fn check_target(&self, p: f64) -> Result<(), MechanicsError> {
        if !p.is_finite() {
            return Err(MechanicsError::NotFinite {
                name: "target",
                value: p,
            });
        }
        if let (None, Some((min, max))) = (self.modulo, self.software_limits) {
            if p < min {
                return Err(MechanicsError::BelowSoftwareLimit { value: p, min });
            }
            if p > max {
                return Err(MechanicsError::AboveSoftwareLimit { value: p, max });
            }
        }
        Ok(())
    }

    /// Checks that a move by `delta` (units, signed) goes an allowed way.
    pub fn check_direction(&self, delta: f64) -> Result<(), MechanicsError> {
        if self.direction.allows(delta) {
            Ok(())
        } else {
            Err(MechanicsError::DirectionNotAllowed {
                delta,
                allowed: self.direction,
            })
        }
    }
}

/// A mechanics or units mistake; every variant names the value and the limit or field.
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
    /// A scaling parameter out of range: gear and counts must be > 0, the feed constant a
    /// finite number > 0 whose counts per unit are a normal `f64`.
    #[error("scaling {field} = {value} must be > 0 (and finite)")]
    BadScaling {
        /// The field of [`ScalingConfig`].
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
    pub fn new(cfg: ScalingConfig) -> Result<Self, MechanicsError> {
        for (field, value) in [
            ("counts_per_motor_rev", cfg.counts_per_motor_rev),
            ("motor_revs", cfg.motor_revs),
            ("load_revs", cfg.load_revs),
        ] {
            if value == 0 {
                return Err(MechanicsError::BadScaling { field, value: 0.0 });
            }
        }
        let feed = cfg.units_per_load_rev;
        let bad_feed = MechanicsError::BadScaling {
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
    pub fn try_units_to_counts(&self, p: f64) -> Result<i64, MechanicsError> {
        if !p.is_finite() {
            return Err(MechanicsError::NotFinite {
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
            .ok_or(MechanicsError::CountsOutOfRange { value: p })
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
    modulo: Modulo,
    num: u128,
    den: u128,
}

impl ModuloCounts {
    /// Precomputes the exact counts per period of `modulo` under `scaling`. Fails when a
    /// period is less than one count or its ratio needs more than 126 bits (a period and
    /// feed constant some 2⁴⁰ apart).
    pub fn new(scaling: Scaling, modulo: Modulo) -> Result<Self, MechanicsError> {
        let period = modulo.period();
        let err = MechanicsError::CountsPerPeriodOutOfRange {
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
            modulo,
            num,
            den,
        })
    }

    /// Counts per period as the exact reduced fraction `(numerator, denominator)`.
    pub const fn counts_per_period(&self) -> (u128, u128) {
        (self.num, self.den)
    }

    /// The modulo period.
    pub const fn modulo(&self) -> Modulo {
        self.modulo
    }

    /// Counts of `turns` whole periods plus `within` units, rounded half up. Exact when
    /// either part is zero; otherwise only the sum of the two sub-count fractions is
    /// rounded in `f64` (so the result can differ from the exact rounding only when the
    /// exact value lies within ~1e-15 counts of a half count). `within` may lie outside
    /// `[0, period)`.
    pub fn try_to_counts(&self, turns: i64, within: f64) -> Result<i64, MechanicsError> {
        if !within.is_finite() {
            return Err(MechanicsError::NotFinite {
                name: "position within the period",
                value: within,
            });
        }
        let out = MechanicsError::CountsOutOfRange {
            value: turns as f64 * self.modulo.period() + within,
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
                let up = (turns as f64 * self.modulo.period() + within) > 0.0;
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
        let within = split.frac() * self.modulo.period();
        if within >= self.modulo.period() {
            (turns.saturating_add(1), 0.0)
        } else {
            (turns, within)
        }
    }
}

/// Extends a wrapping drive position counter (32 bits by default; encoder modules often
/// count 16 or 24) to 64 bits: the drive counts from −2³¹ to 2³¹−1 and wraps, the master
/// keeps the full count. Consecutive values must differ by less than half the counter
/// range (at 2³¹ counts that is ~2·10⁹ counts per cycle, never reached).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CountExtender {
    last: Option<i32>,
    total: i64,
    /// A value set by [`CountExtender::rebase`] before the first raw value.
    pending: Option<i64>,
    /// `32 − width`: shifting the raw difference up and back sign-extends it.
    shift: u32,
}

impl Default for CountExtender {
    fn default() -> Self {
        Self::new()
    }
}

impl CountExtender {
    /// An extender for a full 32-bit counter.
    pub const fn new() -> Self {
        Self {
            last: None,
            total: 0,
            pending: None,
            shift: 0,
        }
    }

    /// An extender for a counter of `bits` bits (2..=32) that wraps from `2^bits − 1` to 0.
    pub fn with_width(bits: u32) -> Result<Self, MechanicsError> {
        if !(2..=32).contains(&bits) {
            return Err(MechanicsError::BadCounterWidth { bits });
        }
        Ok(Self {
            shift: 32 - bits,
            ..Self::new()
        })
    }

    /// Takes the next raw counter value; returns the extended count. The first value (and
    /// the first after [`CountExtender::reset`]) is taken as is. Saturates at the `i64`
    /// range rather than wrapping.
    pub fn update(&mut self, raw: i32) -> i64 {
        match self.last {
            None => self.total = self.pending.take().unwrap_or(i64::from(raw)),
            Some(prev) => {
                let d = raw.wrapping_sub(prev).wrapping_shl(self.shift) >> self.shift;
                self.total = self.total.saturating_add(i64::from(d));
            }
        }
        self.last = Some(raw);
        self.total
    }

    /// The extended count so far, `None` before the first value.
    pub fn value(&self) -> Option<i64> {
        self.last.map(|_| self.total)
    }

    /// Makes the current raw value stand for `total` (restoring a stored absolute position
    /// at power-up, or after homing); takes effect at once if a value has been seen, else
    /// at the next one.
    pub fn rebase(&mut self, total: i64) {
        if self.last.is_some() {
            self.total = total;
        } else {
            self.pending = Some(total);
        }
    }

    /// Forgets the last raw value and any pending rebase (bus restart): the next raw value
    /// is taken as is.
    pub fn reset(&mut self) {
        self.last = None;
        self.pending = None;
    }
}

// ---- Exact arithmetic on dyadic rationals (private) ----

/// `x = m · 2^e` with `m` odd (or 0); `x` must be finite.
fn dyadic(x: f64) -> (i64, i32) {
    let raw = x.to_bits();
    let exp = ((raw >> 52) & 0x7ff) as i32;
    let frac = (raw & ((1u64 << 52) - 1)) as i64;
    let (m, e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1 << 52), exp - 1075)
    };
    if m == 0 {
        return (0, 0);
    }
    let tz = m.trailing_zeros();
    let m = m >> tz;
    let e = e + tz as i32;
    if raw >> 63 == 1 {
        (-m, e)
    } else {
        (m, e)
    }
}

/// `x · 2^e`, exact unless the result overflows or underflows; steps of at most 2^±1000
/// keep each factor representable.
fn scale2(x: f64, e: i32) -> f64 {
    let pow2 = |e: i32| f64::from_bits(((e + 1023) as u64) << 52);
    let (mut x, mut e) = (x, e);
    while e > 1000 && x.is_finite() && x != 0.0 {
        x *= pow2(1000);
        e -= 1000;
    }
    while e < -1000 && x.is_finite() && x != 0.0 {
        x *= pow2(-1000);
        e += 1000;
    }
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    x * pow2(e.clamp(-1022, 1023))
}

fn gcd(mut a: u128, mut b: u128) -> u128 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a.max(1)
}

/// Number of significant bits.
fn bits(x: u128) -> u32 {
    128 - x.leading_zeros()
}

/// The fractional part of an exact quotient.
#[derive(Clone, Copy, Debug)]
enum Frac {
    /// `r / d` with `0 <= r < d`.
    Exact { r: u128, d: u128 },
    /// Known to lie in `[0, 1/4)` or `(3/4, 1)`, so rounding it in `f64` is safe.
    Approx(f64),
}

/// `x = q + frac`, `q = ⌊x⌋`.
#[derive(Clone, Copy, Debug)]
struct Split {
    q: i128,
    frac: Frac,
}

impl Split {
    /// `⌊x + ½⌋`, exactly.
    fn round_half_up(&self) -> i128 {
        let up = match self.frac {
            Frac::Exact { r, d } => r >= d - r,
            Frac::Approx(f) => f >= 0.5,
        };
        self.q + i128::from(up)
    }

    /// The fractional part in `f64` (`[0, 1]` after rounding).
    fn frac(&self) -> f64 {
        match self.frac {
            Frac::Exact { r, d } => r as f64 / d as f64,
            Frac::Approx(f) => f,
        }
    }
}

/// `n · 2^e / d` split into floor and fraction (`d > 0`); `None` if it is beyond ±2⁶⁴
/// (far outside the count range) or the operands are too wide (`|n| >= 2¹²⁰`,
/// `d >= 2⁸⁶`).
fn scaled(n: i128, e: i32, d: u128) -> Option<Split> {
    if n == 0 {
        return Some(Split {
            q: 0,
            frac: Frac::Exact { r: 0, d: 1 },
        });
    }
    let nb = bits(n.unsigned_abs());
    if nb >= 120 || d == 0 || bits(d) >= 86 {
        return None;
    }
    let k = e.unsigned_abs();
    if e >= 0 {
        // |x| >= 2^(nb - 1 + e - bits(d)): beyond 2^64 means out of range.
        if (nb - 1 + k).saturating_sub(bits(d)) > 64 {
            return None;
        }
        let di = d as i128;
        let mut q = n.div_euclid(di);
        let mut r = n.rem_euclid(di);
        let mut left = k;
        while left > 0 {
            let step = left.min(40);
            // r < d < 2^86, so r << 40 < 2^126; q stays below 2^65 (checked below).
            q = q.checked_mul(1i128 << step)?;
            r <<= step;
            q = q.checked_add(r / di)?;
            r %= di;
            if q.unsigned_abs() > 1u128 << 65 {
                return None;
            }
            left -= step;
        }
        return Some(Split {
            q,
            frac: Frac::Exact { r: r as u128, d },
        });
    }
    if nb + 3 <= bits(d) + k {
        // |x| < 2^nb / 2^(bits(d) - 1 + k) <= 1/4: the quotient is 0 or −1, and the
        // fraction is far enough from ½ for `f64`.
        let x = scale2(n as f64 / d as f64, e);
        return Some(if n > 0 {
            Split {
                q: 0,
                frac: Frac::Approx(x),
            }
        } else {
            Split {
                q: -1,
                frac: Frac::Approx(1.0 + x),
            }
        });
    }
    // Here bits(d) + k < nb + 3 < 123, so d << k fits.
    let dd = d << k;
    let di = dd as i128;
    Some(Split {
        q: n.div_euclid(di),
        frac: Frac::Exact {
            r: n.rem_euclid(di) as u128,
            d: dd,
        },
    })
}

/// `⌊a · b / c⌋` and the remainder, for `|a| <= 2⁶³` and `0 < c < 2¹²⁷`, `b < 2¹²⁷`,
/// through a 192-bit product; `None` if the quotient does not fit `i128`.
fn mul_div_floor(a: i128, b: u128, c: u128) -> Option<Split> {
    let mag = a.unsigned_abs();
    if mag > 1u128 << 63 || c == 0 || c >> 127 != 0 || b >> 127 != 0 {
        return None;
    }
    // product = hi · 2^128 + lo, from mag · (b1 · 2^64 + b0).
    let (b1, b0) = (b >> 64, b & u128::from(u64::MAX));
    let p0 = mag * b0;
    let p1 = mag * b1;
    let (lo, carry) = p0.overflowing_add(p1 << 64);
    let hi = (p1 >> 64) + u128::from(carry);
    let (q, r) = if hi == 0 {
        (lo / c, lo % c)
    } else {
        if hi >= c {
            return None;
        }
        // Long division, one bit at a time; r < c < 2^127 so 2r + 1 fits.
        let (mut q, mut r) = (0u128, hi);
        for i in (0..128).rev() {
            r = (r << 1) | ((lo >> i) & 1);
            q <<= 1;
            if r >= c {
                r -= c;
                q |= 1;
            }
        }
        (q, r)
    };
    let q = i128::try_from(q).ok()?;
    Some(if a >= 0 || r == 0 {
        Split {
            q: if a >= 0 { q } else { -q },
            frac: Frac::Exact { r, d: c },
        }
    } else {
        Split {
            q: -q - 1,
            frac: Frac::Exact { r: c - r, d: c },
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn deg() -> Modulo {
        Modulo::new(360.0).unwrap()
    }

    fn scaling(cpr: u32, motor: u32, load: u32, feed: f64, invert: bool) -> Scaling {
        Scaling::new(ScalingConfig {
            counts_per_motor_rev: cpr,
            motor_revs: motor,
            load_revs: load,
            units_per_load_rev: feed,
            invert,
        })
        .unwrap()
    }

    /// `⌊num / den + ½⌋` for exact integer references.
    fn round_ref(num: i128, den: i128) -> i128 {
        (2 * num + den).div_euclid(2 * den)
    }

    // ---- Modulo ----

    #[test]
    fn seed_modulo_distances() {
        let m = deg();
        // Seed 000: at 50° AbsModuloPos to 40° travels +350°.
        assert_eq!(m.delta_positive(50.0, 40.0), 350.0);
        // At 40° AbsModuloNeg to 50° travels −350°.
        assert_eq!(m.delta_negative(40.0, 50.0), -350.0);
        // At 40° AbsModuloAuto to 50° travels +10°.
        assert_eq!(m.delta_shortest(40.0, 50.0), 10.0);
        // At 40° after a positive move, KeepDirection to 20° travels +340°; from 50° (where
        // the seed's example arrives) +330°.
        assert_eq!(m.delta_keep(40.0, 20.0, 1.0), 340.0);
        assert_eq!(m.delta_keep(50.0, 20.0, 1.0), 330.0);
        assert_eq!(m.delta_keep(40.0, 20.0, -1.0), -20.0);
        assert_eq!(m.delta_keep(40.0, 20.0, 0.0), -20.0);
        assert_eq!(m.delta_positive(40.0, 40.0), 0.0);
        assert_eq!(m.delta_negative(40.0, 40.0), 0.0);
        assert!(m.delta_negative(40.0, 40.0).is_sign_positive());
    }

    #[test]
    fn shortest_tie_goes_positive() {
        let m = deg();
        assert_eq!(m.delta_shortest(0.0, 180.0), 180.0);
        assert_eq!(m.delta_shortest(180.0, 0.0), 180.0);
        let d = m.delta_shortest(10.0, 190.000_000_1);
        assert!((d + 179.999_999_9).abs() < 1e-9, "{d}");
    }

    #[test]
    fn actual_is_reported_on_the_side_of_set() {
        let m = deg();
        assert_eq!(m.follow(0.0, 358.0), -2.0);
        assert_eq!(m.follow(359.0, 1.0), 361.0);
        assert_eq!(m.follow(720.0, 358.0), 718.0);
        assert_eq!(m.follow(-1.0, 1.0), 1.0);
    }

    #[test]
    fn wrap_never_returns_the_period() {
        let m = deg();
        assert_eq!(m.wrap(-1e-18), 0.0);
        assert_eq!(m.wrap(-f64::MIN_POSITIVE), 0.0);
        assert_eq!(m.wrap(360.0), 0.0);
        assert_eq!(m.wrap(-360.0), 0.0);
        assert!(m.wrap(-360.0).is_sign_positive());
        assert_eq!(m.wrap(-10.0), 350.0);
        assert_eq!(m.wrap(720.5), 0.5);
        let below = 360.0_f64.next_down();
        assert_eq!(m.wrap(below), below);
        assert_eq!(m.wrap(-below), 360.0 - below);
        // Exact far from zero: fmod is exact.
        assert_eq!(m.wrap(1e6 * 360.0 + 10.0), 10.0);
        assert_eq!(m.wrap(-1e6 * 360.0 - 10.0), 350.0);
        assert!(Modulo::new(0.0).is_none() && Modulo::new(f64::NAN).is_none());
        assert!(Modulo::new(-1.0).is_none() && Modulo::new(f64::INFINITY).is_none());
        assert_eq!(
            Modulo::try_new(-2.0),
            Err(MechanicsError::BadPeriod { period: -2.0 })
        );
    }

    #[test]
    fn split_gives_turns_and_position_within() {
        let m = deg();
        assert_eq!(m.split(725.0), (2, 5.0));
        assert_eq!(m.split(-5.0), (-1, 355.0));
        assert_eq!(m.split(-360.0), (-1, 0.0));
        assert_eq!(m.split(360.0 * 1e6 + 1.5), (1_000_000, 1.5));
    }

    // ---- Mechanics ----

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
        assert_eq!(
            m.validate(),
            Err(MechanicsError::LimitNotFinite {
                min: f64::NEG_INFINITY,
                max: 5.0
            })
        );
        m.software_limits = Some((-5.0, 5.0));
        m.direction = Direction::PositiveOnly;
        assert_eq!(m.validate(), Ok(()), "one-way normal axes are allowed");
    }

    #[test]
    fn targets_are_checked_against_the_software_limits() {
        let m = Mechanics {
            software_limits: Some((-10.0, 100.0)),
            ..Mechanics::default()
        };
        assert_eq!(m.check_target(50.0), Ok(()));
        assert_eq!(m.check_target(100.0), Ok(()));
        assert_eq!(
            m.check_target(-10.5),
            Err(MechanicsError::BelowSoftwareLimit {
                value: -10.5,
                min: -10.0
            })
        );
        assert_eq!(
            m.check_target(100.5),
            Err(MechanicsError::AboveSoftwareLimit {
                value: 100.5,
                max: 100.0
            })
        );
        assert!(matches!(
            m.check_target(f64::NAN),
            Err(MechanicsError::NotFinite { name: "target", .. })
        ));
        // Modulo axes have no software limits.
        let r = Mechanics {
            modulo: Modulo::new(360.0),
            ..m
        };
        assert_eq!(r.check_target(500.0), Ok(()));
        let msg = m.check_target(100.5).unwrap_err().to_string();
        assert!(msg.contains("100.5") && msg.contains("max 100"), "{msg}");
    }

    #[test]
    fn directions_are_checked() {
        let mut m = Mechanics {
            direction: Direction::PositiveOnly,
            ..Mechanics::default()
        };
        assert_eq!(m.check_direction(1.0), Ok(()));
        assert_eq!(m.check_direction(0.0), Ok(()));
        assert_eq!(
            m.check_direction(-1.0),
            Err(MechanicsError::DirectionNotAllowed {
                delta: -1.0,
                allowed: Direction::PositiveOnly
            })
        );
        m.direction = Direction::NegativeOnly;
        assert!(m.check_direction(1.0).is_err() && m.check_direction(-1.0).is_ok());
        assert!(m.check_direction(f64::NAN).is_err());
        m.direction = Direction::Both;
        assert!(m.check_direction(1.0).is_ok() && m.check_direction(-1.0).is_ok());
        let msg = MechanicsError::DirectionNotAllowed {
            delta: -3.0,
            allowed: Direction::PositiveOnly,
        }
        .to_string();
        assert!(msg.contains("-3") && msg.contains("positive only"), "{msg}");
    }

    // ---- Scaling ----

    #[test]
    fn scaling_is_exact_far_from_zero() {
        // 5 mm ball screw, 2:1 gear, 2^17 counts: 52428.8 counts per mm.
        let s = scaling(1 << 17, 2, 1, 5.0, false);
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
    fn unit_steps_as_absolute_positions_never_drift() {
        // 200 counts/mm (1000 counts, 5 mm): every absolute position k·1 mm is exactly
        // 200·k counts, for all k up to 10^6.
        let s = scaling(1000, 1, 1, 5.0, false);
        let mut p = 0.0_f64;
        for k in 1..=1_000_000i64 {
            p += 1.0;
            assert_eq!(s.units_to_counts(p), 200 * k);
        }
        // 25/3 counts per degree (360°, gear 3:1 → 3000 counts per turn): 360° steps.
        let s = scaling(1000, 3, 1, 360.0, false);
        for k in [1i64, 7, 1000, 999_999, 1_000_000] {
            assert_eq!(s.units_to_counts(360.0 * k as f64), 3000 * k);
        }
        // A naive f64 factor is off for large positions: 8.333… · 3.6e8 rounds differently
        // only in the last bits, but exactness is the contract here.
        assert_eq!(s.units_to_counts(0.12), 1);
        assert_eq!(s.units_to_counts(-0.12), -1);
    }

    #[test]
    fn rounding_is_half_up() {
        // 2 counts per unit: 0.25 units = 0.5 counts.
        let s = scaling(2, 1, 1, 1.0, false);
        assert_eq!(s.units_to_counts(0.25), 1);
        assert_eq!(s.units_to_counts(-0.25), 0);
        assert_eq!(s.units_to_counts(0.75), 2);
        assert_eq!(s.units_to_counts(-0.75), -1);
        assert_eq!(s.units_to_counts(0.2499999999999), 0);
        // Tiny values.
        assert_eq!(s.units_to_counts(1e-300), 0);
        assert_eq!(s.units_to_counts(-1e-300), 0);
        assert_eq!(s.units_to_counts(f64::MIN_POSITIVE / 4.0), 0);
        assert_eq!(s.units_to_counts(-0.0), 0);
    }

    #[test]
    fn inverted_scaling_flips_counts() {
        let s = scaling(1 << 20, 1, 1, 360.0, true);
        assert_eq!(s.units_to_counts(360.0), -(1 << 20));
        assert_eq!(s.counts_to_units(-(1 << 20)), 360.0);
        assert_eq!(s.velocity_to_counts(360.0), -((1 << 20) as f64));
        assert_eq!(s.velocity_to_units(-((1 << 20) as f64)), 360.0);
        // The default scaling is the same, not inverted.
        assert_eq!(Scaling::default().units_to_counts(360.0), 1 << 20);
        assert_eq!(
            Scaling::default(),
            Scaling::new(ScalingConfig::default()).unwrap()
        );
    }

    #[test]
    fn velocities_scale_by_counts_per_unit() {
        let s = scaling(10_000, 3, 1, 5.0, false);
        assert_eq!(s.counts_per_unit(), 6000.0);
        assert_eq!(s.velocity_to_counts(2.5), 15_000.0);
        assert_eq!(s.velocity_to_units(15_000.0), 2.5);
    }

    #[test]
    fn bad_scaling_names_the_field() {
        let cfg = ScalingConfig::default();
        for (c, field) in [
            (
                ScalingConfig {
                    counts_per_motor_rev: 0,
                    ..cfg
                },
                "counts_per_motor_rev",
            ),
            (
                ScalingConfig {
                    motor_revs: 0,
                    ..cfg
                },
                "motor_revs",
            ),
            (
                ScalingConfig {
                    load_revs: 0,
                    ..cfg
                },
                "load_revs",
            ),
        ] {
            assert_eq!(
                Scaling::new(c),
                Err(MechanicsError::BadScaling { field, value: 0.0 })
            );
        }
        for feed in [0.0, -5.0, f64::NAN, f64::INFINITY, 1e-320] {
            let r = Scaling::new(ScalingConfig {
                units_per_load_rev: feed,
                ..cfg
            });
            assert!(
                matches!(
                    r,
                    Err(MechanicsError::BadScaling {
                        field: "units_per_load_rev",
                        ..
                    })
                ),
                "{feed}: {r:?}"
            );
        }
    }

    #[test]
    fn out_of_range_positions_are_errors_or_saturate() {
        let s = scaling(1 << 20, 1, 1, 360.0, false);
        assert!(matches!(
            s.try_units_to_counts(f64::NAN),
            Err(MechanicsError::NotFinite { .. })
        ));
        assert_eq!(
            s.try_units_to_counts(1e30),
            Err(MechanicsError::CountsOutOfRange { value: 1e30 })
        );
        assert_eq!(s.units_to_counts(1e30), i64::MAX);
        assert_eq!(s.units_to_counts(-1e30), i64::MIN);
        assert_eq!(s.units_to_counts(f64::INFINITY), i64::MAX);
        assert_eq!(s.units_to_counts(f64::NAN), 0);
        assert_eq!(s.units_to_counts(f64::MAX), i64::MAX);
        let inv = scaling(1 << 20, 1, 1, 360.0, true);
        assert_eq!(inv.units_to_counts(1e30), i64::MIN);
        // The largest counts survive.
        assert!(s.counts_to_units(i64::MAX).is_finite());
        assert!(inv.counts_to_units(i64::MIN).is_finite());
    }

    #[test]
    fn dyadic_decomposition_is_exact() {
        for x in [
            1.0,
            0.1,
            -3.5,
            360.0,
            5.0,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            -0.0,
        ] {
            let (m, e) = dyadic(x);
            assert_eq!(scale2(m as f64, e), x, "{x}");
            assert!(m == 0 || m % 2 != 0);
        }
        assert_eq!(dyadic(360.0), (45, 3));
        assert_eq!(dyadic(-0.75), (-3, -2));
    }

    #[test]
    fn wide_products_divide_exactly() {
        // (2^63 · (2^126 − 1)) / (2^126 − 3): the 192-bit path.
        let b = (1u128 << 126) - 1;
        let c = (1u128 << 126) - 3;
        let s = mul_div_floor(1i128 << 63, b, c).unwrap();
        // = 2^63 · (1 + 2/c) = 2^63 + 2^64/c → floor 2^63, remainder 2^64.
        assert_eq!(s.q, 1i128 << 63);
        assert!(matches!(s.frac, Frac::Exact { r, d } if r == 1u128 << 64 && d == c));
        let s = mul_div_floor(-(1i128 << 63), b, c).unwrap();
        assert_eq!(s.q, -(1i128 << 63) - 1);
        assert_eq!(mul_div_floor(7, 3, 2).unwrap().q, 10);
        assert_eq!(mul_div_floor(-7, 3, 2).unwrap().q, -11);
        assert!(mul_div_floor(1 << 62, 1 << 126, 1).is_none());
    }

    // ---- ModuloCounts ----

    #[test]
    fn modulo_turns_convert_without_accumulated_error() {
        // 360° per load rev, gear 1:3 (one motor rev per three turns), 1000 counts per
        // motor rev: 333⅓ counts per turn, not an integer.
        let s = scaling(1000, 1, 3, 360.0, false);
        let mc = ModuloCounts::new(s, deg()).unwrap();
        assert_eq!(mc.counts_per_period(), (1000, 3));
        // 10^6 turns · 1000/3 = 333_333_333.33… → 333_333_333.
        assert_eq!(mc.to_counts(1_000_000, 0.0), 333_333_333);
        assert_eq!(mc.to_counts(1_000_001, 0.0), 333_333_667);
        assert_eq!(mc.to_counts(-1_000_000, 0.0), -333_333_333);
        assert_eq!(mc.to_counts(1_000_000, 180.0), 333_333_500);
        // Every turn count up to 10^5 and around 10^6, 10^12, 10^15 against integer math.
        let check = |n: i64| {
            assert_eq!(
                i128::from(mc.to_counts(n, 0.0)),
                round_ref(i128::from(n) * 1000, 3),
                "turns {n}"
            );
        };
        (-100_000..=100_000).for_each(check);
        for base in [1_000_000i64, 1_000_000_000_000, 1_000_000_000_000_000] {
            (base - 10..base + 10).for_each(check);
            (-base - 10..-base + 10).for_each(check);
        }
        // Gear 3:1: 3000 counts per turn.
        let mc = ModuloCounts::new(scaling(1000, 3, 1, 360.0, false), deg()).unwrap();
        assert_eq!(mc.to_counts(1_000_000, 0.0), 3_000_000_000);
        assert_eq!(mc.to_counts(1_000_000, 90.0), 3_000_000_750);
    }

    #[test]
    fn modulo_counts_round_half_up_at_exact_ties() {
        // 1001 counts per rev, gear 1:2: 500.5 counts per turn.
        let mc = ModuloCounts::new(scaling(1001, 1, 2, 360.0, false), deg()).unwrap();
        assert_eq!(mc.to_counts(1, 0.0), 501);
        assert_eq!(mc.to_counts(-1, 0.0), -500);
        assert_eq!(mc.to_counts(3, 0.0), 1502);
        assert_eq!(mc.to_counts(2_000_001, 0.0), 1_001_000_501);
        // Within-period ties too: 180° = 250.25 counts; 1 turn + 180° = 750.75 → 751.
        assert_eq!(mc.to_counts(1, 180.0), 751);
    }

    #[test]
    fn modulo_counts_agree_with_scaling_and_invert() {
        let s = scaling(1 << 17, 7, 5, 360.0, true);
        let mc = ModuloCounts::new(s, deg()).unwrap();
        for w in [0.0, 0.1, 90.0, 359.9] {
            assert_eq!(mc.to_counts(0, w), s.units_to_counts(w), "{w}");
            for n in [-3i64, 1, 1000] {
                let direct = s.units_to_counts(360.0 * n as f64 + w);
                assert!((mc.to_counts(n, w) - direct).abs() <= 1, "{n} {w}");
            }
        }
        assert_eq!(
            mc.to_counts(5, 0.0),
            -i64::try_from(round_ref(5 * (1 << 17) * 7, 5)).unwrap()
        );
    }

    #[test]
    fn modulo_counts_back_to_position() {
        let mc = ModuloCounts::new(scaling(1000, 1, 3, 360.0, false), deg()).unwrap();
        assert_eq!(mc.to_position(0), (0, 0.0));
        assert_eq!(mc.to_position(1000), (3, 0.0));
        let (n, w) = mc.to_position(333_333_500);
        assert_eq!(n, 1_000_000);
        assert!((w - 180.0).abs() < 1e-9, "{w}");
        let (n, w) = mc.to_position(-1);
        assert_eq!(n, -1);
        assert!((w - (360.0 - 1.08)).abs() < 1e-9, "{w}");
        let (n, _) = mc.to_position(i64::MIN);
        assert!(n < 0);
    }

    #[test]
    fn modulo_counts_refuse_unusable_periods() {
        let s = scaling(1, 1, 1, 360.0, false);
        // A period of one degree at 1/360 count per degree: less than a count.
        assert!(matches!(
            ModuloCounts::new(s, Modulo::new(1.0).unwrap()),
            Err(MechanicsError::CountsPerPeriodOutOfRange { .. })
        ));
        let s = scaling(1 << 20, 1, 1, 1e-30, false);
        assert!(ModuloCounts::new(s, Modulo::new(1e30).unwrap()).is_err());
        let mc = ModuloCounts::new(scaling(1000, 1, 1, 360.0, false), deg()).unwrap();
        assert!(mc.try_to_counts(1, f64::NAN).is_err());
        assert!(mc.try_to_counts(i64::MAX, 0.0).is_err());
        assert_eq!(mc.to_counts(i64::MAX, 0.0), i64::MAX);
        assert_eq!(mc.to_counts(i64::MIN, 0.0), i64::MIN);
    }

    // ---- CountExtender ----

    #[test]
    fn count_extender_rides_through_wraps() {
        let mut e = CountExtender::default();
        assert_eq!(e.value(), None);
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
        assert_eq!(e.value(), Some(expected));
    }

    #[test]
    fn count_extender_handles_the_extremes() {
        let mut e = CountExtender::new();
        assert_eq!(e.update(i32::MIN), i64::from(i32::MIN));
        assert_eq!(e.update(i32::MAX), i64::from(i32::MIN) - 1, "one step back");
        assert_eq!(e.update(i32::MIN), i64::from(i32::MIN));
        // Largest forward step: 2^31 − 1.
        assert_eq!(e.update(-1), i64::from(i32::MIN) + i64::from(i32::MAX));
        // 10^9-count steps up to 10^12.
        let mut e = CountExtender::new();
        let mut truth: i64 = 0;
        e.update(0);
        while truth < 1_000_000_000_000 {
            truth += 1_000_000_000;
            assert_eq!(e.update(truth as i32), truth);
        }
        // Rebase (a stored absolute position) and reset.
        e.rebase(42);
        assert_eq!(e.update(truth as i32 + 1), 43);
        e.reset();
        assert_eq!(e.update(7), 7);
        let mut fresh = CountExtender::new();
        fresh.rebase(-5_000_000_000);
        assert_eq!(fresh.value(), None);
        assert_eq!(fresh.update(123), -5_000_000_000);
        assert_eq!(fresh.update(124), -4_999_999_999);
    }

    #[test]
    fn narrow_counters_wrap_at_their_width() {
        let mut e = CountExtender::with_width(16).unwrap();
        assert_eq!(e.update(65_530), 65_530);
        assert_eq!(e.update(5), 65_541);
        assert_eq!(e.update(65_535), 65_535);
        let mut e = CountExtender::with_width(24).unwrap();
        let mut truth: i64 = 0;
        e.update(0);
        for _ in 0..1000 {
            truth -= 3_000_000;
            assert_eq!(e.update(truth.rem_euclid(1 << 24) as i32), truth);
        }
        assert_eq!(
            CountExtender::with_width(1),
            Err(MechanicsError::BadCounterWidth { bits: 1 })
        );
        assert!(CountExtender::with_width(33).is_err());
        assert_eq!(CountExtender::with_width(32), Ok(CountExtender::new()));
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 2000,
            rng_seed: proptest::test_runner::RngSeed::Fixed(11),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        #[test]
        fn counts_round_trip_exactly(
            c in prop_oneof![
                -4_000_000_000_000i64..4_000_000_000_000,
                -(1i64 << 50)..(1i64 << 50),
            ],
            cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100,
            feed in prop_oneof![0.1..1000.0f64, Just(360.0), Just(5.0)],
            invert: bool,
        ) {
            let s = scaling(cpr, mr, lr, feed, invert);
            prop_assert_eq!(s.units_to_counts(s.counts_to_units(c)), c);
        }

        #[test]
        fn units_to_counts_matches_integer_math_on_integer_positions(
            k in -1_000_000_000i64..1_000_000_000,
            cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100,
            feed in 1u32..1000,
        ) {
            // Integer positions and feed: counts = k · cpr · mr / (lr · feed), exactly.
            let s = scaling(cpr, mr, lr, f64::from(feed), false);
            let num = i128::from(k) * i128::from(cpr) * i128::from(mr);
            let den = i128::from(lr) * i128::from(feed);
            prop_assert_eq!(i128::from(s.units_to_counts(k as f64)), round_ref(num, den));
        }

        #[test]
        fn units_to_counts_rounds_to_the_nearest_count(
            p in prop_oneof![-1e6..1e6f64, -1.0..1.0f64],
            cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100,
            feed in prop_oneof![0.01..1000.0f64, Just(360.0), Just(0.1)],
            invert: bool,
        ) {
            // Against the f64 product: the exact count is within ½ of p · counts/unit, and the
            // f64 product is within a few ulp of that.
            let s = scaling(cpr, mr, lr, feed, invert);
            let c = s.units_to_counts(p) as f64;
            let x = s.velocity_to_counts(p);
            prop_assert!((c - x).abs() <= 0.5 + 1e-15 * x.abs().max(1.0), "{p}: {c} vs {x}");
        }

        #[test]
        fn modulo_counts_match_integer_math(
            n in prop_oneof![-1_000_000_000_000i64..1_000_000_000_000, -1000i64..1000],
            w in 0u32..360,
            cpr in 1u32..(1 << 24), mr in 1u32..100, lr in 1u32..100,
        ) {
            let s = scaling(cpr, mr, lr, 360.0, false);
            let mc = ModuloCounts::new(s, deg()).unwrap();
            let num = (i128::from(n) * 360 + i128::from(w)) * i128::from(cpr) * i128::from(mr);
            let den = i128::from(lr) * 360;
            let expect = round_ref(num, den);
            if i64::try_from(expect).is_err() {
                prop_assert!(mc.try_to_counts(n, f64::from(w)).is_err());
                return Ok(());
            }
            prop_assert_eq!(i128::from(mc.to_counts(n, f64::from(w))), expect);
            // And back: whole turns and the position within, to a count.
            let c = mc.to_counts(n, f64::from(w));
            let (n2, w2) = mc.to_position(c);
            let back = (n2 as f64 - n as f64) * 360.0 + (w2 - f64::from(w));
            prop_assert!(back.abs() <= 1.0 / s.counts_per_unit() + 1e-9, "{n} {w} → {n2} {w2}");
        }

        #[test]
        fn count_extender_tracks_random_walks(
            start in any::<i32>(),
            steps in proptest::collection::vec(-(i32::MAX as i64)..=(i32::MAX as i64), 1..200),
            bits in prop_oneof![Just(32u32), 8u32..32],
        ) {
            let mut e = CountExtender::with_width(bits).unwrap();
            let range = 1i64 << bits;
            let half = range / 2;
            let raw = |t: i64| if bits == 32 { t as i32 } else { t.rem_euclid(range) as i32 };
            let mut truth = if bits == 32 { i64::from(start) } else { i64::from(start).rem_euclid(range) };
            prop_assert_eq!(e.update(raw(truth)), truth);
            for s in steps {
                let s = s.clamp(-half + 1, half - 1);
                truth += s;
                prop_assert_eq!(e.update(raw(truth)), truth);
            }
        }

        #[test]
        fn modulo_deltas_land_on_the_target(
            from in -1e6..1e6f64, to in 0.0..360.0f64, last in -1.0..1.0f64,
        ) {
            let m = deg();
            let here = m.wrap(from);
            prop_assert!((0.0..360.0).contains(&here));
            for (d, lo, hi) in [
                (m.delta_positive(here, to), 0.0, 360.0),
                (m.delta_negative(here, to), -360.0, 0.0),
                (m.delta_shortest(here, to), -180.0, 180.0),
                (m.delta_keep(here, to, last), -360.0, 360.0),
            ] {
                prop_assert!(d >= lo && d <= hi, "{d} outside [{lo}, {hi}]");
                let err = (m.wrap(here + d) - to).abs();
                prop_assert!(!(1e-9..=360.0 - 1e-9).contains(&err), "{here} + {d} ≠ {to}");
            }
            let f = m.follow(from, to);
            prop_assert!((f - from).abs() <= 180.0 + 1e-9);
            let err = (m.wrap(f) - to).abs();
            prop_assert!(!(1e-6..=360.0 - 1e-6).contains(&err));
        }

        #[test]
        fn wrap_is_in_range_for_any_period(p in any::<f64>(), period in 1e-6..1e9f64) {
            let m = Modulo::new(period).unwrap();
            let w = m.wrap(p);
            if p.is_finite() {
                prop_assert!(w >= 0.0 && w < period, "wrap({p}) = {w} for {period}");
            }
        }
    }
}
