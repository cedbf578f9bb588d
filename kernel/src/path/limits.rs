//! Path dynamics from per-axis limits: the largest path speed V, acceleration A,
//! deceleration D and jerk J such that, with `|ṡ| <= V`, `|s̈| <= A` (D while slowing
//! down) and `|s⃛| <= J`, **no axis** exceeds its own `vmax`, `amax` or `jmax` anywhere on
//! the segment.
//!
//! An axis moves with `v = p'·ṡ`, `a = p''·ṡ² + p'·s̈`, `j = p'''·ṡ³ + 3·p''·ṡ·s̈ + p'·s⃛`
//! (derivatives with respect to the path length s, [`super::segment`]).
//!
//! **Line** (unit direction u): `p'' = p''' = 0`, so each axis is its share of the path:
//! `V = min vmax_i/|u_i|`, `A = D = min amax_i/|u_i|`, `J = min jmax_i/|u_i|` — exact,
//! the tightest axis reaches its limit when the path does.
//!
//! **Helix** (arc of radius R in the circular axes, taking the share `c = arc length /
//! path length`; the other axes linear with shares `u_k`). With `g1 = c`, `g2 = c²/R`,
//! `g3 = c³/R²` the circular axes' acceleration and jerk vectors are
//! - `a = g2·ṡ² (centripetal) ⊥ g1·s̈ (tangential)`, so `|a| = √((g2ṡ²)² + (g1s̈)²)`;
//! - `j = (g1·s⃛ − g3·ṡ³) (tangential) ⊥ 3·g2·ṡ·s̈ (normal)`.
//!
//! Each circular axis' value is a component of these vectors, so it is at most their
//! length: the bound takes the tighter circular axis' limits (`vc`, `ac`, `jc`) for the
//! whole plane — conservative on a short arc that never points the vector along that axis.
//! The budget, in this order:
//! 1. `V <= vc/g1`; centripetal `g2·V² <= ac/2` (V ≤ √(ac / 2g2)); the speed term of the
//!    jerk `g3·V³ <= jc/4` (V ≤ ∛(jc / 4g3)); the linear axes' `vmax_k/|u_k|`.
//! 2. Tangential acceleration gets the rest of the circle: `A, D <= √(ac² − (g2V²)²)/g1`
//!    (≥ 0.866·ac/g1); the cross term `3·g2·V·max(A, D) <= jc/2` caps them at
//!    `jc/(6·g2·V)`; the linear axes' `amax_k/|u_k|`.
//! 3. Jerk gets what is left: `(g1·J + g3·V³)² + (3·g2·V·max(A,D))² <= jc²`, i.e.
//!    `J <= (√(jc² − (3g2V·max(A,D))²) − g3V³)/g1` (≥ 0.616·jc/g1); the linear axes'
//!    `jmax_k/|u_k|`.
//!
//! Every value is then the minimum with the command's own. The half and quarter shares
//! are a choice (the centripetal terms cannot be traded against time without a
//! speed-dependent profile); `tests/path_geometry.rs` measures how close the axes come.

use super::segment::PathSegment;
use thiserror::Error;

/// One axis' own limits (units/s, units/s², units/s³; finite and > 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisLimits {
    /// Maximum speed.
    pub vmax: f64,
    /// Maximum acceleration (and deceleration).
    pub amax: f64,
    /// Maximum jerk.
    pub jmax: f64,
}

/// Dynamics of the path parameter: speed, acceleration, deceleration and jerk along the
/// path (units of path length per s, s², s³). In a command, `f64::INFINITY` leaves a
/// value to the axes' limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathLimits {
    /// Path speed.
    pub v: f64,
    /// Path acceleration while speeding up.
    pub a: f64,
    /// Path deceleration while slowing down.
    pub d: f64,
    /// Path jerk.
    pub j: f64,
}

