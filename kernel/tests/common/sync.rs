//! Helpers of the synchronised-motion tests: a virtual master, followers, and the
//! no-jump check.

use super::*;
use gantry_kernel::axis::command::{Command, MoveDirection, MoveVelocity};
use gantry_kernel::axis::status::AxisStatus;
use gantry_kernel::profile::RampType;
use gantry_kernel::{AxisConfig, AxisKind, Kernel};

/// Unwrapped position of a status (turns · period + p).
pub fn unwrapped(s: &AxisStatus, period: Option<f64>) -> f64 {
    s.turns as f64 * period.unwrap_or(0.0) + s.set.p
}

/// Checks that consecutive set values never jump: the position moves by what the
/// velocities say, the velocity by at most `amax · dt`, the acceleration by at most
/// `jmax · dt` (each with a small margin for rounding).
pub fn assert_smooth(trace: &[AxisStatus], period: Option<f64>, amax: f64, jmax: f64, what: &str) {
    for (i, w) in trace.windows(2).enumerate() {
        let (a, b) = (&w[0], &w[1]);
        let dp = unwrapped(b, period) - unwrapped(a, period);
        let vbar = 0.5 * (a.set.v + b.set.v);
        let dp_err = (dp - vbar * DT).abs();
        assert!(
            dp_err <= 0.05 * amax * DT * DT + 1e-9,
            "{what}: cycle {i}: position step {dp} against velocities {} → {}",
            a.set.v,
            b.set.v
        );
        let dv = (b.set.v - a.set.v).abs();
        assert!(
            dv <= amax * DT * 1.001 + 1e-9,
            "{what}: cycle {i}: velocity step {dv} (v {} → {})",
            a.set.v,
            b.set.v
        );
        let da = (b.set.a - a.set.a).abs();
        assert!(
            da <= jmax * DT * 1.001 + 1e-6,
            "{what}: cycle {i}: acceleration step {da} (a {} → {})",
            a.set.a,
            b.set.a
        );
    }
}

/// A virtual master (vmax 1000) and followers.
pub fn virtual_master() -> AxisConfig {
    let mut c = linear("m");
    c.kind = AxisKind::Virtual;
    c.max.vmax = 1000.0;
    c.max.amax = 1000.0;
    c.max.dmax = 1000.0;
    c.defaults.ramp = RampType::SCurve;
    c.defaults.jerk = 10_000.0;
    c.defaults.acceleration = 200.0;
    c.defaults.deceleration = 200.0;
    c
}

pub fn follower(name: &str) -> AxisConfig {
    let mut c = linear(name);
    c.max.vmax = 500.0;
    c.defaults.ramp = RampType::SCurve;
    c.defaults.acceleration = 500.0;
    c.defaults.deceleration = 500.0;
    c.defaults.jerk = 20_000.0;
    c
}

pub fn velocity(v: f64) -> Command {
    let dir = if v >= 0.0 {
        MoveDirection::Positive
    } else {
        MoveDirection::Negative
    };
    Command::MoveVelocity(MoveVelocity::new(dir, v.abs()))
}

pub fn steps(k: &mut Kernel, n: usize) -> Vec<(AxisStatus, AxisStatus)> {
    (0..n)
        .map(|_| {
            k.step(&[]);
            (*k.axis_status(0).unwrap(), *k.axis_status(1).unwrap())
        })
        .collect()
}
