//! Axis groups driven by the kernel: MC_GroupEnable's rules, MoveLinear and
//! MoveCircular2D along their paths (seed 004's rounded rectangle of four lines and four
//! arcs, buffered: traced and checked against the ideal geometry), no axis ever above its
//! own limits, MC_GroupStop braking along the path, an axis leaving a moving group.

mod common;

use common::*;
use gantry_kernel::axis::command::{Command, CommandError};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisStatus;
use gantry_kernel::group::run::{BufferMode, GroupCmd, GroupMove, GroupPathKind, Transition};
use gantry_kernel::group::{GroupConfig, GroupState};
use gantry_kernel::path::{CircMode, PathChoice, PathLimits};
use gantry_kernel::{AxisKind, Kernel};

const VMAX: f64 = 100.0;
const AMAX: f64 = 1000.0;

fn dynamics(v: f64) -> PathLimits {
    PathLimits {
        v,
        a: f64::INFINITY,
        d: f64::INFINITY,
        j: f64::INFINITY,
    }
}

fn line(x: f64, y: f64, buffered: bool) -> GroupCmd {
    GroupCmd::Move(GroupMove {
        path: GroupPathKind::Linear {
            target: [x, y, 0.0, 0.0],
        },
        relative: false,
        dynamics: dynamics(80.0),
        buffer: if buffered {
            BufferMode::Buffered
        } else {
            BufferMode::Aborting
        },
        transition: Transition::None,
        corner_deviation: f64::INFINITY,
    })
}

fn arc(center: [f64; 2], end: [f64; 2], buffered: bool) -> GroupCmd {
    GroupCmd::Move(GroupMove {
        path: GroupPathKind::Circular {
            circ: (0, 1),
            aux: center,
            end,
            mode: CircMode::Center,
            choice: PathChoice::Ccw,
        },
        relative: false,
        dynamics: dynamics(80.0),
        buffer: if buffered {
            BufferMode::Buffered
        } else {
            BufferMode::Aborting
        },
        transition: Transition::None,
        corner_deviation: f64::INFINITY,
    })
}

/// x and y (simulated, homed) in group 0, enabled; a third axis z outside it.
fn xy() -> Kernel {
    let mut axes = vec![linear("x"), linear("y"), linear("z")];
    for a in &mut axes {
        a.max.vmax = VMAX;
        a.max.amax = AMAX;
        a.max.dmax = AMAX;
        a.max.jmax = 20_000.0;
    }
    let mut k = kernel(axes);
    for i in 0..3 {
        k.command(
            i,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        )
        .unwrap();
    }
    let g = k.add_group(GroupConfig::new("xy", &[0, 1])).unwrap();
    assert_eq!(g, 0);
    k.group_command(0, GroupCmd::Enable).unwrap();
    k
}

fn step(k: &mut Kernel) -> (AxisStatus, AxisStatus) {
    k.step(&[]);
    (*k.axis_status(0).unwrap(), *k.axis_status(1).unwrap())
}

/// Every axis sample within its limits, and no jump between samples.
fn assert_within_limits(trace: &[(AxisStatus, AxisStatus)]) {
    for w in trace.windows(2) {
        for (a, b) in [(&w[0].0, &w[1].0), (&w[0].1, &w[1].1)] {
            assert!(b.set.v.abs() <= VMAX * (1.0 + 1e-9), "speed {}", b.set.v);
            assert!(
                b.set.a.abs() <= AMAX * (1.0 + 1e-6),
                "acceleration {}",
                b.set.a
            );
            let dp = b.set.p - a.set.p;
            assert!(
                (dp - 0.5 * (a.set.v + b.set.v) * DT).abs() < 0.05 * AMAX * DT * DT + 1e-9,
                "position step {dp} against velocities {} {}",
                a.set.v,
                b.set.v
            );
            assert!((b.set.v - a.set.v).abs() <= AMAX * DT * 1.001 + 1e-9);
        }
    }
}

