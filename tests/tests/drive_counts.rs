//! Drive counts end to end (issue 10 §1): gantry's `Cycle` drives catalog servos in the
//! in-process simulator, lockstep, and the drives judge what reached them (the drive
//! invariant, `gantry_tests::invariant`) and where they ended.
//!
//! A drive counts in 32 bits and wraps; a modulo axis wraps its position every period.
//! Neither wrap may reach the drive as a step: the target it gets is the low half of a
//! continuous 64-bit count, whatever the kernel's frame, the number of periods turned,
//! a SetPosition offset, or where the drive's counter stood at power-up.

use std::time::Duration;

use ethercrab::subdevice_group::Op;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup, Timeouts};
use gantry::runtime::cycle::Cycle;
use gantry_drives::csp::CspChannel;
use gantry_drives::scaling::{Scaling, ScalingConfig};
use gantry_kernel::axis::command::{
    Command, HaltMode, MoveDirection, MovePtp, MoveVelocity, PositioningMode, PowerCommand,
};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::mechanics::{Direction, Modulo, MotionKind};
use gantry_kernel::profile::Limits;
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use gantry_sim::catalog::{self, ServoOptions};
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::DeviceModel;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::lockstep::Lockstep;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
type Storage = PduStorage<16, MAX_PDU_DATA>;
static STORAGE_WRAPS: Storage = PduStorage::new();
static STORAGE_SET_POSITION: Storage = PduStorage::new();
static STORAGE_ONE_WAY: Storage = PduStorage::new();
static STORAGE_LINEAR: Storage = PduStorage::new();

type Group = SubDeviceGroup<16, 256, ethercrab::DefaultLock, Op>;

const DT: f64 = 1e-3;

/// One axis of a rig: its kernel configuration, scaling and the drive's counter at power-up.
struct AxisSpec {
    config: AxisConfig,
    scaling: ScalingConfig,
    start_counts: i32,
}

fn scaling(counts_per_motor_rev: u32, motor_revs: u32, load_revs: u32, feed: f64) -> ScalingConfig {
    ScalingConfig {
        counts_per_motor_rev,
        motor_revs,
        load_revs,
        units_per_load_rev: feed,
        invert: false,
    }
}

fn axis(name: &str, period: Option<f64>, vmax: f64) -> AxisConfig {
    let mut c = AxisConfig::new(name, AxisKind::Real);
    c.homing_required = false;
    if let Some(p) = period {
        c.mechanics.kind = MotionKind::Rotary;
        c.mechanics.modulo = Modulo::new(p);
    }
    c.max = Limits {
        vmax,
        amax: 10.0 * vmax,
        dmax: 10.0 * vmax,
        jmax: 100.0 * vmax,
    };
    c.defaults.speed = vmax / 2.0;
    c.defaults.acceleration = 5.0 * vmax;
    c.defaults.deceleration = 5.0 * vmax;
    c.defaults.jerk = 100.0 * vmax;
    c
}

/// A chain of catalog servos driven by a `Cycle`, one exchange per `cycle()`.
struct Rig {
    net: Lockstep,
    md: MainDevice<'static>,
    group: Group,
    cycle: Cycle,
    drives: Vec<DriveUnderTest>,
    scalings: Vec<Scaling>,
}

impl Rig {
    fn new(storage: &'static Storage, axes: Vec<AxisSpec>) -> Self {
        let chain = SlaveChain::new(
            axes.iter()
                .enumerate()
                .map(|(i, a)| {
                    catalog::servo(ServoOptions {
                        serial: i as u32 + 1,
                        start_counts: a.start_counts,
                        ..ServoOptions::default()
                    })
                })
                .collect(),
        );
        let (tx, rx, pdu_loop) = storage.try_split().unwrap();
        let mut net = Lockstep::new(tx, rx, chain);
        // Lockstep on the wall clock of a shared machine: generous timeouts for bring-up.
        let timeouts = Timeouts {
            eeprom: Duration::from_secs(2),
            pdu: Duration::from_secs(2),
            state_transition: Duration::from_secs(10),
            ..Timeouts::default()
        };
        let md = MainDevice::new(pdu_loop, timeouts, MainDeviceConfig::default());
        let group: Group = net.group_in_op(&md).unwrap();
        let scalings: Vec<Scaling> = axes
            .iter()
            .map(|a| Scaling::new(a.scaling).unwrap())
            .collect();
        let drives = axes
            .iter()
            .zip(&scalings)
            .enumerate()
            .map(|(i, (a, s))| DriveUnderTest::new(i, &a.config, *s))
            .collect();
        let kernel = Kernel::new(DT, axes.iter().map(|a| a.config.clone()).collect()).unwrap();
        let channels = scalings.iter().map(|s| CspChannel::new(*s)).collect();
        let cycle = Cycle::new(kernel, channels);
        net.chain.tick(DT);
        Self {
            net,
            md,
            group,
            cycle,
            drives,
            scalings,
        }
    }

