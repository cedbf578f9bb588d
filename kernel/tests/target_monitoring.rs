//! Target position monitoring (issue 11 §5), lockstep with an injected actual position: a
//! positioning move is Done only once the actual has stayed in the target window for the
//! dwell time after the set value reached the target, or ends in Error after the timeout;
//! and PLCopen's rule that only Reset leaves ErrorStop (Power on is refused at once).

mod common;

use common::{linear, DT};
use gantry_kernel::axis::command::{
    BufferMode, Command, CommandError, MovePtp, PositioningMode, PowerCommand,
};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::{AxisFault, AxisStatus, FaultSummary};
use gantry_kernel::axis::{AxisConfig, AxisFeedback, ConfigError, TargetMonitoring};
use gantry_kernel::{AxisKind, Kernel};

const WINDOW: f64 = 0.001;
const DWELL_S: f64 = 0.010;
const TIMEOUT_S: f64 = 0.5;
/// Dwell in cycles (10 ms at 1 ms).
const DWELL_CYCLES: u64 = 10;

/// A real axis (test dynamics of `linear`) with monitoring on: window 0.001, dwell 10 ms,
/// timeout 0.5 s.
fn real(monitoring: bool) -> AxisConfig {
    let mut c = linear("x");
    c.kind = AxisKind::Real;
    c.defaults.target_window = WINDOW;
    c.target_monitoring = TargetMonitoring {
        enabled: monitoring,
        dwell_s: DWELL_S,
        timeout_s: TIMEOUT_S,
    };
    c
}

/// A drive in the loop: its actual position moves each cycle by `gain` × (last set
/// position − actual) + `bias` (a slow position loop; `bias` a friction that holds it off).
struct Drive {
    actual: f64,
    set: f64,
    gain: f64,
    bias: f64,
}

impl Drive {
    fn feedback(&mut self) -> [AxisFeedback; 1] {
        self.actual += self.gain * (self.set - self.actual) + self.bias;
        [AxisFeedback {
            position: self.actual,
            velocity: 0.0,
            operation_enabled: true,
            fault: None,
            ..Default::default()
        }]
    }
}

/// One cycle of a lockstep run.
#[derive(Clone, Copy, Debug)]
struct Cycle {
    tick: u64,
    status: AxisStatus,
    handle: CommandStatus,
}

/// A kernel with the axis enabled on the drive (which stands at 0).
fn enabled(cfg: AxisConfig, gain: f64, bias: f64) -> (Kernel, Drive) {
    let mut k = Kernel::new(DT, vec![cfg]).unwrap();
    let mut d = Drive {
        actual: 0.0,
        set: 0.0,
        gain,
        bias: 0.0,
    };
    let h = k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    let fb = d.feedback();
    k.step(&fb);
    assert_eq!(k.command_status(h), CommandStatus::Done);
    d.bias = bias;
    (k, d)
}

/// Steps with the drive in the loop until `h` is final; every cycle recorded.
fn run(k: &mut Kernel, d: &mut Drive, h: HandleId, max: usize) -> Vec<Cycle> {
    let mut out = Vec::new();
    for _ in 0..max {
        let fb = d.feedback();
        d.set = k.step(&fb)[0].position;
        out.push(Cycle {
            tick: k.tick(),
            status: *k.axis_status(0).unwrap(),
            handle: k.command_status(h),
        });
        if k.command_status(h).is_final() {
            return out;
        }
    }
    panic!(
        "{h:?} not final after {max} cycles: {:?}",
        k.command_status(h)
    );
}

fn to(target: f64) -> Command {
    Command::MovePtp(
        MovePtp::new(PositioningMode::AbsNormal, target)
            .speed(10.0)
            .accel(100.0, 100.0),
    )
}

/// The first cycle whose set value stands at `target` at rest (the profile ended).
fn set_reached(trace: &[Cycle], target: f64) -> u64 {
    trace
        .iter()
        .find(|c| c.status.set.p == target && c.status.set.v == 0.0)
        .map(|c| c.tick)
        .expect("the set value reaches the target")
}

