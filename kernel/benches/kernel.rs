//! Cost of `Kernel::step` per axis per cycle, for 1, 4, 8, 16 and 64 axes all running
//! S-curve PTP moves; and, as the baseline in the same run, the bare closed-form sampling
//! of the same profiles (what any kernel must at least do). The README reports both and
//! their ratio.
//!
//! Synchronised motion in the same run: one virtual master at constant velocity and 1, 4
//! or 16 followers geared to it (`sync_gear`) or cammed on a 20-point periodic cubic table
//! (`sync_cam`). divan's items are the followers, so its throughput column is followers per
//! second; the README divides the median step time by N (the master's own step included)
//! and compares it with `step` at the same N.

use gantry_kernel::axis::command::{
    Command, MoveDirection, MovePtp, MoveVelocity, PositioningMode, PowerCommand,
};
use gantry_kernel::cam::{CamPoint, CamTable, Interpolation};
use gantry_kernel::profile::{plan_position, KinematicState, Limits, Profile, RampType};
use gantry_kernel::sync::command::{CamIn, GearIn};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};

fn main() {
    divan::main();
    planning_distribution();
    path_planning_distribution();
    blend_planning_distribution();
}

/// A small fixed-seed generator so every run plans the same states.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

/// A random start state, target and limits (start inside the limits).
fn random_case(r: &mut XorShift) -> (KinematicState, f64, Limits) {
    let lim = Limits {
        vmax: r.range(0.5, 10.0),
        amax: r.range(0.5, 50.0),
        dmax: r.range(0.5, 50.0),
        jmax: r.range(5.0, 500.0),
    };
    let start = KinematicState {
        p: r.range(-100.0, 100.0),
        v: r.range(-1.0, 1.0) * lim.vmax,
        a: r.range(-1.0, 1.0) * lim.amax.min(lim.dmax),
        j: 0.0,
    };
    (start, r.range(-100.0, 100.0), lim)
}

/// A random start beyond the limits (|v0| up to 1.6·vmax, or a0 carrying v past vmax: a
/// NewSpeed below the current speed, a jog superimposed on a move), target and limits.
fn random_beyond_case(r: &mut XorShift) -> (KinematicState, f64, Limits) {
    let (mut start, target, lim) = random_case(r);
    let side = if r.next() < 0.5 { -1.0 } else { 1.0 };
    if r.next() < 0.5 {
        start.v = side * r.range(1.01, 1.6) * lim.vmax;
    } else {
        // v0 = vmax − u·a0²/2J with a0 towards vmax: carried (1 − u)·a0²/2J past it.
        let a = r.range(0.3, 1.0) * lim.amax.min(lim.dmax);
        start.a = side * a;
        start.v = side * (lim.vmax - r.range(0.05, 0.95) * a * a / (2.0 * lim.jmax));
    }
    (start, target, lim)
}

/// Planning time distribution (median, p99, max) of `ramp` over `cases`. Each state is
/// planned 5 times and its fastest time kept: a plan that was merely interrupted by the
/// (shared, noisy) machine shows as slow once, a slow plan always.
fn measure(cases: &[(KinematicState, f64, Limits)], ramp: RampType) -> (u64, u64, u64) {
    let mut ns: Vec<u64> = cases
        .iter()
        .map(|(s, t, l)| {
            (0..5)
                .map(|_| {
                    let t0 = std::time::Instant::now();
                    let p = plan_position(ramp, *s, *t, 0.0, l);
                    let dt = t0.elapsed().as_nanos() as u64;
                    divan::black_box(p).ok();
                    dt
                })
                .min()
                .unwrap_or(0)
        })
        .collect();
    ns.sort_unstable();
    let q = |f: f64| ns[((ns.len() - 1) as f64 * f) as usize];
    (q(0.5), q(0.99), ns[ns.len() - 1])
}

/// S-curve planning time from 10 000 random states: the distribution (median, p99, max),
/// with trapezoid planning of the same moves as the baseline of the same run; and from
/// 10 000 states beyond the limits.
fn planning_distribution() {
    let mut r = XorShift(0x9e37_79b9_7f4a_7c15);
    let cases: Vec<_> = (0..10_000).map(|_| random_case(&mut r)).collect();
    let beyond: Vec<_> = (0..10_000).map(|_| random_beyond_case(&mut r)).collect();
    // Warm up, then measure.
    let _ = measure(&cases, RampType::SCurve);
    let s = measure(&cases, RampType::SCurve);
    let t = measure(&cases, RampType::Trapezoid);
    let b = measure(&beyond, RampType::SCurve);
    println!("planning over 10000 random states, fastest of 5 runs each (ns): median / p99 / max");
    println!("  scurve     {:>7} / {:>7} / {:>7}", s.0, s.1, s.2);
    println!("  trapezoid  {:>7} / {:>7} / {:>7}", t.0, t.1, t.2);
    println!(
        "  ratio scurve/trapezoid at the median: {:.1}",
        s.0 as f64 / t.0.max(1) as f64
    );
    println!(
        "  scurve from beyond the limits {:>7} / {:>7} / {:>7}",
        b.0, b.1, b.2
    );
}

