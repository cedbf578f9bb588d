//! Axis-group path geometry and timing (seed 004, Omron NJ MC_MoveLinear and
//! MC_MoveCircular2D; SPEC §7): every circular-interpolation rule and error of the seed,
//! and seeded property tests that a planned line or arc never takes any axis beyond its
//! own speed, acceleration or jerk, stays continuous and ends exactly on its target.
//! Planning and sampling run under a counting allocator.

use core::f64::consts::{FRAC_PI_2, FRAC_PI_3, PI, TAU};
use gantry_kernel::path::{
    circular_2d, path_limits, Arc2, AxisLimits, CircAxes, CircMode, CircularError, PathChoice,
    PathLimits, PathProfile, PathSegment, Segment2, SegmentError, MAX_AXES,
};
use proptest::prelude::*;

mod counting {
    include!("common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

const CW: PathChoice = PathChoice::Cw;
const CCW: PathChoice = PathChoice::Ccw;

fn arc(seg: Result<Segment2, CircularError>) -> Arc2 {
    match seg {
        Ok(Segment2::Arc(a)) => a,
        other => panic!("expected an arc, got {other:?}"),
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

fn close2(a: [f64; 2], b: [f64; 2]) -> bool {
    close(a[0], b[0]) && close(a[1], b[1])
}

/// The arc really joins its ends: start and end on the circle, at the start and end
/// angles, and `point_at` gives the commanded points exactly at the ends.
fn assert_consistent(a: &Arc2) {
    let seg = Segment2::Arc(*a);
    for (p, ang) in [(a.start, a.start_angle), (a.end, a.start_angle + a.sweep)] {
        let d = (p[0] - a.center[0]).hypot(p[1] - a.center[1]);
        assert!(
            close(d, a.radius),
            "{p:?} is {d} from the center, R = {}",
            a.radius
        );
        let q = [
            a.center[0] + a.radius * ang.cos(),
            a.center[1] + a.radius * ang.sin(),
        ];
        assert!(
            (q[0] - p[0]).hypot(q[1] - p[1]) <= 1e-12 * a.radius.max(1.0) * 10.0,
            "{p:?} vs {q:?}"
        );
    }
    assert_eq!(seg.point_at(0.0), a.start);
    assert_eq!(seg.point_at(seg.length()), a.end);
    assert!(a.sweep != 0.0 && a.sweep.abs() <= TAU);
}

// ---- Border (through point) ----

#[test]
fn border_arc_passes_through_the_aux_point_counter_clockwise() {
    let h = 0.5_f64.sqrt();
    // PathChoice is ignored: the points fix the direction.
    for choice in [CW, CCW] {
        let a = arc(circular_2d(
            [1.0, 0.0],
            [h, h],
            [0.0, 1.0],
            CircMode::Border,
            choice,
        ));
        assert!(close2(a.center, [0.0, 0.0]), "{a:?}");
        assert!(close(a.radius, 1.0));
        assert!(close(a.sweep, FRAC_PI_2), "{a:?}");
        assert_consistent(&a);
        let mid = Segment2::Arc(a).point_at(a.length() / 2.0);
        assert!(close2(mid, [h, h]), "{mid:?}");
    }
}

#[test]
fn border_arc_direction_follows_the_points_clockwise_and_the_long_way() {
    // Start (1,0) through (0,-1) to (0,1): clockwise, three quarters of a turn.
    let a = arc(circular_2d(
        [1.0, 0.0],
        [0.0, -1.0],
        [0.0, 1.0],
        CircMode::Border,
        CCW,
    ));
    assert!(close(a.sweep, -3.0 * FRAC_PI_2), "{a:?}");
    assert_consistent(&a);
    // The aux point is on the path travelled: a third of the way along.
    let seg = Segment2::Arc(a);
    assert!(close2(seg.point_at(a.length() / 3.0), [0.0, -1.0]));
    assert!(seg.curvature() < 0.0);
}

#[test]
fn border_aux_on_start_or_end_is_a_straight_line() {
    for (aux, what) in [([1.0, 2.0], "start"), ([4.0, 6.0], "end")] {
        let seg = circular_2d([1.0, 2.0], aux, [4.0, 6.0], CircMode::Border, CW).unwrap();
        assert_eq!(
            seg,
            Segment2::Line {
                from: [1.0, 2.0],
                to: [4.0, 6.0]
            },
            "aux on the {what}"
        );
        assert_eq!(seg.length(), 5.0);
        assert_eq!(seg.tangent_at(1.0), [0.6, 0.8]);
        assert_eq!(seg.curvature(), 0.0);
        assert_eq!(seg.point_at(5.0), [4.0, 6.0]);
    }
}

#[test]
fn border_all_three_points_equal_is_an_error() {
    assert_eq!(
        circular_2d([3.0, 3.0], [3.0, 3.0], [3.0, 3.0], CircMode::Border, CW),
        Err(CircularError::AllPointsEqual { point: [3.0, 3.0] })
    );
}

#[test]
fn border_start_on_end_is_a_full_circle_with_start_aux_as_diameter() {
    for (choice, sign) in [(CW, -1.0), (CCW, 1.0)] {
        let a = arc(circular_2d(
            [0.0, 0.0],
            [4.0, 0.0],
            [0.0, 0.0],
            CircMode::Border,
            choice,
        ));
        assert!(close2(a.center, [2.0, 0.0]), "{a:?}");
        assert_eq!(a.radius, 2.0);
        assert_eq!(a.sweep, sign * TAU);
        assert_eq!(a.end, a.start);
        assert_consistent(&a);
        // Half way round is the aux point, the far end of the diameter.
        let seg = Segment2::Arc(a);
        assert!(close2(seg.point_at(seg.length() / 2.0), [4.0, 0.0]));
        // Counter-clockwise from (0,0) around (2,0) goes down first (tangent −y).
        let t = seg.tangent_at(0.0);
        assert!(close(t[1], -sign), "{choice:?} {t:?}");
    }
}

#[test]
fn border_three_collinear_points_are_an_error() {
    // Aux between start and end, and aux beyond the end: no circle through them.
    for aux in [[1.0, 1.0], [3.0, 3.0]] {
        assert_eq!(
            circular_2d([0.0, 0.0], aux, [2.0, 2.0], CircMode::Border, CCW),
            Err(CircularError::CollinearPoints {
                start: [0.0, 0.0],
                aux,
                end: [2.0, 2.0]
            })
        );
    }
}

#[test]
fn points_closer_than_the_tolerance_are_the_same_point() {
    // 1e-13 of coordinates of size 100 is below SAME_POINT_REL (1e-9): aux is the start.
    let seg = circular_2d(
        [100.0, 0.0],
        [100.0 + 1e-11, 0.0],
        [0.0, 100.0],
        CircMode::Border,
        CW,
    )
    .unwrap();
    assert!(matches!(seg, Segment2::Line { .. }), "{seg:?}");
    // 1e-6 of them is a real point.
    let seg = circular_2d(
        [100.0, 0.0],
        [100.0, 1e-4],
        [0.0, 100.0],
        CircMode::Border,
        CW,
    )
    .unwrap();
    assert!(matches!(seg, Segment2::Arc(_)), "{seg:?}");
}

// ---- Center ----

#[test]
fn center_quarter_arc_in_either_direction() {
    let a = arc(circular_2d(
        [1.0, 0.0],
        [0.0, 0.0],
        [0.0, 1.0],
        CircMode::Center,
        CCW,
    ));
    assert!(close(a.sweep, FRAC_PI_2), "{a:?}");
    assert!(close2(a.center, [0.0, 0.0]));
    assert_consistent(&a);
    let a = arc(circular_2d(
        [1.0, 0.0],
        [0.0, 0.0],
        [0.0, 1.0],
        CircMode::Center,
        CW,
    ));
    assert!(close(a.sweep, -3.0 * FRAC_PI_2), "{a:?}");
    assert!(close2(a.center, [0.0, 0.0]));
    assert_consistent(&a);
}

#[test]
fn center_with_start_on_end_is_a_full_circle_around_the_center() {
    for (choice, sign) in [(CW, -1.0), (CCW, 1.0)] {
        let a = arc(circular_2d(
            [5.0, 1.0],
            [2.0, 1.0],
            [5.0, 1.0],
            CircMode::Center,
            choice,
        ));
        assert_eq!(a.center, [2.0, 1.0]);
        assert_eq!(a.radius, 3.0);
        assert_eq!(a.sweep, sign * TAU);
        assert_consistent(&a);
    }
}

#[test]
fn center_radius_mismatch_uses_the_mean_radius_and_a_recomputed_center() {
    // Center (0.8, 1) is 1.2806 from the start (0,0) and 1.5620 from the end (2,0).
    let (s, c, e) = ([0.0, 0.0], [0.8, 1.0], [2.0, 0.0]);
    let r = (0.8_f64.hypot(1.0) + 1.2_f64.hypot(1.0)) / 2.0;
    for choice in [CW, CCW] {
        let a = arc(circular_2d(s, c, e, CircMode::Center, choice));
        assert!(close(a.radius, r), "{a:?}");
        // As in radius mode: on the perpendicular bisector x = 1, on the given center's
        // side of the chord (above it).
        assert!(close2(a.center, [1.0, (r * r - 1.0).sqrt()]), "{a:?}");
        assert_consistent(&a);
        // Center above the chord: counter-clockwise is the short way, under the center.
        let short = (1.0 / r).asin() * 2.0;
        let want = if choice == CCW { short } else { -(TAU - short) };
        assert!(close(a.sweep, want), "{choice:?} {a:?}");
    }
    // The same center reflected below the chord gives the center below.
    let a = arc(circular_2d(s, [0.8, -1.0], e, CircMode::Center, CCW));
    assert!(close2(a.center, [1.0, -(r * r - 1.0).sqrt()]), "{a:?}");
    assert!(close(a.sweep, TAU - (1.0 / r).asin() * 2.0), "{a:?}");
}

#[test]
fn center_on_the_chord_line_outside_the_chord_takes_the_short_arc() {
    // Start (0,0), end (2,0), center (3,0): radii 3 and 1, mean 2; no side: short arc.
    for (choice, sign) in [(CW, -1.0), (CCW, 1.0)] {
        let a = arc(circular_2d(
            [0.0, 0.0],
            [3.0, 0.0],
            [2.0, 0.0],
            CircMode::Center,
            choice,
        ));
        assert!(close(a.radius, 2.0));
        assert!(close(a.sweep, sign * FRAC_PI_3), "{choice:?} {a:?}");
        assert_consistent(&a);
    }
}

#[test]
fn center_on_the_start_is_an_error() {
    assert_eq!(
        circular_2d([1.0, 1.0], [1.0, 1.0], [3.0, 1.0], CircMode::Center, CW),
        Err(CircularError::CenterAtStart { center: [1.0, 1.0] })
    );
}

// ---- Radius ----

#[test]
fn radius_positive_is_the_short_arc_negative_the_long_one() {
    // Start (0,0), end (2,0), |R| = 2: centers (1, ±√3), short arc π/3.
    let up = [1.0, 3.0_f64.sqrt()];
    let down = [1.0, -(3.0_f64.sqrt())];
    for (r, choice, center, sweep) in [
        (2.0, CCW, up, FRAC_PI_3),
        (2.0, CW, down, -FRAC_PI_3),
        (-2.0, CCW, down, TAU - FRAC_PI_3),
        (-2.0, CW, up, -(TAU - FRAC_PI_3)),
    ] {
        let a = arc(circular_2d(
            [0.0, 0.0],
            [r, 99.0],
            [2.0, 0.0],
            CircMode::Radius,
            choice,
        ));
        assert!(close2(a.center, center), "R {r} {choice:?}: {a:?}");
        assert!(close(a.sweep, sweep), "R {r} {choice:?}: {a:?}");
        assert!(close(a.radius, 2.0));
        assert_consistent(&a);
        assert_eq!(a.sweep.abs() > PI, r < 0.0);
    }
}

#[test]
fn radius_of_exactly_half_the_chord_is_a_semicircle() {
    for r in [1.0, -1.0] {
        let a = arc(circular_2d(
            [0.0, 0.0],
            [r, 0.0],
            [2.0, 0.0],
            CircMode::Radius,
            CW,
        ));
        assert!(close2(a.center, [1.0, 0.0]), "{a:?}");
        assert!(close(a.sweep, -PI), "{a:?}");
    }
}

#[test]
fn radius_mode_start_on_end_is_an_error() {
    assert_eq!(
        circular_2d([1.0, 2.0], [5.0, 0.0], [1.0, 2.0], CircMode::Radius, CCW),
        Err(CircularError::StartEqualsEnd { point: [1.0, 2.0] })
    );
}

#[test]
fn radius_below_half_the_chord_is_an_error() {
    for r in [0.99, -0.99] {
        assert_eq!(
            circular_2d([0.0, 0.0], [r, 0.0], [2.0, 0.0], CircMode::Radius, CCW),
            Err(CircularError::RadiusTooSmall {
                radius: r,
                half_chord: 1.0
            })
        );
    }
}

#[test]
fn radius_zero_is_an_error() {
    assert_eq!(
        circular_2d([0.0, 0.0], [0.0, 7.0], [2.0, 0.0], CircMode::Radius, CCW),
        Err(CircularError::ZeroRadius)
    );
}

#[test]
fn non_finite_inputs_are_errors_naming_the_input() {
    let nan = f64::NAN;
    for (s, aux, e, mode, name) in [
        (
            [nan, 0.0],
            [1.0, 0.0],
            [2.0, 0.0],
            CircMode::Border,
            "start",
        ),
        (
            [0.0, 0.0],
            [1.0, f64::INFINITY],
            [2.0, 0.0],
            CircMode::Center,
            "aux point",
        ),
        (
            [0.0, 0.0],
            [1.0, 0.0],
            [2.0, nan],
            CircMode::Border,
            "end point",
        ),
        (
            [0.0, 0.0],
            [nan, 0.0],
            [2.0, 0.0],
            CircMode::Radius,
            "radius",
        ),
    ] {
        match circular_2d(s, aux, e, mode, CW) {
            Err(CircularError::NotFinite { name: got, .. }) => assert_eq!(got, name),
            other => panic!("{name}: {other:?}"),
        }
    }
    // The unused second element of a radius may be anything.
    assert!(circular_2d([0.0, 0.0], [2.0, nan], [2.0, 0.0], CircMode::Radius, CW).is_ok());
}

#[test]
fn errors_read_as_sentences_for_the_commissioning_engineer() {
    let e = circular_2d([0.0, 0.0], [0.5, 0.0], [2.0, 0.0], CircMode::Radius, CCW).unwrap_err();
    assert_eq!(
        e.to_string(),
        "MoveCircular2D (radius): |radius| 0.5 is less than half the distance 1 × 2 from \
         start to end: no arc of that radius joins them"
    );
}

// ---- Segments in the group's axes ----

#[test]
fn circular_2d_in_chosen_axes_leaves_the_others_standing() {
    // Circle in A2 (x) and A0 (y) of a 3-axis group; A1 stays at 7.
    let from = [0.0, 7.0, 1.0, 0.0];
    let circ = CircAxes::new(2, 0, 3).unwrap();
    let seg = PathSegment::circular_2d(
        from,
        3,
        circ,
        [0.0, 0.0],
        [-1.0, 0.0],
        CircMode::Center,
        CCW,
    )
    .unwrap();
    assert!(close(seg.length(), PI));
    for k in 0..=10 {
        let p = seg.position_at(seg.length() * k as f64 / 10.0);
        assert_eq!(p[1], 7.0);
        assert!(close(p[2].hypot(p[0]), 1.0), "{p:?}");
        // Counter-clockwise from A2 towards A0: A0 goes positive first.
        assert!(p[0] >= -1e-15, "{p:?}");
    }
    assert_eq!(seg.end(), [0.0, 7.0, -1.0, 0.0]);
    assert_eq!(seg.position_at(seg.length()), seg.end());
}

#[test]
fn bad_circular_axes_are_refused() {
    assert_eq!(
        CircAxes::new(1, 1, 2),
        Err(SegmentError::BadCircAxes {
            x: 1,
            y: 1,
            axes: 2
        })
    );
    assert_eq!(
        CircAxes::new(0, 2, 2),
        Err(SegmentError::BadCircAxes {
            x: 0,
            y: 2,
            axes: 2
        })
    );
    assert!(matches!(
        PathSegment::line([0.0; 4], [1.0; 4], 5),
        Err(SegmentError::BadAxisCount { axes: 5 })
    ));
}

#[test]
fn a_circle_not_computed_from_the_group_position_is_refused() {
    let planar = circular_2d([1.0, 0.0], [0.0, 0.0], [0.0, 1.0], CircMode::Center, CCW).unwrap();
    let circ = CircAxes::new(0, 1, 2).unwrap();
    assert!(matches!(
        PathSegment::circular([0.5, 0.0, 0.0, 0.0], [0.0; 4], 2, circ, &planar),
        Err(SegmentError::StartMismatch { .. })
    ));
}

#[test]
fn helix_derivatives_match_finite_differences() {
    let planar = circular_2d([1.0, 0.0], [0.0, 0.0], [0.0, 1.0], CircMode::Center, CW).unwrap();
    let circ = CircAxes::new(0, 1, 4).unwrap();
    let seg = PathSegment::circular(
        [1.0, 0.0, 2.0, -1.0],
        [0.0, 0.0, 5.0, 3.0],
        4,
        circ,
        &planar,
    )
    .unwrap();
    let h = 1e-4;
    let s = seg.length() * 0.37;
    let at = |s| seg.derivatives_at(s);
    let (m, c, p) = (at(s - h), at(s), at(s + h));
    for i in 0..MAX_AXES {
        let d1 = (p.p[i] - m.p[i]) / (2.0 * h);
        let d2 = (p.p[i] - 2.0 * c.p[i] + m.p[i]) / (h * h);
        let d3 = (p.d2[i] - m.d2[i]) / (2.0 * h);
        assert!(
            (d1 - c.d1[i]).abs() < 1e-7,
            "axis {i} d1 {d1} vs {}",
            c.d1[i]
        );
        assert!(
            (d2 - c.d2[i]).abs() < 1e-5,
            "axis {i} d2 {d2} vs {}",
            c.d2[i]
        );
        assert!(
            (d3 - c.d3[i]).abs() < 1e-6,
            "axis {i} d3 {d3} vs {}",
            c.d3[i]
        );
    }
    // Arc length parametrisation: |dp/ds| = 1.
    let n = c.d1.iter().map(|d| d * d).sum::<f64>().sqrt();
    assert!(close(n, 1.0), "{n}");
    assert_eq!(seg.position_at(seg.length()), [0.0, 1.0, 5.0, 3.0]);
    assert_eq!(seg.position_at(0.0), [1.0, 0.0, 2.0, -1.0]);
}

#[test]
fn a_line_to_where_the_group_is_plans_an_empty_move() {
    let seg = PathSegment::line([1.0, 2.0, 0.0, 0.0], [1.0, 2.0, 0.0, 0.0], 2).unwrap();
    let lim = [AxisLimits {
        vmax: 1.0,
        amax: 1.0,
        jmax: 1.0,
    }; 2];
    let cmd = PathLimits {
        v: 1.0,
        a: 1.0,
        d: 1.0,
        j: 1.0,
    };
    let plan = PathProfile::plan(seg, &lim, &cmd).unwrap();
    assert_eq!(plan.duration(), 0.0);
    let s = plan.sample(0.5);
    assert_eq!((s[0].p, s[1].p, s[0].v), (1.0, 2.0, 0.0));
}

#[test]
fn geometry_planning_and_sampling_do_not_allocate() {
    let lim = [AxisLimits {
        vmax: 10.0,
        amax: 100.0,
        jmax: 1000.0,
    }; 4];
    let cmd = PathLimits {
        v: 5.0,
        a: f64::INFINITY,
        d: 50.0,
        j: f64::INFINITY,
    };
    let circ = CircAxes::new(1, 3, 4).unwrap();
    let mut sum = 0.0;
    counting::watch(true);
    for mode in [CircMode::Border, CircMode::Center, CircMode::Radius] {
        let seg = PathSegment::circular_2d(
            [0.0, 1.0, 2.0, 3.0],
            4,
            circ,
            [2.5, 4.0],
            [4.0, 3.0],
            mode,
            CW,
        )
        .unwrap();
        let line = PathSegment::line([0.0; 4], [1.0, -2.0, 3.0, 0.5], 4).unwrap();
        for seg in [seg, line] {
            let plan = PathProfile::plan(seg, &lim, &cmd).unwrap();
            for k in 0..=1000 {
                let s = plan.sample(plan.duration() * k as f64 / 1000.0);
                sum += s.iter().map(|s| s.p + s.v + s.a + s.j).sum::<f64>();
            }
        }
    }
    counting::watch(false);
    assert_eq!(
        counting::take_count(),
        0,
        "path planning or sampling allocated"
    );
    assert!(sum.is_finite());
}

// ---- Planned paths: limits, continuity, exact end (property tests) ----

/// Base seed of the property tests (`GANTRY_FUZZ_SEED` to vary it).
fn fuzz_seed() -> u64 {
    std::env::var("GANTRY_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x67656f6d)
}

/// Cases per property (`GANTRY_FUZZ_CASES` to run more).
fn fuzz_cases() -> u32 {
    std::env::var("GANTRY_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(48)
}

fn axis_limits() -> impl Strategy<Value = AxisLimits> {
    (5.0..50.0f64, 5.0..500.0f64, 50.0..5000.0f64).prop_map(|(vmax, amax, jmax)| AxisLimits {
        vmax,
        amax,
        jmax,
    })
}

/// A command value, or none (the axes decide).
fn maybe(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    prop_oneof![3 => lo..hi, 1 => Just(f64::INFINITY)]
}

fn command() -> impl Strategy<Value = PathLimits> {
    (
        5.0..100.0f64,
        maybe(5.0, 1000.0),
        maybe(5.0, 1000.0),
        maybe(50.0, 10000.0),
    )
        .prop_map(|(v, a, d, j)| PathLimits { v, a, d, j })
}

fn point4() -> impl Strategy<Value = [f64; 4]> {
    proptest::array::uniform4(-10.0..10.0f64)
}

fn point2() -> impl Strategy<Value = [f64; 2]> {
    proptest::array::uniform2(-10.0..10.0f64)
}

fn mode() -> impl Strategy<Value = CircMode> {
    prop_oneof![
        Just(CircMode::Border),
        Just(CircMode::Center),
        Just(CircMode::Radius)
    ]
}

fn choice() -> impl Strategy<Value = PathChoice> {
    prop_oneof![Just(CW), Just(CCW)]
}

/// Peak use of each axis' limits over the samples (1 = at the limit), as measured.
#[derive(Clone, Copy, Debug, Default)]
struct Use {
    v: f64,
    a: f64,
    j: f64,
}

/// Samples `plan` every `h` seconds and checks, for every axis at every sample: speed,
/// acceleration (analytic and second differences) and jerk (analytic) within the axis'
/// limits; position and velocity continuous and consistent with the derivatives; the
/// end exactly on the target, at rest. Returns the peak use of the limits.
fn check_plan(plan: &PathProfile, lim: &[AxisLimits], h: f64) -> Use {
    let seg = plan.segment();
    let n = seg.axes();
    let end = seg.end();
    let scale = end
        .iter()
        .chain(seg.start().iter())
        .fold(1.0_f64, |m, p| m.max(p.abs()));
    let mut used = Use::default();
    let steps = (plan.duration() / h).ceil() as usize + 2;
    let mut prev2 = plan.sample(-h);
    let mut prev = plan.sample(0.0);
    for k in 1..=steps {
        let t = k as f64 * h;
        let cur = plan.sample(t);
        for i in 0..n {
            let (l, c, p, pp) = (lim[i], cur[i], prev[i], prev2[i]);
            let rel = 1e-9;
            used.v = used.v.max(c.v.abs() / l.vmax);
            used.a = used.a.max(c.a.abs() / l.amax);
            used.j = used.j.max(c.j.abs() / l.jmax);
            assert!(
                c.v.abs() <= l.vmax * (1.0 + rel),
                "t {t} axis {i}: v {} > {}",
                c.v,
                l.vmax
            );
            assert!(
                c.a.abs() <= l.amax * (1.0 + rel),
                "t {t} axis {i}: a {} > {}",
                c.a,
                l.amax
            );
            assert!(
                c.j.abs() <= l.jmax * (1.0 + rel),
                "t {t} axis {i}: j {} > {}",
                c.j,
                l.jmax
            );
            // Finite differences: the mean speed over a step and the mean acceleration
            // over two are within the limits too (plus the rounding of positions).
            let noise = 8.0 * f64::EPSILON * scale;
            let dp = c.p - p.p;
            assert!(
                dp.abs() <= l.vmax * h * (1.0 + rel) + noise,
                "t {t} axis {i}: step {dp} faster than {}",
                l.vmax
            );
            let dd = c.p - 2.0 * p.p + pp.p;
            assert!(
                dd.abs() <= l.amax * h * h * (1.0 + rel) + 2.0 * noise,
                "t {t} axis {i}: second difference {} above {}",
                dd / (h * h),
                l.amax
            );
            // Continuity and consistency: position follows the velocity (trapezoid rule,
            // error <= h³·jmax/12), velocity follows the acceleration (a is jmax-Lipschitz).
            let trap = h * (c.v + p.v) / 2.0;
            assert!(
                (dp - trap).abs() <= h * h * h * l.jmax / 12.0 * (1.0 + 1e-6) + 4.0 * noise,
                "t {t} axis {i}: position step {dp} vs velocity {trap}"
            );
            let dv = c.v - p.v;
            let trap_a = h * (c.a + p.a) / 2.0;
            assert!(
                (dv - trap_a).abs() <= h * h * l.jmax + 1e-9 * l.vmax,
                "t {t} axis {i}: velocity step {dv} vs acceleration {trap_a}"
            );
        }
        prev2 = prev;
        prev = cur;
    }
    // The end, exactly, at rest — and it stays there.
    for t in [plan.duration(), plan.duration() + h, plan.duration() + 1.0] {
        let s = plan.sample(t);
        for i in 0..MAX_AXES {
            assert_eq!(s[i].p, end[i], "t {t} axis {i} not on the target");
            assert_eq!((s[i].v, s[i].a), (0.0, 0.0), "t {t} axis {i} not at rest");
        }
    }
    for (i, (s, p)) in plan.sample(0.0).iter().zip(seg.start()).enumerate() {
        assert_eq!(s.p, p, "axis {i} does not start at the start");
    }
    used
}

/// Arcs stay on their circle at every sample.
fn check_on_circle(plan: &PathProfile, h: f64) {
    let Some((circ, a, _)) = plan.segment().helix() else {
        return;
    };
    let steps = (plan.duration() / h).ceil() as usize;
    for k in 0..=steps {
        let s = plan.sample(k as f64 * h);
        let d = (s[circ.x()].p - a.center[0]).hypot(s[circ.y()].p - a.center[1]);
        assert!(
            (d - a.radius).abs() <= 1e-9 * a.radius.max(1.0),
            "off the circle by {}",
            d - a.radius
        );
    }
}

/// A random MC_MoveCircular2D (a helix when `helix`: the other axes go to `to`).
#[derive(Clone, Debug)]
struct ArcCase {
    from: [f64; 4],
    to: [f64; 4],
    axes: usize,
    circ: (usize, usize),
    aux: [f64; 2],
    end: [f64; 2],
    mode: CircMode,
    choice: PathChoice,
    helix: bool,
}

fn arc_case() -> impl Strategy<Value = ArcCase> {
    (
        (point4(), point4(), 2usize..=4, (0usize..4, 0usize..4)),
        (point2(), point2(), mode(), choice(), any::<bool>()),
    )
        .prop_map(
            |((from, to, axes, circ), (aux, end, mode, choice, helix))| ArcCase {
                from,
                to,
                axes,
                circ,
                aux,
                end,
                mode,
                choice,
                helix,
            },
        )
}

/// Builds the random arc, or None when the seed's rules refuse it or it is too long to
/// sample finely in a test.
fn build_arc(c: &ArcCase) -> Option<PathSegment> {
    let circ = CircAxes::new(c.circ.0 % c.axes, c.circ.1 % c.axes, c.axes).ok()?;
    let start = [c.from[circ.x()], c.from[circ.y()]];
    // Radius mode: a radius from half the chord to four times it, either sign.
    let aux = if c.mode == CircMode::Radius {
        let half = (c.end[0] - start[0]).hypot(c.end[1] - start[1]) / 2.0;
        let sign = if c.aux[1] < 0.0 { -1.0 } else { 1.0 };
        [sign * half * (1.0 + (c.aux[0] + 10.0) * 0.15), 0.0]
    } else {
        c.aux
    };
    let planar = circular_2d(start, aux, c.end, c.mode, c.choice).ok()?;
    let to = if c.helix { c.to } else { c.from };
    let seg = PathSegment::circular(c.from, to, c.axes, circ, &planar).ok()?;
    (seg.length() < 200.0).then_some(seg)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: fuzz_cases(),
        failure_persistence: None,
        rng_algorithm: proptest::test_runner::RngAlgorithm::ChaCha,
        rng_seed: proptest::test_runner::RngSeed::Fixed(fuzz_seed()),
        ..ProptestConfig::default()
    })]

    #[test]
    fn lines_keep_every_axis_within_its_limits_and_end_on_the_target(
        from in point4(),
        to in point4(),
        axes in 1usize..=4,
        lim in proptest::array::uniform4(axis_limits()),
        cmd in command(),
    ) {
        let seg = PathSegment::line(from, to, axes).unwrap();
        let plan = PathProfile::plan(seg, &lim, &cmd).unwrap();
        check_plan(&plan, &lim, 1e-3);
        check_plan(&plan, &lim, 1e-4);
    }

    #[test]
    fn arcs_and_helices_keep_every_axis_within_its_limits_and_end_on_the_target(
        case in arc_case(),
        lim in proptest::array::uniform4(axis_limits()),
        cmd in command(),
    ) {
        let seg = build_arc(&case);
        prop_assume!(seg.is_some());
        let seg = seg.unwrap();
        let plan = PathProfile::plan(seg, &lim, &cmd).unwrap();
        check_plan(&plan, &lim, 1e-3);
        check_plan(&plan, &lim, 1e-4);
        check_on_circle(&plan, 1e-3);
    }

    #[test]
    fn path_limits_never_exceed_the_command(
        from in point4(),
        to in point4(),
        axes in 1usize..=4,
        lim in proptest::array::uniform4(axis_limits()),
        cmd in command(),
    ) {
        let seg = PathSegment::line(from, to, axes).unwrap();
        let p = path_limits(&seg, &lim, &cmd).unwrap();
        prop_assert!(p.v <= cmd.v && p.a <= cmd.a && p.d <= cmd.d && p.j <= cmd.j);
        prop_assert!(p.v > 0.0 && p.a > 0.0 && p.d > 0.0 && p.j > 0.0);
    }
}

/// How tight the path dynamics are: the peak use of each axis limit (largest over the
/// axes of |value|/limit) on random lines and arcs whose command leaves everything to the
/// axes. Lines are exact (the tightest axis reaches its jerk, and its speed or
/// acceleration when the move is long enough); arcs are conservative by design
/// (`path::limits`). Run with `--nocapture` for the figures.
#[test]
fn measured_peak_use_of_the_axis_limits() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let seed = fuzz_seed().to_le_bytes().repeat(4);
    let mut runner = TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &seed),
    );
    let free = PathLimits {
        v: 1e9,
        a: f64::INFINITY,
        d: f64::INFINITY,
        j: f64::INFINITY,
    };
    let lims = proptest::array::uniform4(axis_limits());
    let mut lines = Vec::new();
    let mut arcs = Vec::new();
    while lines.len() < 100 || arcs.len() < 100 {
        let lim = lims.new_tree(&mut runner).unwrap().current();
        if lines.len() < 100 {
            let (from, to) = (point4(), point4());
            let (from, to) = (
                from.new_tree(&mut runner).unwrap().current(),
                to.new_tree(&mut runner).unwrap().current(),
            );
            let seg = PathSegment::line(from, to, 4).unwrap();
            let plan = PathProfile::plan(seg, &lim, &free).unwrap();
            let u = check_plan(&plan, &lim, 1e-3);
            // Exact bound: the axis that sets the path jerk runs at its jerk limit.
            assert!(u.j > 1.0 - 1e-9, "line {u:?}");
            lines.push(u);
        }
        let case = arc_case().new_tree(&mut runner).unwrap().current();
        if let Some(seg) = build_arc(&case) {
            if arcs.len() < 100 {
                let plan = PathProfile::plan(seg, &lim, &free).unwrap();
                arcs.push(check_plan(&plan, &lim, 1e-3));
            }
        }
    }
    let stats = |what: &str, us: &[Use], f: fn(&Use) -> f64| {
        let mut v: Vec<f64> = us.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        eprintln!(
            "{what}: min {:.3} median {:.3} max {:.6}",
            v[0],
            v[v.len() / 2],
            v[v.len() - 1]
        );
        v[v.len() - 1]
    };
    for (name, us) in [("lines", &lines), ("arcs", &arcs)] {
        let v = stats(&format!("{name} speed"), us, |u| u.v);
        let a = stats(&format!("{name} acceleration"), us, |u| u.a);
        let j = stats(&format!("{name} jerk"), us, |u| u.j);
        let best = stats(&format!("{name} tightest of the three"), us, |u| {
            u.v.max(u.a).max(u.j)
        });
        assert!(v.max(a).max(j).max(best) <= 1.0 + 1e-9);
    }
}