#[test]
fn a_slow_drive_is_done_only_after_it_settled_in_the_window_for_the_dwell() {
    // Time constant 20 ms: the actual trails the set value by v·τ = 0.2 while moving.
    let (mut k, mut d) = enabled(real(true), 0.05, 0.0);
    let h = k.command(0, to(1.0)).unwrap();
    let trace = run(&mut k, &mut d, h, 5_000);
    let done = trace.last().unwrap();
    assert_eq!(done.handle, CommandStatus::Done);
    let t_set = set_reached(&trace, 1.0);
    let inside = |c: &Cycle| (c.status.actual_position - 1.0).abs() <= WINDOW;
    // The unbroken run of in-window cycles that ends with Done, and where it began.
    let run_start = trace
        .iter()
        .rev()
        .take_while(|c| inside(c))
        .last()
        .unwrap()
        .tick;
    assert!(
        run_start > t_set,
        "the drive lags: it enters the window after the set value reached the target \
         (window entered at {run_start}, set value at {t_set})"
    );
    assert_eq!(
        done.tick,
        run_start + DWELL_CYCLES,
        "Done exactly when the window has held for the dwell"
    );
    for c in &trace {
        // The status bit says when the actual is in the window, cycle by cycle.
        assert_eq!(c.status.bits.in_target_window, inside(c), "{c:?}");
        if c.tick < done.tick {
            assert_eq!(c.handle, CommandStatus::Active, "{c:?}");
            assert_eq!(c.status.state, AxisState::DiscreteMotion, "{c:?}");
        }
        if c.tick >= t_set {
            assert_eq!(c.status.set.p, 1.0, "the set value holds the target");
            assert!(!c.status.bits.moving);
        }
    }
    assert_eq!(done.status.state, AxisState::Standstill);
    assert_eq!(k.axes()[0].refused_transitions(), 0);

    // The same drive without monitoring: Done when the set value reaches the target.
    let (mut k, mut d) = enabled(real(false), 0.05, 0.0);
    let h = k.command(0, to(1.0)).unwrap();
    let trace = run(&mut k, &mut d, h, 5_000);
    let last = trace.last().unwrap();
    assert_eq!(last.tick, set_reached(&trace, 1.0));
    assert!(
        !last.status.bits.in_target_window,
        "Done before in position"
    );
}

#[test]
fn a_drive_that_leaves_the_window_restarts_the_dwell() {
    let (mut k, mut d) = enabled(real(true), 1.0, 0.0);
    let h = k.command(0, to(1.0)).unwrap();
    // Follow exactly until the set value arrives, then knock the actual out once.
    let mut t_set = None;
    let mut knocked = None;
    for _ in 0..5_000 {
        let mut fb = d.feedback();
        if let (Some(t), None) = (t_set, knocked) {
            if k.tick() + 1 == t + 5 {
                fb[0].position += 10.0 * WINDOW;
                knocked = Some(k.tick() + 1);
            }
        }
        d.set = k.step(&fb)[0].position;
        let s = k.axis_status(0).unwrap();
        if t_set.is_none() && s.set.p == 1.0 && s.set.v == 0.0 {
            t_set = Some(k.tick());
        }
        if k.command_status(h).is_final() {
            break;
        }
    }
    let knocked = knocked.expect("knocked out during the dwell");
    assert_eq!(k.command_status(h), CommandStatus::Done);
    // Back in the window the cycle after the knock; the dwell counts from there.
    assert_eq!(k.tick(), knocked + 1 + DWELL_CYCLES);
}