const DT: f64 = 0.001;

fn limits(i: usize) -> Limits {
    Limits {
        vmax: 50.0 + (i % 40) as f64,
        amax: 5.0 + (i % 7) as f64,
        dmax: 4.0 + (i % 5) as f64,
        jmax: 20.0 + (i % 3) as f64,
    }
}

/// A kernel whose `n` axes each run a long S-curve move (about 1000 s long, so the bench
/// samples acceleration, cruise and deceleration phases without replanning).
fn busy_kernel(n: usize) -> Kernel {
    let configs = (0..n)
        .map(|i| {
            let mut c = AxisConfig::new(&format!("a{i}"), AxisKind::Simulated);
            c.homing_required = false;
            c
        })
        .collect();
    let mut k = Kernel::new(DT, configs).expect("config");
    for i in 0..n {
        let l = limits(i);
        k.command(i, Command::Power(PowerCommand::Enable))
            .expect("enable");
        k.command(
            i,
            Command::MovePtp(
                MovePtp::new(PositioningMode::AbsNormal, 50_000.0 + 10.0 * i as f64)
                    .speed(l.vmax)
                    .accel(l.amax, l.dmax)
                    .jerk(l.jmax)
                    .ramp(RampType::SCurve),
            ),
        )
        .expect("move");
    }
    // Start somewhere inside the moves.
    for _ in 0..3_000 {
        k.step(&[]);
    }
    k
}

#[divan::bench(args = [1, 4, 8, 16, 64])]
fn step(bencher: divan::Bencher, n: usize) {
    let mut k = busy_kernel(n);
    bencher
        .counter(divan::counter::ItemsCount::new(n))
        .bench_local(|| {
            divan::black_box(k.step(&[]));
        });
}

#[divan::bench(args = [1, 8, 64])]
fn baseline_sample_only(bencher: divan::Bencher, n: usize) {
    let profiles: Vec<Profile> = (0..n)
        .map(|i| {
            plan_position(
                RampType::SCurve,
                KinematicState::at_rest(0.0),
                50_000.0 + 10.0 * i as f64,
                0.0,
                &limits(i),
            )
            .expect("plan")
        })
        .collect();
    let mut tick = 3_000u64;
    bencher
        .counter(divan::counter::ItemsCount::new(n))
        .bench_local(|| {
            tick += 1;
            let t = tick as f64 * DT;
            let mut acc = 0.0;
            for p in &profiles {
                acc += p.sample(t).p;
            }
            divan::black_box(acc);
        });
}

/// Master velocity of the synchronised benches (units/s): about 2.8 cam periods per second.
const MASTER_SPEED: f64 = 1000.0;

/// How the followers of [`synced_kernel`] follow the master.
#[derive(Clone, Copy)]
enum Coupling {
    /// GearIn at ratios cycling through 1:1, −1:2, 3:7 and 5:4.
    Gear,
    /// CamIn, periodic, on the table of [`bench_cam`].
    Cam,
}

/// A periodic cubic cam over 360 master units through 20 points: the eccentric stroke
/// 50·(1 − cos θ) (as deploy/cams/eccentric.toml, sampled more finely).
fn bench_cam() -> CamTable {
    let points = (0..20)
        .map(|i| {
            let master = 360.0 * i as f64 / 19.0;
            CamPoint {
                master,
                slave: 50.0 * (1.0 - master.to_radians().cos()),
            }
        })
        .collect();
    CamTable::new(points, Interpolation::Cubic, true).expect("cam table")
}

