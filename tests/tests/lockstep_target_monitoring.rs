//! Target position monitoring through the simulator (issue 11 §5), lockstep: gantry's
//! engine (`gantry_tests::rig`: bring-up from a configuration, Controller commands, the
//! chain's time stepped one cycle per cycle) drives two catalog servos tuned slow (a soft
//! velocity loop and a low position gain, as an untuned or heavily loaded axis is), and a
//! move is Done only once the drive's own position has settled in the target window for
//! the dwell; on the drive whose timeout is shorter than it needs to settle, the move fails
//! with the position, window and time and the axis is in ErrorStop. The drives judge what
//! reached them (the drive invariant).

use gantry::config::Config;
use gantry::runtime::controller::CommandHandle;
use gantry_kernel::axis::command::{Command, CommandError, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::TargetMonitoring;
use gantry_tests::ball_screw_5mm;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::rig::Rig;

const DT: f64 = 1e-3;
/// In-position window (mm): 26 counts of the 17-bit encoder on a 5 mm screw.
const WINDOW: f64 = 0.001;
const DWELL_S: f64 = 0.02;
/// Axis 0 may take the default 5 s; axis 1 only 50 ms, less than its drive needs.
const TIMEOUT_S: [f64; 2] = [TargetMonitoring::DEFAULT_TIMEOUT_S, 0.05];
const TARGET_MM: f64 = 2.0;

/// Two servos tuned slow (a 20 Hz velocity loop and a position gain of 4/s, τ = 250 ms)
/// under axes `a` and `b` on the 5 mm ball screw, target monitoring on by default (not
/// named here) with the window, the dwell and each axis' timeout.
fn config() -> Config {
    let servo = "[[slave]]\nkind = \"servo\"\nbandwidth_hz = 20.0\nposition_gain = 4.0\n";
    let axes: String = ["a", "b"]
        .iter()
        .zip(TIMEOUT_S)
        .enumerate()
        .map(|(i, (name, timeout_s))| {
            format!(
                "[[axis]]\nname = {name:?}\ndrive = {i}\nhoming_required = false\n\
                 scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
                 max = {{ speed = 20.0, acceleration = 200.0, deceleration = 200.0, jerk = 4000.0 }}\n\
                 defaults = {{ speed = 10.0, acceleration = 100.0, deceleration = 100.0, \
                 jerk = 2000.0, target_window = {WINDOW:?} }}\n\
                 target_monitoring = {{ dwell_s = {DWELL_S:?}, timeout_s = {timeout_s:?} }}\n"
            )
        })
        .collect();
    let config = gantry_tests::sim_config_text((DT * 1e6) as u32, &servo.repeat(2), "", &axes);
    for (i, c) in config.kernel_axes.iter().enumerate() {
        assert!(c.target_monitoring.enabled, "on by default on real axes");
        assert_eq!(config.axes[i].scaling().unwrap(), ball_screw_5mm());
    }
    config
}

/// Where drive `i`'s load is (mm), as the plant holds it: the simulator's truth, not
/// what the kernel was told.
fn drive_mm(rig: &Rig, i: usize) -> f64 {
    rig.servo(i, |s| ball_screw_5mm().counts_to_units(s.position_counts()))
}

fn axis_status(rig: &Rig, i: usize) -> gantry_kernel::axis::status::AxisStatus {
    *rig.engine.cycle.kernel.axis_status(i).unwrap()
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
    let config = config();
    let mut rig = Rig::new(&config);
    for i in 0..2 {
        rig.ctl
            .command(i, Command::Power(PowerCommand::Enable))
            .expect("queued");
    }
    for _ in 0..2000 {
        rig.cycle();
        if (0..2).all(|i| axis_status(&rig, i).state == AxisState::Standstill) {
            break;
        }
    }
    assert!((0..2).all(|i| axis_status(&rig, i).state == AxisState::Standstill));
    let start = [drive_mm(&rig, 0), drive_mm(&rig, 1)];
    let handles: Vec<CommandHandle> = (0..2)
        .map(|i| {
            let to = start[i] + TARGET_MM;
            let m = MovePtp::new(PositioningMode::AbsNormal, to);
            rig.ctl.command(i, Command::MovePtp(m)).expect("queued")
        })
        .collect();
    let targets = [start[0] + TARGET_MM, start[1] + TARGET_MM];
    let mut seen = [Seen::default(), Seen::default()];
    for _ in 0..10_000 {
        rig.cycle();
        let tick = rig.engine.cycle.kernel.tick();
        for i in 0..2 {
            let s = axis_status(&rig, i);
            // The status as of this cycle (the Controller's snapshot has it every few).
            let h = rig.status_now(&handles[i]).expect("the move was taken");
            let seen = &mut seen[i];
            if seen.ended.is_some() {
                continue;
            }
            seen.plant_mm.push((tick, drive_mm(&rig, i)));
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
    assert_eq!(axis_status(&rig, 0).state, AxisState::Standstill);

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
    assert_eq!(axis_status(&rig, 1).state, AxisState::ErrorStop);

    // Power on is refused at once in ErrorStop (in the cycle that takes it); Reset leaves
    // it and the axis stands.
    let enable = rig
        .ctl
        .command(1, Command::Power(PowerCommand::Enable))
        .expect("queued");
    rig.cycle();
    let Some(CommandStatus::Error(refused)) = rig.status_now(&enable) else {
        panic!("power on in ErrorStop: {:?}", rig.status_now(&enable));
    };
    assert!(refused.to_string().contains("ErrorStop"), "{refused}");
    for _ in 0..50 {
        rig.cycle();
    }
    let reset = rig.ctl.reset(1).expect("queued");
    rig.cycle();
    assert!(
        !matches!(rig.status_now(&reset), None | Some(CommandStatus::Error(_))),
        "reset: {:?}",
        rig.status_now(&reset)
    );
    assert_eq!(axis_status(&rig, 1).state, AxisState::Standstill);
    for _ in 0..500 {
        rig.cycle();
    }
    let locked = TestConditions {
        phase_locked: true,
        ..TestConditions::default()
    };
    let drives = DriveUnderTest::of_config(&config);
    let chain = rig.chain.lock().expect("the chain");
    assert_drive_invariants(&chain, &drives, DT, locked);
}
