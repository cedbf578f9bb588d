//! MC_MoveCircular2D geometry (seed 004, Omron NJ; SPEC §7): from where the group is, the
//! command's auxiliary point and end point, its `CircMode` and `PathChoice`, the planar
//! path the two circular axes follow — an arc, a full circle or, where the seed says so, a
//! straight line.
//!
//! The rules, as the seed states them and as decided where it is silent:
//!
//! | mode | case | result |
//! |---|---|---|
//! | Border | start = aux = end | [`CircularError::AllPointsEqual`] |
//! | Border | start = aux or end = aux (not all three) | straight line start → end |
//! | Border | start = end ≠ aux | full circle, diameter start–aux, direction from `PathChoice` |
//! | Border | three distinct collinear points | [`CircularError::CollinearPoints`] (*no circle exists*; seed silent) |
//! | Border | otherwise | the arc through aux; direction follows from the points, `PathChoice` ignored (seed: only the full circle takes it) |
//! | Center | start = center | [`CircularError::CenterAtStart`] (seed silent: a circle of radius 0) |
//! | Center | start = end | full circle around the center, direction from `PathChoice` |
//! | Center | otherwise | radius = mean of the distances center–start and center–end, center recomputed as in radius mode on the side of the chord the given center lies (on the chord's line: the short arc); direction from `PathChoice` |
//! | Radius | radius = 0 | [`CircularError::ZeroRadius`] |
//! | Radius | start = end | [`CircularError::StartEqualsEnd`] |
//! | Radius | \|radius\| < half the chord | [`CircularError::RadiusTooSmall`] |
//! | Radius | radius > 0 / < 0 | the short / long arc, direction from `PathChoice` |
//!
//! "Same point" means closer than [`SAME_POINT_REL`] times the largest coordinate of the
//! three points (see there).

use core::f64::consts::TAU;
use thiserror::Error;

/// A point in the plane of the two circular axes: `[x, y]` in user units.
pub type Point2 = [f64; 2];

/// Two points closer than this fraction of the largest coordinate magnitude among the
/// command's points are the same point. Why 1e-9: positions arrive as `f64` sums of
/// relative moves and unit conversions, whose rounding stays below ~1e-10 of the
/// coordinates even after a million relative moves, while 1e-9 is about four counts of a
/// 32-bit position spanning those coordinates — no command means to distinguish points
/// that close. Relative, so the rule is the same in millimetres and in metres; with all
/// coordinates zero it is exact equality.
pub const SAME_POINT_REL: f64 = 1e-9;

/// How MC_MoveCircular2D's `AuxPoint` is read (`_eMC_CIRC_MODE`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CircMode {
    /// 0 `_mcBorder`: `AuxPoint` is a point the arc passes through.
    Border,
    /// 1 `_mcCenter`: `AuxPoint` is the center.
    Center,
    /// 2 `_mcRadius`: `AuxPoint[0]` is the radius (`AuxPoint[1]` unused); positive for the
    /// short arc, negative for the long one.
    Radius,
}

/// Direction of travel (`_eMC_CIRC_PATHCHOICE`), seen with x to the right and y up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PathChoice {
    /// 0 `_mcCW`: clockwise.
    Cw,
    /// 1 `_mcCCW`: counter-clockwise.
    Ccw,
}

impl PathChoice {
    /// +1 for counter-clockwise, −1 for clockwise (the sign of the sweep).
    pub const fn sign(self) -> f64 {
        match self {
            PathChoice::Cw => -1.0,
            PathChoice::Ccw => 1.0,
        }
    }
}

