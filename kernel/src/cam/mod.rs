//! Cam tables (the data behind PLCopen MC_CamTableSelect): master position → slave
//! position, as a list of points and an interpolation between them. Built once (this is
//! where the work and the allocation happen), then evaluated every cycle by
//! [`CamTable::eval`]: a binary search and one polynomial, no allocation, no panic.
//!
//! Positions are table units (the CamIn that uses the table scales and offsets them to
//! axis units). Master positions must strictly increase; a table has 2 to [`MAX_POINTS`]
//! points.
//!
//! # Interpolation
//!
//! - [`Interpolation::Linear`]: straight segments. d1 is constant on each segment, d2 = 0
//!   everywhere; at a point, d1 is the slope of the segment to its right (at the last
//!   point, of the last segment). Periodic or not makes no difference.
//! - [`Interpolation::Cubic`]: the C2 cubic spline through the points (slave, d1 and d2
//!   continuous at every interior point). Not periodic: natural end conditions, d2 = 0 at
//!   the first and the last point. Periodic: d1 and d2 at the last point equal those at
//!   the first, so the repeated table is C2 across the period (the slave may rise by
//!   [`CamTable::slave_rise`] each period); needs at least 3 points. The spline is global:
//!   moving one point changes the whole curve a little, and it overshoots between points
//!   where the slave dwells (equal values) — use Quintic for dwells.
//! - [`Interpolation::Quintic`] (the "Polynomial 5" motion law of cam editors): each
//!   segment is the quintic that matches slave, d1 and d2 at both of its points, so the
//!   whole is C2 and d2 is smooth inside each segment. The d1 and d2 at a point are those
//!   of the parabola through the point and its two neighbours (local, second-order
//!   accurate), except that **a point whose slave equals a neighbour's gets d1 = d2 = 0**:
//!   a segment between two equal slave values is an exact dwell, and a rise from one dwell
//!   to the next is the rest-to-rest 3-4-5 polynomial. Equal means the same `f64` as
//!   written in the table. Not periodic: the first (last) point takes the parabola through
//!   the first (last) three points, at that end point (a two-point table is a straight
//!   line, or a dwell). Periodic: the neighbours wrap around the period (shifted by one
//!   period and one slave rise), and the last point gets exactly the first point's d1 and
//!   d2, so the repetition is C2; needs at least 3 points. The point derivatives are
//!   deliberately *not* the cubic spline's: a quintic matching the spline's slave, d1 and
//!   d2 at both ends is the spline's own cubic (the Hermite quintic is unique), so Quintic
//!   would be Cubic under another name. [`CamTable::with_derivatives`] takes a d1 and d2
//!   for every point instead (the cam editor's explicit velocity and acceleration).
//!
//! [`CamTable::eval`] clamps the master position into [`CamTable::master_range`]: before
//! the first point it gives the first point's sample, after the last the last point's
//! (slave, d1, d2 as at that point — no extrapolation; the caller decides what the slave
//! does outside the table). The slave at every point is exactly the table's value.

mod error;
mod knots;
mod poly;

use core::fmt;

pub use error::CamError;
use poly::{Knot, Segment};

/// The most points a table may have: 65 536 segments take 4.7 MiB and a binary search of
/// 16 steps; more is a sampled curve, not a cam design.
pub const MAX_POINTS: usize = 65_536;

/// How the slave position is interpolated between the table's points.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// Straight segments: d1 jumps at the points, d2 = 0.
    Linear,
    /// The C2 cubic spline (natural or periodic end conditions).
    Cubic,
    /// Quintic (5th-order) segments matching slave, d1 and d2 at each point.
    Quintic,
}

impl Interpolation {
    /// The interpolation named `s` (ASCII case ignored): "linear", "cubic", "quintic"
    /// (also "5th-order" and "poly5", the names cam editors give that motion law).
    pub fn from_name(s: &str) -> Option<Self> {
        const NAMES: [(&str, Interpolation); 5] = [
            ("linear", Interpolation::Linear),
            ("cubic", Interpolation::Cubic),
            ("quintic", Interpolation::Quintic),
            ("5th-order", Interpolation::Quintic),
            ("poly5", Interpolation::Quintic),
        ];
        NAMES
            .iter()
            .find(|(name, _)| name.eq_ignore_ascii_case(s))
            .map(|&(_, i)| i)
    }

    /// The name used in messages and configuration files.
    pub const fn name(self) -> &'static str {
        match self {
            Interpolation::Linear => "linear",
            Interpolation::Cubic => "cubic",
            Interpolation::Quintic => "quintic",
        }
    }
}

impl fmt::Display for Interpolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One point: master position → slave position (table units, not axis units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CamPoint {
    /// Master position.
    pub master: f64,
    /// Slave position at that master position.
    pub slave: f64,
}

/// Slave position and its derivatives with respect to the master at one master position.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CamSample {
    /// Slave position (table units).
    pub slave: f64,
    /// dslave/dmaster: the slave's velocity is `d1 · master velocity`.
    pub d1: f64,
    /// d²slave/dmaster²: the slave's acceleration is `d2 · v_master² + d1 · a_master`.
    pub d2: f64,
}

