//! The drive-count rig (issue 10 §1, the `drive_counts*` tests): catalog servos in the
//! in-process simulator, each powering up at a counter of its own, under axes with their
//! own scaling, modulo period and direction, driven by gantry's engine through the lockstep
//! [`Rig`] (the configuration's axes, the Controller's commands, the chain's time stepped
//! one cycle per cycle). The drives judge what reached them (the drive invariant,
//! [`crate::invariant`]) and where they ended; every cycle, no drive's load may move
//! further than its axis' speed allows.
//!
//! One rig per test binary: the EtherCAT bus starts once per process.

use crate::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use crate::rig::Rig;
use gantry::runtime::controller::CommandHandle;
use gantry_drives::scaling::{Scaling, ScalingConfig};
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;

/// The cycle time (s).
pub const DT: f64 = 1e-3;

/// One axis of a rig: its name, modulo period, top speed and allowed direction (gantry's
/// `[[axis]]` keys), scaling and the drive's counter at power-up (the simulator's
/// `start_position`).
pub struct AxisSpec {
    /// The axis' name.
    pub name: &'static str,
    /// Its modulo period (units), if it is a modulo axis.
    pub period: Option<f64>,
    /// Its top speed (units/s).
    pub vmax: f64,
    /// `both`, `positive` or `negative`.
    pub direction: &'static str,
    /// Counts to units.
    pub scaling: ScalingConfig,
    /// The drive's position actual value at power-up (counts).
    pub start_counts: i32,
}

/// A scaling of `feed` units per load revolution through a `motor_revs`:`load_revs` gear.
pub fn scaling(
    counts_per_motor_rev: u32,
    motor_revs: u32,
    load_revs: u32,
    feed: f64,
) -> ScalingConfig {
    ScalingConfig {
        counts_per_motor_rev,
        motor_revs,
        load_revs,
        units_per_load_rev: feed,
        invert: false,
    }
}

/// An axis that may turn both ways.
pub fn axis(
    name: &'static str,
    period: Option<f64>,
    vmax: f64,
    scaling: ScalingConfig,
    start_counts: i32,
) -> AxisSpec {
    AxisSpec {
        name,
        period,
        vmax,
        direction: "both",
        scaling,
        start_counts,
    }
}

/// The `[[axis]]` table of `spec` on drive `drive`: no homing needed; rotary with its period
/// when modulo; limits vmax, 10·vmax (acceleration and deceleration), 100·vmax (jerk);
/// defaults half the speed, half the acceleration, the full jerk.
pub fn axis_toml(drive: usize, spec: &AxisSpec) -> String {
    let v = spec.vmax;
    let s = &spec.scaling;
    let mechanics = match spec.period {
        Some(p) => format!("kind = \"rotary\"\nmodulo = {p:?}\n"),
        None => String::new(),
    };
    format!(
        "[[axis]]\nname = {:?}\ndrive = {drive}\nhoming_required = false\n{mechanics}\
         direction = {:?}\n\
         scaling = {{ counts_per_motor_rev = {}, motor_revs = {}, load_revs = {}, \
         units_per_load_rev = {:?}, invert = {} }}\n\
         max = {{ speed = {:?}, acceleration = {:?}, deceleration = {:?}, jerk = {:?} }}\n\
         defaults = {{ speed = {:?}, acceleration = {:?}, deceleration = {:?}, jerk = {:?} }}\n",
        spec.name,
        spec.direction,
        s.counts_per_motor_rev,
        s.motor_revs,
        s.load_revs,
        s.units_per_load_rev,
        s.invert,
        v,
        10.0 * v,
        10.0 * v,
        100.0 * v,
        v / 2.0,
        5.0 * v,
        5.0 * v,
        100.0 * v,
    )
}

/// Catalog servos, one per axis, each powering up at its spec's counter, driven by gantry's
/// engine through the rig, one exchange per `cycle()`.
pub struct Machine {
    /// The engine, its Controller and the chain.
    pub rig: Rig,
    /// What the drive invariant checks, per axis.
    pub drives: Vec<DriveUnderTest>,
    /// Each axis' scaling, as the configuration has it.
    pub scalings: Vec<Scaling>,
}

impl Machine {
    /// Brings up one servo per spec and starts the engine on their axes.
    pub fn new(specs: Vec<AxisSpec>) -> Self {
        let slaves: String = specs
            .iter()
            .map(|a| {
                format!(
                    "[[slave]]\nkind = \"servo\"\nstart_position = {}\n",
                    a.start_counts
                )
            })
            .collect();
        let axes: String = specs
            .iter()
            .enumerate()
            .map(|(i, a)| axis_toml(i, a))
            .collect();
        let config = crate::sim_config_text((DT * 1e6) as u32, &slaves, "", &axes);
        let scalings: Vec<Scaling> = config
            .axes
            .iter()
            .map(|a| a.scaling().expect("a valid scaling"))
            .collect();
        for (a, s) in specs.iter().zip(&scalings) {
            assert_eq!(*s, Scaling::new(a.scaling).unwrap(), "axis {}", a.name);
        }
        let drives = config
            .kernel_axes
            .iter()
            .zip(&scalings)
            .enumerate()
            .map(|(i, (c, s))| DriveUnderTest::new(i, c, *s))
            .collect();
        Self {
            rig: Rig::new(&config),
            drives,
            scalings,
        }
    }

