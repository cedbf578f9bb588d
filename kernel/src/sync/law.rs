//! The law of a relation: the follower's travel as a function of the master's.

use super::{MasterSample, Split};
use crate::cam::CamTable;

/// What a law gives for one master travel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LawOut {
    /// Part of the follower's travel that is an exact multiple of the master's period
    /// (computed without rounding where the law allows; added before `rest`).
    pub whole: f64,
    /// The rest of the follower's travel (units).
    pub rest: f64,
    /// d follower / d master.
    pub d1: f64,
    /// d² follower / d master².
    pub d2: f64,
    /// A non-periodic cam is past the end of its table.
    pub ended: bool,
    /// A periodic cam began another period.
    pub wrapped: bool,
    /// A master-driven jog's lock took hold in this cycle (the follower must catch up).
    pub locked: bool,
}

/// A cam relation's placement of its table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CamLaw {
    /// Table slot.
    pub table: usize,
    /// Whether the table repeats.
    pub periodic: bool,
    /// Table master units per master unit.
    pub master_scaling: f64,
    /// Follower units per table slave unit.
    pub slave_scaling: f64,
    /// Table master coordinate at the relation's master reference.
    pub x_ref: f64,
    /// `slave_scaling ·` the unrolled table value at `x_ref` (subtracted: the law's travel
    /// is 0 at the reference).
    pub y_ref: f64,
    /// Table period the master was in last cycle (periodic cams).
    pub cycle: i64,
    /// The table segment of the last cycle (where the next lookup starts).
    pub segment: usize,
}

impl CamLaw {
    /// The table's coordinate `x` as (period index, coordinate within the table).
    pub fn locate(table: &CamTable, x: f64, periodic: bool) -> (i64, f64) {
        let (x0, x1) = table.master_range();
        if !periodic {
            return (0, x.clamp(x0, x1));
        }
        let len = x1 - x0;
        let c = ((x - x0) / len).floor();
        let phase = (x - c * len).clamp(x0, x1);
        (c as i64, phase)
    }

    /// The unrolled table value at `x` (a periodic table rises by its rise each period).
    pub fn unrolled(table: &CamTable, x: f64, periodic: bool) -> f64 {
        let (c, phase) = Self::locate(table, x, periodic);
        table.eval(phase).slave + c as f64 * table.slave_rise()
    }
}

/// A master-driven jog's state: it follows the master at `ratio` while its lock holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JogLaw {
    /// Follower units per master unit, signed by the jog's direction.
    pub ratio: f64,
    /// +1: only while the master moves forward; −1: only backwards; 0: both ways.
    pub only: f64,
    /// A Position* lock not yet reached: the master position to cross (in the direction
    /// `only`).
    pub wait_at: Option<Split>,
    /// Whether it follows now (Logix JogLockStatus).
    pub locked: bool,
    /// Master position where the current lock began.
    pub anchor: Split,
    /// Follower travel of the earlier locks.
    pub travel: f64,
}

impl JogLaw {
    /// Updates the lock for master sample `m`; returns the follower travel, its
    /// derivative, and whether the lock took hold in this cycle.
    pub fn eval(&mut self, m: &MasterSample) -> (f64, f64, bool) {
        if let Some(at) = self.wait_at {
            if self.only * m.delta_f64(&at) >= 0.0 {
                self.wait_at = None;
            } else {
                return (self.travel, 0.0, false);
            }
        }
        let holds = self.only == 0.0 || m.v * self.only > 0.0;
        let mut opened = false;
        if holds && !self.locked {
            self.locked = true;
            self.anchor = m.at;
            opened = true;
        } else if !holds && self.locked {
            self.travel += self.ratio * m.delta_f64(&self.anchor);
            self.locked = false;
        }
        if self.locked {
            (
                self.travel + self.ratio * m.delta_f64(&self.anchor),
                self.ratio,
                opened,
            )
        } else {
            (self.travel, 0.0, false)
        }
    }
}

