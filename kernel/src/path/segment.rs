//! One path segment of an axis group in up to [`MAX_AXES`] axes, parametrised by its arc
//! length `s` (units along the path): a straight line (MC_MoveLinear) or a helix — an arc
//! in two chosen axes ([`CircAxes`]) while the group's other axes move linearly with the
//! path length (MC_MoveCircular2D moves only the two, so its other axes stay put; the
//! helix is there for a circular move that also carries the others).
//!
//! The derivatives with respect to `s` ([`PathDerivatives`]) are what the path dynamics
//! ([`super::limits`]) and the time sampling ([`super::profile`]) need: with ṡ, s̈, s⃛ the
//! path speed, acceleration and jerk, an axis moves with `v = p'·ṡ`,
//! `a = p''·ṡ² + p'·s̈`, `j = p'''·ṡ³ + 3·p''·ṡ·s̈ + p'·s⃛`.

use super::circle::{self, Arc2, CircMode, CircularError, PathChoice, Point2, Segment2};
use thiserror::Error;

/// Most axes in a group (Omron NJ: A0..A3).
pub const MAX_AXES: usize = 4;

/// A position of every axis of a group (entries from `axes` on are unused and kept as
/// given).
pub type GroupPoint = [f64; MAX_AXES];

/// Which two of the group's axes carry the circle (`CircAxes`: logical axes A0..A3). The
/// first is the circle's x, the second its y, so `PathChoice` counter-clockwise turns from
/// the first towards the second.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CircAxes {
    x: usize,
    y: usize,
}

impl CircAxes {
    /// The axes `x` and `y` of a group of `axes` axes; they must differ and exist.
    pub fn new(x: usize, y: usize, axes: usize) -> Result<Self, SegmentError> {
        if x == y || x >= axes || y >= axes || axes > MAX_AXES {
            return Err(SegmentError::BadCircAxes { x, y, axes });
        }
        Ok(Self { x, y })
    }

    /// The circle's x axis (index into the group).
    pub const fn x(self) -> usize {
        self.x
    }

    /// The circle's y axis (index into the group).
    pub const fn y(self) -> usize {
        self.y
    }
}

/// Why a segment cannot be built.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum SegmentError {
    /// A group has 1 to 4 axes.
    #[error("an axis group has 1 to {MAX_AXES} axes, not {axes}")]
    BadAxisCount {
        /// The count given.
        axes: usize,
    },
    /// The circular axes are the same axis or not in the group.
    #[error(
        "CircAxes [{x}, {y}]: the two circular axes must be two different axes of the \
         group's {axes} (A0..A{})",
        axes.saturating_sub(1)
    )]
    BadCircAxes {
        /// First circular axis.
        x: usize,
        /// Second circular axis.
        y: usize,
        /// Axes in the group.
        axes: usize,
    },
    /// A position is NaN or infinite.
    #[error("axis A{axis}: {what} position {value} is not a finite number")]
    NotFinite {
        /// Logical axis.
        axis: usize,
        /// "start" or "target".
        what: &'static str,
        /// The value.
        value: f64,
    },
    /// The planar path does not start where the group's circular axes are.
    #[error(
        "the circle starts at {planar:?} but the circular axes are at {group:?} (the \
         circle must be computed from the group's position)"
    )]
    StartMismatch {
        /// Start of the planar path.
        planar: Point2,
        /// Where the circular axes are.
        group: Point2,
    },
    /// The circular geometry is refused.
    #[error(transparent)]
    Circular(#[from] CircularError),
}

/// Position and its first three derivatives with respect to the path length, per axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathDerivatives {
    /// Position (units).
    pub p: GroupPoint,
    /// dp/ds (dimensionless; a unit vector over the group's axes).
    pub d1: GroupPoint,
    /// d²p/ds² (1/units).
    pub d2: GroupPoint,
    /// d³p/ds³ (1/units²).
    pub d3: GroupPoint,
}

/// A straight line in the group's axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineSegment {
    from: GroupPoint,
    to: GroupPoint,
    axes: usize,
    length: f64,
    unit: GroupPoint,
}

