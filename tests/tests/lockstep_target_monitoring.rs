//! Target position monitoring through the simulator (issue 11 §5), lockstep: gantry's
//! `Cycle` drives two catalog servos tuned slow (a soft velocity loop and a low position
//! gain, as an untuned or heavily loaded axis is), and a move is Done only once the drive's
//! own position has settled in the target window for the dwell; on the drive whose timeout
//! is shorter than it needs to settle, the move fails with the position, window and time
//! and the axis is in ErrorStop. The drives judge what reached them (the drive invariant).

use std::time::Duration;

use ethercrab::subdevice_group::Op;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup, Timeouts};
use gantry::runtime::cycle::Cycle;
use gantry_drives::csp::CspChannel;
use gantry_drives::scaling::Scaling;
use gantry_kernel::axis::command::{Command, CommandError, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::TargetMonitoring;
use gantry_kernel::profile::Limits;
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use gantry_sim::catalog::{self, ServoOptions};
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::servo::ServoParams;
use gantry_sim::plant::DeviceModel;
use gantry_tests::ball_screw_5mm;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::lockstep::Lockstep;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();
type Group = SubDeviceGroup<16, 256, ethercrab::DefaultLock, Op>;

const DT: f64 = 1e-3;
/// In-position window (mm): 26 counts of the 17-bit encoder on a 5 mm screw.
const WINDOW: f64 = 0.001;
const DWELL_S: f64 = 0.02;
/// Axis 0 may take the default 5 s; axis 1 only 50 ms, less than its drive needs.
const TIMEOUT_S: [f64; 2] = [TargetMonitoring::DEFAULT_TIMEOUT_S, 0.05];
const TARGET_MM: f64 = 2.0;

fn axis(name: &str, timeout_s: f64) -> AxisConfig {
    let mut c = AxisConfig::new(name, AxisKind::Real);
    assert!(c.target_monitoring.enabled, "on by default on real axes");
    c.homing_required = false;
    c.max = Limits {
        vmax: 20.0,
        amax: 200.0,
        dmax: 200.0,
        jmax: 4000.0,
    };
    c.defaults.speed = 10.0;
    c.defaults.acceleration = 100.0;
    c.defaults.deceleration = 100.0;
    c.defaults.jerk = 2000.0;
    c.defaults.target_window = WINDOW;
    c.target_monitoring.dwell_s = DWELL_S;
    c.target_monitoring.timeout_s = timeout_s;
    c
}

/// A servo tuned slow: a 20 Hz velocity loop and a position gain of 4/s (τ = 250 ms).
fn slow_servo(serial: u32) -> gantry_sim::slave::Slave {
    catalog::servo(ServoOptions {
        serial,
        params: ServoParams {
            velocity_loop_hz: 20.0,
            position_gain: 4.0,
            ..ServoParams::default()
        },
        ..ServoOptions::default()
    })
}

struct Rig {
    net: Lockstep,
    md: MainDevice<'static>,
    group: Group,
    cycle: Cycle,
    drives: Vec<DriveUnderTest>,
}

impl Rig {
    fn new() -> Self {
        let chain = SlaveChain::new(vec![slow_servo(1), slow_servo(2)]);
        let (tx, rx, pdu_loop) = STORAGE.try_split().unwrap();
        let mut net = Lockstep::new(tx, rx, chain);
        let timeouts = Timeouts {
            eeprom: Duration::from_secs(2),
            pdu: Duration::from_secs(2),
            state_transition: Duration::from_secs(10),
            ..Timeouts::default()
        };
        let md = MainDevice::new(pdu_loop, timeouts, MainDeviceConfig::default());
        let group: Group = net.group_in_op(&md).unwrap();
        let configs = vec![axis("a", TIMEOUT_S[0]), axis("b", TIMEOUT_S[1])];
        let drives = configs
            .iter()
            .enumerate()
            .map(|(i, c)| DriveUnderTest::new(i, c, ball_screw_5mm()))
            .collect();
        let kernel = Kernel::new(DT, configs).unwrap();
        let cycle = Cycle::new(kernel, vec![CspChannel::new(ball_screw_5mm()); 2]);
        net.chain.tick(DT);
        Self {
            net,
            md,
            group,
            cycle,
            drives,
        }
    }

    fn cycle(&mut self) {
        self.net.block_on(self.group.tx_rx(&self.md)).unwrap();
        for i in 0..2 {
            let sd = self.group.subdevice(&self.md, i).unwrap();
            self.cycle.read_inputs(i, &sd.inputs_raw()).unwrap();
        }
        self.cycle.step();
        for i in 0..2 {
            let sd = self.group.subdevice(&self.md, i).unwrap();
            self.cycle
                .write_outputs(i, sd.io_raw_mut().outputs())
                .unwrap();
        }
        self.net.chain.tick(DT);
    }

    /// Where drive `i`'s load is (mm), as the plant holds it: the simulator's truth, not
    /// what the kernel was told.
    fn drive_mm(&self, i: usize) -> f64 {
        let scaling: Scaling = ball_screw_5mm();
        match self.net.chain.slaves()[i].device() {
            DeviceModel::Servo(s) => scaling.counts_to_units(s.position_counts()),
            other => panic!("slave {i} is {other:?}"),
        }
    }

    fn status(&self, i: usize) -> gantry_kernel::axis::status::AxisStatus {
        *self.cycle.kernel.axis_status(i).unwrap()
    }
}

/// Per axis: the cycle its set value reached the target, the cycle its move ended, and
/// the plant's position over the cycles in between.
#[derive(Default)]
struct Seen {
    set_reached: Option<u64>,
    ended: Option<(u64, CommandStatus)>,
    plant_mm: Vec<(u64, f64)>,
}

#[test]
fn a_slow_drive_is_done_in_position_and_one_that_cannot_settle_in_time_fails() {
    let mut rig = Rig::new();
    for i in 0..2 {
        rig.cycle
            .kernel
            .command(i, Command::Power(PowerCommand::Enable))
            .unwrap();
    }
    for _ in 0..2000 {
        rig.cycle();
        if (0..2).all(|i| rig.status(i).state == AxisState::Standstill) {
            break;
        }
    }
    assert!((0..2).all(|i| rig.status(i).state == AxisState::Standstill));
    let start = [rig.drive_mm(0), rig.drive_mm(1)];
    let handles: Vec<HandleId> = (0..2)
        .map(|i| {
            let to = start[i] + TARGET_MM;
            let m = MovePtp::new(PositioningMode::AbsNormal, to);
            rig.cycle.kernel.command(i, Command::MovePtp(m)).unwrap()
        })
        .collect();
    let targets = [start[0] + TARGET_MM, start[1] + TARGET_MM];
    let mut seen = [Seen::default(), Seen::default()];
    for _ in 0..10_000 {
        rig.cycle();
        let tick = rig.cycle.kernel.tick();
        for i in 0..2 {
            let s = rig.status(i);
            let h = rig.cycle.kernel.command_status(handles[i]);
            let seen = &mut seen[i];
            if seen.ended.is_some() {
                continue;
            }
            seen.plant_mm.push((tick, rig.drive_mm(i)));
            if seen.set_reached.is_none() && s.set.p == targets[i] && s.set.v == 0.0 {
                seen.set_reached = Some(tick);
            }
            if h.is_final() {
                seen.ended = Some((tick, h));
            } else {
                assert_eq!(s.state, AxisState::DiscreteMotion, "axis {i} at {tick}");
            }
        }
        if seen.iter().all(|s| s.ended.is_some()) {
            break;
        }
    }
    let dwell = (DWELL_S / DT).round() as u64;

    // Axis 0: Done only after the drive's own position has stayed in the window for the
    // dwell, which the slow drive reaches well after its set value stopped.
    let a = &seen[0];
    let (done_at, status) = a.ended.expect("axis 0 ended");
    assert_eq!(status, CommandStatus::Done);
    let reached = a
        .set_reached
        .expect("axis 0's set value reached the target");
    let lag = a
        .plant_mm
        .iter()
        .find(|(t, _)| *t == reached)
        .map(|(_, p)| targets[0] - p);
    eprintln!(
        "axis 0: set value at the target in cycle {reached} (drive {lag:?} mm short), \
         Done in cycle {done_at}"
    );
    assert!(
        done_at > reached + 5 * dwell,
        "the slow drive settles long after its set value stopped (set {reached}, done {done_at})"
    );
    // The plant was in the window for the dwell before Done (one cycle of feedback delay:
    // the kernel sees the position the drive had at the previous exchange).
    let inside = |p: f64| (p - targets[0]).abs() <= WINDOW;
    let last: Vec<_> = a
        .plant_mm
        .iter()
        .rev()
        .skip(1)
        .take(dwell as usize)
        .collect();
    assert!(
        last.iter().all(|(_, p)| inside(*p)),
        "in the window for the dwell before Done: {last:?}"
    );
    let before = a
        .plant_mm
        .iter()
        .rev()
        .nth(dwell as usize + 2)
        .expect("cycles before the dwell");
    assert!(
        !inside(before.1),
        "Done at the first cycle the dwell allows, not later: {before:?}"
    );
    assert_eq!(rig.status(0).state, AxisState::Standstill);

    // Axis 1: not in the window 50 ms after the set value arrived: Error and ErrorStop,
    // naming the position, the window and the time.
    let b = &seen[1];
    let (failed_at, status) = b.ended.expect("axis 1 ended");
    let reached = b
        .set_reached
        .expect("axis 1's set value reached the target");
    assert_eq!(failed_at, reached + (TIMEOUT_S[1] / DT).round() as u64);
    let CommandStatus::Error(e) = status else {
        panic!("axis 1: {status:?}");
    };
    let CommandError::TargetNotReached {
        target,
        actual,
        window,
        timeout_s,
        ..
    } = e
    else {
        panic!("axis 1: {e:?}");
    };
    assert_eq!(
        (target, window, timeout_s),
        (targets[1], WINDOW, TIMEOUT_S[1])
    );
    assert!((actual - targets[1]).abs() > WINDOW, "{e}");
    assert!(e.to_string().contains("0.05 s"), "{e}");
    assert_eq!(rig.status(1).state, AxisState::ErrorStop);

    // Power on is refused at once in ErrorStop; Reset leaves it and the axis stands.
    let refused = rig
        .cycle
        .kernel
        .command(1, Command::Power(PowerCommand::Enable))
        .unwrap_err();
    assert!(refused.to_string().contains("ErrorStop"), "{refused}");
    for _ in 0..50 {
        rig.cycle();
    }
    rig.cycle.kernel.command(1, Command::Reset).unwrap();
    rig.cycle();
    assert_eq!(rig.status(1).state, AxisState::Standstill);
    for _ in 0..500 {
        rig.cycle();
    }
    let locked = TestConditions {
        phase_locked: true,
        ..TestConditions::default()
    };
    assert_drive_invariants(&rig.net.chain, &rig.drives, DT, locked);
}