/// A kernel with a virtual master (axis 0) at [`MASTER_SPEED`] and `n` simulated
/// followers coupled to it, stepped until every follower has caught up (InSync).
fn synced_kernel(n: usize, coupling: Coupling) -> Kernel {
    let mut master = AxisConfig::new("m", AxisKind::Virtual);
    master.homing_required = false;
    master.max = Limits {
        vmax: 2.0 * MASTER_SPEED,
        amax: 10_000.0,
        dmax: 10_000.0,
        jmax: 1e6,
    };
    let mut configs = vec![master];
    configs.extend((0..n).map(|i| {
        let mut c = AxisConfig::new(&format!("f{i}"), AxisKind::Simulated);
        c.homing_required = false;
        c.max = Limits {
            vmax: 5_000.0,
            amax: 1e5,
            dmax: 1e5,
            jmax: 1e8,
        };
        c.defaults.acceleration = 10_000.0;
        c.defaults.deceleration = 10_000.0;
        c.defaults.jerk = 1e6;
        c.defaults.ramp = RampType::SCurve;
        c
    }));
    let mut k = Kernel::new(DT, configs).expect("config");
    k.set_cam_table(0, Some(bench_cam())).expect("cam slot");
    for i in 0..=n {
        k.command(i, Command::Power(PowerCommand::Enable))
            .expect("enable");
    }
    k.command(
        0,
        Command::MoveVelocity(MoveVelocity {
            acceleration: Some(10_000.0),
            deceleration: Some(10_000.0),
            jerk: Some(1e6),
            ..MoveVelocity::new(MoveDirection::Positive, MASTER_SPEED)
        }),
    )
    .expect("master velocity");
    const RATIOS: [(i32, u32); 4] = [(1, 1), (-1, 2), (3, 7), (5, 4)];
    for i in 1..=n {
        let command = match coupling {
            Coupling::Gear => {
                let (num, den) = RATIOS[i % RATIOS.len()];
                Command::GearIn(GearIn::new(0, num, den))
            }
            Coupling::Cam => Command::CamIn(CamIn::new(0, 0, true)),
        };
        k.command(i, command).expect("couple");
    }
    for _ in 0..3_000 {
        k.step(&[]);
    }
    for i in 1..=n {
        let s = k.axis_status(i).expect("follower");
        assert!(s.bits.in_sync, "follower {i} not in sync after 3 s: {s:?}");
    }
    k
}

#[divan::bench(args = [1, 4, 16])]
fn sync_gear(bencher: divan::Bencher, n: usize) {
    let mut k = synced_kernel(n, Coupling::Gear);
    bencher
        .counter(divan::counter::ItemsCount::new(n))
        .bench_local(|| {
            divan::black_box(k.step(&[]));
        });
}

#[divan::bench(args = [1, 4, 16])]
fn sync_cam(bencher: divan::Bencher, n: usize) {
    let mut k = synced_kernel(n, Coupling::Cam);
    bencher
        .counter(divan::counter::ItemsCount::new(n))
        .bench_local(|| {
            divan::black_box(k.step(&[]));
        });
}

/// The master alone at constant velocity: what [`sync_gear`] and [`sync_cam`] pay besides
/// their followers.
#[divan::bench]
fn sync_master_only(bencher: divan::Bencher) {
    let mut k = synced_kernel(0, Coupling::Gear);
    bencher.bench_local(|| {
        divan::black_box(k.step(&[]));
    });
}

/// A kernel with four simulated axes in one enabled group, at 0.
fn group_kernel_at_rest() -> Kernel {
    use gantry_kernel::group::run::GroupCmd;
    use gantry_kernel::group::GroupConfig;
    let configs = (0..4)
        .map(|i| {
            let mut c = AxisConfig::new(&format!("a{i}"), AxisKind::Simulated);
            c.homing_required = false;
            c.max = Limits {
                vmax: 100.0,
                amax: 1000.0,
                dmax: 1000.0,
                jmax: 10_000.0,
            };
            c
        })
        .collect();
    let mut k = Kernel::new(DT, configs).expect("config");
    for i in 0..4 {
        k.command(i, Command::Power(PowerCommand::Enable))
            .expect("enable");
        k.command(
            i,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        )
        .expect("home");
    }
    k.step(&[]);
    k.add_group(GroupConfig::new("g", &[0, 1, 2, 3]))
        .expect("group");
    k.group_command(0, GroupCmd::Enable).expect("enable");
    k
}

/// A kernel with four simulated axes in one group moving along a long straight line in
/// four axes (about 2000 s: the bench samples the cruise without replanning).
fn group_kernel() -> Kernel {
    use gantry_kernel::group::run::{BufferMode, GroupCmd, GroupMove, GroupPathKind, Transition};
    use gantry_kernel::path::PathLimits;
    let mut k = group_kernel_at_rest();
    k.group_command(
        0,
        GroupCmd::Move(GroupMove {
            path: GroupPathKind::Linear {
                target: [1e5, 5e4, -3e4, 2e4],
            },
            relative: false,
            dynamics: PathLimits {
                v: 60.0,
                a: f64::INFINITY,
                d: f64::INFINITY,
                j: f64::INFINITY,
            },
            buffer: BufferMode::Aborting,
            transition: Transition::None,
            corner_deviation: f64::INFINITY,
        }),
    )
    .expect("move");
    for _ in 0..3_000 {
        k.step(&[]);
    }
    k
}