    /// One cycle: exchange, kernel, outputs, the world moves.
    fn cycle(&mut self) {
        self.net.block_on(self.group.tx_rx(&self.md)).unwrap();
        for i in 0..self.drives.len() {
            let sd = self.group.subdevice(&self.md, i).unwrap();
            self.cycle.read_inputs(i, &sd.inputs_raw()).unwrap();
        }
        self.cycle.step();
        for i in 0..self.drives.len() {
            let sd = self.group.subdevice(&self.md, i).unwrap();
            self.cycle
                .write_outputs(i, sd.io_raw_mut().outputs())
                .unwrap();
        }
        self.net.chain.tick(DT);
    }

    /// The drive's position demand (counts): the targets it took, interpolated.
    fn demand(&self, i: usize) -> f64 {
        match self.net.chain.slaves()[i].device() {
            DeviceModel::Servo(s) => s.demand(),
            other => panic!("slave {i} is {other:?}"),
        }
    }

    /// The drive's load position (counts, as the plant holds it).
    fn counts(&self, i: usize) -> f64 {
        match self.net.chain.slaves()[i].device() {
            DeviceModel::Servo(s) => s.position(),
            other => panic!("slave {i} is {other:?}"),
        }
    }

    fn command(&mut self, i: usize, cmd: Command) -> HandleId {
        self.cycle.kernel.command(i, cmd).unwrap()
    }

    fn state(&self, i: usize) -> AxisState {
        self.cycle.kernel.axis_status(i).unwrap().state
    }