#[test]
fn a_drive_that_never_settles_ends_the_move_in_error_after_the_timeout() {
    // A friction that holds the actual 0.005 short of wherever it is sent.
    let (mut k, mut d) = enabled(real(true), 1.0, 0.0);
    d.bias = 0.0;
    let h = k.command(0, to(1.0)).unwrap();
    let mut trace = Vec::new();
    for _ in 0..5_000 {
        let mut fb = d.feedback();
        fb[0].position -= 0.005;
        d.set = k.step(&fb)[0].position;
        trace.push(Cycle {
            tick: k.tick(),
            status: *k.axis_status(0).unwrap(),
            handle: k.command_status(h),
        });
        if k.command_status(h).is_final() {
            break;
        }
    }
    let t_set = set_reached(&trace, 1.0);
    let last = trace.last().unwrap();
    let timeout_cycles = (TIMEOUT_S / DT).round() as u64;
    assert_eq!(
        last.tick,
        t_set + timeout_cycles,
        "Error exactly at the timeout"
    );
    for c in &trace[..trace.len() - 1] {
        assert_eq!(c.handle, CommandStatus::Active, "{c:?}");
        assert_eq!(c.status.state, AxisState::DiscreteMotion);
        assert!(!c.status.bits.in_target_window);
    }
    let CommandStatus::Error(e) = last.handle else {
        panic!("not an error: {:?}", last.handle);
    };
    let CommandError::TargetNotReached {
        command,
        target,
        actual,
        window,
        timeout_s,
    } = e
    else {
        panic!("wrong error: {e:?}");
    };
    assert_eq!(
        (command, target, window, timeout_s),
        ("MovePtp", 1.0, WINDOW, TIMEOUT_S)
    );
    assert!((actual - 0.995).abs() < 1e-12, "{actual}");
    let text = e.to_string();
    for part in ["MovePtp", "0.995", "±0.001", "target 1", "0.5 s"] {
        assert!(text.contains(part), "{part:?} missing from {text:?}");
    }
    assert_eq!(last.status.state, AxisState::ErrorStop);
    assert!(last.status.bits.error);
    assert!(matches!(
        last.status.error,
        Some(AxisFault::TargetNotReached { target, window, .. }) if target == 1.0 && window == WINDOW
    ));
    // PLCopen: only Reset leaves ErrorStop; power on is refused at once, naming why.
    let e = k
        .command(0, Command::Power(PowerCommand::Enable))
        .unwrap_err();
    assert!(matches!(
        e,
        CommandError::InErrorStop {
            command: "Power.Enable",
            cause: FaultSummary::TargetNotReached { .. }
        }
    ));
    let text = e.to_string();
    assert!(
        text.contains("ErrorStop") && text.contains("target 1 not reached"),
        "{text}"
    );
    let mut fb = d.feedback();
    fb[0].position -= 0.005;
    k.step(&fb);
    let r = k.command(0, Command::Reset).unwrap();
    assert_eq!(k.command_status(r), CommandStatus::Done);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
    assert_eq!(k.axes()[0].refused_transitions(), 0);
}

#[test]
fn a_buffered_move_starts_once_the_previous_is_in_position_a_blending_one_at_once() {
    // Buffered (PLCopen: starts when the previous is Done): now after it settled.
    let (mut k, mut d) = enabled(real(true), 0.05, 0.0);
    let first = k.command(0, to(1.0)).unwrap();
    let second = k
        .command(
            0,
            Command::MovePtp(
                MovePtp::new(PositioningMode::AbsNormal, 2.0)
                    .speed(10.0)
                    .accel(100.0, 100.0)
                    .buffered(BufferMode::Buffered),
            ),
        )
        .unwrap();
    let mut first_done = None;
    let mut second_active = None;
    let mut t_set = None;
    for _ in 0..5_000 {
        let fb = d.feedback();
        d.set = k.step(&fb)[0].position;
        let s = *k.axis_status(0).unwrap();
        if t_set.is_none() && s.set.p == 1.0 && s.set.v == 0.0 {
            t_set = Some(k.tick());
        }
        if first_done.is_none() && k.command_status(first) == CommandStatus::Done {
            first_done = Some(k.tick());
            assert_eq!(s.state, AxisState::DiscreteMotion, "the next move runs");
        }
        if second_active.is_none() && k.command_status(second) == CommandStatus::Active {
            second_active = Some(k.tick());
        }
        if first_done.is_none() {
            assert_eq!(k.command_status(second), CommandStatus::Busy);
            if t_set.is_some() {
                assert_eq!(s.set.p, 1.0, "stands at the first target while it settles");
            }
        }
        if k.command_status(second).is_final() {
            break;
        }
    }
    let (t_set, first_done) = (t_set.unwrap(), first_done.unwrap());
    assert!(first_done > t_set + DWELL_CYCLES, "waited for the drive");
    assert_eq!(
        second_active,
        Some(first_done),
        "starts in the cycle the first is Done"
    );
    assert_eq!(k.command_status(second), CommandStatus::Done);

    // BlendingLow: takes over when the set value arrives, no standstill cycle, no wait.
    let (mut k, mut d) = enabled(real(true), 0.05, 0.0);
    let first = k.command(0, to(1.0)).unwrap();
    let second = k
        .command(
            0,
            Command::MovePtp(
                MovePtp::new(PositioningMode::AbsNormal, 2.0)
                    .speed(10.0)
                    .accel(100.0, 100.0)
                    .buffered(BufferMode::BlendingLow),
            ),
        )
        .unwrap();
    let mut first_done = false;
    for _ in 0..5_000 {
        let fb = d.feedback();
        d.set = k.step(&fb)[0].position;
        let s = *k.axis_status(0).unwrap();
        if !first_done && k.command_status(first) == CommandStatus::Done {
            first_done = true;
            assert!(s.set.v > 0.0, "blended at speed: {s:?}");
            assert!(
                (s.actual_position - 1.0).abs() > WINDOW,
                "did not wait for the actual"
            );
        }
        if k.command_status(second).is_final() {
            break;
        }
        assert!(first_done || s.set.p < 1.0);
    }
    assert!(first_done);
    assert_eq!(k.command_status(second), CommandStatus::Done);
}