/// A validated cam table with its segments' polynomials computed; see the module doc for
/// what each [`Interpolation`] does.
#[derive(Clone, Debug, PartialEq)]
pub struct CamTable {
    points: Vec<CamPoint>,
    interpolation: Interpolation,
    periodic: bool,
    /// One per pair of neighbouring points, in master order.
    segments: Vec<Segment>,
    /// The sample at the last point (returned at and beyond it).
    end: CamSample,
    max_d1: f64,
    max_d2: f64,
}

impl CamTable {
    /// Builds the table. `periodic`: the table is meant to repeat (CamIn periodic):
    /// cubic/quintic boundary conditions make the repetition C1/C2 continuous — first and
    /// second derivatives at the last point equal those at the first (the slave may rise
    /// by a constant each period: slave(last) - slave(first) need not be 0).
    pub fn new(
        points: Vec<CamPoint>,
        interpolation: Interpolation,
        periodic: bool,
    ) -> Result<Self, CamError> {
        validate(&points)?;
        let needs_three = interpolation != Interpolation::Linear && periodic;
        if needs_three && points.len() < 3 {
            return Err(CamError::PeriodicTooFewPoints {
                interpolation,
                count: points.len(),
            });
        }
        let knots = match interpolation {
            Interpolation::Linear => None,
            Interpolation::Cubic => Some(knots::cubic_spline(&points, periodic)),
            Interpolation::Quintic => Some(knots::local_parabolas(&points, periodic)),
        };
        let knots = knots.map(|mut k| {
            // Periodic: the same d1, d2 at both ends, bit for bit (computed once).
            if let (true, Some(first)) = (periodic, k.first().copied()) {
                if let Some(last) = k.last_mut() {
                    *last = first;
                }
            }
            k
        });
        build(points, interpolation, periodic, knots.as_deref())
    }

    /// A quintic table with the d1 (dslave/dmaster) and d2 given at every point
    /// (`derivatives[i] = (d1, d2)` at `points[i]`), as a cam editor's explicit velocity and
    /// acceleration per point; each segment is the quintic matching them. Periodic: the
    /// last point's pair must equal the first's exactly (the repetition is C2 only then).
    pub fn with_derivatives(
        points: Vec<CamPoint>,
        derivatives: &[(f64, f64)],
        periodic: bool,
    ) -> Result<Self, CamError> {
        validate(&points)?;
        if derivatives.len() != points.len() {
            return Err(CamError::DerivativeCount {
                points: points.len(),
                derivatives: derivatives.len(),
            });
        }
        if let Some((index, &(d1, d2))) = derivatives
            .iter()
            .enumerate()
            .find(|(_, (d1, d2))| !d1.is_finite() || !d2.is_finite())
        {
            return Err(CamError::DerivativeNotFinite { index, d1, d2 });
        }
        if let (true, Some(&(first_d1, first_d2)), Some(&(last_d1, last_d2))) =
            (periodic, derivatives.first(), derivatives.last())
        {
            if (first_d1, first_d2) != (last_d1, last_d2) {
                return Err(CamError::PeriodicDerivativesDiffer {
                    first_d1,
                    first_d2,
                    last_d1,
                    last_d2,
                });
            }
        }
        build(points, Interpolation::Quintic, periodic, Some(derivatives))
    }

    /// The points, as given.
    pub fn points(&self) -> &[CamPoint] {
        &self.points
    }

    /// The interpolation between the points.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Whether the table was built to repeat (see [`CamTable::new`]).
    pub fn is_periodic(&self) -> bool {
        self.periodic
    }

    /// First and last master position.
    pub fn master_range(&self) -> (f64, f64) {
        match (self.points.first(), self.points.last()) {
            (Some(f), Some(l)) => (f.master, l.master),
            _ => (0.0, 0.0), // never: a table has at least 2 points
        }
    }

    /// slave(last) - slave(first): what the slave gains each period of a periodic cam.
    pub fn slave_rise(&self) -> f64 {
        match (self.points.first(), self.points.last()) {
            (Some(f), Some(l)) => l.slave - f.slave,
            _ => 0.0, // never: a table has at least 2 points
        }
    }

    /// The table at master position `x` clamped into [`CamTable::master_range`] (no
    /// extrapolation). O(log n) (binary search), no allocation. At a point the segment to
    /// its right is used (so the slave is the table's value exactly); a NaN `x` gives a
    /// NaN sample rather than hiding the caller's fault behind a plausible value.
    pub fn eval(&self, x: f64) -> CamSample {
        if x.is_nan() {
            return CamSample {
                slave: f64::NAN,
                d1: f64::NAN,
                d2: f64::NAN,
            };
        }
        let (first, last) = self.master_range();
        if x >= last {
            return self.end;
        }
        let x = x.max(first);
        let i = self
            .segments
            .partition_point(|s| s.x0 <= x)
            .saturating_sub(1);
        match self.segments.get(i) {
            Some(s) => s.sample(x),
            None => self.end,
        }
    }