    /// Runs cycles until `done`, at most `max`; every cycle each drive's load may move by
    /// no more than its axis' `vmax · T` (plus the plant's rounding): a target one period
    /// (or 2³² counts) away would move it by a large part of that at once.
    fn run_until(&mut self, max: u32, what: &str, mut done: impl FnMut(&Self) -> bool) {
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

    fn enable_all(&mut self) {
        for i in 0..self.drives.len() {
            self.command(i, Command::Power(PowerCommand::Enable));
        }
        let n = self.drives.len();
        self.run_until(2000, "enable", |r| {
            (0..n).all(|i| r.state(i) == AxisState::Standstill)
        });
    }

    fn settle(&mut self, cycles: u32) {
        for _ in 0..cycles {
            self.cycle();
        }
    }

    fn assert_invariants(&self) {
        // Lockstep: exactly one exchange per drive cycle, as locked to the drives as a
        // master can be, so no setpoint may be missed or doubled.
        let locked = TestConditions {
            phase_locked: true,
            ..TestConditions::default()
        };
        assert_drive_invariants(&self.net.chain, &self.drives, DT, locked);
    }

    /// The kernel's set position of axis `i` as `turns · period + position` (units).
    fn unwrapped_set(&self, i: usize) -> f64 {
        let s = self.cycle.kernel.axis_status(i).unwrap();
        let p = self.cycle.kernel.axes()[i]
            .config()
            .mechanics
            .modulo
            .map_or(0.0, |m| m.period());
        s.turns as f64 * p + s.set.p
    }

    /// `units` of travel in counts on axis `i` (exact rational, rounded).
    fn travel_counts(&self, i: usize, units: f64) -> f64 {
        self.scalings[i].units_to_counts(units) as f64
    }
}

/// `a − b` as a drive's 32-bit counter tells it (in [−2³¹, 2³¹)), whether the plant keeps
/// its position unbounded or wrapped as the drive reports it.
fn counter_difference(a: f64, b: f64) -> f64 {
    const R: f64 = 4_294_967_296.0;
    (a - b + R / 2.0).rem_euclid(R) - R / 2.0
}

/// Rotary modulo axes whose periods are not whole numbers of counts (gears 7:3, 3:7 and
/// 13:5, a period that is not the feed constant) and one that is (the example machine's
/// 10:1 table), starting anywhere in their counters, turn a dozen periods and more one
/// way and twice as many back at speed: no drive ever sees a step, and each ends exactly
/// where the kernel's travel says, to the count.
#[test]
fn modulo_axes_turn_many_periods_both_ways_without_a_step() {
    let specs = vec![
        // 2^17 · 10 = 1 310 720 counts per 360°, the example's c axis.
        AxisSpec {
            config: axis("c", Some(360.0), 2000.0),
            scaling: scaling(1 << 17, 10, 1, 360.0),
            start_counts: 5_000_000,
        },
        // 10 000 · 7/3 = 23 333⅓ counts per 360°.
        AxisSpec {
            config: axis("r", Some(360.0), 2000.0),
            scaling: scaling(10_000, 7, 3, 360.0),
            start_counts: -1_234_567,
        },
        // 2^20 · 3/7, inverted: 449 389.7… counts per 360°, counting down.
        AxisSpec {
            config: axis("s", Some(360.0), 2000.0),
            scaling: ScalingConfig {
                invert: true,
                ..scaling(1 << 20, 3, 7, 360.0)
            },
            start_counts: 0,
        },
        // 4096 · 13/5 per 360° of load, period 100°: 2958.2… counts.
        AxisSpec {
            config: axis("t", Some(100.0), 2000.0),
            scaling: scaling(4096, 13, 5, 360.0),
            start_counts: 2_000_000_000,
        },
    ];
    let mut rig = Rig::new(&STORAGE_WRAPS, specs);
    rig.enable_all();
    let start: Vec<f64> = (0..4).map(|i| rig.counts(i)).collect();
    let start_units: Vec<f64> = (0..4).map(|i| rig.unwrapped_set(i)).collect();
    let velocity = |d| Command::MoveVelocity(MoveVelocity::new(d, 1440.0));
    // 3 s forward (12 turns of 360°, 43 periods of 100°), 6 s back, stop.
    for i in 0..4 {
        rig.command(i, velocity(MoveDirection::Positive));
    }
    let mut n = 0;
    rig.run_until(3000, "forward", |_| {
        n += 1;
        n == 3000
    });
    for i in 0..4 {
        rig.command(i, velocity(MoveDirection::Negative));
    }
    let mut n = 0;
    rig.run_until(6000, "back", |_| {
        n += 1;
        n == 6000
    });
    let halts: Vec<HandleId> = (0..4)
        .map(|i| {
            rig.command(
                i,
                Command::Halt {
                    mode: HaltMode::Normal,
                    deceleration: None,
                },
            )
        })
        .collect();
    rig.run_until(2000, "halt", |r| {
        halts
            .iter()
            .all(|h| r.cycle.kernel.command_status(*h) == CommandStatus::Done)
    });
    rig.settle(200);
    for i in 0..4 {
        // The kernel's travel since enabled (turns · period + position, no SetPosition
        // here) against what the drive travelled.
        let travel_units = rig.unwrapped_set(i) - start_units[i];
        let expect = rig.travel_counts(i, travel_units);
        let got = rig.counts(i) - start[i];
        assert!(
            (got - expect).abs() <= 2.0,
            "axis {}: drive travelled {got} counts, the kernel {travel_units} units = {expect} counts",
            rig.drives[i].axis
        );
        // It really turned: forward ~4320° then back ~8640°.
        assert!(
            travel_units < -3.0 * 360.0,
            "axis {}: travel {travel_units}",
            rig.drives[i].axis
        );
    }
    rig.assert_invariants();
}

/// The user's report (issue 10 §1): the drive powers up 3.8 periods into its counter (and
/// another below zero); enable, `set-position c 350`, `move c --to 720 --mode relative
/// --speed 360`. Enabling must not move the drive, the move must be continuous in drive
/// counts — the drive travels exactly 720° = 2 621 440 counts — and `c.actual` never jumps
/// (it jumped 349.8° → 452.6° in one cycle).
#[test]
fn set_position_and_enable_with_the_actual_outside_one_period() {
    let specs = vec![
        AxisSpec {
            config: axis("c", Some(360.0), 720.0),
            scaling: scaling(1 << 17, 10, 1, 360.0),
            start_counts: 5_000_000,
        },
        AxisSpec {
            config: axis("d", Some(360.0), 720.0),
            scaling: scaling(10_000, 7, 3, 360.0),
            start_counts: -3_000_001,
        },
        // Set to 350° while still disabled, then enabled.
        AxisSpec {
            config: axis("e", Some(360.0), 720.0),
            scaling: ScalingConfig {
                invert: true,
                ..scaling(1 << 17, 10, 1, 360.0)
            },
            start_counts: 1_999_999_999,
        },
    ];
    let mut rig = Rig::new(&STORAGE_SET_POSITION, specs);
    rig.settle(3);
    let h = rig.command(
        2,
        Command::SetPosition {
            position: 350.0,
            relative: false,
        },
    );
    assert_eq!(rig.cycle.kernel.command_status(h), CommandStatus::Done);
    rig.settle(3);
    let before: Vec<f64> = (0..3).map(|i| rig.counts(i)).collect();
    rig.enable_all();
    rig.settle(50);
    for (i, b) in before.iter().enumerate() {
        assert!(
            (rig.counts(i) - b).abs() < 1.0,
            "axis {}: enabling moved the drive from {b} to {} counts",
            rig.drives[i].axis,
            rig.counts(i)
        );
    }
    for i in 0..2 {
        let h = rig.command(
            i,
            Command::SetPosition {
                position: 350.0,
                relative: false,
            },
        );
        assert_eq!(rig.cycle.kernel.command_status(h), CommandStatus::Done);
    }
    rig.settle(5);
    let start: Vec<f64> = (0..3).map(|i| rig.counts(i)).collect();
    let moves: Vec<HandleId> = (0..3)
        .map(|i| {
            rig.command(
                i,
                Command::MovePtp(MovePtp::new(PositioningMode::RelTarget, 720.0).speed(360.0)),
            )
        })
        .collect();
    let mut last_actual = [350.0f64; 3];
    let mut worst = [0.0f64; 3];
    rig.run_until(5000, "move 720°", |r| {
        for (i, (last, w)) in last_actual.iter_mut().zip(&mut worst).enumerate() {
            let a = r.cycle.kernel.axis_status(i).unwrap().actual_position;
            let m = Modulo::new(360.0).unwrap();
            *w = w.max(m.delta_shortest(m.wrap(*last), m.wrap(a)).abs());
            *last = a;
        }
        moves
            .iter()
            .all(|h| r.cycle.kernel.command_status(*h) == CommandStatus::Done)
    });
    rig.settle(300);
    for i in 0..3 {
        let axis = &rig.drives[i].axis;
        assert!(
            worst[i] <= 360.0 * DT * 1.5,
            "axis {axis}: actual jumped {}° in one cycle",
            worst[i]
        );
        let expect = rig.travel_counts(i, 720.0);
        let got = rig.counts(i) - start[i];
        assert!(
            (got - expect).abs() <= 2.0,
            "axis {axis}: drive travelled {got} counts, 720° is {expect}"
        );
        let s = rig.cycle.kernel.axis_status(i).unwrap();
        assert!(
            (s.set.p - 350.0).abs() < 1e-9,
            "axis {axis}: set {}",
            s.set.p
        );
        assert!(
            (s.actual_position - 350.0).abs() < 0.01,
            "axis {axis}: actual {}",
            s.actual_position
        );
    }
    rig.assert_invariants();
}

/// One-way modulo axes (a conveyor, a ratchet): absolute moves go the allowed way round,
/// through the wrap, every time, and the drive only ever counts that way.
#[test]
fn positive_only_and_negative_only_modulo_axes_wrap_one_way() {
    let mut pos = axis("p", Some(360.0), 720.0);
    pos.mechanics.direction = Direction::PositiveOnly;
    let mut neg = axis("n", Some(360.0), 720.0);
    neg.mechanics.direction = Direction::NegativeOnly;
    let specs = vec![
        AxisSpec {
            config: pos,
            scaling: scaling(10_000, 7, 3, 360.0),
            start_counts: 1_000_000,
        },
        AxisSpec {
            config: neg,
            scaling: ScalingConfig {
                invert: true,
                ..scaling(1 << 17, 10, 1, 360.0)
            },
            start_counts: -7_777_777,
        },
    ];
    let mut rig = Rig::new(&STORAGE_ONE_WAY, specs);
    rig.enable_all();
    let start: Vec<f64> = (0..2).map(|i| rig.counts(i)).collect();
    let mut travelled = [0.0f64; 2];
    let mut from = [0, 1].map(|i| rig.cycle.kernel.axis_status(i).unwrap().set.p);
    for target in [90.0, 10.0, 300.0, 5.0, 359.0, 0.5, 180.0, 179.0] {
        let m = Modulo::new(360.0).unwrap();
        let handles = [
            rig.command(
                0,
                Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloPos, target)),
            ),
            rig.command(
                1,
                Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloNeg, target)),
            ),
        ];
        travelled[0] += m.delta_positive(from[0], target);
        travelled[1] += m.delta_negative(from[1], target);
        from = [target; 2];
        // The drive's position demand (the targets it got, interpolated) runs one way only;
        // the load follows it through a PI velocity loop, which may settle back by a
        // fraction of a count at the end of a move, as a real drive's does, never by one.
        let mut last: Vec<(f64, f64)> = (0..2).map(|i| (rig.demand(i), rig.counts(i))).collect();
        // p counts up as it turns positive; n is inverted, so its counts grow too as it
        // turns negative.
        rig.run_until(5000, "one-way move", |r| {
            for (i, last) in last.iter_mut().enumerate() {
                let (demand, c) = (r.demand(i), r.counts(i));
                assert!(
                    demand - last.0 >= 0.0,
                    "axis {i}: the drive's demand went back: {} → {demand}",
                    last.0
                );
                assert!(
                    c - last.1 > -1.0,
                    "axis {i}: the load counted back: {} → {c}",
                    last.1
                );
                *last = (demand, c);
            }
            handles
                .iter()
                .all(|h| r.cycle.kernel.command_status(*h) == CommandStatus::Done)
        });
    }
    rig.settle(300);
    for i in 0..2 {
        let expect = rig.travel_counts(i, travelled[i]);
        let got = rig.counts(i) - start[i];
        assert!(
            (got - expect).abs() <= 2.0,
            "axis {}: drive travelled {got} counts, {}° is {expect}",
            rig.drives[i].axis,
            travelled[i]
        );
        assert!(travelled[i].abs() > 3.0 * 360.0, "{travelled:?}");
    }
    rig.assert_invariants();
}

