//! Two path segments joined in motion (the Blending buffer modes of MC_MoveLinear and
//! MC_MoveCircular2D).
//!
//! **The transit speed** is the path speed at the junction, as the buffer mode names it
//! (seed 004): BlendingLow the lower of the two moves' velocities, BlendingPrevious the
//! running one's, BlendingNext the new one's, BlendingHigh the higher — capped by what
//! the axes allow on both segments.
//!
//! **The superimposed corner.** A junction where the path turns cannot be passed in
//! motion without a jump in some axis' velocity, and one where only its curvature changes
//! not without a jump in acceleration: both exceed an axis' limits however slow the
//! path. So the junction is passed by superposition: in the last stretch of the first
//! segment the path speed ramps from the transit speed `V` down to rest at its end, and
//! in the same time the second segment ramps up from rest to `V`, and every axis' set
//! value is the sum of the two motions (minus the corner point they share). The two ramps
//! are the same S-curve (acceleration `A`, jerk `J`) mirrored, so the path speeds add up
//! to `V` at every instant and
//! - each axis' velocity is a convex combination of `V·t1` and `V·t2` (the two tangents):
//!   never above what either segment allows at `V`;
//! - its acceleration is the curvature terms of both (together at most the larger one,
//!   `g2·V²`, as `v1² + v2² <= V²`) plus `A·(t2 − t1)`;
//! - its jerk is `g3·V³`, the cross term `3·g2·V·A` and `J·(t2 − t1)`.
//!
//! [`corner`] picks `A` and `J` per axis from those bounds (with `Δ = |t2 − t1|` exact
//! where both tangent components are constant, `|t1| + |t2|` otherwise), so no axis
//! exceeds its vmax, amax or jmax in the blend — what LinuxCNC's blends do (its issue
//! #3773 measures 1.9–8.1× the axis acceleration) cannot happen here.
//!
//! **The deviation.** At any instant the blended point is the first segment's point plus
//! the chord the second has travelled, or the second's point plus the chord the first
//! has still to go: so its distance from the programmed path is at most the smaller of
//! the two path lengths `m` (the other one `M`), which is largest half-way, where both
//! equal the distance `e` a ramp covers in half its time. Near a smooth junction it is
//! much less: comparing with the point `M − m` along the path, the first-order terms
//! leave `m·|t2 − t1|` and the curvature `κ` adds at most `κ·(m²/2 + m·M)`. The reported
//! bound is the smaller of `e` and `e·|t2 − t1| + κ·(e²/2 + e·d)` (`d` a ramp's length):
//! exact at a right-angled corner of two lines, 0 when two lines are collinear (the
//! superposition stays on the line). A configured largest deviation caps `V` so that the
//! bound stays within it.
//!
//! **Transition None** asks the path to go through the junction: it is passed in motion
//! only where two collinear lines meet (the superposition is then exactly the line), and
//! at rest elsewhere.

use super::limits::AxisLimits;
use super::segment::{PathSegment, MAX_AXES};
use crate::axis::command::BufferMode;

/// How a blended junction may leave the programmed path (PLCopen Part 4 TransitionMode;
/// Omron `_eMC_TRANSITION_MODE`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Transition {
    /// `_mcTMNone`: the path goes through the junction.
    #[default]
    None,
    /// `_mcTMCornerSuperimposed`: the next segment starts while the one before ends, so
    /// the corner is rounded.
    CornerSuperimposed,
}

/// The path speed a buffer mode asks at the junction of a move running at `previous` and
/// one commanded at `next` (0 for Aborting and Buffered: those pass it at rest).
pub fn transit_speed(mode: BufferMode, previous: f64, next: f64) -> f64 {
    match mode {
        BufferMode::Aborting | BufferMode::Buffered => 0.0,
        BufferMode::BlendingLow => previous.min(next),
        BufferMode::BlendingPrevious => previous,
        BufferMode::BlendingNext => next,
        BufferMode::BlendingHigh => previous.max(next),
    }
}

/// One axis' share of a segment's motion, for the blend's bounds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct AxisShape {
    /// Largest |dp/ds| on the segment.
    d1: f64,
    /// Largest |d²p/ds²|.
    d2: f64,
    /// Largest |d³p/ds³|.
    d3: f64,
    /// dp/ds where it is the same all along the segment (lines; a helix' linear axes).
    constant: Option<f64>,
}

