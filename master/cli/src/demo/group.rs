//! The axis group of `gantry demo` (EtherCAT), seed 004's example: x and y as the group
//! `xy` (the demo configuration's `[[group]]`) trace a rounded rectangle, 200 × 120 mm
//! with corners of radius 20 mm — four lines (MC_MoveLinear) and four arcs
//! (MC_MoveCircular2D in Center mode, each tangent to the lines beside it). The group
//! goes from home to the rectangle's start corner, the first side starts the rectangle
//! and the other seven are queued while the group moves, each BlendingNext with its
//! corner superimposed within [`CORNER_DEVIATION`]; then the group goes home and is
//! disabled.
//!
//! The demo checks every cycle ([`GroupCheck`]) that x and y stay within their limits
//! ([`within_limits`], the rule the synchronised axes are held to), that on the rectangle
//! the path stays within the corner deviation the kernel reports of the ideal rounded
//! rectangle, and that the group comes to rest exactly where the script sends it: at the
//! start corner after the approach and after the rectangle, home at the end (within
//! [`REST_BOUND`]).

use std::io::Write;

use gantry::config::Config;
use gantry_kernel::group::run::{BufferMode, GroupCmd, GroupMove, GroupPathKind, Transition};
use gantry_kernel::path::{CircMode, PathChoice, PathLimits, MAX_AXES};
use gantry_kernel::profile::Limits;
use gantry_kernel::Kernel;

use super::limits::within_limits;
use super::{group_step, DemoError, Step, Wait};

/// The group's name in the demo's configuration.
pub const GROUP: &str = "xy";
/// Its axes, A0 first.
pub const AXES: [&str; 2] = ["x", "y"];
/// How far a superimposed corner may pass from the corner (mm); the configuration's
/// `corner_deviation` of the group says the same, the moves name it anyway.
pub const CORNER_DEVIATION: f64 = 0.5;
/// The rectangle: its width and height (mm) from (0, 0), and its corners' radius.
pub const WIDTH: f64 = 200.0;
/// Its height (mm).
pub const HEIGHT: f64 = 120.0;
/// Its corners' radius (mm).
pub const RADIUS: f64 = 20.0;
/// Where the rectangle starts and ends: the start of its bottom side.
pub const START: [f64; 2] = [RADIUS, 0.0];
/// How far from where the script sends it the group may come to rest (mm): the kernel
/// ends a segment on its end point, so only rounding.
pub const REST_BOUND: f64 = 1e-9;

/// Path velocity (mm/s), acceleration and deceleration (mm/s²) and jerk (mm/s³).
const PATH: PathLimits = PathLimits {
    v: 150.0,
    a: 1000.0,
    d: 1000.0,
    j: 20_000.0,
};

/// How long the group stands on the start corner before and after the rectangle (s), so
/// the time plots show where the rectangle begins and ends.
const PAUSE_S: f64 = 0.1;

/// The labels of the rectangle's eight moves, in order.
const SIDES: [&str; 8] = [
    "xy-1", "xy-2", "xy-3", "xy-4", "xy-5", "xy-6", "xy-7", "xy-8",
];

/// A line to `(x, y)`.
const fn line(x: f64, y: f64) -> GroupPathKind {
    let mut target = [0.0; MAX_AXES];
    target[0] = x;
    target[1] = y;
    GroupPathKind::Linear { target }
}

/// A counter-clockwise arc about `center` to `end`.
const fn arc(center: [f64; 2], end: [f64; 2]) -> GroupPathKind {
    GroupPathKind::Circular {
        circ: (0, 1),
        aux: center,
        end,
        mode: CircMode::Center,
        choice: PathChoice::Ccw,
    }
}

/// The rounded rectangle from [`START`], counter-clockwise: bottom, right, top and left
/// side, each followed by the corner after it.
pub fn rectangle() -> [GroupPathKind; 8] {
    let (w, h, r) = (WIDTH, HEIGHT, RADIUS);
    [
        line(w - r, 0.0),
        arc([w - r, r], [w, r]),
        line(w, h - r),
        arc([w - r, h - r], [w - r, h]),
        line(r, h),
        arc([r, h - r], [0.0, h - r]),
        line(0.0, r),
        arc([r, r], START),
    ]
}

/// A move along `path` joining the running one as `buffer` says, corners superimposed
/// within [`CORNER_DEVIATION`] where it blends.
const fn motion(path: GroupPathKind, buffer: BufferMode) -> GroupCmd {
    let blended = !matches!(buffer, BufferMode::Aborting | BufferMode::Buffered);
    GroupCmd::Move(GroupMove {
        path,
        relative: false,
        dynamics: PATH,
        buffer,
        transition: if blended {
            Transition::CornerSuperimposed
        } else {
            Transition::None
        },
        corner_deviation: if blended {
            CORNER_DEVIATION
        } else {
            f64::INFINITY
        },
    })
}

