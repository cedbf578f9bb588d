//! Catching up: what takes a follower from where it was when a relation began onto the
//! relation's law without a jump in position, velocity or acceleration.
//!
//! The follower's set position is `law + e`; `e` starts at what the follower's own motion
//! differs from the law (position 0 — the law is placed where the follower is —, velocity
//! and acceleration the difference) and ends constant:
//! - in time (MC_GearIn, MC_CamIn): a velocity profile of `e` down to 0 with the command's
//!   acceleration, deceleration and jerk (the position offset is what it leaves), or a
//!   positioning profile to a given offset (an absolute cam: onto the table's value);
//! - in the master's position (MC_GearInPos): a 5th-order polynomial in the master's
//!   travel that reaches `e = 0` with zero derivatives exactly at the sync position,
//!   wherever the master's speed takes it.

use crate::axis::motion::Epoch;
use crate::profile::{KinematicState, Profile};

use super::MasterSample;

/// The catch-up of a relation.
// The profile stays inline: boxing it would allocate when a relation starts, in `step`.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Catch {
    /// `e` runs a profile in time from `epoch`.
    Time {
        /// The profile of `e`.
        profile: Profile,
        /// When it starts.
        epoch: Epoch,
    },
    /// `e` is a quintic in `s = (Δm − start) / (−start)`, `Δm` the master's travel from the
    /// sync position (so `s = 1` there).
    Master {
        /// Coefficients of `e(s)`, lowest first.
        c: [f64; 6],
        /// Master travel (from the sync position) where `s = 0`; ≠ 0.
        start: f64,
    },
    /// Caught up: `e` stays at `offset`.
    Done {
        /// The position offset left.
        offset: f64,
    },
}

impl Catch {
    /// A quintic from `e0`, `de/ds`, `d²e/ds²` at `s = 0` to 0 with zero derivatives at 1.
    pub fn quintic(e0: f64, e1: f64, e2: f64, start: f64) -> Self {
        let (c0, c1, c2) = (e0, e1, e2 / 2.0);
        let a = -(c0 + c1 + c2);
        let b = -(c1 + 2.0 * c2);
        let c = -(2.0 * c2);
        Catch::Master {
            c: [
                c0,
                c1,
                c2,
                10.0 * a - 4.0 * b + 0.5 * c,
                -15.0 * a + 7.0 * b - c,
                6.0 * a - 3.0 * b + 0.5 * c,
            ],
            start,
        }
    }

    /// Whether the follower is on the law (InGear / InSync).
    pub const fn is_done(&self) -> bool {
        matches!(self, Catch::Done { .. })
    }

    /// `e` (p, v, a) at master travel `dm` (from the relation's master reference), master
    /// sample `m`, cycle `now`; moves to [`Catch::Done`] once over.
    pub fn sample(&mut self, dm: f64, m: &MasterSample, now: u64, dt: f64) -> KinematicState {
        match *self {
            Catch::Done { offset } => KinematicState::at_rest(offset),
            Catch::Time { profile, epoch } => {
                let t = epoch.elapsed(now, dt);
                if t >= profile.duration() {
                    let end = profile.end_state();
                    *self = Catch::Done { offset: end.p };
                    return KinematicState::at_rest(end.p);
                }
                profile.sample(t)
            }
            Catch::Master { c, start } => {
                let len = -start;
                let s = (dm - start) / len;
                if s >= 1.0 {
                    *self = Catch::Done { offset: 0.0 };
                    return KinematicState::default();
                }
                let [c0, c1, c2, c3, c4, c5] = c;
                let (e, es, ess) = if s < 0.0 {
                    // The master went back past where catching up began: go on along the
                    // tangent there.
                    (c0 + c1 * s, c1, 0.0)
                } else {
                    (
                        c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5)))),
                        c1 + s * (2.0 * c2 + s * (3.0 * c3 + s * (4.0 * c4 + s * 5.0 * c5))),
                        2.0 * c2 + s * (6.0 * c3 + s * (12.0 * c4 + s * 20.0 * c5)),
                    )
                };
                let em = es / len;
                let emm = ess / (len * len);
                KinematicState {
                    p: e,
                    v: em * m.v,
                    a: emm * m.v * m.v + em * m.a,
                    j: 0.0,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quintic_meets_both_ends() {
        let mut q = Catch::quintic(2.0, -3.0, 5.0, -10.0);
        let Catch::Master { c, .. } = q else {
            unreachable!()
        };
        let at = |s: f64| c.iter().rev().fold(0.0, |acc, ci| acc * s + ci);
        assert!((at(0.0) - 2.0).abs() < 1e-12);
        assert!(at(1.0).abs() < 1e-12);
        let m = MasterSample {
            v: 1.0,
            available: true,
            ..MasterSample::default()
        };
        let e = q.sample(-1e-9, &m, 0, 1e-3);
        assert!(e.p.abs() < 1e-9 && e.v.abs() < 1e-6);
        q.sample(0.0, &m, 0, 1e-3);
        assert!(q.is_done());
    }
}