/// Why MC_MoveCircular2D's geometry is refused. The seed gives no Omron error numbers
/// for these cases (only 5466 Hex "not homed", 543D Hex "axis type" and 544A Hex "rotary
/// count mode", which are checked where the group's axes are known, not here).
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum CircularError {
    /// A coordinate is NaN or infinite.
    #[error("MoveCircular2D: {name} {value:?} is not a finite number")]
    NotFinite {
        /// Which input ("start", "aux point", "end point", "radius").
        name: &'static str,
        /// The offending point (a radius is reported as `[r, 0]`).
        value: Point2,
    },
    /// Border mode with the start, the through point and the end point all the same
    /// (seed: "起点、通过点位置、终点为同一点时，会发生异常").
    #[error(
        "MoveCircular2D (border point): the start {point:?}, the through point and the end \
         point are the same point: there is no path to follow"
    )]
    AllPointsEqual {
        /// The common point.
        point: Point2,
    },
    /// Border mode with three distinct points on one straight line: no circle passes
    /// through them (the seed is silent; a line through the middle point would ignore the
    /// command's meaning, and an aux point outside the segment cannot be reached at all).
    #[error(
        "MoveCircular2D (border point): start {start:?}, through point {aux:?} and end \
         {end:?} lie on one straight line: no circle passes through them"
    )]
    CollinearPoints {
        /// Where the group is.
        start: Point2,
        /// The through point.
        aux: Point2,
        /// The end point.
        end: Point2,
    },
    /// Center mode with the center on the start point: a circle of radius zero.
    #[error(
        "MoveCircular2D (center): the center {center:?} is the start point: the radius \
         would be zero"
    )]
    CenterAtStart {
        /// The given center (= the start).
        center: Point2,
    },
    /// Radius mode with radius 0.
    #[error("MoveCircular2D (radius): the radius is 0")]
    ZeroRadius,
    /// Radius mode with the end on the start (seed: "起点和终点为同一点时，会发生圆弧插补起点
    /// 终点相同的异常" — in radius mode the full circle's center is undefined).
    #[error(
        "MoveCircular2D (radius): the end point {point:?} is the start point: a radius \
         alone does not fix a full circle's center"
    )]
    StartEqualsEnd {
        /// The common point.
        point: Point2,
    },
    /// Radius mode with |radius| below half the start–end distance (seed: "指定的半径小于
    /// 起点和终点间距离的 1/2 时，无法绘制圆弧").
    #[error(
        "MoveCircular2D (radius): |radius| {radius} is less than half the distance \
         {half_chord} × 2 from start to end: no arc of that radius joins them"
    )]
    RadiusTooSmall {
        /// The given radius (signed).
        radius: f64,
        /// Half the start–end distance: the smallest usable |radius|.
        half_chord: f64,
    },
}

/// A circular arc (or full circle) in the plane. The arc starts at `start` and ends at
/// `end` exactly: they are kept so that a path samples the commanded points to the bit at
/// its ends, whatever rounding the center and angles carry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arc2 {
    /// Center (units).
    pub center: Point2,
    /// Radius (units, > 0).
    pub radius: f64,
    /// Angle of the start point seen from the center (rad, from +x towards +y).
    pub start_angle: f64,
    /// Signed angle travelled (rad): positive counter-clockwise, `0 < |sweep| <= 2π`
    /// (`±2π` is a full circle).
    pub sweep: f64,
    /// The start point as commanded.
    pub start: Point2,
    /// The end point as commanded (for a full circle, `start`).
    pub end: Point2,
}

impl Arc2 {
    /// Length along the arc (units).
    pub fn length(&self) -> f64 {
        self.radius * self.sweep.abs()
    }

    /// Angle at arc length `s` from the start (rad).
    pub fn angle_at(&self, s: f64) -> f64 {
        self.start_angle + self.sweep.signum() * s / self.radius
    }
}

/// The planar path of one MC_MoveCircular2D.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Segment2 {
    /// A straight line (Border mode with the through point on the start or the end).
    Line {
        /// Start point.
        from: Point2,
        /// End point.
        to: Point2,
    },
    /// An arc or a full circle.
    Arc(Arc2),
}

impl Segment2 {
    /// Path length (units).
    pub fn length(&self) -> f64 {
        match self {
            Segment2::Line { from, to } => dist(*from, *to),
            Segment2::Arc(arc) => arc.length(),
        }
    }

    /// The start point.
    pub fn start(&self) -> Point2 {
        match self {
            Segment2::Line { from, .. } => *from,
            Segment2::Arc(arc) => arc.start,
        }
    }

    /// The end point.
    pub fn end(&self) -> Point2 {
        match self {
            Segment2::Line { to, .. } => *to,
            Segment2::Arc(arc) => arc.end,
        }
    }

    /// The point at path length `s` from the start; `s <= 0` is the start and
    /// `s >= length()` the end, both exactly as commanded.
    pub fn point_at(&self, s: f64) -> Point2 {
        let len = self.length();
        if s <= 0.0 || len <= 0.0 {
            return self.start();
        }
        if s >= len {
            return self.end();
        }
        match self {
            Segment2::Line { from, to } => lerp2(*from, *to, s / len),
            Segment2::Arc(arc) => {
                let (sin, cos) = arc.angle_at(s).sin_cos();
                [
                    arc.center[0] + arc.radius * cos,
                    arc.center[1] + arc.radius * sin,
                ]
            }
        }
    }

    /// Unit tangent in the direction of travel at path length `s` (`[0, 0]` for a line of
    /// length zero).
    pub fn tangent_at(&self, s: f64) -> Point2 {
        match self {
            Segment2::Line { from, to } => {
                let len = dist(*from, *to);
                if len > 0.0 {
                    [(to[0] - from[0]) / len, (to[1] - from[1]) / len]
                } else {
                    [0.0, 0.0]
                }
            }
            Segment2::Arc(arc) => {
                let (sin, cos) = arc.angle_at(s.clamp(0.0, arc.length())).sin_cos();
                let d = arc.sweep.signum();
                [-d * sin, d * cos]
            }
        }
    }