#[test]
fn halt_is_done_at_standstill_without_waiting_for_the_actual() {
    let (mut k, mut d) = enabled(real(true), 0.05, 0.0);
    k.command(0, to(1.0)).unwrap();
    for _ in 0..50 {
        let fb = d.feedback();
        d.set = k.step(&fb)[0].position;
    }
    let h = k
        .command(
            0,
            Command::Halt {
                mode: gantry_kernel::axis::command::HaltMode::Normal,
                deceleration: None,
            },
        )
        .unwrap();
    let trace = run(&mut k, &mut d, h, 5_000);
    let last = trace.last().unwrap();
    assert_eq!(last.handle, CommandStatus::Done);
    assert_eq!(last.status.set.v, 0.0);
    assert!(
        (last.status.actual_position - last.status.set.p).abs() > WINDOW,
        "Done at zero set velocity while the drive still trails"
    );
}

#[test]
fn power_on_in_error_stop_is_refused_at_once_and_a_pending_one_ends_with_the_fault() {
    let mut k = Kernel::new(DT, vec![real(true)]).unwrap();
    let fb = |on, fault| {
        [AxisFeedback {
            position: 0.0,
            velocity: 0.0,
            operation_enabled: on,
            fault,
            ..Default::default()
        }]
    };
    // An enable waiting for the drive when the drive faults: it ends in that cycle.
    let h = k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    k.step(&fb(false, None));
    assert_eq!(k.command_status(h), CommandStatus::Busy);
    k.step(&fb(false, Some(0x7500)));
    assert_eq!(
        k.command_status(h),
        CommandStatus::Error(CommandError::InErrorStop {
            command: "Power.Enable",
            cause: FaultSummary::Drive { code: 0x7500 },
        })
    );
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::ErrorStop);
    // A new one is refused when given, naming the state and the error.
    let e = k
        .command(0, Command::Power(PowerCommand::Enable))
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "Power.Enable is refused: the axis is in ErrorStop (drive fault, error code 0x7500); \
         only Reset leaves ErrorStop"
    );
    // Reset (the drive clears its fault) leads to Disabled; then power on works.
    let r = k.command(0, Command::Reset).unwrap();
    k.step(&fb(false, None));
    assert_eq!(k.command_status(r), CommandStatus::Done);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Disabled);
    let h = k.command(0, Command::Power(PowerCommand::Enable)).unwrap();
    k.step(&fb(true, None));
    assert_eq!(k.command_status(h), CommandStatus::Done);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Standstill);
    assert_eq!(k.axes()[0].refused_transitions(), 0);
}

#[test]
fn monitoring_is_on_for_real_axes_by_default_and_its_times_are_checked() {
    assert!(
        AxisConfig::new("x", AxisKind::Real)
            .target_monitoring
            .enabled
    );
    for kind in [AxisKind::Simulated, AxisKind::Virtual] {
        assert!(!AxisConfig::new("x", kind).target_monitoring.enabled);
    }
    for (dwell_s, timeout_s) in [
        (0.5, 0.5),
        (-0.1, 1.0),
        (0.0, f64::INFINITY),
        (f64::NAN, 1.0),
    ] {
        let mut c = AxisConfig::new("x", AxisKind::Real);
        c.target_monitoring.dwell_s = dwell_s;
        c.target_monitoring.timeout_s = timeout_s;
        let e = c.validate().unwrap_err();
        assert!(
            matches!(e, ConfigError::TargetMonitoring { ref axis, .. } if axis == "x"),
            "{e:?}"
        );
        assert!(e.to_string().contains("target_monitoring"), "{e}");
    }
}