/// Gear, cam or master-driven jog.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Law {
    /// Follower travel = numerator · master travel / denominator.
    Gear {
        /// Numerator.
        numerator: i64,
        /// Denominator (> 0).
        denominator: i64,
    },
    /// Follower travel through a cam table.
    Cam(CamLaw),
    /// A master-driven jog (Logix MAJ locked to a master).
    Jog(JogLaw),
}

impl Law {
    /// The follower's travel for a master travel of `k` whole periods plus `r`.
    pub fn eval(&mut self, k: i64, r: f64, m: &MasterSample, cams: &[Option<CamTable>]) -> LawOut {
        let period = m.period;
        match self {
            Law::Jog(j) => {
                let (rest, d1, opened) = j.eval(m);
                LawOut {
                    rest,
                    d1,
                    locked: opened,
                    ..LawOut::default()
                }
            }
            Law::Gear {
                numerator,
                denominator,
            } => {
                let (num, den) = (*numerator, (*denominator).max(1));
                let ratio = num as f64 / den as f64;
                let (whole, rest) = match period {
                    Some(pm) => {
                        // numerator · k · pm / den: the whole multiples of pm in integers.
                        let a = num as i128 * k as i128;
                        let q = a.div_euclid(den as i128);
                        let rem = a.rem_euclid(den as i128);
                        (
                            q as f64 * pm,
                            (rem as f64 * pm + num as f64 * r) / den as f64,
                        )
                    }
                    None => (0.0, ratio * r),
                };
                LawOut {
                    whole,
                    rest,
                    d1: ratio,
                    ..LawOut::default()
                }
            }
            Law::Cam(c) => {
                let Some(table) = cams.get(c.table).and_then(Option::as_ref) else {
                    return LawOut {
                        ended: true,
                        ..LawOut::default()
                    };
                };
                let travel = match period {
                    Some(pm) => k as f64 * pm + r,
                    None => r,
                };
                let x = c.x_ref + c.master_scaling * travel;
                let (x0, x1) = table.master_range();
                let (cycle, phase) = CamLaw::locate(table, x, c.periodic);
                let mut s = table.eval_near(phase, &mut c.segment);
                if !c.periodic && phase != x {
                    // Past the end of a non-periodic table (the relation ends this cycle):
                    // along the end's tangent, so the last set value keeps the velocity.
                    s.slave += s.d1 * (x - phase);
                    s.d2 = 0.0;
                }
                let wrapped = c.periodic && cycle != c.cycle;
                c.cycle = cycle;
                let ss = c.slave_scaling;
                LawOut {
                    whole: ss * cycle as f64 * table.slave_rise(),
                    rest: ss * s.slave - c.y_ref,
                    d1: ss * s.d1 * c.master_scaling,
                    d2: ss * s.d2 * c.master_scaling * c.master_scaling,
                    ended: !c.periodic && (x > x1 || x < x0),
                    wrapped,
                    locked: false,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gear_counts_whole_master_periods_in_integers() {
        let mut g = Law::Gear {
            numerator: 3,
            denominator: 7,
        };
        // 7 · 10⁶ master turns of 360 at 3/7: exactly 3 · 10⁶ · 360.
        let m = MasterSample {
            period: Some(360.0),
            ..MasterSample::default()
        };
        let out = g.eval(7_000_000, 0.0, &m, &[]);
        assert_eq!(out.whole, 3_000_000.0 * 360.0);
        assert_eq!(out.rest, 0.0);
        // One turn more: 3/7 of 360, in the rest.
        let out = g.eval(7_000_001, 0.0, &m, &[]);
        assert_eq!(out.whole, 3_000_000.0 * 360.0);
        assert!((out.rest - 3.0 * 360.0 / 7.0).abs() < 1e-12);
        // Backwards: floor division keeps the rest non-negative.
        let out = g.eval(-1, 0.0, &m, &[]);
        assert_eq!(out.whole, -360.0);
        assert!((out.rest - 4.0 * 360.0 / 7.0).abs() < 1e-12);
    }
}