    /// Signed curvature (1/units): 0 for a line, `+1/R` counter-clockwise, `−1/R`
    /// clockwise.
    pub fn curvature(&self) -> f64 {
        match self {
            Segment2::Line { .. } => 0.0,
            Segment2::Arc(arc) => arc.sweep.signum() / arc.radius,
        }
    }
}

/// The planar path of MC_MoveCircular2D from `start` (where the two circular axes are)
/// with `aux` read as `mode` says, to `end`, in the direction `choice` where the mode
/// takes one. See the module documentation for the rules.
pub fn circular_2d(
    start: Point2,
    aux: Point2,
    end: Point2,
    mode: CircMode,
    choice: PathChoice,
) -> Result<Segment2, CircularError> {
    finite("start", start)?;
    finite("end point", end)?;
    match mode {
        CircMode::Border => {
            finite("aux point", aux)?;
            border(start, aux, end, choice)
        }
        CircMode::Center => {
            finite("aux point", aux)?;
            center(start, aux, end, choice)
        }
        CircMode::Radius => {
            let r = aux[0];
            if !r.is_finite() {
                return Err(CircularError::NotFinite {
                    name: "radius",
                    value: [r, 0.0],
                });
            }
            radius(start, r, end, choice)
        }
    }
}

/// Border (through-point) mode.
fn border(
    start: Point2,
    aux: Point2,
    end: Point2,
    choice: PathChoice,
) -> Result<Segment2, CircularError> {
    let tol = same_point_tol(&[start, aux, end]);
    let s_a = dist(start, aux) <= tol;
    let e_a = dist(end, aux) <= tol;
    let s_e = dist(start, end) <= tol;
    // Two coincidences make the third (within twice the tolerance): all three are one.
    if [s_a, e_a, s_e].iter().filter(|same| **same).count() >= 2 {
        return Err(CircularError::AllPointsEqual { point: start });
    }
    if s_a || e_a {
        return Ok(Segment2::Line {
            from: start,
            to: end,
        });
    }
    if s_e {
        // Seed: the start and the through point are the ends of a diameter.
        let c = mid(start, aux);
        return Ok(full_circle(c, dist(start, aux) / 2.0, start, choice));
    }
    let b = sub(aux, start);
    let e = sub(end, start);
    let cr = cross(b, e);
    // The triangle's smallest height (twice its area over its longest side) below the
    // point tolerance: the three points lie on one line.
    let longest = dist(start, aux).max(dist(aux, end)).max(dist(start, end));
    if cr.abs() / longest <= tol {
        return Err(CircularError::CollinearPoints { start, aux, end });
    }
    // Circumcenter relative to the start.
    let d = 2.0 * cr;
    let (bb, ee) = (dot(b, b), dot(e, e));
    let u = [(e[1] * bb - b[1] * ee) / d, (b[0] * ee - e[0] * bb) / d];
    let c = add(start, u);
    // Going start → aux → end around the circle is counter-clockwise exactly when the
    // triangle (start, aux, end) is: the direction is fixed by the points.
    let dir = cr.signum();
    Ok(arc_from(c, start, end, dir))
}

/// Center mode.
fn center(
    start: Point2,
    c: Point2,
    end: Point2,
    choice: PathChoice,
) -> Result<Segment2, CircularError> {
    let tol = same_point_tol(&[start, c, end]);
    let r_s = dist(c, start);
    if r_s <= tol {
        return Err(CircularError::CenterAtStart { center: c });
    }
    let chord = dist(start, end);
    if chord <= tol {
        return Ok(full_circle(c, r_s, start, choice));
    }
    // Seed: "使用两个半径的平均值进行圆弧插补。这种情况下，按照与半径指定同样的方法计算中心位置"
    // — always applied, so the start and the end lie on the circle to rounding (with
    // matching radii the recomputed center is the given one).
    let r = (r_s + dist(c, end)) / 2.0;
    let side_cross = cross(sub(end, start), sub(c, start));
    // Which side of the chord start → end the given center lies on (+1 left). A center on
    // the chord's line fixes no side: take the short arc, as radius mode does for a
    // positive radius (the center is on the left of the chord for a counter-clockwise
    // short arc). By the triangle inequality r >= chord/2, so an arc always exists.
    let side = if side_cross.abs() / chord <= tol {
        choice.sign()
    } else {
        side_cross.signum()
    };
    let cc = center_on_bisector(start, end, r, side);
    Ok(arc_from(cc, start, end, choice.sign()))
}

