//! The synchronised motion of `gantry demo` (EtherCAT): a virtual master `m` (a line
//! shaft in degrees, no drive) turns forward, reverses and stops; three real axes on
//! simulated servos follow it — `g1` geared 1:1 and `g2` geared −1:2 (GearIn with
//! catch-up while the master turns), `ram` cammed on `eccentric.toml` (the stroke of an
//! eccentric press, periodic over one turn of `m`) — then gear and cam out and go home.
//!
//! The demo checks every cycle, from the kernel's own status, that each follower stayed
//! on its law while in sync — its set position against the ideal ratio or the table
//! evaluated independently of the kernel's relation — and that no follower's set speed or
//! acceleration went beyond its maximum ([`SyncCheck`]); its actual position (what the
//! simulated drive's encoder reports) is held against the same ideal within
//! [`ACTUAL_BOUND`].

use std::io::Write;

use gantry::config::Config;
use gantry_kernel::axis::command::{
    Command, HaltMode, MoveDirection, MovePtp, MoveVelocity, PositioningMode, PowerCommand,
};
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisStatus;
use gantry_kernel::cam::CamTable;
use gantry_kernel::profile::Limits;
use gantry_kernel::sync::command::{CamIn, GearIn};
use gantry_kernel::Kernel;

use super::limits::within_limits;
use super::{step, DemoError, Step, Wait};

/// The cam table, written to the output folder as [`CAM_FILE`] and loaded from there
/// (a copy of `deploy/cams/eccentric.toml`).
pub const CAM_TOML: &str = include_str!("eccentric.toml");
/// Its file name in the output folder.
pub const CAM_FILE: &str = "eccentric.toml";
/// Its name in the demo's configuration (`[[cam]]`).
pub const CAM_NAME: &str = "press";
/// The kernel's cam slot it is in (the configuration's first `[[cam]]`).
pub const CAM_SLOT: usize = 0;

/// The demo's cam table as its configuration loaded it, in [`CAM_SLOT`].
pub fn configured_cam(config: &Config) -> Result<&gantry::config::CamConfig, DemoError> {
    config
        .cams
        .iter()
        .find(|c| c.name == CAM_NAME && c.slot == CAM_SLOT)
        .ok_or(DemoError::NoCam {
            name: CAM_NAME,
            slot: CAM_SLOT,
        })
}
/// The master's name and its index in the demo's configuration (GearIn and CamIn name
/// their master by index; [`SyncCheck::of_config`] checks that it is `m`).
pub const MASTER: (&str, usize) = ("m", 3);
/// The geared followers: name, numerator, denominator.
pub const GEARS: [(&str, i32, u32); 2] = [("g1", 1, 1), ("g2", -1, 2)];
/// The cammed follower.
pub const CAM_FOLLOWER: &str = "ram";

/// How far a follower's set position may be from its law while in sync (units): the
/// kernel computes it in closed form from the master's position, so only rounding is
/// allowed.
pub const SET_BOUND: f64 = 1e-6;
/// How far its actual position may be from the law [`ACTUAL_DELAY_CYCLES`] earlier while
/// in sync (units: ° for the gears, mm for the ram): the simulated servo's lag behind its
/// target with velocity feed-forward, at most 0.023° and 0.0005 mm in this demo; a drive
/// that lost its load or a target that jumped would be far beyond.
pub const ACTUAL_BOUND: f64 = 0.05;
/// The actual position the kernel has in a cycle answers the set position of two or three
/// cycles before (the set value leaves with one frame, the drive takes it at a following
/// SYNC0, its encoder value comes back with a later frame). Measured on the demo's chain:
/// three cycles in one run, two in another whose slaves reached OP at another cycle; the
/// actual matches the law of that many cycles back to 0.023° at 360°/s and misses the
/// others by a cycle's travel (0.36°). The check takes the nearer of the two.
pub const ACTUAL_DELAY_CYCLES: std::ops::RangeInclusive<usize> = 2..=3;
/// The longest delay (the laws kept).
const MAX_DELAY: usize = 3;
/// Cycles in sync (0.1 s) before the actual position is judged: the catching up ends with
/// the follower decelerating onto the law, and the simulated servo (velocity feed-forward,
/// no torque feed-forward) comes out of it up to a cycle's travel behind (0.18° at 180°/s).
pub const SETTLE_CYCLES: u64 = 100;

