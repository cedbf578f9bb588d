//! Synchronised motion: a follower whose set values come from a master's position
//! (PLCopen MC_GearIn, MC_GearInPos, MC_CamIn) — the third kind of set-value source
//! beside an axis' own profile and the homing sequencer.
//!
//! A relation ([`Follow`]) is `follower = reference + law(Δmaster) + catch-up`:
//! - `Δmaster` is the master's travel since the relation's master reference, kept as whole
//!   modulo periods (an `i64`) and the rest, so a modulo master can turn for ever without
//!   the position losing resolution ([`MasterSample::delta`]);
//! - the law ([`law::Law`]) maps it to the follower's travel: a gear computes
//!   `numerator · Δ / denominator` with the whole periods in integer arithmetic (no drift
//!   over any number of turns), a cam evaluates its table;
//! - the catch-up ([`catch::Catch`]) is what takes the follower from where it was when the
//!   relation began onto the law without a jump: a profile in time (GearIn, CamIn) or a
//!   5th-order polynomial in the master's position (GearInPos).
//!
//! Nothing here allocates; evaluating a relation is a few dozen floating-point operations.

pub mod catch;
pub mod command;
pub mod law;

use crate::axis::handle::HandleId;
use crate::cam::CamTable;
use catch::Catch;
use command::MasterValue;
use law::Law;

/// A position as whole modulo periods and the rest (the rest within a period on modulo
/// axes; on normal axes `turns` is 0 and `p` the position).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Split {
    /// Whole periods.
    pub turns: i64,
    /// The rest (units).
    pub p: f64,
}

impl Split {
    /// `turns · period + p` as one number (loses resolution on very long runs; for
    /// displays and tests).
    pub fn unwrapped(&self, period: Option<f64>) -> f64 {
        match period {
            Some(period) => self.turns as f64 * period + self.p,
            None => self.p,
        }
    }

    /// This position moved by `whole + rest`, where `whole` is an exact multiple the caller
    /// computed without rounding (e.g. whole master periods times a gear ratio): the whole
    /// periods of the sum are split off first, so the rest keeps full resolution.
    pub fn moved(&self, whole: f64, rest: f64, period: Option<f64>) -> Split {
        let Some(period) = period else {
            return Split {
                turns: 0,
                p: self.p + whole + rest,
            };
        };
        let n1 = (whole / period).floor();
        let rem1 = whole - n1 * period;
        let x = self.p + rest + rem1;
        let n2 = (x / period).floor();
        let mut p = x - n2 * period;
        let mut n2 = n2 as i64;
        if p >= period {
            p -= period;
            n2 += 1;
        }
        if p < 0.0 {
            p = 0.0;
        }
        Split {
            turns: self.turns.saturating_add(n1 as i64).saturating_add(n2),
            p,
        }
    }
}

/// A master's position and motion as a follower reads them this cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MasterSample {
    /// Position (whole periods and the rest).
    pub at: Split,
    /// Velocity (master units/s).
    pub v: f64,
    /// Acceleration (master units/s²); 0 for actual values (not estimated: an encoder's
    /// velocity differences are noise).
    pub a: f64,
    /// Whether its values can be followed. An axis whose values come from the bus (real,
    /// external, a shadow of one) is unavailable in ErrorStop: its encoder or drive failed
    /// (seed 001: its followers go to ErrorStop). A virtual or simulated master in ErrorStop
    /// still ramps down, and its followers come down with it.
    pub available: bool,
    /// Its modulo period, if any.
    pub period: Option<f64>,
    /// Whether these are actual values (the acceleration is then unknown).
    pub actual: bool,
}

impl MasterSample {
    /// Travel since `from`: whole periods and the rest (`k · period + r`).
    pub fn delta(&self, from: &Split) -> (i64, f64) {
        match self.period {
            Some(_) => (self.at.turns.wrapping_sub(from.turns), self.at.p - from.p),
            None => (0, self.at.p - from.p),
        }
    }

    /// Travel since `from` as one number (for short distances: catch-up, lock points).
    pub fn delta_f64(&self, from: &Split) -> f64 {
        let (k, r) = self.delta(from);
        match self.period {
            Some(period) => k as f64 * period + r,
            None => r,
        }
    }
}

/// The follower's set values from a relation this cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FollowOut {
    /// Position (follower frame: whole periods and the rest).
    pub at: Split,
    /// Velocity (units/s).
    pub v: f64,
    /// Acceleration (units/s²).
    pub a: f64,
    /// The catch-up is over: the follower is on the law (InGear / InSync).
    pub in_sync: bool,
    /// A non-periodic cam passed the end of its table (EndOfProfile): the relation ends.
    pub ended: bool,
    /// A periodic cam began a new period this cycle (EndOfProfile pulse).
    pub wrapped: bool,
}

