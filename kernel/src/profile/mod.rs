//! Motion profiles: a planned move is a short, fixed-size list of segments that can be
//! sampled in closed form at any time `t >= 0` (Ruckig's `at_time`), so nothing drifts
//! however long the move runs and the RT cycle never integrates.
//!
//! Every planner takes the current state (p, v, a) and [`Limits`] and returns a
//! [`Profile`]. The limits' meaning (shared by every ramp type and checked by the property
//! tests):
//! - `|v| <= vmax`;
//! - while speeding up (`a·v > 0`) `|a| <= amax`, while slowing down (`a·v < 0`)
//!   `|a| <= dmax` (PLCopen's Acceleration and Deceleration);
//! - `|j| <= jmax` (S-curve only; the other ramp types have no jerk limit).
//!
//! A start state already beyond a limit is brought back inside as fast as the other limits
//! allow, and never goes further out. For the S-curve that is the braking rule: the axis
//! never goes faster than the fastest landing on vmax with a = 0 that the jerk allows (the
//! velocity change to vmax); below that landing the move is time-optimal (it leaves the
//! landing early when the target is near: `scurve`'s dip window).

pub mod ramp;
pub mod scurve;

use thiserror::Error;

/// Position, velocity, acceleration and jerk at one instant, in user units and seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KinematicState {
    /// Position (units).
    pub p: f64,
    /// Velocity (units/s).
    pub v: f64,
    /// Acceleration (units/s²).
    pub a: f64,
    /// Jerk (units/s³).
    pub j: f64,
}

impl KinematicState {
    /// A state at rest at `p`.
    pub const fn at_rest(p: f64) -> Self {
        Self {
            p,
            v: 0.0,
            a: 0.0,
            j: 0.0,
        }
    }
}

/// Dynamic limits of one move (all strictly positive; `jmax` may be `f64::INFINITY`
/// for ramp types without a jerk limit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Maximum speed (units/s).
    pub vmax: f64,
    /// Maximum acceleration while speeding up (units/s²).
    pub amax: f64,
    /// Maximum deceleration while slowing down (units/s²).
    pub dmax: f64,
    /// Maximum jerk (units/s³), S-curve only.
    pub jmax: f64,
}

/// How velocity changes during a ramp (seed 000 §6.1.1, Logix MAJ "Profile").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum RampType {
    /// Linear ramps: constant acceleration, jumps in acceleration.
    Trapezoid,
    /// Jerk-limited, time-optimal, continuous acceleration.
    #[default]
    SCurve,
    /// Sine acceleration, sine² deceleration: shock-free stop.
    Sine,
    /// Linear acceleration, sine deceleration.
    LinearSine,
}

impl RampType {
    /// The name used on the command line and in JSON.
    pub const fn name(self) -> &'static str {
        match self {
            RampType::Trapezoid => "trapezoid",
            RampType::SCurve => "scurve",
            RampType::Sine => "sine",
            RampType::LinearSine => "linear-sine",
        }
    }

    /// Parses [`RampType::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        [
            RampType::Trapezoid,
            RampType::SCurve,
            RampType::Sine,
            RampType::LinearSine,
        ]
        .into_iter()
        .find(|r| r.name() == name)
    }
}

/// How acceleration evolves inside one segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// Constant jerk `j` (units/s³) from the segment's start state; `Jerk(0.0)` is a
    /// constant-acceleration (or cruise) segment.
    Jerk(f64),
    /// Constant acceleration `a` (units/s²) whatever the previous segment ended with:
    /// trapezoid ramps jump in acceleration.
    Accel(f64),
    /// Velocity changes by `dv` along a half cosine: `a(τ) = (π·dv / 2T)·sin(π τ / T)`.
    /// Acceleration starts and ends at zero. Start acceleration of the segment is ignored.
    Sine {
        /// Velocity change over the segment (units/s).
        dv: f64,
    },
    /// Velocity changes by `dv` with `a(τ) = (2·dv / T)·sin²(π τ / T)`: acceleration and
    /// jerk start and end at zero (shock-free). Start acceleration of the segment is ignored.
    SineSquared {
        /// Velocity change over the segment (units/s).
        dv: f64,
    },
}

/// One piece of a profile: a start state, a duration and a shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// State at the start of the segment (`j` is ignored; the shape gives it).
    pub start: KinematicState,
    /// Length of the segment (s), `>= 0`.
    pub duration: f64,
    /// How acceleration evolves.
    pub shape: Shape,
}