/// Master speed while the followers couple (°/s): one turn a second.
const MASTER_SPEED: f64 = 360.0;

/// Inserts the synchronised steps into the EtherCAT demo's `steps`, each where it waits
/// for nothing the other axes' steps do not already wait for: the sequence of x, y and c
/// keeps its timing.
pub fn insert(steps: &mut Vec<Step>) {
    let (m, master) = MASTER;
    let [(g1, n1, d1), (g2, n2, d2)] = GEARS;
    let ram = CAM_FOLLOWER;
    let enable = Command::Power(PowerCommand::Enable);
    let set = |position| Command::SetPosition {
        position,
        relative: false,
    };
    let velocity = |direction, speed| Command::MoveVelocity(MoveVelocity::new(direction, speed));
    // After c is homed (x still homing, for about 1.5 s): enable, reference, the master
    // turning, the followers coupling in while it turns.
    put(
        steps,
        "c-home",
        [
            step(
                Wait::Now,
                m,
                enable,
                "m-on",
                "m (virtual, no drive), g1, g2, ram: enable; g1, g2 = 0°, ram = 0 mm",
            ),
            step(Wait::Now, g1, enable, "g1-on", ""),
            step(Wait::Now, g2, enable, "g2-on", ""),
            step(Wait::Now, ram, enable, "ram-on", ""),
            step(Wait::Done("g1-on"), g1, set(0.0), "g1-home", ""),
            step(Wait::Done("g2-on"), g2, set(0.0), "g2-home", ""),
            step(Wait::Done("ram-on"), ram, set(0.0), "ram-home", ""),
            step(
                Wait::Done("m-on"),
                m,
                velocity(MoveDirection::Positive, MASTER_SPEED),
                "m-vel",
                "m: MoveVelocity +360°/s (S-curve)",
            ),
            step(
                Wait::Seconds(0.6),
                g1,
                Command::GearIn(GearIn::new(master, n1, d1)),
                "g1-gear",
                "g1: GearIn 1:1, g2: GearIn -1:2 on m, catching up while m turns (InGear once \
                 the velocities match); ram: CamIn eccentric.toml, periodic, absolute (catches \
                 up onto the table)",
            ),
            step(
                Wait::Now,
                g2,
                Command::GearIn(GearIn::new(master, n2, d2)),
                "g2-gear",
                "",
            ),
            step(
                Wait::Now,
                ram,
                Command::CamIn(CamIn::new(master, CAM_SLOT, true)),
                "ram-cam",
                "",
            ),
        ],
    );
    // When x has done its first move (about 3 s): the master reverses.
    put_before(
        steps,
        "x-rel",
        [step(
            Wait::Done("x-ptp"),
            m,
            velocity(MoveDirection::Negative, MASTER_SPEED / 2.0),
            "m-back",
            "m: MoveVelocity -180°/s: the followers reverse with it, in gear and on the cam",
        )],
    );
    // When x has halted: the master stops.
    put_before(
        steps,
        "x-zero",
        [step(
            Wait::Done("x-halt"),
            m,
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: None,
            },
            "m-halt",
            "m: Halt (the followers stop with it)",
        )],
    );
    // At the end: out of gear and cam, every synchronised axis home.
    steps.extend([
        step(
            Wait::Done("m-halt"),
            g1,
            Command::GearOut,
            "g1-out",
            "g1, g2: GearOut, ram: CamOut; m, g1, g2 to 0° the short way, ram to 0 mm",
        ),
        step(Wait::Now, g2, Command::GearOut, "g2-out", ""),
        step(Wait::Now, ram, Command::CamOut, "ram-out", ""),
        step(
            Wait::Now,
            m,
            ptp(PositioningMode::AbsModuloAuto, 0.0),
            "m-zero",
            "",
        ),
        step(
            Wait::Done("g1-out"),
            g1,
            ptp(PositioningMode::AbsModuloAuto, 0.0),
            "g1-zero",
            "",
        ),
        step(
            Wait::Done("g2-out"),
            g2,
            ptp(PositioningMode::AbsModuloAuto, 0.0),
            "g2-zero",
            "",
        ),
        step(
            Wait::Done("ram-out"),
            ram,
            ptp(PositioningMode::AbsNormal, 0.0),
            "ram-zero",
            "",
        ),
    ]);
}