/// A running relation of a follower to its master.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Follow {
    /// Master axis index.
    pub master: usize,
    /// Set or actual values of the master.
    pub source: MasterValue,
    /// Gear or cam.
    pub law: Law,
    /// Master position the law's travel counts from.
    pub master_ref: Split,
    /// Follower position where the law's travel is 0.
    pub follower_ref: Split,
    /// How the follower gets onto the law.
    pub catch: Catch,
    /// The command's handle.
    pub handle: HandleId,
    /// The command's name, for errors.
    pub command: &'static str,
    /// Dynamics of the catch-up (a master-driven jog catches up again each time its lock
    /// takes hold).
    pub catch_limits: (crate::profile::Limits, crate::profile::RampType),
}

impl Follow {
    /// The follower's set values for master sample `m` at cycle `now`.
    pub fn sample(
        &mut self,
        m: &MasterSample,
        follower_period: Option<f64>,
        cams: &[Option<CamTable>],
        now: u64,
        dt: f64,
    ) -> FollowOut {
        let (k, r) = m.delta(&self.master_ref);
        let law = self.law.eval(k, r, m, cams);
        let mut e = self.catch.sample(m.delta_f64(&self.master_ref), m, now, dt);
        if law.locked {
            // The lock took hold with the master moving: catch up from the follower's
            // velocity onto the master-driven one, starting now.
            let start = crate::profile::KinematicState {
                p: e.p,
                v: e.v - law.d1 * m.v,
                a: if m.actual { e.a } else { e.a - law.d1 * m.a },
                j: 0.0,
            };
            let (limits, ramp) = self.catch_limits;
            let limits = crate::profile::Limits {
                vmax: limits.vmax.max(start.v.abs()),
                ..limits
            };
            if let Ok(profile) =
                crate::profile::plan_velocity(ramp, start, 0.0, &limits).or_else(|_| {
                    crate::profile::plan_velocity(
                        crate::profile::RampType::Trapezoid,
                        start,
                        0.0,
                        &limits,
                    )
                })
            {
                self.catch = Catch::Time {
                    profile,
                    epoch: crate::axis::motion::Epoch::at(now),
                };
                e = self.catch.sample(0.0, m, now, dt);
            }
        }
        let at = self
            .follower_ref
            .moved(law.whole, law.rest + e.p, follower_period);
        FollowOut {
            at,
            v: law.d1 * m.v + e.v,
            a: law.d2 * m.v * m.v + law.d1 * m.a + e.a,
            in_sync: self.catch.is_done(),
            ended: law.ended,
            wrapped: law.wrapped,
        }
    }

    /// Whether this relation is a cam.
    pub const fn is_cam(&self) -> bool {
        matches!(self.law, Law::Cam(_))
    }

    /// Whether this relation is a gear.
    pub const fn is_gear(&self) -> bool {
        matches!(self.law, Law::Gear { .. })
    }

    /// Whether this relation is a master-driven jog, and whether its lock holds.
    pub const fn jog_lock(&self) -> Option<bool> {
        match self.law {
            Law::Jog(j) => Some(j.locked),
            _ => None,
        }
    }

    /// The cam table slot this relation reads, if it is a cam.
    pub const fn cam_table(&self) -> Option<usize> {
        match self.law {
            Law::Cam(c) => Some(c.table),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moved_splits_whole_periods_before_adding_the_rest() {
        let s = Split { turns: 3, p: 350.0 };
        let m = s.moved(720.0 * 1e6, 20.0, Some(360.0));
        assert_eq!(m.turns, 3 + 2_000_000 + 1);
        assert!((m.p - 10.0).abs() < 1e-9);
        let back = s.moved(-360.0, -351.0, Some(360.0));
        assert_eq!(back.turns, 1);
        assert!((back.p - 359.0).abs() < 1e-9);
        let linear = Split { turns: 0, p: 1.5 }.moved(2.0, 0.25, None);
        assert_eq!(linear, Split { turns: 0, p: 3.75 });
    }

    #[test]
    fn master_delta_counts_whole_periods_exactly() {
        let m = MasterSample {
            at: Split {
                turns: 1_000_000,
                p: 10.0,
            },
            period: Some(360.0),
            available: true,
            ..MasterSample::default()
        };
        assert_eq!(m.delta(&Split { turns: 0, p: 350.0 }), (1_000_000, -340.0));
    }
}
