//! A modulo period and the distances on it (rotary tables, conveyors).

use super::MechanicsError;

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

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 2000,
            rng_seed: proptest::test_runner::RngSeed::Fixed(11),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

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
