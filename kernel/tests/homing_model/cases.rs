//! One homing run against the model, checked: limits on every sample, status bits in
//! order, and the end the seeds define.

use super::expect::{Expect, MoveHomeExpect};
use super::*;
use gantry_kernel::axis::command::{Command, CommandError};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use gantry_kernel::homing::{
    HomingMode, HomingStatus, MoveHome, MoveHomeCall, StepAbsoluteSwitch, SwitchConfig,
};

/// Runs one case; returns the samples or a description of what went wrong.
pub fn run_step_switch(
    layout: Layout,
    x0: f64,
    p: StepAbsoluteSwitch,
    expect: Expect,
) -> Result<Vec<Sample>, String> {
    run_step_switch_lag(layout, DEFAULT_LAG_S, x0, p, expect)
}

/// [`run_step_switch`] with the load lagging `lag_s` behind the set position.
pub fn run_step_switch_lag(
    layout: Layout,
    lag_s: f64,
    x0: f64,
    p: StepAbsoluteSwitch,
    expect: Expect,
) -> Result<Vec<Sample>, String> {
    run_step_switch_at(layout, lag_s, DT, x0, p, expect)
}

/// [`run_step_switch_lag`] at cycle time `dt`.
pub fn run_step_switch_at(
    layout: Layout,
    lag_s: f64,
    dt: f64,
    x0: f64,
    p: StepAbsoluteSwitch,
    expect: Expect,
) -> Result<Vec<Sample>, String> {
    let mut rig = Rig::with_cycle(axis_config(), layout, x0, dt);
    rig.m.lag_s = lag_s;
    let h = rig
        .k
        .command(0, Command::StepAbsoluteSwitch(p))
        .map_err(|e| format!("refused: {e}"))?;
    let mut out = Vec::new();
    let max_cycles = (1000.0 / rig.m.dt) as usize; // 1000 s of axis time
    let st = rig.run_until_final(h, max_cycles, &mut out);
    check_limits(&out, p.velocity, p.acceleration.max(p.deceleration), p.jerk)?;
    if let CommandStatus::Error(e) = st {
        return Err(named_error(&mut rig, e));
    }
    if st != CommandStatus::Done {
        return Err(format!("ended {st:?}"));
    }
    let last = out.last().copied().ok_or("no samples")?;
    let s = last.status;
    if s.state != AxisState::Standstill || !s.bits.homed {
        return Err(format!("state {:?}, homed {}", s.state, s.bits.homed));
    }
    let seq = check_status_sequence(&out)?;
    let h = s.homing;
    if !(h.started && h.switch_found && h.reference_found && h.reference_set) {
        return Err(format!("final status {h:?} (sequence {seq:?})"));
    }
    match expect {
        Expect::AtOnce => {
            if out.iter().any(|x| x.status.set.v != 0.0) {
                return Err("moved although the level held at the start".into());
            }
            if (s.set.p - p.position).abs() > 1e-9 {
                return Err(format!("position {} != {}", s.set.p, p.position));
            }
        }
        Expect::Edge { at, moving } => {
            // Axis frame − drive frame is the same everywhere: the reference (drive frame
            // `at`) has the position `p.position`.
            let got = s.set.p - last.setpoint.position;
            let want = p.position - at;
            if (got - want).abs() > 1e-9 {
                return Err(format!(
                    "reference at drive {} (want {at})",
                    last.setpoint.position - (s.set.p - p.position)
                ));
            }
            let found = out
                .iter()
                .find(|x| x.status.homing.reference_found)
                .ok_or("reference never found")?;
            let v = found.status.actual_velocity;
            if v * moving <= 0.0 {
                return Err(format!("found moving {v}, want sign {moving}"));
            }
            if (last.setpoint.position - at) * moving < -1e-9 {
                return Err(format!(
                    "stands at {} before the edge {at} (moving {moving})",
                    last.setpoint.position
                ));
            }
        }
    }
    Ok(out)
}

pub fn rig_for(layout: Layout, p: &MoveHome, x0: f64) -> Rig {
    rig_for_at(layout, p, x0, DT)
}

/// [`rig_for`] at cycle time `dt`.
pub fn rig_for_at(layout: Layout, _p: &MoveHome, x0: f64, dt: f64) -> Rig {
    let mut rig = Rig::with_cycle(axis_config(), layout, x0, dt);
    rig.m.lag_s = DEFAULT_LAG_S;
    // The probe follows the kernel's routing (`AxisSetpoint::probe_on_limit`, see
    // `Rig::cycle`): a LimitSwitch run gets the limit switch's edges only if it asks.
    rig
}

pub fn run_move_home(
    layout: Layout,
    p: MoveHome,
    x0: f64,
    expect: MoveHomeExpect,
) -> Result<(), String> {
    run_move_home_lag(layout, DEFAULT_LAG_S, p, x0, expect)
}

/// [`run_move_home`] with the load lagging `lag_s` behind the set position.
pub fn run_move_home_lag(
    layout: Layout,
    lag_s: f64,
    p: MoveHome,
    x0: f64,
    expect: MoveHomeExpect,
) -> Result<(), String> {
    run_move_home_at(layout, lag_s, DT, p, x0, expect)
}