/// Appends the group's steps to the EtherCAT demo's `steps`: once x and y are home at
/// the end of their own moves, the group is enabled and runs the rectangle; nothing of
/// the other axes waits for it.
pub fn insert(steps: &mut Vec<Step>) {
    steps.push(group_step(
        Wait::DoneAll(&["x-zero", "y-zero"]),
        GROUP,
        GroupCmd::Enable,
        "xy-on",
        "xy: x and y as an axis group (MC_GroupEnable); MoveLinear to the start corner (20, 0)",
    ));
    steps.push(group_step(
        Wait::Done("xy-on"),
        GROUP,
        motion(line(START[0], START[1]), BufferMode::Aborting),
        "xy-start",
        "",
    ));
    for (k, (path, label)) in rectangle().into_iter().zip(SIDES).enumerate() {
        let (wait, buffer, says) = match k {
            0 => (
                Wait::DoneFor("xy-start", PAUSE_S),
                BufferMode::Aborting,
                "xy: a rounded rectangle 200 × 120 mm, corners of radius 20 mm: 4 MoveLinear \
                 and 4 MoveCircular2D (center), the 7 after the first queued while the group \
                 moves, BlendingNext with the corners superimposed within 0.5 mm",
            ),
            _ => (Wait::Now, BufferMode::BlendingNext, ""),
        };
        steps.push(group_step(wait, GROUP, motion(path, buffer), label, says));
    }
    steps.push(group_step(
        Wait::DoneFor("xy-8", PAUSE_S),
        GROUP,
        motion(line(0.0, 0.0), BufferMode::Aborting),
        "xy-home",
        "xy: MoveLinear home (0, 0), then MC_GroupDisable",
    ));
    steps.push(group_step(
        Wait::Done("xy-home"),
        GROUP,
        GroupCmd::Disable,
        "xy-off",
        "",
    ));
}

/// Distance from `p` to the ideal rounded rectangle of [`rectangle`].
fn off_rectangle(p: [f64; 2]) -> f64 {
    let (w, h, r) = (WIDTH, HEIGHT, RADIUS);
    let side = |a: [f64; 2], b: [f64; 2]| {
        let d = [b[0] - a[0], b[1] - a[1]];
        let t = (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1]))
            .clamp(0.0, 1.0);
        (p[0] - a[0] - t * d[0]).hypot(p[1] - a[1] - t * d[1])
    };
    let sides = [
        side([r, 0.0], [w - r, 0.0]),
        side([w, r], [w, h - r]),
        side([w - r, h], [r, h]),
        side([0.0, h - r], [0.0, r]),
    ];
    // Each corner's quarter circle, where the point lies in its quadrant.
    let corners = [
        ([w - r, r], [1.0, -1.0]),
        ([w - r, h - r], [1.0, 1.0]),
        ([r, h - r], [-1.0, 1.0]),
        ([r, r], [-1.0, -1.0]),
    ];
    let arcs = corners.iter().filter_map(|(c, q)| {
        let inside = (p[0] - c[0]) * q[0] >= 0.0 && (p[1] - c[1]) * q[1] >= 0.0;
        inside.then(|| ((p[0] - c[0]).hypot(p[1] - c[1]) - r).abs())
    });
    sides.into_iter().chain(arcs).fold(f64::INFINITY, f64::min)
}

/// One axis of the group as the check sees it.
#[derive(Clone, Debug)]
struct Member {
    axis: usize,
    name: String,
    max: Limits,
}

/// The demo's check of its axis group, every cycle (see the module doc).
#[derive(Clone, Debug)]
pub struct GroupCheck {
    /// The group's kernel index.
    group: usize,
    members: [Member; 2],
    /// Where the group must come to rest, in order.
    rests: Vec<[f64; 2]>,
    /// How many of them it has reached.
    reached: usize,
    /// Whether it drove its axes last cycle.
    moving: bool,
    /// The first and last time it drove its axes (s).
    span: Option<(f64, f64)>,
    /// Largest distance between where it came to rest and where it was sent (mm).
    worst_rest: f64,
    /// Its blends' figures at the last cycle.
    corners: gantry_kernel::group::run::CornerReport,
    /// Largest distance of the path from the ideal rounded rectangle while on it (mm).
    worst_off: f64,
}

