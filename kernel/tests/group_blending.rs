//! Group moves joined in motion (the Blending buffer modes, TransitionMode None and
//! CornerSuperimposed) and Aborting a moving group: seed 004's rounded rectangle blended
//! all the way round, each buffer mode's transit speed, the corner deviation within what
//! is reported and allowed, and property tests over random sequences (blended, buffered
//! and Aborting moves given at random times) — no axis
//! above its speed, acceleration or jerk at any sample (1 ms and 0.1 ms cycles), positions
//! continuous with the velocities, velocities with the accelerations, the end exactly on
//! the last target.

mod common;

use common::*;
use gantry_kernel::axis::command::Command;
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::status::AxisStatus;
use gantry_kernel::group::run::{BufferMode, GroupCmd, GroupMove, GroupPathKind, Transition};
use gantry_kernel::group::{GroupConfig, GroupState};
use gantry_kernel::path::{CircMode, PathChoice, PathLimits};
use gantry_kernel::Kernel;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed, TestRunner};

/// Per-axis limits of the x, y (and z) axes.
#[derive(Clone, Copy, Debug)]
struct Lim {
    vmax: f64,
    amax: f64,
    jmax: f64,
}

const XY: Lim = Lim {
    vmax: 100.0,
    amax: 1000.0,
    jmax: 20_000.0,
};

fn dynamics(v: f64) -> PathLimits {
    PathLimits {
        v,
        a: f64::INFINITY,
        d: f64::INFINITY,
        j: f64::INFINITY,
    }
}

fn mv(path: GroupPathKind, v: f64, buffer: BufferMode, transition: Transition) -> GroupCmd {
    GroupCmd::Move(GroupMove {
        path,
        relative: false,
        dynamics: dynamics(v),
        buffer,
        transition,
        corner_deviation: f64::INFINITY,
    })
}

fn to(x: f64, y: f64) -> GroupPathKind {
    GroupPathKind::Linear {
        target: [x, y, 0.0, 0.0],
    }
}

fn around(center: [f64; 2], end: [f64; 2]) -> GroupPathKind {
    GroupPathKind::Circular {
        circ: (0, 1),
        aux: center,
        end,
        mode: CircMode::Center,
        choice: PathChoice::Ccw,
    }
}

/// `n` linear axes with limits `lim` (each its own), at 0, in group 0 (all of them),
/// enabled; cycle time `dt`.
fn group(lims: &[Lim], dt: f64) -> Kernel {
    let axes = lims
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let mut a = linear(["x", "y", "z", "w"][i]);
            a.max.vmax = l.vmax;
            a.max.amax = l.amax;
            a.max.dmax = l.amax;
            a.max.jmax = l.jmax;
            a.defaults.speed = l.vmax / 2.0;
            a.defaults.acceleration = l.amax / 2.0;
            a.defaults.deceleration = l.amax / 2.0;
            a.defaults.jerk = l.jmax / 2.0;
            a
        })
        .collect::<Vec<_>>();
    let n = axes.len();
    let mut k = Kernel::new(dt, axes).unwrap();
    for i in 0..n {
        k.command(
            i,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
        )
        .unwrap();
        k.command(
            i,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        )
        .unwrap();
    }
    k.step(&[]);
    let members: Vec<usize> = (0..n).collect();
    k.add_group(GroupConfig::new("g", &members)).unwrap();
    k.group_command(0, GroupCmd::Enable).unwrap();
    k
}

/// Steps until the group stands (at most `max` cycles); every axis' status per cycle.
fn run(k: &mut Kernel, n: usize, max: usize) -> Vec<Vec<AxisStatus>> {
    let mut trace = Vec::new();
    for _ in 0..max {
        k.step(&[]);
        trace.push((0..n).map(|i| *k.axis_status(i).unwrap()).collect());
        if k.groups()[0].state() != GroupState::Moving {
            break;
        }
    }
    trace
}

