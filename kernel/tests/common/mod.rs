//! Helpers shared by the axis tests: lockstep runs of a kernel with simulated axes.
#![allow(dead_code)]

pub mod commands;
pub mod sync;

use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::status::AxisStatus;
use gantry_kernel::mechanics::Modulo;
use gantry_kernel::profile::{Limits, RampType};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};

/// Cycle time of the tests (1 ms).
pub const DT: f64 = 0.001;

/// A simulated linear axis: vmax 100, amax/dmax 1000, jmax 1e5, defaults v=10 a=d=10,
/// trapezoid, homed not required.
pub fn linear(name: &str) -> AxisConfig {
    let mut c = AxisConfig::new(name, AxisKind::Simulated);
    c.max = Limits {
        vmax: 100.0,
        amax: 1000.0,
        dmax: 1000.0,
        jmax: 100_000.0,
    };
    c.defaults.speed = 10.0;
    c.defaults.acceleration = 10.0;
    c.defaults.deceleration = 10.0;
    c.defaults.jerk = 100.0;
    c.defaults.ramp = RampType::Trapezoid;
    c.defaults.target_window = 0.001;
    c.homing_required = false;
    c
}

/// A simulated rotary modulo axis with period 360.
pub fn rotary(name: &str) -> AxisConfig {
    let mut c = linear(name);
    c.mechanics.kind = gantry_kernel::mechanics::MotionKind::Rotary;
    c.mechanics.modulo = Modulo::new(360.0);
    c.defaults.speed = 90.0;
    c.defaults.acceleration = 360.0;
    c.defaults.deceleration = 360.0;
    c
}

/// A kernel with the given axes, all enabled.
pub fn kernel(axes: Vec<AxisConfig>) -> Kernel {
    let n = axes.len();
    let mut k = Kernel::new(DT, axes).expect("valid config");
    for i in 0..n {
        k.command(i, Command::Power(PowerCommand::Enable))
            .expect("enable");
    }
    k.step(&[]);
    k
}

/// Steps `n` cycles and records axis `axis`'s status after each.
pub fn run(k: &mut Kernel, axis: usize, n: usize) -> Vec<AxisStatus> {
    (0..n)
        .map(|_| {
            k.step(&[]);
            *k.axis_status(axis).expect("axis")
        })
        .collect()
}

/// Steps until the handle is final (at most `max` cycles); returns the recorded statuses.
pub fn run_until_final(k: &mut Kernel, axis: usize, h: HandleId, max: usize) -> Vec<AxisStatus> {
    let mut out = Vec::new();
    for _ in 0..max {
        k.step(&[]);
        out.push(*k.axis_status(axis).expect("axis"));
        if k.command_status(h).is_final() {
            return out;
        }
    }
    panic!(
        "command {h:?} not final after {max} cycles: {:?}",
        k.command_status(h)
    );
}

/// Unwrapped set position (turns × period + wrapped position).
pub fn unwrapped(s: &AxisStatus, period: f64) -> f64 {
    s.turns as f64 * period + s.set.p
}

/// Moves axis `axis` absolutely (AbsNormal) and runs until done.
pub fn move_abs(k: &mut Kernel, axis: usize, target: f64) -> Vec<AxisStatus> {
    let h = k
        .command(
            axis,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, target)),
        )
        .expect("move accepted");
    let out = run_until_final(k, axis, h, 1_000_000);
    assert_eq!(k.command_status(h), CommandStatus::Done);
    out
}