const fn ptp(mode: PositioningMode, target: f64) -> Command {
    Command::MovePtp(MovePtp::new(mode, target))
}

/// `new` right after the step labelled `after` (at the end if there is none).
fn put<const N: usize>(steps: &mut Vec<Step>, after: &str, new: [Step; N]) {
    let at = steps
        .iter()
        .position(|s| s.label == after)
        .map_or(steps.len(), |i| i + 1);
    steps.splice(at..at, new);
}

/// `new` right before the step labelled `before` (at the end if there is none).
fn put_before<const N: usize>(steps: &mut Vec<Step>, before: &str, new: [Step; N]) {
    let at = steps
        .iter()
        .position(|s| s.label == before)
        .unwrap_or(steps.len());
    steps.splice(at..at, new);
}

/// What a follower follows.
#[derive(Clone, Debug)]
enum Law {
    /// Follower travel = ratio · master travel, from where it got in gear.
    Gear { numerator: i32, denominator: u32 },
    /// Follower position = the table at the master's position (periodic, absolute, no
    /// offsets or scaling: as the demo's CamIn).
    Cam(Box<CamTable>),
}

/// One follower as the check sees it.
#[derive(Clone, Debug)]
struct Follower {
    axis: usize,
    name: String,
    law: Law,
    period: Option<f64>,
    max: Limits,
    /// Gears: master and follower position (unwrapped) when it got in gear.
    reference: Option<(f64, f64)>,
    /// Cycles it was in sync.
    in_sync: u64,
    /// Largest |set − law| and |actual − law| while in sync.
    worst_set: f64,
    worst_actual: f64,
    /// Largest |set velocity| and |set acceleration| over the whole run.
    peak_v: f64,
    peak_a: f64,
    /// The law's position this cycle and the [`MAX_DELAY`] before (newest first).
    laws: [f64; MAX_DELAY + 1],
}

/// The demo's check of its synchronised axes, every cycle (see the module doc).
#[derive(Clone, Debug)]
pub struct SyncCheck {
    master: usize,
    master_period: Option<f64>,
    followers: Vec<Follower>,
    /// Cycles between a set position and the actual that answers it (at most
    /// [`MAX_DELAY`]; on the demo's chain [`ACTUAL_DELAY_CYCLES`]).
    delays: std::ops::RangeInclusive<usize>,
}

impl SyncCheck {
    /// The master and followers of `config` (the demo's), `table` the ram's cam.
    pub fn of_config(config: &Config, table: CamTable) -> Result<Self, DemoError> {
        let index = |name: &'static str| {
            config
                .axes
                .iter()
                .position(|a| a.name == name)
                .ok_or(DemoError::Script(name))
        };
        let (m, master) = MASTER;
        if index(m)? != master {
            return Err(DemoError::Script("m: not the configuration's fourth axis"));
        }
        let mut laws: Vec<(&'static str, Law)> = GEARS
            .iter()
            .map(|&(name, numerator, denominator)| {
                (
                    name,
                    Law::Gear {
                        numerator,
                        denominator,
                    },
                )
            })
            .collect();
        laws.push((CAM_FOLLOWER, Law::Cam(Box::new(table))));
        let followers = laws
            .into_iter()
            .map(|(name, law)| {
                let axis = index(name)?;
                let k = config
                    .kernel_axes
                    .get(axis)
                    .ok_or(DemoError::Script(name))?;
                Ok(Follower {
                    axis,
                    name: name.to_string(),
                    law,
                    period: config.axes.get(axis).and_then(|a| a.modulo),
                    max: k.max,
                    reference: None,
                    in_sync: 0,
                    worst_set: 0.0,
                    worst_actual: 0.0,
                    peak_v: 0.0,
                    peak_a: 0.0,
                    laws: [0.0; MAX_DELAY + 1],
                })
            })
            .collect::<Result<_, DemoError>>()?;
        Ok(Self {
            master,
            master_period: config.axes.get(master).and_then(|a| a.modulo),
            followers,
            delays: ACTUAL_DELAY_CYCLES,
        })
    }