fn shapes(seg: &PathSegment) -> [AxisShape; MAX_AXES] {
    let d1 = seg.derivatives_at(0.0).d1;
    let mut out = [AxisShape::default(); MAX_AXES];
    for (o, u) in out.iter_mut().zip(d1) {
        *o = AxisShape {
            d1: u.abs(),
            d2: 0.0,
            d3: 0.0,
            constant: Some(u),
        };
    }
    if let Some((c, arc, share)) = seg.helix() {
        let r = arc.radius;
        let circular = AxisShape {
            d1: share,
            d2: share * share / r,
            d3: share * share * share / (r * r),
            constant: None,
        };
        for i in [c.x(), c.y()] {
            if let Some(o) = out.get_mut(i) {
                *o = circular;
            }
        }
    }
    out
}

/// A superimposed corner at path speed `speed`: the second segment's start ramps from rest
/// to `speed` with `accel` and `jerk`, the first segment's end is the same ramp mirrored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// Path speed at the junction.
    pub speed: f64,
    /// Path acceleration of both ramps.
    pub accel: f64,
    /// Path jerk of both ramps.
    pub jerk: f64,
    /// Path length each ramp covers.
    pub distance: f64,
    /// Bound on the distance between the blended path and the programmed one (units).
    pub deviation: f64,
}

/// Duration, distance and half-time distance of the S-curve from rest to `v` with
/// acceleration `a` and jerk `j` (closed form; the axes' planner builds the same curve).
pub fn ramp_metrics(v: f64, a: f64, j: f64) -> (f64, f64, f64) {
    if v <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    if v <= a * a / j {
        // Jerk up, jerk down: no constant-acceleration phase.
        let th = (v / j).sqrt();
        (2.0 * th, v * th, j * th * th * th / 6.0)
    } else {
        let t1 = a / j;
        let t2 = v / a - t1;
        let dur = 2.0 * t1 + t2;
        let v1 = a * t1 / 2.0;
        let tau = t2 / 2.0;
        (
            dur,
            v * dur / 2.0,
            j * t1 * t1 * t1 / 6.0 + v1 * tau + a * tau * tau / 2.0,
        )
    }
}

/// What the corner between two segments must respect.
#[derive(Clone, Copy, Debug)]
pub struct CornerInputs<'a> {
    /// The segment that ends at the junction.
    pub first: &'a PathSegment,
    /// The segment that starts there.
    pub second: &'a PathSegment,
    /// The group axes' own limits.
    pub axes: &'a [AxisLimits],
    /// Path acceleration and jerk the ramps may use at most (the first segment's
    /// deceleration and the second's acceleration, the lower jerk).
    pub accel: f64,
    /// See `accel`.
    pub jerk: f64,
    /// TransitionMode.
    pub transition: Transition,
    /// Largest deviation allowed (units; infinite: none).
    pub max_deviation: f64,
    /// The second segment's deceleration and jerk: after its ramp it must still be able
    /// to stop on itself.
    pub stop_decel: f64,
    /// See `stop_decel`.
    pub stop_jerk: f64,
}

/// The junction's geometry, for the bounds: each axis' share of both segments, the
/// tangents where they meet and the largest curvature of each.
#[derive(Clone, Copy, Debug)]
pub(super) struct Junction {
    s1: [AxisShape; MAX_AXES],
    s2: [AxisShape; MAX_AXES],
    /// Tangent at the end of the first segment and at the start of the second.
    t1: [f64; MAX_AXES],
    t2: [f64; MAX_AXES],
    /// |t2 − t1| over the group's axes.
    turn: f64,
    /// The larger of the two segments' curvatures (1/units; 0 for lines).
    curvature: f64,
    /// Both lines, and no axis' direction changes.
    collinear: bool,
}