/// Why path dynamics cannot be derived.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum PathLimitsError {
    /// Fewer axis limits than the segment has axes.
    #[error("the segment moves {axes} axes but limits were given for {given}")]
    MissingAxisLimits {
        /// Axes of the segment.
        axes: usize,
        /// Limits given.
        given: usize,
    },
    /// An axis limit is not finite and > 0.
    #[error("axis A{axis}: {name} = {value} must be a finite number > 0")]
    BadAxisLimit {
        /// Logical axis.
        axis: usize,
        /// Which limit.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A command value is not > 0 (infinity is allowed: no limit of its own).
    #[error("path {name} = {value} must be > 0")]
    BadCommand {
        /// Which value ("velocity", "acceleration", "deceleration", "jerk").
        name: &'static str,
        /// Its value.
        value: f64,
    },
}

/// Share of the circular axes' acceleration the centripetal term may take at full speed.
pub const CENTRIPETAL_SHARE: f64 = 0.5;
/// Share of the circular axes' jerk the speed term `g3·V³` may take.
pub const JERK_SPEED_SHARE: f64 = 0.25;
/// Share of the circular axes' jerk the cross term `3·g2·V·A` may take.
pub const JERK_CROSS_SHARE: f64 = 0.5;

/// The path dynamics for `seg` under the axes' `axes` limits (indexed like the group's
/// axes) and the command's `cmd`; see the module documentation for the bound.
pub fn path_limits(
    seg: &PathSegment,
    axes: &[AxisLimits],
    cmd: &PathLimits,
) -> Result<PathLimits, PathLimitsError> {
    let n = seg.axes();
    let lims = axes.get(..n).ok_or(PathLimitsError::MissingAxisLimits {
        axes: n,
        given: axes.len(),
    })?;
    for (axis, l) in lims.iter().enumerate() {
        for (name, value) in [("vmax", l.vmax), ("amax", l.amax), ("jmax", l.jmax)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(PathLimitsError::BadAxisLimit { axis, name, value });
            }
        }
    }
    for (name, value) in [
        ("velocity", cmd.v),
        ("acceleration", cmd.a),
        ("deceleration", cmd.d),
        ("jerk", cmd.j),
    ] {
        if value.is_nan() || value <= 0.0 {
            return Err(PathLimitsError::BadCommand { name, value });
        }
    }
    // Shares of the path in each axis moving linearly (all axes of a line; the
    // non-circular axes of a helix).
    let d1 = seg.derivatives_at(0.0).d1;
    let circ = seg.helix().map(|(c, _, _)| (c.x(), c.y()));
    let mut out = *cmd;
    for (i, (l, u)) in lims.iter().zip(d1).enumerate() {
        if circ.is_some_and(|(x, y)| i == x || i == y) {
            continue;
        }
        let u = u.abs();
        if u > 0.0 {
            out.v = out.v.min(l.vmax / u);
            out.a = out.a.min(l.amax / u);
            out.d = out.d.min(l.amax / u);
            out.j = out.j.min(l.jmax / u);
        }
    }
    let Some((c, arc, share)) = seg.helix() else {
        return Ok(out);
    };
    let pick = |f: fn(&AxisLimits) -> f64| {
        let x = lims.get(c.x()).map_or(f64::INFINITY, f);
        let y = lims.get(c.y()).map_or(f64::INFINITY, f);
        x.min(y)
    };
    let (vc, ac, jc) = (pick(|l| l.vmax), pick(|l| l.amax), pick(|l| l.jmax));
    let r = arc.radius;
    let g1 = share;
    let g2 = share * share / r;
    let g3 = share * share * share / (r * r);
    out.v = out
        .v
        .min(vc / g1)
        .min((CENTRIPETAL_SHARE * ac / g2).sqrt())
        .min((JERK_SPEED_SHARE * jc / g3).cbrt());
    let v = out.v;
    let centripetal = g2 * v * v;
    let tangential = (ac * ac - centripetal * centripetal).max(0.0).sqrt() / g1;
    let cross_cap = JERK_CROSS_SHARE * jc / (3.0 * g2 * v);
    out.a = out.a.min(tangential).min(cross_cap);
    out.d = out.d.min(tangential).min(cross_cap);
    let normal_jerk = 3.0 * g2 * v * out.a.max(out.d);
    let tangential_jerk = (jc * jc - normal_jerk * normal_jerk).max(0.0).sqrt() - g3 * v * v * v;
    out.j = out.j.min(tangential_jerk.max(0.0) / g1);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path::circle::{circular_2d, CircMode, PathChoice};
    use crate::path::segment::CircAxes;

    const FREE: PathLimits = PathLimits {
        v: f64::INFINITY,
        a: f64::INFINITY,
        d: f64::INFINITY,
        j: f64::INFINITY,
    };

    fn axis(vmax: f64, amax: f64, jmax: f64) -> AxisLimits {
        AxisLimits { vmax, amax, jmax }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1.0)
    }

    /// A circle of radius `r` in axes 0 and 1, axis 2 rising by `dz` (a helix).
    fn helix(r: f64, dz: f64) -> PathSegment {
        let planar = circular_2d(
            [r, 0.0],
            [-r, 0.0],
            [r, 0.0],
            CircMode::Border,
            PathChoice::Ccw,
        )
        .unwrap();
        PathSegment::circular(
            [r, 0.0, 0.0, 0.0],
            [0.0, 0.0, dz, 0.0],
            3,
            CircAxes::new(0, 1, 3).unwrap(),
            &planar,
        )
        .unwrap()
    }

    #[test]
    fn line_limits_are_each_axis_limit_over_its_share() {
        // Direction (3, 4)/5: axis 0 carries 0.6 of the path, axis 1 0.8.
        let seg = PathSegment::line([0.0; 4], [3.0, 4.0, 0.0, 0.0], 2).unwrap();
        let lim = [axis(6.0, 60.0, 600.0), axis(4.0, 80.0, 400.0)];
        let p = path_limits(&seg, &lim, &FREE).unwrap();
        assert!(close(p.v, (6.0 / 0.6_f64).min(4.0 / 0.8)), "{p:?}");
        assert!(close(p.a, (60.0 / 0.6_f64).min(80.0 / 0.8)), "{p:?}");
        assert_eq!(p.a, p.d);
        assert!(close(p.j, (600.0 / 0.6_f64).min(400.0 / 0.8)), "{p:?}");
    }

    #[test]
    fn line_takes_the_command_when_it_is_lower() {
        let seg = PathSegment::line([0.0; 4], [1.0, 0.0, 0.0, 0.0], 1).unwrap();
        let cmd = PathLimits {
            v: 1.0,
            a: 2.0,
            d: 3.0,
            j: 4.0,
        };
        let p = path_limits(&seg, &[axis(10.0, 100.0, 1000.0)], &cmd).unwrap();
        assert_eq!(p, cmd);
    }

    #[test]
    fn arc_speed_is_capped_by_the_centripetal_half() {
        // R = 2, planar (c = 1): V = √(ac/2 · R) = √(10/2·2) = √10 < vmax and the jerk cap.
        let p = path_limits(&helix(2.0, 0.0), &[axis(100.0, 10.0, 1e6); 3], &FREE).unwrap();
        assert!(close(p.v, 10.0_f64.sqrt()), "{p:?}");
        // The centripetal half leaves √(1 − ¼)·ac to the tangential acceleration.
        assert!(close(p.a, 0.75_f64.sqrt() * 10.0), "{p:?}");
        assert_eq!(p.a, p.d);
    }

    #[test]
    fn arc_speed_is_capped_by_the_jerk_speed_quarter() {
        // R = 1: V = ∛(jc/4 · R²) = ∛(4/4) = 1, below √(ac/2·R) = √50.
        let p = path_limits(&helix(1.0, 0.0), &[axis(100.0, 100.0, 4.0); 3], &FREE).unwrap();
        assert!(close(p.v, 1.0), "{p:?}");
    }

    #[test]
    fn arc_speed_is_capped_by_the_tighter_circular_axis_speed() {
        let lim = [
            axis(3.0, 1e6, 1e9),
            axis(2.0, 1e6, 1e9),
            axis(1.0, 1.0, 1.0),
        ];
        let p = path_limits(&helix(1.0, 0.0), &lim, &FREE).unwrap();
        assert!(close(p.v, 2.0), "{p:?}");
    }

    #[test]
    fn arc_acceleration_is_capped_by_the_jerk_cross_term() {
        // R = 1, V = 1 (command): 3·g2·V·A <= jc/2 gives A <= 60/6 = 10, below the
        // tangential √(100² − 1) ≈ 99.99.
        let cmd = PathLimits { v: 1.0, ..FREE };
        let p = path_limits(&helix(1.0, 0.0), &[axis(100.0, 100.0, 60.0); 3], &cmd).unwrap();
        assert!(close(p.a, 10.0), "{p:?}");
        assert!(close(p.d, 10.0), "{p:?}");
    }

    #[test]
    fn arc_jerk_gets_what_the_speed_and_cross_terms_leave() {
        // R = 1, V = 1, A = D = 5 (command): normal 3·1·1·5 = 15, speed term 1:
        // J = √(100² − 15²) − 1.
        let cmd = PathLimits {
            v: 1.0,
            a: 5.0,
            d: 5.0,
            j: f64::INFINITY,
        };
        let p = path_limits(&helix(1.0, 0.0), &[axis(100.0, 100.0, 100.0); 3], &cmd).unwrap();
        assert!(
            close(p.j, (100.0_f64 * 100.0 - 225.0).sqrt() - 1.0),
            "{p:?}"
        );
    }

    #[test]
    fn helix_shares_the_path_between_the_arc_and_the_linear_axis() {
        // Full circle of R = 1 (arc length 2π) and 2π·√3 in z: c = 1/2, u_z = √3/2.
        let seg = helix(1.0, 2.0 * core::f64::consts::PI * 3.0_f64.sqrt());
        let (_, _, share) = seg.helix().unwrap();
        assert!(close(share, 0.5));
        let lim = [
            axis(1.0, 1e6, 1e9),
            axis(1.0, 1e6, 1e9),
            axis(3.0_f64.sqrt() / 2.0 * 0.5, 1.0, 2.0),
        ];
        let p = path_limits(&seg, &lim, &FREE).unwrap();
        // z: vmax/u_z = 0.5 beats the plane's 1/c = 2; amax/u_z, jmax/u_z likewise.
        assert!(close(p.v, 0.5), "{p:?}");
        assert!(close(p.a, 2.0 / 3.0_f64.sqrt()), "{p:?}");
        assert!(close(p.j, 4.0 / 3.0_f64.sqrt()), "{p:?}");
    }

    #[test]
    fn bad_inputs_name_the_culprit() {
        let seg = PathSegment::line([0.0; 4], [1.0, 1.0, 0.0, 0.0], 2).unwrap();
        assert_eq!(
            path_limits(&seg, &[axis(1.0, 1.0, 1.0)], &FREE),
            Err(PathLimitsError::MissingAxisLimits { axes: 2, given: 1 })
        );
        assert_eq!(
            path_limits(&seg, &[axis(1.0, 1.0, 1.0), axis(1.0, 0.0, 1.0)], &FREE),
            Err(PathLimitsError::BadAxisLimit {
                axis: 1,
                name: "amax",
                value: 0.0
            })
        );
        assert!(matches!(
            path_limits(
                &seg,
                &[axis(1.0, 1.0, 1.0); 2],
                &PathLimits { v: 0.0, ..FREE }
            ),
            Err(PathLimitsError::BadCommand {
                name: "velocity",
                ..
            })
        ));
    }
}