/// One cycle of a kernel whose four-axis group is in the middle of a superimposed corner
/// (two segments sampled and added each cycle; the ramps made a minute long so the bench
/// stays inside the blend).
#[divan::bench(sample_count = 100, sample_size = 100)]
fn group_blending_4_axes(bencher: divan::Bencher) {
    use gantry_kernel::axis::handle::CommandStatus;
    use gantry_kernel::group::run::{BufferMode, GroupCmd, GroupMove, GroupPathKind, Transition};
    let mut k = group_kernel_at_rest();
    let slow = |target: [f64; 4], buffer| {
        GroupCmd::Move(GroupMove {
            path: GroupPathKind::Linear { target },
            relative: false,
            dynamics: gantry_kernel::path::PathLimits {
                v: 60.0,
                a: 1.0,
                d: 1.0,
                j: 1.0,
            },
            buffer,
            transition: Transition::CornerSuperimposed,
            corner_deviation: f64::INFINITY,
        })
    };
    k.group_command(0, slow([5000.0, 0.0, 0.0, 0.0], BufferMode::Aborting))
        .expect("move");
    let second = k
        .group_command(
            0,
            slow([5000.0, 5000.0, 100.0, 0.0], BufferMode::BlendingNext),
        )
        .expect("blend");
    while k.command_status(second) != CommandStatus::Active {
        k.step(&[]);
    }
    for _ in 0..100 {
        k.step(&[]);
    }
    bencher.bench_local(|| {
        divan::black_box(k.step(&[]));
    });
}

/// One cycle of a kernel whose four axes move with their group along a line: the cost of
/// a moving 4-axis group per cycle (compare `step` with 4 axes, each on its own PTP).
#[divan::bench]
fn group_moving_4_axes(bencher: divan::Bencher) {
    let mut k = group_kernel();
    bencher.bench_local(|| {
        divan::black_box(k.step(&[]));
    });
}

/// The planning cost of one group segment (`PathProfile::plan`: geometry, path limits
/// from the axes' limits, the S-curve along the path) over 2 000 random lines in 4 axes
/// and 2 000 random arcs (center mode, random radius and sweep) with random limits; the
/// fastest of 5 runs per segment; median / p99 / max.
fn path_planning_distribution() {
    use gantry_kernel::path::{AxisLimits, PathLimits, PathProfile, PathSegment};
    let mut r = XorShift(0x5eed_9a7e_0042_0017);
    let mut segments = Vec::new();
    for i in 0..4_000 {
        let from = [
            r.range(-100.0, 100.0),
            r.range(-100.0, 100.0),
            r.range(-100.0, 100.0),
            r.range(-100.0, 100.0),
        ];
        let seg = if i % 2 == 0 {
            let to = [
                r.range(-100.0, 100.0),
                r.range(-100.0, 100.0),
                r.range(-100.0, 100.0),
                r.range(-100.0, 100.0),
            ];
            PathSegment::line(from, to, 4)
        } else {
            random_arc(&mut r, from)
        };
        let limits = random_axis_limits(&mut r);
        if let Ok(seg) = seg {
            segments.push((seg, limits));
        }
    }
    let cmd = PathLimits {
        v: 150.0,
        a: f64::INFINITY,
        d: f64::INFINITY,
        j: f64::INFINITY,
    };
    let time = |segments: &[(PathSegment, Vec<AxisLimits>)]| {
        let mut ns: Vec<u64> = segments
            .iter()
            .map(|(seg, lim)| {
                (0..5)
                    .map(|_| {
                        let t = std::time::Instant::now();
                        let p = divan::black_box(PathProfile::plan(*seg, lim, &cmd));
                        let e = t.elapsed().as_nanos() as u64;
                        assert!(p.is_ok(), "{p:?}");
                        e
                    })
                    .min()
                    .unwrap_or(0)
            })
            .collect();
        ns.sort_unstable();
        let q = |f: f64| ns[((ns.len() - 1) as f64 * f) as usize];
        (q(0.5), q(0.99), ns[ns.len() - 1])
    };
    let _ = time(&segments);
    let all = time(&segments);
    let lines: Vec<_> = segments.iter().step_by(2).cloned().collect();
    let arcs: Vec<_> = segments.iter().skip(1).step_by(2).cloned().collect();
    let (l, a) = (time(&lines), time(&arcs));
    println!(
        "group segment planning over {} random segments, fastest of 5 runs each (ns): \
         median / p99 / max",
        segments.len()
    );
    println!("  all        {:>7} / {:>7} / {:>7}", all.0, all.1, all.2);
    println!("  lines      {:>7} / {:>7} / {:>7}", l.0, l.1, l.2);
    println!("  arcs       {:>7} / {:>7} / {:>7}", a.0, a.1, a.2);
}