impl Junction {
    pub(super) fn new(k: &CornerInputs<'_>) -> Self {
        let (s1, s2) = (shapes(k.first), shapes(k.second));
        let t1 = k.first.derivatives_at(k.first.length()).d1;
        let t2 = k.second.derivatives_at(0.0).d1;
        let turn = t1.iter().zip(&t2).fold(0.0_f64, |h, (a, b)| h.hypot(b - a));
        // |d²p/ds²|: share²/R on a helix, 0 on a line.
        let curvature = |seg: &PathSegment| {
            seg.helix()
                .map_or(0.0, |(_, arc, share)| share * share / arc.radius)
        };
        let lines = matches!(
            (k.first, k.second),
            (PathSegment::Line(_), PathSegment::Line(_))
        );
        Self {
            s1,
            s2,
            t1,
            t2,
            turn,
            curvature: curvature(k.first).max(curvature(k.second)),
            collinear: lines && turn == 0.0,
        }
    }

    /// The largest change of axis `i`'s tangent component over the ramps, when each
    /// covers at most `d` of its segment: exact where both components are constant, else
    /// the change at the junction plus what the curvature turns in `d` on either side (at
    /// most the two components' sizes).
    fn delta(&self, i: usize, d: f64) -> f64 {
        let (Some(p), Some(q)) = (self.s1.get(i), self.s2.get(i)) else {
            return 0.0;
        };
        match (p.constant, q.constant) {
            (Some(x), Some(y)) => (y - x).abs(),
            _ => {
                let at = |t: &[f64; MAX_AXES]| t.get(i).copied().unwrap_or(0.0);
                let drift = (at(&self.t2) - at(&self.t1)).abs() + (p.d2 + q.d2) * d;
                (p.d1 + q.d1).min(drift)
            }
        }
    }
}

/// Refinements of the ramps' acceleration against the tangents' change over them.
const DELTA_PASSES: usize = 4;

/// The ramps' path acceleration and jerk at path speed `v` (see the module
/// documentation), `None` when no positive pair keeps the axes within their limits.
fn ramps_at(k: &CornerInputs<'_>, g: &Junction, v: f64) -> Option<(f64, f64)> {
    let n = k.first.axes().min(k.second.axes()).min(k.axes.len());
    // For a bound `d` on the ramps' length; each pass takes the length the last one gave
    // (shorter ramps, smaller changes of the tangents: the bound of each pass holds for
    // the next's shorter ramps).
    let ramps = |d: f64| -> Option<(f64, f64)> {
        let (mut a, mut j) = (k.accel, k.jerk);
        for i in 0..n {
            let (p, q, l) = (g.s1.get(i)?, g.s2.get(i)?, k.axes.get(i)?);
            let delta = g.delta(i, d);
            let g2 = p.d2.max(q.d2);
            if delta > 0.0 {
                a = a.min((l.amax - g2 * v * v) / delta);
            }
            if g2 > 0.0 {
                a = a.min(0.5 * l.jmax / (3.0 * g2 * v));
            }
        }
        for i in 0..n {
            let (p, q, l) = (g.s1.get(i)?, g.s2.get(i)?, k.axes.get(i)?);
            let delta = g.delta(i, d);
            let (g2, g3) = (p.d2.max(q.d2), p.d3.max(q.d3));
            if delta > 0.0 {
                j = j.min((l.jmax - g3 * v * v * v - 3.0 * a * g2 * v) / delta);
            }
        }
        (a.is_finite() && a > 0.0 && j.is_finite() && j > 0.0).then_some((a, j))
    };
    let (mut a, mut j) = ramps(f64::INFINITY)?;
    for _ in 0..DELTA_PASSES {
        let (_, d, _) = ramp_metrics(v, a, j);
        match ramps(d) {
            Some((a2, j2)) if a2 >= a && j2 >= j => (a, j) = (a2, j2),
            _ => break,
        }
    }
    Some((a, j))
}

/// The corner at path speed `v` with ramps of acceleration `a` and jerk `j`, if its
/// deviation and lengths fit.
fn fit(k: &CornerInputs<'_>, g: &Junction, v: f64, a: f64, j: f64) -> Option<Corner> {
    let (_, distance, half) = ramp_metrics(v, a, j);
    // Half-way the blended point is within `half` of the path whatever the geometry; near
    // a smooth junction it is much closer (module documentation).
    let deviation = if g.collinear {
        0.0
    } else {
        half.min(half * g.turn + g.curvature * (half * half / 2.0 + half * distance))
    };
    if deviation > k.max_deviation {
        return None;
    }
    let (_, stop, _) = ramp_metrics(v, k.stop_decel, k.stop_jerk);
    if distance + stop > k.second.length() || distance > k.first.length() {
        return None;
    }
    Some(Corner {
        speed: v,
        accel: a,
        jerk: j,
        distance,
        deviation,
    })
}