/// No axis above its limits at any sample; positions continuous with the velocities,
/// velocities with the accelerations; the jerk between samples within jmax.
fn assert_within_limits(trace: &[Vec<AxisStatus>], lims: &[Lim], dt: f64) {
    for (c, w) in trace.windows(2).enumerate() {
        for (i, l) in lims.iter().enumerate() {
            let (a, b) = (&w[0][i], &w[1][i]);
            let tol = 1e-9;
            assert!(
                b.set.v.abs() <= l.vmax * (1.0 + tol),
                "cycle {c} axis {i}: speed {} above {}",
                b.set.v,
                l.vmax
            );
            assert!(
                b.set.a.abs() <= l.amax * (1.0 + 1e-6),
                "cycle {c} axis {i}: acceleration {} above {}",
                b.set.a,
                l.amax
            );
            assert!(
                b.set.j.abs() <= l.jmax * (1.0 + 1e-6),
                "cycle {c} axis {i}: jerk {} above {}",
                b.set.j,
                l.jmax
            );
            let da = (b.set.a - a.set.a).abs();
            assert!(
                da <= l.jmax * dt * (1.0 + 1e-6) + 1e-9,
                "cycle {c} axis {i}: acceleration step {da} (jerk {} above {})",
                da / dt,
                l.jmax
            );
            let dv = b.set.v - a.set.v;
            assert!(
                (dv - 0.5 * (a.set.a + b.set.a) * dt).abs() <= l.jmax * dt * dt + 1e-9,
                "cycle {c} axis {i}: velocity step {dv} against accelerations {} {}",
                a.set.a,
                b.set.a
            );
            let dp = b.set.p - a.set.p;
            assert!(
                (dp - 0.5 * (a.set.v + b.set.v) * dt).abs() <= l.amax * dt * dt + 1e-9,
                "cycle {c} axis {i}: position step {dp} against velocities {} {}",
                a.set.v,
                b.set.v
            );
        }
    }
}

fn speed(s: &[AxisStatus]) -> f64 {
    s.iter().fold(0.0_f64, |h, a| h.hypot(a.set.v))
}

/// The lowest path speed between the first and the last time the path is faster than
/// `above` (its start and its end left out).
fn slowest_between(trace: &[Vec<AxisStatus>], above: f64) -> f64 {
    let first = trace.iter().position(|s| speed(s) > above).unwrap_or(0);
    let last = trace.iter().rposition(|s| speed(s) > above).unwrap_or(0);
    trace[first..=last]
        .iter()
        .map(|s| speed(s))
        .fold(f64::INFINITY, f64::min)
}

/// Seed 004's rounded rectangle (100 × 60, corners of radius 10, counter-clockwise from
/// (10, 0)), every segment after the first given with `buffer` and `transition`.
fn rounded_rectangle(buffer: BufferMode, transition: Transition, deviation: f64) -> Vec<GroupCmd> {
    let path = [
        to(90.0, 0.0),
        around([90.0, 10.0], [100.0, 10.0]),
        to(100.0, 50.0),
        around([90.0, 50.0], [90.0, 60.0]),
        to(10.0, 60.0),
        around([10.0, 50.0], [0.0, 50.0]),
        to(0.0, 10.0),
        around([10.0, 10.0], [10.0, 0.0]),
    ];
    path.iter()
        .enumerate()
        .map(|(i, p)| {
            let b = if i == 0 { BufferMode::Aborting } else { buffer };
            GroupCmd::Move(GroupMove {
                path: *p,
                relative: false,
                dynamics: dynamics(80.0),
                buffer: b,
                transition,
                corner_deviation: deviation,
            })
        })
        .collect()
}