/// The planning cost of a blended segment: the next segment planned from rest
/// (`PathProfile::plan`) and the corner decided (`PathProfile::blend_into`: the fastest
/// transit speed the axes, both lengths and the allowed deviation permit, the running
/// segment's rest planned again to reach it) — over 2 000 random pairs (a line in 4 axes,
/// then a line or an arc from its end), random limits, deviation 1; the fastest of 5 runs
/// per pair; median / p99 / max, and how many pairs were blended.
fn blend_planning_distribution() {
    use gantry_kernel::path::{PathLimits, PathProfile, PathSegment, Transition};
    let mut r = XorShift(0x0b1e_9d00_c0de_0042);
    let cmd = PathLimits {
        v: 150.0,
        a: f64::INFINITY,
        d: f64::INFINITY,
        j: f64::INFINITY,
    };
    let mut pairs = Vec::new();
    for i in 0..2_000 {
        let mut point = || {
            [
                r.range(-100.0, 100.0),
                r.range(-100.0, 100.0),
                r.range(-100.0, 100.0),
                r.range(-100.0, 100.0),
            ]
        };
        let (a, b, c) = (point(), point(), point());
        let first = PathSegment::line(a, b, 4).expect("line");
        let second = if i % 2 == 0 {
            PathSegment::line(b, c, 4)
        } else {
            random_arc(&mut r, b)
        };
        let limits = random_axis_limits(&mut r);
        if let (Ok(p), Ok(second)) = (PathProfile::plan(first, &limits, &cmd), second) {
            pairs.push((p, second, limits));
        }
    }
    let mut blended = 0;
    let mut ns: Vec<u64> = pairs
        .iter()
        .map(|(p, second, lim)| {
            let mut got = None;
            let e = (0..5)
                .map(|_| {
                    let mut first = *p;
                    let t = std::time::Instant::now();
                    let mut next = PathProfile::plan(*second, lim, &cmd).expect("plan");
                    let c = first.blend_into(
                        &mut next,
                        0.0,
                        150.0,
                        lim,
                        Transition::CornerSuperimposed,
                        1.0,
                    );
                    let e = t.elapsed().as_nanos() as u64;
                    got = divan::black_box(c);
                    e
                })
                .min()
                .unwrap_or(0);
            blended += usize::from(got.is_some());
            e
        })
        .collect();
    ns.sort_unstable();
    let q = |f: f64| ns[((ns.len() - 1) as f64 * f) as usize];
    println!(
        "blended segment planning (plan + corner) over {} random pairs, {} blended, fastest \
         of 5 runs each (ns): median {} / p99 {} / max {}",
        ns.len(),
        blended,
        q(0.5),
        q(0.99),
        ns[ns.len() - 1]
    );
}

/// A counter-clockwise arc in axes 0 and 1 from `from` (center mode): random radius
/// 1–50, start angle and sweep 0.1–6 rad.
fn random_arc(
    r: &mut XorShift,
    from: [f64; 4],
) -> Result<gantry_kernel::path::PathSegment, gantry_kernel::path::SegmentError> {
    use gantry_kernel::path::{CircAxes, CircMode, PathChoice, PathSegment};
    let radius = r.range(1.0, 50.0);
    let a0 = r.range(0.0, std::f64::consts::TAU);
    let sweep = r.range(0.1, 6.0);
    let center = [from[0] - radius * a0.cos(), from[1] - radius * a0.sin()];
    let end = [
        center[0] + radius * (a0 + sweep).cos(),
        center[1] + radius * (a0 + sweep).sin(),
    ];
    let circ = CircAxes::new(0, 1, 4)?;
    PathSegment::circular_2d(
        from,
        4,
        circ,
        center,
        end,
        CircMode::Center,
        PathChoice::Ccw,
    )
}

/// Random limits of four axes.
fn random_axis_limits(r: &mut XorShift) -> Vec<gantry_kernel::path::AxisLimits> {
    (0..4)
        .map(|_| gantry_kernel::path::AxisLimits {
            vmax: r.range(10.0, 200.0),
            amax: r.range(100.0, 2000.0),
            jmax: r.range(1_000.0, 50_000.0),
        })
        .collect()
}
