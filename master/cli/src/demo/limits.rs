//! The demos' check that an axis' set values stay within its maxima, every cycle: the
//! synchronised axes ([`super::sync`]) and the axis group's ([`super::group`]) use it, so
//! that both judge by one rule.

use gantry_kernel::axis::status::AxisStatus;
use gantry_kernel::profile::Limits;

use super::DemoError;

/// Fails when axis `name`'s set speed is beyond its maximum, or its set acceleration
/// beyond the maximum of its kind (the kernel's own rule: deceleration when the
/// acceleration opposes the velocity); `time_s` dates the failure.
pub fn within_limits(
    name: &str,
    s: &AxisStatus,
    max: &Limits,
    time_s: f64,
) -> Result<(), DemoError> {
    let (v, a) = (s.set.v, s.set.a);
    let (what, amax) = if a * v < 0.0 {
        ("deceleration", max.dmax)
    } else {
        ("acceleration", max.amax)
    };
    let beyond = if v.abs() > max.vmax * (1.0 + 1e-9) {
        Some(("speed", v, max.vmax))
    } else if a.abs() > amax * (1.0 + 1e-6) {
        Some((what, a, amax))
    } else {
        None
    };
    match beyond {
        None => Ok(()),
        Some((what, value, max)) => Err(DemoError::Fault(format!(
            "{name}: set {what} {value:.3} beyond its maximum {max} at t = {time_s:.3} s"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_kernel::profile::KinematicState;

    #[test]
    fn speed_then_acceleration_or_deceleration_is_judged_against_its_own_maximum() {
        let max = Limits {
            vmax: 100.0,
            amax: 1000.0,
            dmax: 500.0,
            jmax: 1e5,
        };
        let at = |v: f64, a: f64| AxisStatus {
            set: KinematicState {
                v,
                a,
                ..KinematicState::default()
            },
            ..AxisStatus::default()
        };
        within_limits("x", &at(100.0, 1000.0), &max, 0.0).unwrap();
        within_limits("x", &at(-100.0, 500.0), &max, 0.0).unwrap();
        let e = within_limits("x", &at(-100.0, 600.0), &max, 1.5).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the demo stopped: x: set deceleration 600.000 beyond its maximum 500 at t = 1.500 s"
        );
        let e = within_limits("y", &at(100.1, 0.0), &max, 2.0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the demo stopped: y: set speed 100.100 beyond its maximum 100 at t = 2.000 s"
        );
    }
}