/// Distance from (x, y) to the ideal rounded rectangle.
fn off_rectangle(x: f64, y: f64) -> f64 {
    let seg = |ax: f64, ay: f64, bx: f64, by: f64| {
        let (dx, dy) = (bx - ax, by - ay);
        let t = (((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
        (x - ax - t * dx).hypot(y - ay - t * dy)
    };
    let mut best = [
        seg(10.0, 0.0, 90.0, 0.0),
        seg(100.0, 10.0, 100.0, 50.0),
        seg(90.0, 60.0, 10.0, 60.0),
        seg(0.0, 50.0, 0.0, 10.0),
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min);
    for (cx, cy, qx, qy) in [
        (90.0, 10.0, 1.0, -1.0),
        (90.0, 50.0, 1.0, 1.0),
        (10.0, 50.0, -1.0, 1.0),
        (10.0, 10.0, -1.0, -1.0),
    ] {
        if (x - cx) * qx >= -1e-9 && (y - cy) * qy >= -1e-9 {
            best = best.min(((x - cx).hypot(y - cy) - 10.0).abs());
        }
    }
    best
}

/// Runs the rounded rectangle from its start corner; the trace and the handles.
fn trace_rectangle(cmds: &[GroupCmd]) -> (Kernel, Vec<Vec<AxisStatus>>, Vec<HandleId>) {
    let mut k = group(&[XY, XY], DT);
    k.group_command(
        0,
        mv(to(10.0, 0.0), 80.0, BufferMode::Aborting, Transition::None),
    )
    .unwrap();
    run(&mut k, 2, 10_000);
    let handles: Vec<HandleId> = cmds
        .iter()
        .map(|c| k.group_command(0, *c).unwrap())
        .collect();
    let trace = run(&mut k, 2, 20_000);
    (k, trace, handles)
}

#[test]
fn the_rounded_rectangle_blended_never_stops_and_stays_within_the_reported_deviation() {
    let allowed = 0.5;
    let (k, trace, handles) = trace_rectangle(&rounded_rectangle(
        BufferMode::BlendingNext,
        Transition::CornerSuperimposed,
        allowed,
    ));
    assert_eq!(k.groups()[0].state(), GroupState::Standby, "the path ends");
    for h in &handles {
        assert_eq!(k.command_status(*h), CommandStatus::Done);
    }
    assert_within_limits(&trace, &[XY, XY], DT);
    let report = k.groups()[0].corners();
    assert_eq!(
        report.blends, 7,
        "every junction passed in motion: {report:?}"
    );
    assert!(report.max_deviation <= allowed, "{report:?}");
    let worst = trace
        .iter()
        .map(|s| off_rectangle(s[0].set.p, s[1].set.p))
        .fold(0.0, f64::max);
    assert!(
        worst <= report.max_deviation + 1e-9,
        "the path left the rectangle by {worst}, more than the reported {}",
        report.max_deviation
    );
    // In motion from the first cycle to the last: no standstill at any junction.
    let slowest = slowest_between(&trace, 1.0);
    assert!(slowest > 1.0, "the path slowed to {slowest} somewhere");
    let last = trace.last().unwrap();
    assert_eq!((last[0].set.p, last[1].set.p), (10.0, 0.0), "ends exactly");
    // Faster than the same path buffered (at rest at every junction).
    let (_, buffered, _) = trace_rectangle(&rounded_rectangle(
        BufferMode::Buffered,
        Transition::None,
        f64::INFINITY,
    ));
    eprintln!(
        "rounded rectangle: blended {} ms, buffered {} ms, {} blends, corner deviation at most \
         {:.2e} (measured {:.2e})",
        trace.len(),
        buffered.len(),
        report.blends,
        report.max_deviation,
        worst
    );
    // The time at full speed on every segment (lines at 80, arcs at the √(amax/2·R) their
    // centripetal share allows), without speeding up or slowing down anywhere.
    let arc_speed = (0.5 * XY.amax * 10.0_f64).sqrt();
    let ideal_ms = 1000.0 * (240.0 / 80.0 + 4.0 * 5.0 * std::f64::consts::PI / arc_speed);
    eprintln!("  at full speed throughout: {ideal_ms:.0} ms");
    assert!(
        (trace.len() as f64) < 1.2 * ideal_ms,
        "blended {} ms, against {ideal_ms:.0} ms at full speed throughout",
        trace.len()
    );
    assert!(trace.len() < buffered.len());
}

#[test]
fn a_tighter_deviation_slows_the_corners_down_and_holds() {
    let mut prev = f64::INFINITY;
    for allowed in [1.0, 0.1, 0.01] {
        let (k, trace, _) = trace_rectangle(&rounded_rectangle(
            BufferMode::BlendingNext,
            Transition::CornerSuperimposed,
            allowed,
        ));
        assert_within_limits(&trace, &[XY, XY], DT);
        let report = k.groups()[0].corners();
        let worst = trace
            .iter()
            .map(|s| off_rectangle(s[0].set.p, s[1].set.p))
            .fold(0.0, f64::max);
        assert!(report.max_deviation <= allowed, "{allowed}: {report:?}");
        assert!(worst <= report.max_deviation + 1e-9, "{allowed}: {worst}");
        assert!(report.last_transit_speed <= prev, "{allowed}: {report:?}");
        prev = report.last_transit_speed;
    }
}

/// Two collinear lines along x (to 50 at `v1`, then to 100 at `v2` given with `mode`): the
/// speed where the path crosses x = 50.
fn junction_speed(mode: BufferMode, transition: Transition, v1: f64, v2: f64) -> (f64, Kernel) {
    let mut k = group(&[XY, XY], DT);
    k.group_command(
        0,
        mv(to(50.0, 0.0), v1, BufferMode::Aborting, Transition::None),
    )
    .unwrap();
    k.group_command(0, mv(to(100.0, 0.0), v2, mode, transition))
        .unwrap();
    let trace = run(&mut k, 2, 20_000);
    assert_within_limits(&trace, &[XY, XY], DT);
    assert!(trace.iter().all(|s| s[1].set.p == 0.0), "stays on the line");
    assert_eq!(trace.last().unwrap()[0].set.p, 100.0);
    let at = trace
        .iter()
        .find(|s| s[0].set.p >= 50.0)
        .map(|s| s[0].set.v)
        .unwrap();
    (at, k)
}

#[test]
fn each_blending_mode_passes_the_junction_at_its_transit_speed() {
    for (mode, want) in [
        (BufferMode::BlendingLow, 20.0),
        (BufferMode::BlendingPrevious, 20.0),
        (BufferMode::BlendingNext, 50.0),
        (BufferMode::BlendingHigh, 50.0),
        (BufferMode::Buffered, 0.0),
    ] {
        for transition in [Transition::None, Transition::CornerSuperimposed] {
            let (v, k) = junction_speed(mode, transition, 20.0, 50.0);
            assert!(
                (v - want).abs() < 1e-6 || (want == 0.0 && v.abs() < 1.0),
                "{mode:?} {transition:?}: {v} at the junction, want {want}"
            );
            assert_eq!(k.groups()[0].corners().max_deviation, 0.0, "collinear");
        }
    }
    // Slower first, faster second, the other way round.
    let (v, _) = junction_speed(BufferMode::BlendingLow, Transition::None, 50.0, 20.0);
    assert!((v - 20.0).abs() < 1e-6, "{v}");
    let (v, _) = junction_speed(BufferMode::BlendingHigh, Transition::None, 50.0, 20.0);
    assert!((v - 50.0).abs() < 1e-6, "{v}");
}

#[test]
fn transition_none_passes_a_turn_at_rest_and_superimposed_rounds_it() {
    for (transition, moving) in [
        (Transition::None, false),
        (Transition::CornerSuperimposed, true),
    ] {
        let mut k = group(&[XY, XY], DT);
        k.group_command(0, mv(to(50.0, 0.0), 50.0, BufferMode::Aborting, transition))
            .unwrap();
        k.group_command(
            0,
            mv(to(50.0, 50.0), 50.0, BufferMode::BlendingNext, transition),
        )
        .unwrap();
        let trace = run(&mut k, 2, 20_000);
        assert_within_limits(&trace, &[XY, XY], DT);
        let slowest = slowest_between(&trace, 1.0);
        assert_eq!(slowest > 1.0, moving, "{transition:?}: slowest {slowest}");
        assert_eq!(k.groups()[0].corners().blends, u32::from(moving));
        let last = trace.last().unwrap();
        assert_eq!((last[0].set.p, last[1].set.p), (50.0, 50.0));
    }
}

#[test]
fn aborting_brakes_along_the_path_then_goes_to_the_new_target() {
    let mut k = group(&[XY, XY], DT);
    let first = k
        .group_command(
            0,
            mv(to(100.0, 0.0), 80.0, BufferMode::Aborting, Transition::None),
        )
        .unwrap();
    let mut trace = run(&mut k, 2, 300);
    assert!(trace.last().unwrap()[0].set.v > 50.0, "at speed");
    let x_then = trace.last().unwrap()[0].set.p;
    // Relative: 10 up from where the group is when the command is given.
    let second = k
        .group_command(
            0,
            GroupCmd::Move(GroupMove {
                path: GroupPathKind::Linear {
                    target: [0.0, 10.0, 0.0, 0.0],
                },
                relative: true,
                dynamics: dynamics(40.0),
                buffer: BufferMode::Aborting,
                transition: Transition::None,
                corner_deviation: f64::INFINITY,
            }),
        )
        .unwrap();
    assert_eq!(k.command_status(first), CommandStatus::Aborted);
    assert_eq!(k.command_status(second), CommandStatus::Busy);
    let rest = run(&mut k, 2, 20_000);
    // Brakes on the line (y stays 0 until x stands), then goes up.
    let stop = rest.iter().position(|s| s[1].set.p != 0.0).unwrap();
    assert!(rest[..stop].iter().all(|s| s[0].set.v >= 0.0));
    assert!(
        rest[stop - 1][0].set.v.abs() < 1e-9,
        "x stands before y moves"
    );
    trace.extend(rest);
    assert_within_limits(&trace, &[XY, XY], DT);
    let last = trace.last().unwrap();
    assert_eq!(
        last[1].set.p, 10.0,
        "relative to where the command was given"
    );
    assert_eq!(
        last[0].set.p, x_then,
        "x: where it was when the move was given"
    );
    assert_eq!(k.command_status(second), CommandStatus::Done);
    assert_eq!(k.groups()[0].state(), GroupState::Standby);
}

#[test]
fn a_stop_in_the_middle_of_a_corner_keeps_the_limits_and_the_path() {
    let allowed = 0.5;
    let cmds = rounded_rectangle(
        BufferMode::BlendingNext,
        Transition::CornerSuperimposed,
        allowed,
    );
    let (k0, reference, _) = trace_rectangle(&cmds);
    let dev = k0.groups()[0].corners().max_deviation;
    // The first corner's blend: where the speed dips the most around the first arc.
    for at in (0..reference.len()).step_by(reference.len() / 23) {
        let mut k = group(&[XY, XY], DT);
        k.group_command(
            0,
            mv(to(10.0, 0.0), 80.0, BufferMode::Aborting, Transition::None),
        )
        .unwrap();
        run(&mut k, 2, 10_000);
        for c in &cmds {
            k.group_command(0, *c).unwrap();
        }
        let mut trace = Vec::new();
        for _ in 0..at {
            k.step(&[]);
            trace.push(vec![*k.axis_status(0).unwrap(), *k.axis_status(1).unwrap()]);
        }
        let h = k.group_command(0, GroupCmd::Stop).unwrap();
        for _ in 0..5000 {
            k.step(&[]);
            trace.push(vec![*k.axis_status(0).unwrap(), *k.axis_status(1).unwrap()]);
            if !k.groups()[0].drives_axes() {
                break;
            }
        }
        assert_within_limits(&trace, &[XY, XY], DT);
        assert_eq!(k.command_status(h), CommandStatus::Done, "stopped at {at}");
        assert_eq!(k.groups()[0].state(), GroupState::Stopping);
        let worst = trace
            .iter()
            .map(|s| off_rectangle(s[0].set.p, s[1].set.p))
            .fold(0.0, f64::max);
        assert!(worst <= dev + 1e-9, "stop at {at}: off the path by {worst}");
        let last = trace.last().unwrap();
        assert!(speed(last) == 0.0, "stop at {at}: still moving {:?}", last);
    }
}

// ---- Property tests: random blended sequences ----

fn fuzz_seed() -> u64 {
    std::env::var("GANTRY_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x626c656e)
}

fn fuzz_cases(default: u32) -> u32 {
    std::env::var("GANTRY_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

#[derive(Clone, Copy, Debug)]
enum Piece {
    Line([f64; 3]),
    /// Center and end point in x, y relative to the start (Center mode: a mismatch takes
    /// the mean radius), CCW or not.
    Arc([f64; 2], [f64; 2], bool),
}

impl Piece {
    /// Where the move ends when it starts at `from`.
    fn end(&self, from: [f64; 3]) -> [f64; 3] {
        match *self {
            Piece::Line(to) => to,
            Piece::Arc(_, e, _) => [from[0] + e[0], from[1] + e[1], from[2]],
        }
    }
}

fn lim() -> impl Strategy<Value = Lim> {
    (5.0..60.0f64, 20.0..800.0f64, 200.0..20_000.0f64).prop_map(|(vmax, amax, jmax)| Lim {
        vmax,
        amax,
        jmax,
    })
}

fn piece() -> impl Strategy<Value = Piece> {
    let p = || -20.0..20.0f64;
    prop_oneof![
        3 => (p(), p(), p()).prop_map(|(x, y, z)| Piece::Line([x, y, z])),
        1 => (-10.0..10.0f64, -10.0..10.0f64, -10.0..10.0f64, -10.0..10.0f64, any::<bool>())
            .prop_map(|(ax, ay, ex, ey, ccw)| Piece::Arc([ax, ay], [ex, ey], ccw)),
    ]
}

fn buffer() -> impl Strategy<Value = BufferMode> {
    prop_oneof![
        1 => Just(BufferMode::Aborting),
        1 => Just(BufferMode::Buffered),
        2 => Just(BufferMode::BlendingLow),
        2 => Just(BufferMode::BlendingPrevious),
        2 => Just(BufferMode::BlendingNext),
        2 => Just(BufferMode::BlendingHigh),
    ]
}

fn transition() -> impl Strategy<Value = Transition> {
    prop_oneof![
        1 => Just(Transition::None),
        3 => Just(Transition::CornerSuperimposed),
    ]
}

/// One random move after the first: where, how fast, how it joins, and how many cycles
/// after the previous command it is given (0: at once, queued behind).
fn step_cmd() -> impl Strategy<Value = (Piece, f64, BufferMode, Transition, f64, usize)> {
    (
        piece(),
        5.0..80.0f64,
        buffer(),
        transition(),
        prop_oneof![1 => Just(f64::INFINITY), 2 => 0.01..2.0f64],
        prop_oneof![3 => Just(0usize), 1 => 0..400usize],
    )
}

fn as_move(p: Piece, v: f64, b: BufferMode, t: Transition, dev: f64) -> GroupCmd {
    let (path, relative) = match p {
        Piece::Line(to) => (
            GroupPathKind::Linear {
                target: [to[0], to[1], to[2], 0.0],
            },
            false,
        ),
        Piece::Arc(aux, end, ccw) => (
            GroupPathKind::Circular {
                circ: (0, 1),
                aux,
                end,
                mode: CircMode::Center,
                choice: if ccw { PathChoice::Ccw } else { PathChoice::Cw },
            },
            true,
        ),
    };
    GroupCmd::Move(GroupMove {
        path,
        relative,
        dynamics: dynamics(v),
        buffer: b,
        transition: t,
        corner_deviation: dev,
    })
}

/// Runs one random sequence and checks it; the number of blends.
fn check_sequence(
    lims: &[Lim; 3],
    first: Piece,
    rest: &[(Piece, f64, BufferMode, Transition, f64, usize)],
    dt: f64,
) -> Result<u32, TestCaseError> {
    let mut k = group(lims, dt);
    let mut trace: Vec<Vec<AxisStatus>> = Vec::new();
    let record = |k: &Kernel, trace: &mut Vec<Vec<AxisStatus>>| {
        trace.push((0..3).map(|i| *k.axis_status(i).unwrap()).collect());
    };
    let mut handles = Vec::new();
    let cmd = as_move(
        first,
        40.0,
        BufferMode::Aborting,
        Transition::None,
        f64::INFINITY,
    );
    if let Ok(h) = k.group_command(0, cmd) {
        handles.push((h, first));
    }
    // An Aborting move takes the path elsewhere than the polyline through the targets.
    let mut aborted_path = false;
    for &(p, v, b, t, dev, wait) in rest {
        for _ in 0..wait {
            k.step(&[]);
            record(&k, &mut trace);
        }
        // A relative arc given Aborting would count from wherever the group is then:
        // arcs join as Buffered instead, so each move's end follows from the last one's.
        let b = match (p, b) {
            (Piece::Arc(..), BufferMode::Aborting) => BufferMode::Buffered,
            _ => b,
        };
        aborted_path |= b == BufferMode::Aborting;
        if let Ok(h) = k.group_command(0, as_move(p, v, b, t, dev)) {
            handles.push((h, p));
        }
    }
    for _ in 0..(200_000.0 * DT / dt) as usize {
        k.step(&[]);
        record(&k, &mut trace);
        if !k.groups()[0].drives_axes() {
            break;
        }
    }
    prop_assert!(!k.groups()[0].drives_axes(), "the sequence ends");
    assert_within_limits(&trace, &lims[..], dt);
    // Every move ended (Done; Error or CommandAborted behind one the rules refuse) and
    // the last one that was Done ends exactly where it said.
    let mut end = [0.0; 3];
    for (h, p) in &handles {
        let s = k.command_status(*h);
        prop_assert!(
            matches!(
                s,
                CommandStatus::Done | CommandStatus::Error(_) | CommandStatus::Aborted
            ),
            "{s:?}"
        );
        if s == CommandStatus::Done {
            end = p.end(end);
        }
    }
    // Lines only: the path within the reported deviation of the polyline through the
    // targets (an arc's ideal geometry is checked on the rounded rectangle).
    let lines: Option<Vec<[f64; 3]>> = handles
        .iter()
        .map(|(h, p)| match p {
            Piece::Line(to) if k.command_status(*h) == CommandStatus::Done => Some(*to),
            _ => None,
        })
        .collect();
    if let Some(points) = lines.filter(|_| !aborted_path) {
        let bound = k.groups()[0].corners().max_deviation;
        let mut corners = vec![[0.0; 3]];
        corners.extend(points);
        for s in &trace {
            let p = [s[0].set.p, s[1].set.p, s[2].set.p];
            let off = corners
                .windows(2)
                .map(|w| off_segment(p, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            prop_assert!(
                off <= bound + 1e-9,
                "{off} off the polyline, the reported bound {bound}"
            );
        }
    }
    if let Some(at) = trace.last() {
        for (i, e) in end.iter().enumerate() {
            let got = at[i].set.p;
            prop_assert!(
                (got - e).abs() <= 1e-9 * e.abs().max(1.0),
                "axis {i} ends at {got}, not {e}"
            );
        }
    }
    Ok(k.groups()[0].corners().blends)
}

/// Distance from `p` to the segment from `a` to `b`.
fn off_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1] + (p[2] - a[2]) * d[2]) / len2)
            .clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3).fold(0.0_f64, |h, i| h.hypot(p[i] - a[i] - t * d[i]))
}

fn property(cases: u32, dt: f64, seed_offset: u64) {
    let mut runner = TestRunner::new(Config {
        cases,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(fuzz_seed() + seed_offset),
        failure_persistence: None,
        ..Config::default()
    });
    let blends = std::cell::Cell::new(0u32);
    runner
        .run(
            &(
                [lim(), lim(), lim()],
                piece(),
                proptest::collection::vec(step_cmd(), 1..7),
            ),
            |(lims, first, rest)| {
                blends.set(blends.get() + check_sequence(&lims, first, &rest, dt)?);
                Ok(())
            },
        )
        .unwrap();
    eprintln!(
        "{cases} random sequences at dt = {dt}: {} blends",
        blends.get()
    );
    assert!(
        blends.get() > cases,
        "the sequences blend ({})",
        blends.get()
    );
}

#[test]
fn random_blended_sequences_keep_every_axis_within_its_limits() {
    property(fuzz_cases(64), DT, 0);
}

#[test]
fn random_blended_sequences_keep_the_limits_at_a_tenth_of_the_cycle() {
    property(fuzz_cases(64) / 4, DT / 10.0, 1);
}

/// Each cycle's status of the handles `hs`, until the group stands.
fn statuses(k: &mut Kernel, hs: &[HandleId]) -> Vec<Vec<CommandStatus>> {
    let mut out = Vec::new();
    for _ in 0..20_000 {
        k.step(&[]);
        out.push(hs.iter().map(|h| k.command_status(*h)).collect());
        if !k.groups()[0].drives_axes() {
            break;
        }
    }
    out
}

/// The first cycle where handle `i` shows `s`.
fn first(trace: &[Vec<CommandStatus>], i: usize, s: CommandStatus) -> usize {
    trace.iter().position(|c| c[i] == s).unwrap()
}

#[test]
fn handles_follow_the_seed_charts_buffered_blended_and_halted() {
    use CommandStatus::{Aborted, Active, Busy, Done};
    // Buffered: the second is Busy while the first runs and Active in the cycle the first
    // is Done.
    let mut k = group(&[XY, XY], DT);
    let a = k
        .group_command(
            0,
            mv(to(20.0, 0.0), 50.0, BufferMode::Aborting, Transition::None),
        )
        .unwrap();
    let b = k
        .group_command(
            0,
            mv(to(20.0, 20.0), 50.0, BufferMode::Buffered, Transition::None),
        )
        .unwrap();
    assert_eq!((k.command_status(a), k.command_status(b)), (Active, Busy));
    let t = statuses(&mut k, &[a, b]);
    let (a_done, b_active) = (first(&t, 0, Done), first(&t, 1, Active));
    assert_eq!(a_done, b_active, "Buffered: Done and Active in one cycle");
    assert!(t[..b_active].iter().all(|c| c[1] == Busy));
    assert_eq!(t.last().unwrap(), &vec![Done, Done]);
    assert_eq!(k.groups()[0].state(), GroupState::Standby);

    // Blended: the second turns Active when its ramp starts, while the first is still
    // Active; the first is Done when the corner is passed.
    let mut k = group(&[XY, XY], DT);
    let a = k
        .group_command(
            0,
            mv(
                to(20.0, 0.0),
                50.0,
                BufferMode::Aborting,
                Transition::CornerSuperimposed,
            ),
        )
        .unwrap();
    let b = k
        .group_command(
            0,
            mv(
                to(20.0, 20.0),
                50.0,
                BufferMode::BlendingNext,
                Transition::CornerSuperimposed,
            ),
        )
        .unwrap();
    let t = statuses(&mut k, &[a, b]);
    let (a_done, b_active) = (first(&t, 0, Done), first(&t, 1, Active));
    assert!(b_active < a_done, "overlap: {b_active} < {a_done}");
    assert!(t[b_active..a_done]
        .iter()
        .all(|c| c[0] == Active && c[1] == Active));
    assert_eq!(t.last().unwrap(), &vec![Done, Done]);
    assert_eq!(k.groups()[0].corners().blends, 1);

    // Halt: Active while the group brakes along the path, Done when it stands; the move it
    // took over and the one waiting end CommandAborted at once; Standby, not locked.
    let mut k = group(&[XY, XY], DT);
    let a = k
        .group_command(
            0,
            mv(to(100.0, 0.0), 80.0, BufferMode::Aborting, Transition::None),
        )
        .unwrap();
    let b = k
        .group_command(
            0,
            mv(to(0.0, 0.0), 80.0, BufferMode::Buffered, Transition::None),
        )
        .unwrap();
    let mut trace = run_for(&mut k, 400);
    let h = k.group_command(0, GroupCmd::Halt).unwrap();
    assert_eq!(
        (
            k.command_status(a),
            k.command_status(b),
            k.command_status(h)
        ),
        (Aborted, Aborted, Active)
    );
    let mut t = Vec::new();
    while k.groups()[0].drives_axes() && t.len() < 20_000 {
        trace.extend(run_for(&mut k, 1));
        t.push(k.command_status(h));
    }
    assert!(t[..t.len() - 1].iter().all(|c| *c == Active));
    assert_eq!(t.last(), Some(&Done));
    assert_eq!(k.groups()[0].state(), GroupState::Standby);
    assert_within_limits(&trace, &[XY, XY], DT);
    let last = trace.last().unwrap();
    assert!(
        last[0].set.p < 100.0 && last[1].set.p == 0.0,
        "on the line, short of it"
    );
    // Not locked: the next move starts at once.
    let c = k
        .group_command(
            0,
            mv(to(0.0, 0.0), 80.0, BufferMode::Aborting, Transition::None),
        )
        .unwrap();
    assert_eq!(k.command_status(c), Active);
}

fn run_for(k: &mut Kernel, cycles: usize) -> Vec<Vec<AxisStatus>> {
    (0..cycles)
        .map(|_| {
            k.step(&[]);
            vec![*k.axis_status(0).unwrap(), *k.axis_status(1).unwrap()]
        })
        .collect()
}