impl Segment {
    const EMPTY: Segment = Segment {
        start: KinematicState::at_rest(0.0),
        duration: 0.0,
        shape: Shape::Jerk(0.0),
    };

    /// The state `tau` seconds into the segment (closed form, `0 <= tau <= duration`).
    pub fn sample(&self, tau: f64) -> KinematicState {
        let s = self.start;
        match self.shape {
            Shape::Jerk(j) => KinematicState {
                p: s.p + tau * (s.v + tau * (s.a / 2.0 + tau * j / 6.0)),
                v: s.v + tau * (s.a + tau * j / 2.0),
                a: s.a + tau * j,
                j,
            },
            Shape::Accel(a) => KinematicState {
                p: s.p + tau * (s.v + tau * a / 2.0),
                v: s.v + tau * a,
                a,
                j: 0.0,
            },
            Shape::Sine { dv } => {
                if self.duration <= 0.0 {
                    return KinematicState { j: 0.0, ..s };
                }
                let w = core::f64::consts::PI / self.duration;
                let amp = w * dv / 2.0;
                let (sin, cos) = (w * tau).sin_cos();
                KinematicState {
                    p: s.p + s.v * tau + dv / 2.0 * (tau - sin / w),
                    v: s.v + dv / 2.0 * (1.0 - cos),
                    a: amp * sin,
                    j: amp * w * cos,
                }
            }
            Shape::SineSquared { dv } => {
                if self.duration <= 0.0 {
                    return KinematicState { j: 0.0, ..s };
                }
                let w = core::f64::consts::PI / self.duration;
                let amp = 2.0 * dv / self.duration;
                let (sin2, cos2) = (2.0 * w * tau).sin_cos();
                KinematicState {
                    p: s.p
                        + s.v * tau
                        + amp / 2.0 * (tau * tau / 2.0 + (cos2 - 1.0) / (4.0 * w * w)),
                    v: s.v + amp / 2.0 * (tau - sin2 / (2.0 * w)),
                    a: amp / 2.0 * (1.0 - cos2),
                    j: amp * w * sin2,
                }
            }
        }
    }

    /// The state at the end of the segment.
    pub fn end(&self) -> KinematicState {
        self.sample(self.duration)
    }
}

/// Shortest segment a profile keeps (s).
pub const MIN_SEGMENT_S: f64 = 1e-12;

/// Most segments any planner emits (S-curve: 7 phases + a brake pre-profile).
pub const MAX_SEGMENTS: usize = 12;

/// Errors of profile planning.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum PlanError {
    /// A limit is not a finite number > 0 (`jmax` may also be infinite).
    #[error("limit {name} = {value} must be a finite number > 0")]
    BadLimit {
        /// Which limit.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A start or target value is NaN or infinite.
    #[error("{name} = {value} is not a finite number")]
    NotFinite {
        /// Which input.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The planner needed more segments than a profile holds (a planner bug, reported
    /// instead of panicking).
    #[error("profile needs more than {MAX_SEGMENTS} segments")]
    TooManySegments,
    /// No profile satisfies the inputs (a planner bug or numerically degenerate input).
    #[error("no profile found from p={p} v={v} a={a} to target {target}")]
    NoSolution {
        /// Start position.
        p: f64,
        /// Start velocity.
        v: f64,
        /// Start acceleration.
        a: f64,
        /// Target (position or velocity).
        target: f64,
    },
}

/// A planned motion: sampled in closed form at any `t >= 0`. Past its end it continues
/// from [`Profile::end_state`] at constant velocity (zero for position moves).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Profile {
    segments: [Segment; MAX_SEGMENTS],
    len: usize,
    duration: f64,
    origin: KinematicState,
    end: KinematicState,
}

impl Profile {
    /// An empty profile: standing (or moving at constant `start.v`) from `start`.
    pub fn new(start: KinematicState) -> Self {
        let mut end = start;
        end.a = 0.0;
        end.j = 0.0;
        Self {
            segments: [Segment::EMPTY; MAX_SEGMENTS],
            len: 0,
            duration: 0.0,
            origin: KinematicState { j: 0.0, ..start },
            end,
        }
    }