/// An arc in two axes, the others linear in the path length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HelixSegment {
    from: GroupPoint,
    to: GroupPoint,
    axes: usize,
    circ: CircAxes,
    arc: Arc2,
    length: f64,
    /// dθ/ds (rad/unit, signed like the sweep).
    rate: f64,
}

/// A path segment of an axis group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathSegment {
    /// MC_MoveLinear, or a circular move the rules turned into a line.
    Line(LineSegment),
    /// An arc (or full circle) in the circular axes; other axes linear in `s`.
    Helix(HelixSegment),
}

impl PathSegment {
    /// The straight line from `from` to `to` in the first `axes` axes (the others stay at
    /// `from`). A line of length zero is allowed (a move to where the group is).
    pub fn line(from: GroupPoint, to: GroupPoint, axes: usize) -> Result<Self, SegmentError> {
        check_points(&from, &to, axes)?;
        let mut to = to;
        for (t, f) in to.iter_mut().zip(from).skip(axes) {
            *t = f;
        }
        let length = from
            .iter()
            .zip(to)
            .fold(0.0_f64, |h, (f, t)| h.hypot(t - f));
        let mut unit = [0.0; MAX_AXES];
        if length > 0.0 {
            for ((u, f), t) in unit.iter_mut().zip(from).zip(to) {
                *u = (t - f) / length;
            }
        }
        Ok(Self::Line(LineSegment {
            from,
            to,
            axes,
            length,
            unit,
        }))
    }

    /// The segment that follows `planar` (computed by [`circle::circular_2d`] from the
    /// circular axes' position in `from`) in the axes `circ`, while the other axes go from
    /// `from` to `to` linearly in the path length. `to`'s circular entries are replaced by
    /// the planar end point.
    pub fn circular(
        from: GroupPoint,
        to: GroupPoint,
        axes: usize,
        circ: CircAxes,
        planar: &Segment2,
    ) -> Result<Self, SegmentError> {
        check_points(&from, &to, axes)?;
        let circ = CircAxes::new(circ.x, circ.y, axes)?;
        let group = [get(&from, circ.x), get(&from, circ.y)];
        let start = planar.start();
        let tol = circle::same_point_tol(&[group, start]);
        if (group[0] - start[0]).hypot(group[1] - start[1]) > tol {
            return Err(SegmentError::StartMismatch {
                planar: start,
                group,
            });
        }
        let mut to = to;
        for (t, f) in to.iter_mut().zip(from).skip(axes) {
            *t = f;
        }
        let end = planar.end();
        set(&mut to, circ.x, end[0]);
        set(&mut to, circ.y, end[1]);
        let mut from = from;
        set(&mut from, circ.x, start[0]);
        set(&mut from, circ.y, start[1]);
        match planar {
            Segment2::Line { .. } => Self::line(from, to, axes),
            Segment2::Arc(arc) => {
                let others = from
                    .iter()
                    .zip(to)
                    .enumerate()
                    .filter(|(i, _)| *i != circ.x && *i != circ.y)
                    .fold(0.0_f64, |h, (_, (f, t))| h.hypot(t - f));
                let length = arc.length().hypot(others);
                Ok(Self::Helix(HelixSegment {
                    from,
                    to,
                    axes,
                    circ,
                    arc: *arc,
                    length,
                    rate: arc.sweep / length,
                }))
            }
        }
    }

    /// MC_MoveCircular2D in the axes `circ` from `from`: the planar path by the seed's
    /// rules ([`circle::circular_2d`]); the group's other axes do not move.
    pub fn circular_2d(
        from: GroupPoint,
        axes: usize,
        circ: CircAxes,
        aux: Point2,
        end: Point2,
        mode: CircMode,
        choice: PathChoice,
    ) -> Result<Self, SegmentError> {
        let circ = CircAxes::new(circ.x, circ.y, axes)?;
        let start = [get(&from, circ.x), get(&from, circ.y)];
        let planar = circle::circular_2d(start, aux, end, mode, choice)?;
        Self::circular(from, from, axes, circ, &planar)
    }

    /// Number of axes in the group.
    pub fn axes(&self) -> usize {
        match self {
            PathSegment::Line(l) => l.axes,
            PathSegment::Helix(h) => h.axes,
        }
    }