    /// The master's index and the followers' (the plot draws them apart): gears, cams.
    pub fn axes(&self) -> (usize, Vec<usize>, Vec<usize>) {
        let pick = |cam: bool| {
            self.followers
                .iter()
                .filter(|f| matches!(f.law, Law::Cam(_)) == cam)
                .map(|f| f.axis)
                .collect()
        };
        (self.master, pick(false), pick(true))
    }

    /// One cycle of `kernel` at `time_s`: fails on a follower off its law beyond the
    /// bounds while in sync, or a set value beyond its maximum.
    pub fn observe(&mut self, kernel: &Kernel, time_s: f64) -> Result<(), DemoError> {
        let Some(m) = kernel.axis_status(self.master).copied() else {
            return Err(DemoError::Script("m: not in the kernel"));
        };
        let mu = unwrapped(&m, self.master_period);
        for f in &mut self.followers {
            let Some(s) = kernel.axis_status(f.axis).copied() else {
                continue;
            };
            f.limits(&s, time_s)?;
            let synced = s.state == AxisState::SynchronizedMotion
                && s.bits.in_sync
                && s.master == Some(self.master);
            if !synced {
                f.reference = None;
                continue;
            }
            let fu = unwrapped(&s, f.period);
            let ideal = match &f.law {
                Law::Gear {
                    numerator,
                    denominator,
                } => {
                    let (m0, f0) = *f.reference.get_or_insert((mu, fu));
                    f0 + f64::from(*numerator) / f64::from(*denominator) * (mu - m0)
                }
                Law::Cam(table) => unrolled(table, mu),
            };
            let set_error = fu - ideal;
            // The actual position beside the set, the short way on a modulo axis.
            let lag = match f.period {
                Some(p) => (s.actual_position - s.set.p + p / 2.0).rem_euclid(p) - p / 2.0,
                None => s.actual_position - s.set.p,
            };
            // The actual against the law of a few cycles ago, once the drive has settled
            // from the catching up.
            f.laws.rotate_right(1);
            f.laws[0] = ideal;
            // The nearest of the laws `delays` cycles back.
            let (delay, then) = self
                .delays
                .clone()
                .filter_map(|d| f.laws.get(d).map(|&law| (d, law)))
                .min_by(|a, b| (fu + lag - a.1).abs().total_cmp(&(fu + lag - b.1).abs()))
                .unwrap_or((0, ideal));
            let actual_error = (f.in_sync >= SETTLE_CYCLES).then_some(fu + lag - then);
            f.in_sync += 1;
            f.worst_set = f.worst_set.max(set_error.abs());
            let actual_error = actual_error.unwrap_or(0.0);
            f.worst_actual = f.worst_actual.max(actual_error.abs());
            if set_error.abs() > SET_BOUND || actual_error.abs() > ACTUAL_BOUND {
                return Err(DemoError::Fault(format!(
                    "{} left its {} at t = {time_s:.3} s: set {fu:.6} against {ideal:.6} for m \
                     at {mu:.6}, actual {:.6} against {then:.6} {delay} cycles before (bounds \
                     {SET_BOUND} set, {ACTUAL_BOUND} actual)",
                    f.name,
                    f.law_name(),
                    fu + lag,
                )));
            }
        }
        Ok(())
    }