    /// One cycle: commands in, inputs, kernel, outputs, exchange; the world moves.
    pub fn cycle(&mut self) {
        self.rig.cycle();
    }

    /// The drive's position demand (counts): the targets it took, interpolated.
    pub fn demand(&self, i: usize) -> f64 {
        self.rig.servo(i, |s| s.demand())
    }

    /// The drive's load position (counts, as the plant holds it).
    pub fn counts(&self, i: usize) -> f64 {
        self.rig.servo(i, |s| s.position())
    }

    /// Sends `cmd` to axis `i` (taken at the next cycle).
    pub fn command(&mut self, i: usize, cmd: Command) -> CommandHandle {
        self.rig.ctl.command(i, cmd).expect("queued")
    }

    /// `h` is Done as of the last cycle.
    pub fn done(&self, h: &CommandHandle) -> bool {
        self.rig.status_now(h) == Some(CommandStatus::Done)
    }

    /// The engine's kernel.
    pub fn kernel(&self) -> &gantry_kernel::Kernel {
        &self.rig.engine.cycle.kernel
    }

    /// Axis `i`'s state, as the kernel has it now.
    pub fn state(&self, i: usize) -> AxisState {
        self.rig.state(i)
    }

    /// Runs cycles until `done`, at most `max`; every cycle each drive's load may move by
    /// no more than its axis' `vmax · T` (plus the plant's rounding): a target one period
    /// (or 2³² counts) away would move it by a large part of that at once.
    pub fn run_until(&mut self, max: u32, what: &str, mut done: impl FnMut(&Self) -> bool) {
        let bounds: Vec<f64> = self
            .drives
            .iter()
            .map(|d| d.max_step_counts(DT) as f64 + 1.0)
            .collect();
        for _ in 0..max {
            let before: Vec<f64> = (0..self.drives.len()).map(|i| self.counts(i)).collect();
            self.cycle();
            for (i, b) in before.iter().enumerate() {
                let step = counter_difference(self.counts(i), *b).abs();
                assert!(
                    step <= bounds[i],
                    "{what}: drive {i} ({}) moved {step} counts in one cycle, bound {}",
                    self.drives[i].axis,
                    bounds[i]
                );
            }
            if done(self) {
                return;
            }
        }
        panic!("{what}: not done after {max} cycles");
    }

    /// Enables every axis and cycles until all stand.
    pub fn enable_all(&mut self) {
        for i in 0..self.drives.len() {
            self.command(i, Command::Power(PowerCommand::Enable));
        }
        let n = self.drives.len();
        self.run_until(2000, "enable", |r| {
            (0..n).all(|i| r.state(i) == AxisState::Standstill)
        });
    }

    /// SetPosition on axis `i`, Done in the cycle that takes it (a SetPosition completes
    /// at once in the kernel).
    pub fn set_position(&mut self, i: usize, position: f64) {
        let h = self.command(
            i,
            Command::SetPosition {
                position,
                relative: false,
            },
        );
        self.cycle();
        assert_eq!(
            self.rig.status_now(&h),
            Some(CommandStatus::Done),
            "SetPosition on axis {i}"
        );
    }

    /// `cycles` cycles.
    pub fn settle(&mut self, cycles: u32) {
        self.rig.run(cycles as usize);
    }

    /// Asserts the drive invariant on every drive.
    pub fn assert_invariants(&self) {
        // Lockstep: exactly one exchange per drive cycle, as locked to the drives as a
        // master can be, so no setpoint may be missed or doubled.
        let locked = TestConditions {
            phase_locked: true,
            ..TestConditions::default()
        };
        let chain = self.rig.chain.lock().expect("the chain");
        assert_drive_invariants(&chain, &self.drives, DT, locked);
    }

    /// The kernel's set position of axis `i` as `turns · period + position` (units).
    pub fn unwrapped_set(&self, i: usize) -> f64 {
        let s = self.kernel().axis_status(i).unwrap();
        let p = self.kernel().axes()[i]
            .config()
            .mechanics
            .modulo
            .map_or(0.0, |m| m.period());
        s.turns as f64 * p + s.set.p
    }

    /// `units` of travel in counts on axis `i` (exact rational, rounded).
    pub fn travel_counts(&self, i: usize, units: f64) -> f64 {
        self.scalings[i].units_to_counts(units) as f64
    }
}

/// `a − b` as a drive's 32-bit counter tells it (in [−2³¹, 2³¹)), whether the plant keeps
/// its position unbounded or wrapped as the drive reports it.
pub fn counter_difference(a: f64, b: f64) -> f64 {
    const R: f64 = 4_294_967_296.0;
    (a - b + R / 2.0).rem_euclid(R) - R / 2.0
}