    /// Appends a segment that starts where the previous one ended. Zero-length segments
    /// are skipped.
    pub fn push(&mut self, duration: f64, shape: Shape) -> Result<(), PlanError> {
        // Sub-picosecond segments change nothing measurable and would make the sine
        // shapes divide by (almost) zero.
        if duration.is_nan() || duration < MIN_SEGMENT_S {
            return Ok(());
        }
        let start = match self.len {
            0 => self.origin,
            n => self
                .segments
                .get(n - 1)
                .map(Segment::end)
                .unwrap_or(self.end),
        };
        let seg = Segment {
            start,
            duration,
            shape,
        };
        let slot = self
            .segments
            .get_mut(self.len)
            .ok_or(PlanError::TooManySegments)?;
        *slot = seg;
        self.len += 1;
        self.duration += duration;
        self.end = seg.end();
        self.end.j = 0.0;
        Ok(())
    }

    /// Moves the whole profile by `dp` in position (modulo axes move whole periods out
    /// of the frame this way; velocities and times are unchanged).
    pub fn shift(&mut self, dp: f64) {
        self.origin.p += dp;
        self.end.p += dp;
        for seg in self.segments.iter_mut().take(self.len) {
            seg.start.p += dp;
        }
    }

    /// Replaces the exact final state (a planner sets the exact target position so that
    /// floating-point integration error never reaches the end state).
    pub fn set_end(&mut self, end: KinematicState) {
        self.end = KinematicState { j: 0.0, ..end };
    }

    /// The segments, in order.
    pub fn segments(&self) -> &[Segment] {
        self.segments.get(..self.len).unwrap_or(&[])
    }

    /// Total duration (s).
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// The state at the end; past the end the profile continues from it at constant
    /// velocity.
    pub fn end_state(&self) -> KinematicState {
        self.end
    }

    /// The state at the start.
    pub fn start_state(&self) -> KinematicState {
        self.origin
    }

    /// The state at time `t` (s) after the start. `t < 0` gives the start state; `t` past
    /// the end continues from the end state with zero acceleration.
    pub fn sample(&self, t: f64) -> KinematicState {
        if t >= self.duration || t.is_nan() {
            let dt = if t.is_nan() { 0.0 } else { t - self.duration };
            let mut s = self.end;
            s.p += s.v * dt;
            return s;
        }
        let mut t0 = 0.0;
        for seg in self.segments() {
            if t < t0 + seg.duration {
                return seg.sample((t - t0).max(0.0));
            }
            t0 += seg.duration;
        }
        self.end
    }

    /// Largest |v|, |a| and |j| over the whole profile (exact: looks at every segment's
    /// boundaries and interior extrema).
    pub fn peaks(&self) -> Peaks {
        let mut pk = Peaks::default();
        self.visit_extremes(|s| {
            pk.v = pk.v.max(s.v.abs());
            pk.a = pk.a.max(s.a.abs());
            pk.j = pk.j.max(s.j.abs());
        });
        pk
    }

    /// The lowest velocity (signed) over the whole profile: below zero when it goes back
    /// at some point.
    pub fn lowest_velocity(&self) -> f64 {
        let mut low = f64::INFINITY;
        self.visit_extremes(|s| low = low.min(s.v));
        low
    }

    /// Calls `note` with every state where v, a or j can be extreme: the ends of every
    /// segment and the interior extrema of its shape.
    fn visit_extremes(&self, mut note: impl FnMut(KinematicState)) {
        note(self.start_state());
        for seg in self.segments() {
            note(seg.sample(0.0));
            note(seg.end());
            match seg.shape {
                Shape::Jerk(j) => {
                    // v has an interior extremum where a crosses zero.
                    if j != 0.0 {
                        let tau = -seg.start.a / j;
                        if tau > 0.0 && tau < seg.duration {
                            note(seg.sample(tau));
                        }
                    }
                }
                Shape::Accel(_) => {}
                Shape::Sine { .. } => note(seg.sample(seg.duration / 2.0)),
                Shape::SineSquared { .. } => {
                    note(seg.sample(seg.duration / 2.0));
                    note(seg.sample(seg.duration / 4.0));
                }
            }
        }
        note(self.end);
    }
}

/// Largest absolute values reached over a profile.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Peaks {
    /// Largest |v| (units/s).
    pub v: f64,
    /// Largest |a| (units/s²).
    pub a: f64,
    /// Largest |j| (units/s³).
    pub j: f64,
}

/// Checks that every limit is usable; `jmax` may be infinite when `needs_jerk` is false.
pub fn check_limits(lim: &Limits, needs_jerk: bool) -> Result<(), PlanError> {
    let finite_pos = |name, value: f64| {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(PlanError::BadLimit { name, value })
        }
    };
    finite_pos("vmax", lim.vmax)?;
    finite_pos("amax", lim.amax)?;
    finite_pos("dmax", lim.dmax)?;
    if needs_jerk {
        finite_pos("jmax", lim.jmax)?;
    }
    Ok(())
}