    /// After the run: each follower's figures; fails if one was never in sync long enough
    /// for the check to mean something (a second).
    pub fn said(&self, cycle_s: f64, out: &mut dyn Write) -> Result<(), DemoError> {
        for f in &self.followers {
            let seconds = f.in_sync as f64 * cycle_s;
            if seconds < 1.0 {
                return Err(DemoError::Fault(format!(
                    "{} was in sync with m for {seconds:.3} s only",
                    f.name
                )));
            }
            let unit = if f.period.is_some() { "°" } else { " mm" };
            let _ = writeln!(
                out,
                ">> {}: on its {} for {seconds:.3} s: set within {:.1e}{unit} of it, actual \
                 within {:.4}{unit} of it {}..{} cycles before; peak speed {:.1} \
                 of {:.0}, peak acceleration {:.0} of {:.0}",
                f.name,
                f.law_name(),
                f.worst_set,
                f.worst_actual,
                self.delays.start(),
                self.delays.end(),
                f.peak_v,
                f.max.vmax,
                f.peak_a,
                f.max.amax.max(f.max.dmax),
            );
        }
        Ok(())
    }
}

impl Follower {
    fn law_name(&self) -> String {
        match &self.law {
            Law::Gear {
                numerator,
                denominator,
            } => format!("gear {numerator}:{denominator} with m"),
            Law::Cam(_) => format!("cam ({CAM_FILE}) on m"),
        }
    }

    /// The follower's set speed and acceleration against its maxima
    /// ([`within_limits`]), and its peaks.
    fn limits(&mut self, s: &AxisStatus, time_s: f64) -> Result<(), DemoError> {
        self.peak_v = self.peak_v.max(s.set.v.abs());
        self.peak_a = self.peak_a.max(s.set.a.abs());
        within_limits(&self.name, s, &self.max, time_s)
    }
}

/// An axis' set position with its whole periods (turns · period + p).
fn unwrapped(s: &AxisStatus, period: Option<f64>) -> f64 {
    s.turns as f64 * period.unwrap_or(0.0) + s.set.p
}