/// Radius mode.
fn radius(
    start: Point2,
    r: f64,
    end: Point2,
    choice: PathChoice,
) -> Result<Segment2, CircularError> {
    if r == 0.0 {
        return Err(CircularError::ZeroRadius);
    }
    let tol = same_point_tol(&[start, end, [r, 0.0]]);
    let chord = dist(start, end);
    if chord <= tol {
        return Err(CircularError::StartEqualsEnd { point: start });
    }
    let half = chord / 2.0;
    if r.abs() < half - tol {
        return Err(CircularError::RadiusTooSmall {
            radius: r,
            half_chord: half,
        });
    }
    // Short arc counter-clockwise: the center is on the left of the chord (travel around a
    // center counter-clockwise keeps it on the left); the long arc or clockwise flips it,
    // both flips cancel.
    let side = choice.sign() * r.signum();
    let cc = center_on_bisector(start, end, r.abs().max(half), side);
    Ok(arc_from(cc, start, end, choice.sign()))
}

/// The center at distance `r` from both `start` and `end`, on the left of the chord
/// start → end for `side > 0`, on the right otherwise. `r` below half the chord (only by
/// rounding) gives the midpoint.
fn center_on_bisector(start: Point2, end: Point2, r: f64, side: f64) -> Point2 {
    let chord = dist(start, end);
    let half = chord / 2.0;
    let h = (r * r - half * half).max(0.0).sqrt();
    let d = sub(end, start);
    let left = [-d[1] / chord, d[0] / chord];
    let m = mid(start, end);
    [m[0] + side * h * left[0], m[1] + side * h * left[1]]
}

/// The arc around `c` from `start` to `end` in direction `dir` (+1 counter-clockwise),
/// `0 < |sweep| < 2π`; the radius is the mean of both distances.
fn arc_from(c: Point2, start: Point2, end: Point2, dir: f64) -> Segment2 {
    let u = sub(start, c);
    let v = sub(end, c);
    let mut phi = cross(u, v).atan2(dot(u, v));
    if dir > 0.0 && phi <= 0.0 {
        phi += TAU;
    } else if dir < 0.0 && phi >= 0.0 {
        phi -= TAU;
    }
    Segment2::Arc(Arc2 {
        center: c,
        radius: (norm(u) + norm(v)) / 2.0,
        start_angle: u[1].atan2(u[0]),
        sweep: phi,
        start,
        end,
    })
}

/// A full circle around `c` through `start`, direction from `choice`.
fn full_circle(c: Point2, r: f64, start: Point2, choice: PathChoice) -> Segment2 {
    let u = sub(start, c);
    Segment2::Arc(Arc2 {
        center: c,
        radius: r,
        start_angle: u[1].atan2(u[0]),
        sweep: choice.sign() * TAU,
        start,
        end: start,
    })
}

/// The "same point" distance for these points (see [`SAME_POINT_REL`]).
pub fn same_point_tol(points: &[Point2]) -> f64 {
    let scale = points
        .iter()
        .flat_map(|p| p.iter())
        .fold(0.0_f64, |m, c| m.max(c.abs()));
    SAME_POINT_REL * scale
}

fn finite(name: &'static str, p: Point2) -> Result<(), CircularError> {
    if p.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(CircularError::NotFinite { name, value: p })
    }
}

fn sub(a: Point2, b: Point2) -> Point2 {
    [a[0] - b[0], a[1] - b[1]]
}

fn add(a: Point2, b: Point2) -> Point2 {
    [a[0] + b[0], a[1] + b[1]]
}

fn mid(a: Point2, b: Point2) -> Point2 {
    [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]
}

fn dot(a: Point2, b: Point2) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

fn cross(a: Point2, b: Point2) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn norm(a: Point2) -> f64 {
    a[0].hypot(a[1])
}

fn dist(a: Point2, b: Point2) -> f64 {
    norm(sub(a, b))
}

fn lerp2(a: Point2, b: Point2, l: f64) -> Point2 {
    [lerp(a[0], b[0], l), lerp(a[1], b[1], l)]
}

/// `a + (b − a)·λ`, computed from the nearer end so that λ = 0 gives `a` and λ = 1 gives
/// `b` to the bit, and `a = b` gives `a` for every λ (an axis that does not move stays
/// exactly where it is).
pub fn lerp(a: f64, b: f64, l: f64) -> f64 {
    if l < 0.5 {
        a + (b - a) * l
    } else {
        b - (b - a) * (1.0 - l)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    #[test]
    fn semicircle_in_radius_mode_takes_either_direction() {
        for choice in [PathChoice::Cw, PathChoice::Ccw] {
            for r in [1.0, -1.0] {
                let Segment2::Arc(a) =
                    circular_2d([0.0, 0.0], [r, 0.0], [2.0, 0.0], CircMode::Radius, choice)
                        .unwrap()
                else {
                    panic!("not an arc");
                };
                assert!((a.sweep.abs() - PI).abs() < 1e-12, "{a:?}");
                assert_eq!(a.sweep.signum(), choice.sign());
            }
        }
    }
}