#[test]
fn the_rounded_rectangle_of_seed_004_is_traced_on_its_ideal_geometry() {
    let mut k = xy();
    // 100 × 60 with corners of radius 10, counter-clockwise from (10, 0).
    k.group_command(0, line(10.0, 0.0, false)).unwrap();
    let segments: Vec<GroupCmd> = vec![
        line(90.0, 0.0, true),
        arc([90.0, 10.0], [100.0, 10.0], true),
        line(100.0, 50.0, true),
        arc([90.0, 50.0], [90.0, 60.0], true),
        line(10.0, 60.0, true),
        arc([10.0, 50.0], [0.0, 50.0], true),
        line(0.0, 10.0, true),
        arc([10.0, 10.0], [10.0, 0.0], true),
    ];
    // The first line to the start point, then the eight segments queued behind it.
    let mut handles = Vec::new();
    for s in &segments {
        let h = k.group_command(0, *s).unwrap();
        assert_eq!(k.command_status(h), CommandStatus::Busy, "queued");
        handles.push(h);
    }
    assert_eq!(k.groups()[0].state(), GroupState::Moving);
    let mut trace = Vec::new();
    for _ in 0..20_000 {
        let t = step(&mut k);
        trace.push(t);
        if k.groups()[0].state() == GroupState::Standby {
            break;
        }
    }
    assert_eq!(k.groups()[0].state(), GroupState::Standby, "the path ends");
    for h in &handles {
        assert_eq!(k.command_status(*h), CommandStatus::Done);
    }
    assert_within_limits(&trace);
    // On the ideal rounded rectangle: each sample's distance to the nearest piece.
    let dist = |x: f64, y: f64| -> f64 {
        let mut best = f64::INFINITY;
        let seg = |ax: f64, ay: f64, bx: f64, by: f64| {
            let (dx, dy) = (bx - ax, by - ay);
            let t = (((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
            (x - ax - t * dx).hypot(y - ay - t * dy)
        };
        for d in [
            seg(0.0, 0.0, 10.0, 0.0), // the approach from the origin
            seg(10.0, 0.0, 90.0, 0.0),
            seg(100.0, 10.0, 100.0, 50.0),
            seg(90.0, 60.0, 10.0, 60.0),
            seg(0.0, 50.0, 0.0, 10.0),
        ] {
            best = best.min(d);
        }
        for (cx, cy, qx, qy) in [
            (90.0, 10.0, 1.0, -1.0),
            (90.0, 50.0, 1.0, 1.0),
            (10.0, 50.0, -1.0, 1.0),
            (10.0, 10.0, -1.0, -1.0),
        ] {
            // Only the corner's quarter.
            if (x - cx) * qx >= -1e-9 && (y - cy) * qy >= -1e-9 {
                best = best.min(((x - cx).hypot(y - cy) - 10.0).abs());
            }
        }
        best
    };
    let worst = trace
        .iter()
        .map(|(a, b)| dist(a.set.p, b.set.p))
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "deviation from the ideal path {worst}");
    let (x, y) = trace.last().unwrap();
    assert_eq!(
        (x.set.p, y.set.p),
        (10.0, 0.0),
        "ends exactly on the target"
    );
    // Each corner was gone round (samples near its middle).
    for (cx, cy, qx, qy) in [(90.0, 10.0, 1.0, -1.0), (10.0, 50.0, -1.0, 1.0)] {
        let mid = (cx + qx * 10.0 / 2f64.sqrt(), cy + qy * 10.0 / 2f64.sqrt());
        assert!(trace
            .iter()
            .any(|(a, b)| (a.set.p - mid.0).hypot(b.set.p - mid.1) < 0.2));
    }
    // Coordinated the whole time; back to Standstill at the end.
    assert!(trace[..trace.len() - 1]
        .iter()
        .all(|(a, b)| a.state == AxisState::SynchronizedMotion && b.bits.coordinated));
    step(&mut k);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
}

#[test]
fn enable_rules_and_group_refusals_say_why() {
    let mut k = xy();
    // x is in group 0 (enabled): a second group with x is refused at enable.
    k.add_group(GroupConfig::new("xz", &[0, 2])).unwrap();
    let e = k.group_command(1, GroupCmd::Enable).unwrap_err();
    assert!(e.to_string().contains("group"), "{e}");
    // A single-axis move of a moving group's axis is refused.
    k.group_command(0, line(50.0, 20.0, false)).unwrap();
    step(&mut k);
    let e = k
        .command(
            0,
            Command::MovePtp(gantry_kernel::axis::command::MovePtp::new(
                gantry_kernel::axis::command::PositioningMode::AbsNormal,
                1.0,
            )),
        )
        .unwrap_err();
    assert_eq!(
        e,
        CommandError::MovesWithGroup {
            command: "MovePtp",
            group: 0
        }
    );
    // A circle the rules refuse names the rule.
    let bad = GroupCmd::Move(GroupMove {
        path: GroupPathKind::Circular {
            circ: (0, 1),
            aux: [1.0, 0.0],
            end: [60.0, 20.0],
            mode: CircMode::Radius,
            choice: PathChoice::Cw,
        },
        relative: false,
        dynamics: dynamics(50.0),
        buffer: BufferMode::Buffered,
        transition: Transition::None,
        corner_deviation: f64::INFINITY,
    });
    let h = k.group_command(0, bad).unwrap();
    for _ in 0..5000 {
        step(&mut k);
    }
    let CommandStatus::Error(e) = k.command_status(h) else {
        panic!("{:?}", k.command_status(h))
    };
    assert!(e.to_string().contains("radius"), "{e}");
    // A group with an external axis is refused when it is added.
    let mut axes = vec![linear("x"), linear("e")];
    axes[1].kind = AxisKind::External;
    let mut k2 = Kernel::new(DT, axes).unwrap();
    let e = k2.add_group(GroupConfig::new("bad", &[0, 1])).unwrap_err();
    assert!(e.to_string().contains("external"), "{e}");
}

#[test]
fn group_stop_brakes_along_the_path_and_locks_until_released() {
    let mut k = xy();
    let mv = k.group_command(0, line(80.0, 60.0, false)).unwrap();
    let mut trace: Vec<_> = (0..400).map(|_| step(&mut k)).collect();
    let stop = k.group_command(0, GroupCmd::Stop).unwrap();
    assert_eq!(k.command_status(mv), CommandStatus::Aborted);
    assert_eq!(k.groups()[0].state(), GroupState::Stopping);
    trace.extend((0..1000).map(|_| step(&mut k)));
    assert_eq!(k.command_status(stop), CommandStatus::Done);
    assert_within_limits(&trace);
    // On the line all the way: y = ¾ x.
    for (x, y) in &trace {
        assert!(
            (y.set.p - 0.75 * x.set.p).abs() < 1e-9,
            "{} {}",
            x.set.p,
            y.set.p
        );
    }
    let (x, _) = trace.last().unwrap();
    assert_eq!(x.set.v, 0.0);
    assert!(x.set.p < 80.0, "stopped before the end");
    // Locked until released: a move given now ends CommandAborted (seed 004: started
    // while MC_GroupStop runs), and nothing moves.
    let h = k.group_command(0, line(0.0, 0.0, false)).unwrap();
    assert_eq!(k.command_status(h), CommandStatus::Aborted);
    step(&mut k);
    assert_eq!(k.axis_status(0).unwrap().set.v, 0.0);
    // Enable is refused there (Error, naming the state).
    let e = k.group_command(0, GroupCmd::Enable).unwrap_err();
    assert!(e.to_string().contains("Stopping"), "{e}");
    k.group_command(0, GroupCmd::Release).unwrap();
    assert_eq!(k.groups()[0].state(), GroupState::Standby);
    k.group_command(0, line(0.0, 0.0, false)).unwrap();
}

#[test]
fn an_axis_leaving_a_moving_group_puts_the_group_in_error_stop_the_other_brakes_on_the_path() {
    let mut k = xy();
    let mv = k.group_command(0, line(80.0, 60.0, false)).unwrap();
    let mut trace: Vec<_> = (0..400).map(|_| step(&mut k)).collect();
    // x is stopped by itself (its own MC_Stop).
    k.command(0, Command::Stop { deceleration: None }).unwrap();
    trace.extend((0..1000).map(|_| step(&mut k)));
    assert_eq!(k.groups()[0].state(), GroupState::ErrorStop);
    assert_eq!(k.command_status(mv), CommandStatus::Aborted);
    let (x, y) = trace.last().unwrap();
    assert_eq!(x.state, AxisState::Stopping);
    assert_eq!(y.set.v, 0.0, "y braked");
    assert_ne!(
        y.state,
        AxisState::ErrorStop,
        "the group's error does not fault its axes"
    );
    assert_within_limits(&trace);
    // Reset leaves ErrorStop once the group stands.
    k.group_command(0, GroupCmd::Reset).unwrap();
    assert_eq!(k.groups()[0].state(), GroupState::Standby);
}