/// The periodic table at master position `x`, unrolled over its periods (a table rising
/// by its rise each period), evaluated apart from the kernel's relation.
fn unrolled(table: &CamTable, x: f64) -> f64 {
    let (x0, x1) = table.master_range();
    let len = x1 - x0;
    let c = ((x - x0) / len).floor();
    table.eval(x - c * len).slave + c * table.slave_rise()
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_kernel::cam::{CamPoint, Interpolation};

    fn table() -> CamTable {
        let points = [
            (0.0, 0.0),
            (90.0, 50.0),
            (180.0, 100.0),
            (270.0, 50.0),
            (360.0, 0.0),
        ]
        .map(|(master, slave)| CamPoint { master, slave })
        .to_vec();
        CamTable::new(points, Interpolation::Cubic, true).unwrap()
    }

    /// A kernel with a virtual master at 360/s and a follower geared `num:den` to it, in
    /// gear after 2 s; and the check of a follower geared 1:1 with maxima `max`.
    fn geared(num: i32, den: u32, max: Limits) -> (Kernel, SyncCheck) {
        use gantry_kernel::{AxisConfig, AxisKind};
        let limits = Limits {
            vmax: 1000.0,
            amax: 10_000.0,
            dmax: 10_000.0,
            jmax: 1e6,
        };
        let mut m = AxisConfig::new("m", AxisKind::Virtual);
        m.max = limits;
        let mut f = AxisConfig::new("f", AxisKind::Simulated);
        (f.max, f.homing_required) = (limits, false);
        let mut k = Kernel::new(0.001, vec![m, f]).unwrap();
        for i in 0..2 {
            k.command(i, Command::Power(PowerCommand::Enable)).unwrap();
        }
        k.command(
            0,
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 360.0)),
        )
        .unwrap();
        k.command(1, Command::GearIn(GearIn::new(0, num, den)))
            .unwrap();
        for _ in 0..2000 {
            k.step(&[]);
        }
        assert!(k.axis_status(1).unwrap().bits.in_sync);
        let check = SyncCheck {
            master: 0,
            master_period: None,
            followers: vec![Follower {
                axis: 1,
                name: "f".into(),
                law: Law::Gear {
                    numerator: 1,
                    denominator: 1,
                },
                period: None,
                max,
                reference: None,
                in_sync: 0,
                worst_set: 0.0,
                worst_actual: 0.0,
                peak_v: 0.0,
                peak_a: 0.0,
                laws: [0.0; MAX_DELAY + 1],
            }],
            // A simulated follower: its actual is its set, in the same cycle.
            delays: 0..=0,
        };
        (k, check)
    }

    fn observe(k: &mut Kernel, check: &mut SyncCheck, cycles: usize) -> Result<(), DemoError> {
        for _ in 0..cycles {
            k.step(&[]);
            check.observe(k, 0.0)?;
        }
        Ok(())
    }

    #[test]
    fn the_check_holds_a_follower_in_gear_and_fails_one_off_its_ratio_or_beyond_its_limits() {
        let ample = Limits {
            vmax: 1000.0,
            amax: 10_000.0,
            dmax: 10_000.0,
            jmax: 1e6,
        };
        let (mut k, mut check) = geared(1, 1, ample);
        observe(&mut k, &mut check, 1000).unwrap();
        let f = &check.followers[0];
        assert_eq!(f.in_sync, 1000);
        assert!(f.worst_set < 1e-9 && f.worst_actual < 1e-9, "{f:?}");
        assert!((f.peak_v - 360.0).abs() < 1e-9, "{f:?}");
        let mut out = Vec::new();
        check.said(0.001, &mut out).unwrap();
        let said = String::from_utf8(out).unwrap();
        assert!(said.starts_with(">> f: on its gear 1:1 with m for 1.000 s: set within "));
        // Geared 3:2 where the check expects 1:1: off its ratio within a cycle.
        let (mut k, mut check) = geared(3, 2, ample);
        let e = observe(&mut k, &mut check, 2).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("the demo stopped: f left its gear 1:1 with m at t = 0.000 s: set "),
            "{e}"
        );
        // Its set speed (360) beyond a maximum of 300.
        let (mut k, mut check) = geared(
            1,
            1,
            Limits {
                vmax: 300.0,
                ..ample
            },
        );
        let e = observe(&mut k, &mut check, 1).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the demo stopped: f: set speed 360.000 beyond its maximum 300 at t = 0.000 s"
        );
        // In sync for less than a second: the check meant nothing, and says so.
        let (mut k, mut check) = geared(1, 1, ample);
        observe(&mut k, &mut check, 10).unwrap();
        let e = check.said(0.001, &mut Vec::new()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the demo stopped: f was in sync with m for 0.010 s only"
        );
    }

    #[test]
    fn the_unrolled_table_repeats_over_periods_both_ways() {
        let t = table();
        for x in [0.0, 45.0, 180.0, 300.0] {
            let y = t.eval(x).slave;
            assert!((unrolled(&t, x) - y).abs() < 1e-12);
            assert!((unrolled(&t, x + 720.0) - y).abs() < 1e-9);
            assert!((unrolled(&t, x - 360.0) - y).abs() < 1e-9);
        }
        assert_eq!(unrolled(&t, 180.0), 100.0);
    }

    #[test]
    fn the_synchronised_steps_keep_the_other_axes_order_and_wait_for_nothing_new() {
        let base = super::super::ethercat::motion_script();
        let mut steps = base.clone();
        insert(&mut steps);
        // The other axes' steps in their order, with their waits.
        let others: Vec<_> = steps
            .iter()
            .filter(|s| ["x", "y", "c"].contains(&s.axis))
            .copied()
            .collect();
        assert_eq!(others, base);
        // A synchronised step placed among them waits for nothing new: right after the
        // step before it, or for the step the next base step waits for anyway.
        for (i, s) in steps.iter().enumerate() {
            let next_base = steps[i..]
                .iter()
                .find(|n| ["x", "y", "c"].contains(&n.axis));
            match (s.label, s.wait) {
                ("m-back", w) | ("m-halt", w) => {
                    assert_eq!(Some(w), next_base.map(|n| n.wait), "{}", s.label)
                }
                _ => {}
            }
        }
        // Every follower couples in after the master moves, and out after it halted.
        let at = |label: &str| steps.iter().position(|s| s.label == label).unwrap();
        for f in ["g1-gear", "g2-gear", "ram-cam"] {
            assert!(at("m-vel") < at(f) && at(f) < at("m-back"), "{f}");
        }
        for f in ["g1-out", "g2-out", "ram-out"] {
            assert!(at("m-halt") < at(f), "{f}");
        }
    }
}