/// [`run_move_home_lag`] at cycle time `dt`.
pub fn run_move_home_at(
    layout: Layout,
    lag_s: f64,
    dt: f64,
    p: MoveHome,
    x0: f64,
    expect: MoveHomeExpect,
) -> Result<(), String> {
    let mut rig = rig_for_at(layout, &p, x0, dt);
    rig.m.lag_s = lag_s;
    let h = match rig.k.command(0, Command::MoveHome(MoveHomeCall::all(p))) {
        Ok(h) => h,
        Err(e) if expect == MoveHomeExpect::Refused => {
            return match e {
                CommandError::HomingParameter {
                    parameter: "Mode", ..
                } => Ok(()),
                e => Err(format!("refused with {e}")),
            };
        }
        Err(e) => return Err(format!("refused: {e}")),
    };
    if expect == MoveHomeExpect::Refused {
        return Err("accepted SwitchingEdge without a switch".into());
    }
    let mut out = Vec::new();
    let max_cycles = (1000.0 / rig.m.dt) as usize; // 1000 s of axis time
    let st = rig.run_until_final(h, max_cycles, &mut out);
    let vmax = p.speed_switch_search.max(p.speed_reference_search);
    check_limits(&out, vmax, p.acceleration, p.jerk)?;
    let seq = check_status_sequence(&out)?;
    let last = *out.last().ok_or("no samples")?;
    let s = last.status;
    match expect {
        MoveHomeExpect::Refused => unreachable!(),
        MoveHomeExpect::Limit(side) => {
            let CommandStatus::Error(e) = st else {
                return Err(format!("ended {st:?}, want the {side}"));
            };
            if e.to_string() != format!("MoveHome: {side} reached") {
                return Err(format!("error {e}"));
            }
            rig.run(2000, &mut out);
            let s = rig.k.axis_status(0).unwrap();
            if s.state != AxisState::ErrorStop
                || s.error != Some(AxisFault::LimitSwitch { side })
                || s.set.v != 0.0
                || s.bits.homed
            {
                return Err(format!("after the limit: {s:?}"));
            }
            Ok(())
        }
        MoveHomeExpect::Reference(r) => {
            if let CommandStatus::Error(e) = st {
                return Err(named_error(&mut rig, e));
            }
            if st != CommandStatus::Done {
                return Err(format!("ended {st:?}"));
            }
            if s.state != AxisState::Standstill || !s.bits.homed {
                return Err(format!("state {:?} homed {}", s.state, s.bits.homed));
            }
            // The drive stands at reference + ReferenceOffset, and that is NormalPosition.
            let at = last.setpoint.position;
            if (at - (r + p.reference_offset)).abs() > 1e-9 {
                return Err(format!(
                    "stands at drive {at}, want {} (reference {r})",
                    r + p.reference_offset
                ));
            }
            if (s.set.p - p.normal_position).abs() > 1e-9 {
                return Err(format!("position {} != NormalPosition", s.set.p));
            }
            let all = HomingStatus {
                started: true,
                switch_found: true,
                reference_found: true,
                reference_set: true,
            };
            if s.homing != all {
                return Err(format!("status {:?}", s.homing));
            }
            // The reference is crossed at the fine speed (seed 000: SpeedReferenceSearch).
            let found = out
                .iter()
                .find(|x| x.status.homing.reference_found)
                .ok_or("reference never found")?;
            let v = found.status.set.v.abs();
            if v > p.speed_reference_search * (1.0 + 1e-6) {
                return Err(format!(
                    "reference crossed at {v}, above SpeedReferenceSearch {}",
                    p.speed_reference_search
                ));
            }
            // Two phases (and a zero pulse behind a switch): "switch found" comes first.
            let separate = matches!(
                p.mode,
                HomingMode::ZeroPulse2Phase | HomingMode::SwitchingEdge2Phase
            ) || (p.mode == HomingMode::ZeroPulse1Phase
                && p.switch_config != SwitchConfig::NoSwitch);
            let has_switch_only = seq.iter().any(|h| h.switch_found && !h.reference_found);
            if separate != has_switch_only {
                return Err(format!("status sequence {seq:?}"));
            }
            Ok(())
        }
    }
}

/// Lag of the load behind the set position in the matrix tests (s).
pub const DEFAULT_LAG_S: f64 = 0.004;

/// Prefix of the message for a run that ended in a named homing error with the axis
/// stopped in ErrorStop.
pub const NAMED_ERROR: &str = "named error: ";

/// A run ended in `e`: the axis must come to a stop in ErrorStop, not homed. The message
/// starts with [`NAMED_ERROR`] when it did and `e` is a homing error.
fn named_error(rig: &mut Rig, e: CommandError) -> String {
    let mut rest = Vec::new();
    rig.run(5000, &mut rest);
    let s = rig.k.axis_status(0).expect("axis");
    let stopped = s.state == AxisState::ErrorStop && s.set.v == 0.0 && !s.bits.homed;
    let named = matches!(e, CommandError::Homing(_));
    if stopped && named {
        format!("{NAMED_ERROR}{e}")
    } else {
        format!(
            "error {e:?}, then {:?} v {} homed {}",
            s.state, s.set.v, s.bits.homed
        )
    }
}