    /// [`CamTable::eval`] for a caller that evaluates near where it did last (a follower,
    /// cycle after cycle): `hint` is the segment of the last call (any value will do; it
    /// is updated). The segment at the hint and the next one are tried before the binary
    /// search, so a master moving steadily costs no search; the result is `eval`'s.
    pub fn eval_near(&self, x: f64, hint: &mut usize) -> CamSample {
        let (first, last) = self.master_range();
        if x.is_nan() || x >= last {
            return self.eval(x);
        }
        let x = x.max(first);
        let holds = |i: usize| {
            self.segments.get(i).is_some_and(|s| s.x0 <= x)
                && self.segments.get(i + 1).is_none_or(|n| x < n.x0)
        };
        let i = if holds(*hint) {
            *hint
        } else if holds(hint.wrapping_add(1)) {
            hint.wrapping_add(1)
        } else {
            self.segments
                .partition_point(|s| s.x0 <= x)
                .saturating_sub(1)
        };
        *hint = i;
        match self.segments.get(i) {
            Some(s) => s.sample(x),
            None => self.end,
        }
    }

    /// The largest |d1| over the whole table, exact up to rounding (each segment's
    /// extremes, at its ends or the roots of d2), computed at construction: used to refuse
    /// a CamIn whose follower could not keep up.
    pub fn max_d1(&self) -> f64 {
        self.max_d1
    }

    /// The largest |d2| over the whole table, exact up to rounding like
    /// [`CamTable::max_d1`].
    pub fn max_d2(&self) -> f64 {
        self.max_d2
    }
}

/// Count, finiteness and order of the points.
fn validate(points: &[CamPoint]) -> Result<(), CamError> {
    let count = points.len();
    if count < 2 {
        return Err(CamError::TooFewPoints { count });
    }
    if count > MAX_POINTS {
        return Err(CamError::TooManyPoints {
            count,
            max: MAX_POINTS,
        });
    }
    if let Some((index, p)) = points
        .iter()
        .enumerate()
        .find(|(_, p)| !p.master.is_finite() || !p.slave.is_finite())
    {
        return Err(CamError::NotFinite {
            index,
            master: p.master,
            slave: p.slave,
        });
    }
    for (index, w) in points.windows(2).enumerate() {
        if let [a, b] = w {
            if b.master <= a.master {
                return Err(CamError::NotIncreasing {
                    index: index + 1,
                    previous_master: a.master,
                    master: b.master,
                });
            }
        }
    }
    Ok(())
}

/// The segments from validated points and, for Cubic and Quintic, the (d1, d2) at every
/// point; then the end sample and the maxima.
fn build(
    points: Vec<CamPoint>,
    interpolation: Interpolation,
    periodic: bool,
    knots: Option<&[(f64, f64)]>,
) -> Result<CamTable, CamError> {
    let knot = |i: usize| {
        let p = points.get(i).map_or(0.0, |p| p.slave);
        let (d1, d2) = knots.and_then(|k| k.get(i)).copied().unwrap_or_default();
        Knot { p, d1, d2 }
    };
    let mut segments = Vec::with_capacity(points.len().saturating_sub(1));
    let (mut max_d1, mut max_d2) = (0.0_f64, 0.0_f64);
    for (index, w) in points.windows(2).enumerate() {
        let [a, b] = w else { continue };
        let h = b.master - a.master;
        let (k0, k1) = (knot(index), knot(index + 1));
        let segment = match interpolation {
            Interpolation::Linear => Segment::linear(a.master, h, a.slave, b.slave),
            Interpolation::Cubic => Segment::cubic(a.master, h, k0, k1.d2),
            Interpolation::Quintic => Segment::quintic(a.master, h, k0, k1),
        };
        let (d1, d2) = segment.max_abs_derivatives();
        if !segment.is_finite() || !d1.is_finite() || !d2.is_finite() {
            return Err(CamError::Degenerate {
                index,
                master_from: a.master,
                master_to: b.master,
            });
        }
        max_d1 = max_d1.max(d1);
        max_d2 = max_d2.max(d2);
        segments.push(segment);
    }
    let last = points.len().saturating_sub(1);
    let end = match (interpolation, segments.last()) {
        (Interpolation::Linear, Some(s)) => CamSample {
            slave: knot(last).p,
            d1: s.sample_u(1.0).d1,
            d2: 0.0,
        },
        _ => {
            let k = knot(last);
            CamSample {
                slave: k.p,
                d1: k.d1,
                d2: k.d2,
            }
        }
    };
    Ok(CamTable {
        points,
        interpolation,
        periodic,
        segments,
        end,
        max_d1,
        max_d2,
    })
}

#[cfg(test)]
mod tests;