/// The corner at path speed `v`, if every bound holds there (see the module
/// documentation).
pub(super) fn corner_at(k: &CornerInputs<'_>, g: &Junction, v: f64) -> Option<Corner> {
    if k.transition == Transition::None && !g.collinear {
        return None;
    }
    let (a, j) = ramps_at(k, g, v)?;
    fit(k, g, v, a, j)
}

/// Iterations of the search for the fastest corner (each halves the interval: 2⁻³⁰ of
/// the wanted speed).
const SEARCH_STEPS: usize = 30;

/// The fastest corner at most `wanted` that keeps every bound (see the module
/// documentation); `None` when the junction must be passed at rest.
pub fn corner(k: &CornerInputs<'_>, wanted: f64) -> Option<Corner> {
    corner_in(k, &Junction::new(k), wanted)
}

/// [`corner`] with the junction's geometry worked out.
pub(super) fn corner_in(k: &CornerInputs<'_>, g: &Junction, wanted: f64) -> Option<Corner> {
    if !(wanted.is_finite() && wanted > 0.0) {
        return None;
    }
    if let Some(c) = corner_at(k, g, wanted) {
        return Some(c);
    }
    if k.transition == Transition::None && !g.collinear {
        return None;
    }
    // The ramps allowed at `wanted` are allowed at every lower speed (the bounds tighten
    // with the speed): with them fixed, the deviation and the lengths grow with the speed
    // alone, in closed form, so the search is cheap; the corner found then takes the
    // ramps of its own speed, which only shortens them.
    let (a, j) = ramps_at(k, g, wanted)?;
    let (mut lo, mut hi) = (0.0, wanted);
    for _ in 0..SEARCH_STEPS {
        let mid = 0.5 * (lo + hi);
        match fit(k, g, mid, a, j) {
            Some(_) => lo = mid,
            None => hi = mid,
        }
    }
    if lo <= 1e-9 * wanted {
        return None;
    }
    corner_at(k, g, lo).or_else(|| fit(k, g, lo, a, j))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::{plan_velocity, KinematicState, Limits, RampType};

    fn axis(vmax: f64, amax: f64, jmax: f64) -> AxisLimits {
        AxisLimits { vmax, amax, jmax }
    }

    fn line(from: [f64; 2], to: [f64; 2]) -> PathSegment {
        PathSegment::line([from[0], from[1], 0.0, 0.0], [to[0], to[1], 0.0, 0.0], 2).unwrap()
    }

    fn inputs<'a>(
        first: &'a PathSegment,
        second: &'a PathSegment,
        axes: &'a [AxisLimits],
        transition: Transition,
    ) -> CornerInputs<'a> {
        CornerInputs {
            first,
            second,
            axes,
            accel: 1e9,
            jerk: 1e12,
            transition,
            max_deviation: f64::INFINITY,
            stop_decel: 1000.0,
            stop_jerk: 1e5,
        }
    }

    #[test]
    fn transit_speed_follows_the_buffer_mode() {
        assert_eq!(transit_speed(BufferMode::BlendingLow, 3.0, 5.0), 3.0);
        assert_eq!(transit_speed(BufferMode::BlendingPrevious, 3.0, 5.0), 3.0);
        assert_eq!(transit_speed(BufferMode::BlendingNext, 3.0, 5.0), 5.0);
        assert_eq!(transit_speed(BufferMode::BlendingHigh, 3.0, 5.0), 5.0);
        assert_eq!(transit_speed(BufferMode::Buffered, 3.0, 5.0), 0.0);
        assert_eq!(transit_speed(BufferMode::Aborting, 3.0, 5.0), 0.0);
    }

    #[test]
    fn ramp_metrics_match_the_planner() {
        for (v, a, j) in [(10.0, 100.0, 1000.0), (0.5, 100.0, 1000.0), (7.0, 3.0, 2.0)] {
            let lim = Limits {
                vmax: v,
                amax: a,
                dmax: a,
                jmax: j,
            };
            let p = plan_velocity(RampType::SCurve, KinematicState::at_rest(0.0), v, &lim).unwrap();
            let (dur, dist, half) = ramp_metrics(v, a, j);
            let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * y.abs().max(1.0);
            assert!(
                close(dur, p.duration()),
                "{v} {a} {j}: {dur} {}",
                p.duration()
            );
            assert!(close(dist, p.end_state().p), "{dist} {}", p.end_state().p);
            assert!(close(half, p.sample(dur / 2.0).p), "{half}");
        }
    }

    #[test]
    fn a_right_angle_shares_each_axis_acceleration_between_the_ramps() {
        // x then y: Δ = 1 in both axes, so the ramps may use each axis' full amax and jmax.
        let (a, b) = (
            line([0.0, 0.0], [10.0, 0.0]),
            line([10.0, 0.0], [10.0, 10.0]),
        );
        let axes = [axis(100.0, 50.0, 500.0), axis(100.0, 80.0, 800.0)];
        let c = corner(&inputs(&a, &b, &axes, Transition::CornerSuperimposed), 5.0).unwrap();
        assert_eq!(c.speed, 5.0);
        assert_eq!(c.accel, 50.0);
        assert_eq!(c.jerk, 500.0);
        let (_, dist, half) = ramp_metrics(5.0, 50.0, 500.0);
        assert_eq!((c.distance, c.deviation), (dist, half));
    }

    #[test]
    fn a_reversal_halves_the_ramps() {
        let (a, b) = (line([0.0, 0.0], [10.0, 0.0]), line([10.0, 0.0], [0.0, 0.0]));
        let axes = [axis(100.0, 50.0, 500.0); 2];
        let c = corner(&inputs(&a, &b, &axes, Transition::CornerSuperimposed), 5.0).unwrap();
        assert_eq!((c.accel, c.jerk), (25.0, 250.0));
    }

    #[test]
    fn collinear_lines_blend_without_deviation_also_without_transition() {
        let (a, b) = (line([0.0, 0.0], [3.0, 4.0]), line([3.0, 4.0], [6.0, 8.0]));
        let axes = [axis(100.0, 50.0, 500.0); 2];
        let c = corner(&inputs(&a, &b, &axes, Transition::None), 5.0).unwrap();
        assert_eq!(c.deviation, 0.0);
        assert_eq!(c.speed, 5.0);
    }

    #[test]
    fn transition_none_passes_a_turn_at_rest() {
        let (a, b) = (
            line([0.0, 0.0], [10.0, 0.0]),
            line([10.0, 0.0], [20.0, 1.0]),
        );
        let axes = [axis(100.0, 50.0, 500.0); 2];
        assert_eq!(corner(&inputs(&a, &b, &axes, Transition::None), 5.0), None);
    }

    #[test]
    fn the_deviation_bound_caps_the_transit_speed() {
        let (a, b) = (
            line([0.0, 0.0], [100.0, 0.0]),
            line([100.0, 0.0], [100.0, 100.0]),
        );
        let axes = [axis(100.0, 50.0, 500.0); 2];
        let mut k = inputs(&a, &b, &axes, Transition::CornerSuperimposed);
        let free = corner(&k, 40.0).unwrap();
        assert_eq!(free.speed, 40.0);
        k.max_deviation = free.deviation / 4.0;
        let capped = corner(&k, 40.0).unwrap();
        assert!(capped.speed < 40.0, "{capped:?}");
        assert!(capped.deviation <= k.max_deviation, "{capped:?}");
        assert!(capped.deviation > 0.99 * k.max_deviation, "{capped:?}");
    }

    #[test]
    fn the_second_segment_must_hold_its_ramp_and_a_stop() {
        // 0.1 long after the corner: at 40/s the ramp alone would need more.
        let (a, b) = (
            line([0.0, 0.0], [100.0, 0.0]),
            line([100.0, 0.0], [100.0, 0.1]),
        );
        let axes = [axis(100.0, 50.0, 500.0); 2];
        let k = inputs(&a, &b, &axes, Transition::CornerSuperimposed);
        let c = corner(&k, 40.0).unwrap();
        let (_, stop, _) = ramp_metrics(c.speed, k.stop_decel, k.stop_jerk);
        assert!(c.distance + stop <= 0.1, "{c:?}");
        assert!(c.speed < 40.0);
    }
}