    /// Path length (units): the Euclidean length over all the group's axes.
    pub fn length(&self) -> f64 {
        match self {
            PathSegment::Line(l) => l.length,
            PathSegment::Helix(h) => h.length,
        }
    }

    /// Start position of every axis.
    pub fn start(&self) -> GroupPoint {
        match self {
            PathSegment::Line(l) => l.from,
            PathSegment::Helix(h) => h.from,
        }
    }

    /// End position of every axis (reached exactly at `s = length()`).
    pub fn end(&self) -> GroupPoint {
        match self {
            PathSegment::Line(l) => l.to,
            PathSegment::Helix(h) => h.to,
        }
    }

    /// For a helix: the circular axes, the arc, and the share of the path length the arc
    /// takes (`arc length / length`, 1 without other moving axes).
    pub fn helix(&self) -> Option<(CircAxes, Arc2, f64)> {
        match self {
            PathSegment::Line(_) => None,
            PathSegment::Helix(h) => Some((h.circ, h.arc, h.arc.length() / h.length)),
        }
    }

    /// Position of every axis at path length `s` (clamped to `[0, length]`); the ends are
    /// the start and the end points exactly.
    pub fn position_at(&self, s: f64) -> GroupPoint {
        self.derivatives_at(s).p
    }

    /// Position and its derivatives with respect to `s` at path length `s` (clamped to
    /// `[0, length]`). The derivatives are those of the segment's interior also at its
    /// ends (a path leaves its start with the tangent it has there).
    pub fn derivatives_at(&self, s: f64) -> PathDerivatives {
        let len = self.length();
        let s = if s.is_nan() { 0.0 } else { s.clamp(0.0, len) };
        let mut out = PathDerivatives::default();
        match self {
            PathSegment::Line(l) => {
                out.p = lerp(&l.from, &l.to, s, len);
                out.d1 = l.unit;
            }
            PathSegment::Helix(h) => {
                out.p = lerp(&h.from, &h.to, s, len);
                for (d, (f, t)) in out.d1.iter_mut().zip(h.from.iter().zip(h.to)) {
                    *d = (t - f) / len;
                }
                let arc = &h.arc;
                let k = h.rate;
                let (sin, cos) = (arc.start_angle + k * s).sin_cos();
                let r = arc.radius;
                let (x, y) = (h.circ.x, h.circ.y);
                if s > 0.0 && s < len {
                    set(&mut out.p, x, arc.center[0] + r * cos);
                    set(&mut out.p, y, arc.center[1] + r * sin);
                }
                // x = cx + R cos θ, y = cy + R sin θ, θ = θ0 + k·s.
                set(&mut out.d1, x, -r * k * sin);
                set(&mut out.d1, y, r * k * cos);
                set(&mut out.d2, x, -r * k * k * cos);
                set(&mut out.d2, y, -r * k * k * sin);
                set(&mut out.d3, x, r * k * k * k * sin);
                set(&mut out.d3, y, -r * k * k * k * cos);
            }
        }
        out
    }
}

fn check_points(from: &GroupPoint, to: &GroupPoint, axes: usize) -> Result<(), SegmentError> {
    if axes == 0 || axes > MAX_AXES {
        return Err(SegmentError::BadAxisCount { axes });
    }
    for (what, pt) in [("start", from), ("target", to)] {
        for (axis, &value) in pt.iter().enumerate().take(axes) {
            if !value.is_finite() {
                return Err(SegmentError::NotFinite { axis, what, value });
            }
        }
    }
    Ok(())
}

/// Linear interpolation at `s` of `len`, exact at both ends and on axes that do not move.
fn lerp(from: &GroupPoint, to: &GroupPoint, s: f64, len: f64) -> GroupPoint {
    if len <= 0.0 || s <= 0.0 {
        return *from;
    }
    if s >= len {
        return *to;
    }
    let l = s / len;
    let mut p = [0.0; MAX_AXES];
    for ((p, f), t) in p.iter_mut().zip(from).zip(to) {
        *p = circle::lerp(*f, *t, l);
    }
    p
}

fn get(p: &GroupPoint, i: usize) -> f64 {
    p.get(i).copied().unwrap_or(0.0)
}

fn set(p: &mut GroupPoint, i: usize, v: f64) {
    if let Some(x) = p.get_mut(i) {
        *x = v;
    }
}