impl GroupCheck {
    /// The group [`GROUP`] of `config` (the demo's), of the axes [`AXES`].
    pub fn of_config(config: &Config) -> Result<Self, DemoError> {
        let group = config
            .groups
            .iter()
            .position(|g| g.name == GROUP)
            .ok_or(DemoError::Script(GROUP))?;
        let member = |logical: usize| -> Result<Member, DemoError> {
            let name = AXES[logical];
            let axis = config
                .axes
                .iter()
                .position(|a| a.name == name)
                .ok_or(DemoError::Script(name))?;
            if config.groups[group].axes.get(logical) != Some(&axis) {
                return Err(DemoError::Script("xy: not the group of x and y"));
            }
            let max = config
                .kernel_axes
                .get(axis)
                .ok_or(DemoError::Script(name))?
                .max;
            Ok(Member {
                axis,
                name: name.to_string(),
                max,
            })
        };
        Ok(Self {
            group,
            members: [member(0)?, member(1)?],
            rests: vec![START, START, [0.0, 0.0]],
            reached: 0,
            moving: false,
            span: None,
            worst_rest: 0.0,
            corners: Default::default(),
            worst_off: 0.0,
        })
    }

    /// The kernel indices of the group's axes, A0 first.
    pub fn axes(&self) -> [usize; 2] {
        [self.members[0].axis, self.members[1].axis]
    }

    /// The first and last time the group drove its axes (s), once it has.
    pub fn span(&self) -> Option<(f64, f64)> {
        self.span
    }

    /// One cycle of `kernel` at `time_s`: fails on a set value of x or y beyond its
    /// limits, or on the group coming to rest elsewhere than the script sent it.
    pub fn observe(&mut self, kernel: &Kernel, time_s: f64) -> Result<(), DemoError> {
        let mut at = [0.0; 2];
        for (m, p) in self.members.iter().zip(&mut at) {
            let s = kernel
                .axis_status(m.axis)
                .ok_or(DemoError::Script("xy: an axis not in the kernel"))?;
            within_limits(&m.name, s, &m.max, time_s)?;
            *p = s.set.p;
        }
        let group = kernel
            .groups()
            .get(self.group)
            .ok_or(DemoError::Script("xy: not in the kernel"))?;
        self.corners = group.corners();
        let moving = group.drives_axes();
        // On the rectangle (after the approach came to rest, until the rectangle ends):
        // never farther from it than the corners' reported bound.
        if self.reached == 1 {
            let off = off_rectangle(at);
            self.worst_off = self.worst_off.max(off);
            let bound = self.corners.max_deviation;
            if off > bound + 1e-9 {
                return Err(DemoError::Fault(format!(
                    "xy at ({:.6}, {:.6}) at t = {time_s:.3} s is {off:.3e} mm off the rounded \
                     rectangle, beyond the corner deviation the kernel reports ({bound:.3e} mm)",
                    at[0], at[1]
                )));
            }
        }
        if moving {
            let (first, _) = self.span.unwrap_or((time_s, time_s));
            self.span = Some((first, time_s));
        }
        if self.moving && !moving {
            let Some(&sent) = self.rests.get(self.reached) else {
                return Err(DemoError::Fault(format!(
                    "xy came to rest at ({:.6}, {:.6}) at t = {time_s:.3} s, more often than \
                     the script sends it",
                    at[0], at[1]
                )));
            };
            let off = (at[0] - sent[0]).hypot(at[1] - sent[1]);
            self.worst_rest = self.worst_rest.max(off);
            if off > REST_BOUND {
                return Err(DemoError::Fault(format!(
                    "xy came to rest at ({:.9}, {:.9}) at t = {time_s:.3} s, {off:.3e} mm from \
                     ({}, {}) where the script sent it",
                    at[0], at[1], sent[0], sent[1]
                )));
            }
            self.reached += 1;
        }
        self.moving = moving;
        Ok(())
    }