/// Drive counters crossing ±2³¹, on a linear axis each way and on a modulo axis each way:
/// the drive wraps its 32-bit count (its target is the low half of gantry's 64-bit count)
/// and the axis goes on smoothly past it and back — the old code froze a linear axis'
/// target at the drive's actual without a word.
#[test]
fn drive_counters_cross_plus_and_minus_2_pow_31_counts() {
    let specs = vec![
        AxisSpec {
            config: axis("x", None, 250.0),
            scaling: scaling(1 << 17, 1, 1, 5.0),
            start_counts: i32::MAX - 100_000,
        },
        AxisSpec {
            config: axis("y", None, 250.0),
            scaling: scaling(1 << 17, 1, 1, 5.0),
            start_counts: i32::MIN + 100_000,
        },
        AxisSpec {
            config: axis("c", Some(360.0), 720.0),
            scaling: scaling(1 << 17, 10, 1, 360.0),
            start_counts: i32::MAX - 100_000,
        },
        AxisSpec {
            config: axis("d", Some(360.0), 720.0),
            scaling: scaling(10_000, 7, 3, 360.0),
            start_counts: i32::MIN + 1_000,
        },
    ];
    let mut rig = Rig::new(&STORAGE_LINEAR, specs);
    rig.enable_all();
    let start: Vec<f64> = (0..4).map(|i| rig.counts(i)).collect();
    let p0: Vec<f64> = (0..4).map(|i| rig.unwrapped_set(i)).collect();
    // x +20 mm (524 288 counts) across +2³¹, y −20 mm across −2³¹, c +90° (327 680
    // counts) across +2³¹, d −90° (5833 counts) across −2³¹; then all go back.
    let there = [20.0, -20.0, 90.0, -90.0];
    for (leg, share) in [("across", 1.0), ("back", 0.0)] {
        let h: Vec<HandleId> = (0..4)
            .map(|i| {
                let to = p0[i] + share * there[i];
                let m = if i < 2 {
                    MovePtp::new(PositioningMode::AbsNormal, to)
                } else {
                    // The whole way, not the short way round the period.
                    MovePtp::new(PositioningMode::RelTarget, to - rig.unwrapped_set(i))
                };
                rig.command(i, Command::MovePtp(m))
            })
            .collect();
        rig.run_until(5000, leg, |r| {
            h.iter()
                .all(|h| r.cycle.kernel.command_status(*h) == CommandStatus::Done)
        });
        rig.settle(300);
        for i in 0..4 {
            let expect = share * there[i];
            let axis = &rig.drives[i].axis;
            let set = rig.unwrapped_set(i) - p0[i];
            assert!(
                (set - expect).abs() < 1e-6,
                "{leg}: axis {axis} set {set} from the start, expected {expect}"
            );
            let s = rig.cycle.kernel.axis_status(i).unwrap();
            let count = 1.0 / rig.scalings[i].counts_per_unit();
            assert!(
                (s.actual_position - s.set.p).abs() <= count,
                "{leg}: axis {axis} actual {} against set {}, more than a count",
                s.actual_position,
                s.set.p
            );
            let travelled = counter_difference(rig.counts(i), start[i]);
            let want = rig.travel_counts(i, expect);
            assert!(
                (travelled - want).abs() <= 2.0,
                "{leg}: drive {axis} travelled {travelled} counts, {expect} units is {want}"
            );
        }
    }
    rig.assert_invariants();
}