/// Checks that a start state and a target are finite.
pub fn check_inputs(start: &KinematicState, target: f64) -> Result<(), PlanError> {
    for (name, value) in [
        ("start position", start.p),
        ("start velocity", start.v),
        ("start acceleration", start.a),
        ("target", target),
    ] {
        if !value.is_finite() {
            return Err(PlanError::NotFinite { name, value });
        }
    }
    Ok(())
}

/// Plans a move from `start` to rest (or to `v_end`, for blending) at `target` with the
/// given ramp type. `v_end` is the velocity wanted at the target, in the direction of the
/// move; when it cannot be reached in the distance available the profile ends at the
/// largest reachable speed below it. Ramp types without a jerk limit ignore `start.a`.
pub fn plan_position(
    ramp: RampType,
    start: KinematicState,
    target: f64,
    v_end: f64,
    lim: &Limits,
) -> Result<Profile, PlanError> {
    match ramp {
        RampType::SCurve => scurve::plan_position(start, target, v_end, lim),
        RampType::Trapezoid => {
            ramp::plan_position(ramp::RampShape::Linear, start, target, v_end, lim)
        }
        RampType::Sine => ramp::plan_position(ramp::RampShape::Sine, start, target, v_end, lim),
        RampType::LinearSine => {
            ramp::plan_position(ramp::RampShape::LinearSine, start, target, v_end, lim)
        }
    }
}

/// Plans a change from `start` to the constant velocity `v_target` (signed); the profile
/// then goes on at that velocity forever.
pub fn plan_velocity(
    ramp: RampType,
    start: KinematicState,
    v_target: f64,
    lim: &Limits,
) -> Result<Profile, PlanError> {
    match ramp {
        RampType::SCurve => scurve::plan_velocity(start, v_target, lim),
        RampType::Trapezoid => ramp::plan_velocity(ramp::RampShape::Linear, start, v_target, lim),
        RampType::Sine => ramp::plan_velocity(ramp::RampShape::Sine, start, v_target, lim),
        RampType::LinearSine => {
            ramp::plan_velocity(ramp::RampShape::LinearSine, start, v_target, lim)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_segments_reach_dv_with_mean_velocity() {
        for shape in [Shape::Sine { dv: 3.0 }, Shape::SineSquared { dv: 3.0 }] {
            let seg = Segment {
                start: KinematicState {
                    p: 1.0,
                    v: 2.0,
                    a: 0.0,
                    j: 0.0,
                },
                duration: 0.5,
                shape,
            };
            let e = seg.end();
            assert!((e.v - 5.0).abs() < 1e-12, "{shape:?} {e:?}");
            assert!((e.p - (1.0 + 0.5 * 3.5)).abs() < 1e-12, "{shape:?} {e:?}");
            assert!(e.a.abs() < 1e-12, "{shape:?} {e:?}");
        }
    }

    #[test]
    fn sample_past_end_continues_at_constant_velocity() {
        let mut p = Profile::new(KinematicState::at_rest(0.0));
        p.push(1.0, Shape::Jerk(0.0)).unwrap();
        let mut p2 = Profile::new(KinematicState {
            v: 2.0,
            ..KinematicState::at_rest(0.0)
        });
        p2.push(1.0, Shape::Jerk(0.0)).unwrap();
        assert_eq!(p.sample(5.0).p, 0.0);
        assert!((p2.sample(3.0).p - 6.0).abs() < 1e-12);
        assert_eq!(p2.sample(-1.0).p, 0.0);
    }

    #[test]
    fn too_many_segments_is_an_error_not_a_panic() {
        let mut p = Profile::new(KinematicState::at_rest(0.0));
        for _ in 0..MAX_SEGMENTS {
            p.push(0.1, Shape::Jerk(1.0)).unwrap();
        }
        assert_eq!(
            p.push(0.1, Shape::Jerk(1.0)),
            Err(PlanError::TooManySegments)
        );
    }

    #[test]
    fn ramp_names_round_trip() {
        for r in [
            RampType::Trapezoid,
            RampType::SCurve,
            RampType::Sine,
            RampType::LinearSine,
        ] {
            assert_eq!(RampType::from_name(r.name()), Some(r));
        }
        assert_eq!(RampType::from_name("cubic"), None);
    }
}