    /// After the run: where the group came to rest and what its blends did; fails if it
    /// did not come to rest at each place the script sent it.
    pub fn said(&self, out: &mut dyn Write) -> Result<(), DemoError> {
        if self.reached != self.rests.len() {
            return Err(DemoError::Fault(format!(
                "xy came to rest {} times of {}: the rectangle did not run to its end",
                self.reached,
                self.rests.len()
            )));
        }
        let c = &self.corners;
        let _ = writeln!(
            out,
            ">> xy: the rounded rectangle ended on its start corner ({}, {}) and the group \
             at home, each within {:.1e} mm; x and y within their limits all along; {} \
             corners passed in motion, each within {:.3} mm of its corner by the kernel's \
             bound (allowed {CORNER_DEVIATION}; the path came at most {:.3} mm off the \
             ideal rectangle), the last at {:.1} mm/s",
            START[0],
            START[1],
            self.worst_rest,
            c.blends,
            c.max_deviation,
            self.worst_off,
            c.last_transit_speed,
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_kernel::axis::command::{Command, PowerCommand};
    use gantry_kernel::AxisKind;

    /// The demo's configuration as the demo loads it (written with the files beside it,
    /// its cam table among them, to a folder of this test's own).
    fn config(tag: &str) -> Config {
        let dir =
            std::env::temp_dir().join(format!("gantry-demo-group-{tag}-{}", std::process::id()));
        let config =
            super::super::ethercat::write_config(&dir, super::super::ethercat::SERVOS_TOML, None)
                .expect("the demo's configuration");
        let _ = std::fs::remove_dir_all(&dir);
        config
    }

    /// A kernel of the demo configuration's axes (simulated: actual = set, no drive) and
    /// its groups, x and y enabled and at 0.
    fn kernel(config: &Config) -> Kernel {
        let axes = config
            .kernel_axes
            .iter()
            .cloned()
            .map(|mut a| {
                (a.kind, a.homing_required) = (AxisKind::Simulated, false);
                a
            })
            .collect();
        let mut k = Kernel::new(f64::from(config.bus.cycle_us) * 1e-6, axes).unwrap();
        for g in &config.groups {
            k.add_group(g.clone()).unwrap();
        }
        for a in AXES {
            let i = k.axis_index(a).unwrap();
            k.command(i, Command::Power(PowerCommand::Enable)).unwrap();
            k.step(&[]);
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
        k
    }

    /// The group's steps of the demo's script straight into `k`, each when the one it
    /// waits for is done, the check watching every cycle.
    fn run(k: &mut Kernel, check: &mut GroupCheck, steps: &[Step]) -> Result<(), DemoError> {
        let mut handles = Vec::new();
        for s in steps {
            let super::super::Order::Group(cmd) = s.command else {
                panic!("{s:?}");
            };
            let (waits, pause): (&[&str], f64) = match s.wait {
                Wait::Done(label) => (&[label][..], 0.0),
                Wait::DoneAll(labels) => (labels, 0.0),
                Wait::DoneFor(label, seconds) => (&[label][..], seconds),
                _ => (&[], 0.0),
            };
            let mut done_at = None;
            for _ in 0..100_000 {
                let done = waits.iter().all(|w| {
                    handles
                        .iter()
                        .find(|(l, _)| l == w)
                        .is_none_or(|&(_, h)| k.command_status(h).is_final())
                });
                if done {
                    let t = *done_at.get_or_insert(k.time());
                    if k.time() - t >= pause - 1e-9 {
                        break;
                    }
                }
                k.step(&[]);
                check.observe(k, k.time())?;
            }
            handles.push((s.label, k.group_command(check.group, cmd).unwrap()));
        }
        for _ in 0..1000 {
            k.step(&[]);
            check.observe(k, k.time())?;
        }
        Ok(())
    }

    /// Where a segment ends.
    fn end(path: &GroupPathKind) -> [f64; 2] {
        match *path {
            GroupPathKind::Linear { target } => [target[0], target[1]],
            GroupPathKind::Circular { end, .. } => end,
        }
    }

    #[test]
    fn the_rectangle_is_closed_and_each_arc_is_tangent_to_the_lines_beside_it() {
        let sides = rectangle();
        let mut from = START;
        for (k, path) in sides.iter().enumerate() {
            let to = end(path);
            match *path {
                GroupPathKind::Linear { .. } => {
                    // Lines are axis-parallel: one coordinate stays.
                    assert!(from[0] == to[0] || from[1] == to[1], "side {k}");
                }
                GroupPathKind::Circular { aux: c, mode, .. } => {
                    assert_eq!(mode, CircMode::Center);
                    let r0 = (from[0] - c[0]).hypot(from[1] - c[1]);
                    let r1 = (to[0] - c[0]).hypot(to[1] - c[1]);
                    assert!((r0 - RADIUS).abs() < 1e-12 && (r1 - RADIUS).abs() < 1e-12);
                    // Tangent: the radius at each end is perpendicular to the line there
                    // (the line before ends where the arc starts, the one after starts
                    // where it ends; the lines are axis-parallel, so exactly).
                    let before = if k == 1 { START } else { end(&sides[k - 2]) };
                    let after = end(&sides[(k + 1) % 8]);
                    let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
                    let along_in = [from[0] - before[0], from[1] - before[1]];
                    let along_out = [after[0] - to[0], after[1] - to[1]];
                    assert_eq!(dot(along_in, [from[0] - c[0], from[1] - c[1]]), 0.0, "{k}");
                    assert_eq!(dot(along_out, [to[0] - c[0], to[1] - c[1]]), 0.0, "{k}");
                }
            }
            from = to;
        }
        assert_eq!(from, START);
    }

    #[test]
    fn the_group_steps_come_after_every_other_step_and_queue_the_sides_blended() {
        let mut steps = super::super::ethercat::motion_script();
        let others = steps.len();
        insert(&mut steps);
        let group: Vec<&Step> = steps[others..].iter().collect();
        assert!(group.iter().all(|s| s.axis == GROUP));
        assert_eq!(group[0].wait, Wait::DoneAll(&["x-zero", "y-zero"]));
        let sides: Vec<&Step> = group
            .iter()
            .copied()
            .filter(|s| SIDES.contains(&s.label))
            .collect();
        assert_eq!(sides.len(), 8);
        for (k, s) in sides.iter().enumerate() {
            let super::super::Order::Group(GroupCmd::Move(m)) = s.command else {
                panic!("{s:?}");
            };
            if k == 0 {
                assert_eq!(s.wait, Wait::DoneFor("xy-start", PAUSE_S));
                assert_eq!(m.buffer, BufferMode::Aborting);
            } else {
                assert_eq!(s.wait, Wait::Now, "{}", s.label);
                assert_eq!(
                    (m.buffer, m.transition, m.corner_deviation),
                    (
                        BufferMode::BlendingNext,
                        Transition::CornerSuperimposed,
                        CORNER_DEVIATION
                    )
                );
            }
        }
    }

    #[test]
    fn the_check_follows_the_rectangle_to_its_start_corner_and_fails_a_group_sent_elsewhere() {
        let config = config("check");
        assert_eq!(
            config.group_defaults[0].corner_deviation, CORNER_DEVIATION,
            "the configuration's default is the moves' deviation"
        );
        let mut steps = Vec::new();
        insert(&mut steps);
        let mut k = kernel(&config);
        let mut check = GroupCheck::of_config(&config).unwrap();
        assert_eq!(check.axes(), [0, 1]);
        run(&mut k, &mut check, &steps).unwrap();
        let mut out = Vec::new();
        check.said(&mut out).unwrap();
        let said = String::from_utf8(out).unwrap();
        assert!(
            said.starts_with(
                ">> xy: the rounded rectangle ended on its start corner (20, 0) and the group \
                 at home, each within "
            ),
            "{said}"
        );
        let (from, to) = check.span().unwrap();
        // 600 mm of path at 150 mm/s at most, and the approach and the way home.
        assert!(to - from > 600.0 / 150.0, "{from}..{to}");
        // The rectangle's last corner cut short half-way round: on the rectangle all
        // along, the group comes to rest elsewhere, and the check says where and where it
        // was sent.
        let half = RADIUS - RADIUS * std::f64::consts::FRAC_1_SQRT_2;
        let run_with_last = |last: GroupPathKind| {
            let mut changed = steps.clone();
            let s = changed.iter_mut().find(|s| s.label == "xy-8").unwrap();
            s.command = super::super::Order::Group(motion(last, BufferMode::BlendingNext));
            let mut k = kernel(&config);
            let mut check = GroupCheck::of_config(&config).unwrap();
            run(&mut k, &mut check, &changed).unwrap_err().to_string()
        };
        let e = run_with_last(arc([RADIUS, RADIUS], [half, half]));
        assert!(
            e.starts_with(
                "the demo stopped: xy came to rest at (5.857864376, 5.857864376) at t = "
            ) && e.ends_with(" mm from (20, 0) where the script sent it"),
            "{e}"
        );
        // Its left side going on straight down to (0, 10) instead: off the rectangle by
        // more than any corner's bound.
        let e = run_with_last(line(0.0, 10.0));
        assert!(
            e.starts_with("the demo stopped: xy at (0.000000, ")
                && e.contains("mm off the rounded rectangle, beyond the corner deviation"),
            "{e}"
        );
        // Stopped halfway: the rectangle did not run to its end, and the check says so.
        let mut k = kernel(&config);
        let mut check = GroupCheck::of_config(&config).unwrap();
        run(&mut k, &mut check, &steps[..2]).unwrap();
        let e = check.said(&mut Vec::new()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the demo stopped: xy came to rest 1 times of 3: the rectangle did not run to its end"
        );
    }
}
