//! Behaviour of the servo model, through its process data as a master sees it. Lockstep:
//! each `cycle` is one 1 ms application period.

use super::*;
use crate::esc::registers::PROCESS_RAM;
use gantry_drives::cia402::Statusword;
use objects::*;

const DT: f64 = 0.001;
const OUT: [ObjectId; 6] = [
    CONTROLWORD,
    MODES_OF_OPERATION,
    TARGET_POSITION,
    TARGET_VELOCITY,
    TARGET_TORQUE,
    TOUCH_PROBE_FUNCTION,
];
const IN: [ObjectId; 13] = [
    STATUSWORD,
    POSITION_ACTUAL_VALUE,
    VELOCITY_ACTUAL_VALUE,
    TORQUE_ACTUAL_VALUE,
    ERROR_CODE,
    MODES_OF_OPERATION_DISPLAY,
    FOLLOWING_ERROR_ACTUAL_VALUE,
    TOUCH_PROBE_STATUS,
    TOUCH_PROBE_POS1_POS_VALUE,
    TOUCH_PROBE_POS1_NEG_VALUE,
    TOUCH_PROBE_POS2_POS_VALUE,
    TOUCH_PROBE_POS2_NEG_VALUE,
    DIGITAL_INPUTS,
];

/// What the master reads.
#[derive(Clone, Copy, Debug)]
struct Inputs {
    sw: Statusword,
    position: i32,
    velocity: i32,
    torque: i16,
    error: u16,
    mode: i8,
    following: i32,
    tp_status: u16,
    tp_pos1: i32,
    tp_pos1_neg: i32,
    tp_pos2: i32,
    tp_pos2_neg: i32,
    digital_inputs: u32,
}

/// A drive with every object mapped, and what the master writes to it.
struct Rig {
    d: ServoDrive,
    mem: Memory,
    cw: u16,
    mode: i8,
    target: i32,
    velocity: i32,
    torque: i16,
    tp: u16,
}

impl Rig {
    fn new(start: i32, params: ServoParams) -> Self {
        let mut d = ServoDrive::with_params(PROCESS_RAM, PROCESS_RAM + 0x100, start, params);
        d.configure(PdoLayout {
            outputs: OUT.to_vec(),
            inputs: IN.to_vec(),
        });
        Self {
            d,
            mem: Memory::new(),
            cw: 0,
            mode: CSP,
            target: start,
            velocity: 0,
            torque: 0,
            tp: 0,
        }
    }

    /// Enabled in `mode` (target = actual, as a master enables).
    fn enabled(start: i32, params: ServoParams, mode: i8) -> Self {
        let mut r = Self::new(start, params);
        r.mode = mode;
        for cw in [0x06, 0x07, 0x0F, 0x0F] {
            r.cw = cw;
            r.cycle();
        }
        assert_eq!(r.d.state(), State::OperationEnabled);
        r
    }

    fn cycle(&mut self) -> Inputs {
        let mut b = [0u8; 15];
        b[0..2].copy_from_slice(&self.cw.to_le_bytes());
        b[2] = self.mode as u8;
        b[3..7].copy_from_slice(&self.target.to_le_bytes());
        b[7..11].copy_from_slice(&self.velocity.to_le_bytes());
        b[11..13].copy_from_slice(&self.torque.to_le_bytes());
        b[13..15].copy_from_slice(&self.tp.to_le_bytes());
        self.mem.pdi_write(PROCESS_RAM, &b);
        self.d.step(&mut self.mem, DT);
        self.inputs()
    }

    fn cycles(&mut self, n: usize) -> Inputs {
        for _ in 1..n {
            self.cycle();
        }
        self.cycle()
    }

    fn inputs(&self) -> Inputs {
        let mut b = [0u8; 41];
        self.mem.ecat_read(PROCESS_RAM + 0x100, &mut b, false);
        let i32_at = |at: usize| i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        Inputs {
            sw: Statusword(u16::from_le_bytes([b[0], b[1]])),
            position: i32_at(2),
            velocity: i32_at(6),
            torque: i16::from_le_bytes([b[10], b[11]]),
            error: u16::from_le_bytes([b[12], b[13]]),
            mode: b[14] as i8,
            following: i32_at(15),
            tp_status: u16::from_le_bytes([b[19], b[20]]),
            tp_pos1: i32_at(21),
            tp_pos1_neg: i32_at(25),
            tp_pos2: i32_at(29),
            tp_pos2_neg: i32_at(33),
            digital_inputs: i32_at(37) as u32,
        }
    }
}

fn p() -> ServoParams {
    ServoParams::default()
}

/// Counts per second at `rpm`.
fn rpm(rpm: f64) -> f64 {
    rpm / 60.0 * f64::from(p().counts_per_rev)
}

/// Torque (N·m) for acceleration `a` (counts/s²) of the default servo's inertia.
fn torque_for(a: f64) -> f64 {
    let p = p();
    p.inertia() * a * 2.0 * core::f64::consts::PI / f64::from(p.counts_per_rev)
}

#[test]
fn enables_through_the_state_machine_and_holds_without_moving_before() {
    let mut r = Rig::new(1000, p());
    r.target = 5000;
    for cw in [0x06, 0x07] {
        r.cw = cw;
        let i = r.cycle();
        assert_eq!(i.position, 1000, "does not move before Operation enabled");
    }
    r.cw = 0x0F;
    r.target = 1000;
    r.cycles(2);
    let i = r.cycles(100);
    assert_eq!(i.sw.state(), Some(State::OperationEnabled));
    assert_eq!(i.position, 1000);
    assert_ne!(
        i.sw.0 & statusword::MODE_SPECIFIC_12,
        0,
        "follows the target"
    );
    assert_eq!((i.following, i.mode), (0, CSP));
}

#[test]
fn a_one_count_step_settles_and_stays() {
    let mut r = Rig::enabled(0, p(), CSP);
    r.target = 1;
    let i = r.cycles(50);
    assert_eq!((i.position, i.following), (1, 0), "{i:?}");
    // It stays: every later cycle reads 1 with no motion left.
    for _ in 0..200 {
        let i = r.cycle();
        assert_eq!(i.position, 1);
        assert!(i.velocity.abs() < 100, "{i:?}");
    }
    assert!((r.d.position() - 1.0).abs() < 0.5);
}

#[test]
fn a_smooth_move_is_followed_with_a_small_following_error() {
    // A cycloidal move of 10 turns in 0.4 s: 50 rev/s (3000 rpm) top speed, 393 rev/s²
    // peak acceleration, as a ball-screw axis moves at 250 mm/s.
    let params = p();
    let rev = f64::from(params.counts_per_rev);
    let (d, t_move) = (10.0 * rev, 0.4);
    let mut r = Rig::enabled(0, params, CSP);
    let mut worst = 0;
    let mut peak_torque = 0;
    for k in 1..=500 {
        let t = (k as f64 * DT).min(t_move);
        let x = t / t_move;
        let s = d * (x - (2.0 * core::f64::consts::PI * x).sin() / (2.0 * core::f64::consts::PI));
        r.target = s.round() as i32;
        let i = r.cycle();
        worst = worst.max(i.following.abs());
        peak_torque = peak_torque.max(i.torque.abs());
    }
    assert_eq!(r.inputs().position, r.target);
    assert_eq!(r.d.record().faults, 0);
    // Figures: the worst following error, and the torque the acceleration needs
    // (J · 2π · 393 rev/s² ≈ 0.39 N·m ≈ 300 ‰ plus friction).
    eprintln!("worst following error {worst} counts, peak torque {peak_torque} ‰");
    // Measured 13 counts (0.04° of the motor, 0.5 µm on a 5 mm screw): velocity
    // feed-forward leaves the velocity PI only the acceleration to lag behind (no torque
    // feed-forward), and the model has no encoder noise.
    assert!(worst > 0 && worst < 40, "{worst} counts");
    assert!((300..400).contains(&peak_torque), "{peak_torque} ‰");
}

#[test]
fn a_large_step_saturates_the_torque_limit_and_is_limited_by_it() {
    let params = p();
    let mut r = Rig::enabled(0, params, CSP);
    // 10 000 counts in one cycle: under the setpoint step limit (0x607F · 1 ms = 13 107
    // counts), far more than the inertia can follow in one cycle.
    let step = 10_000;
    r.target = step;
    let i = r.cycle();
    assert_ne!(i.sw.0 & statusword::INTERNAL_LIMIT_ACTIVE, 0, "{i:?}");
    let peak = (params.peak_torque_nm / params.rated_torque_nm * 1000.0).round() as i16;
    // The first period's mean includes the current loop's rise; the second is all peak.
    assert!(i.torque > peak / 2, "{i:?}");
    let i = r.cycle();
    assert!(i.torque > peak - 10, "torque at the limit: {i:?}");
    // Bang-bang at peak torque is the fastest possible move: 2·√(d/a).
    let a_peak = (params.peak_torque_nm - params.coulomb_friction_nm) / torque_for(1.0);
    let fastest = 2.0 * (f64::from(step) / a_peak).sqrt();
    let mut settled_at = None;
    for n in 3..200 {
        let i = r.cycle();
        if settled_at.is_none() && (i.position - step).abs() <= 10 {
            settled_at = Some(n as f64 * DT);
        }
    }
    let t = settled_at.expect("settles");
    assert!(
        t >= fastest,
        "{t} s, physics allows no less than {fastest} s"
    );
    assert!(t < 0.05, "{t} s: the loops bring it in");
    assert_eq!(r.inputs().position, step);
    assert_eq!(r.d.record().faults, 0);
}

#[test]
fn following_error_faults_with_0x8611_after_the_window_time() {
    // A motor that gives no torque (commutation 90° electrical off) cannot follow.
    let mut params = p();
    params.counts_per_rev = 20_000;
    params.commutation_offset = (params.counts_per_rev / params.pole_pairs / 4) as i32;
    params.following_error_window = 1000;
    params.following_error_timeout_ms = 10;
    let mut r = Rig::enabled(0, params, CSP);
    assert!(r.d.torque_efficiency().abs() < 1e-9);
    // A ramp of 100 counts per cycle: beyond the window after the 10th cycle.
    let mut beyond_at = None;
    let mut fault_at = None;
    for n in 1..=40 {
        r.target += 100;
        let i = r.cycle();
        if beyond_at.is_none() && i.following > 1000 {
            beyond_at = Some(n);
        }
        // Bit 13 shows the following error once it is beyond the window, not before.
        assert_eq!(
            i.sw.0 & statusword::MODE_SPECIFIC_13 != 0,
            beyond_at.is_some(),
            "cycle {n}: {i:?}"
        );
        if fault_at.is_none() && i.error != 0 {
            fault_at = Some(n);
            assert_eq!(i.error, ERROR_FOLLOWING);
        }
    }
    let (beyond, fault) = (beyond_at.unwrap(), fault_at.unwrap());
    // Beyond the window during cycle 11; faults once 10 ms more have passed.
    assert_eq!(beyond, 11);
    assert!(
        fault == beyond + 10 || fault == beyond + 11,
        "{beyond} {fault}"
    );
    assert_eq!(r.inputs().sw.state(), Some(State::Fault));
    assert_eq!(r.d.record().following_error_faults, 1);
    assert_eq!(r.d.record().last_fault_code, ERROR_FOLLOWING);
    // The window at u32::MAX switches the check off.
    params.following_error_window = u32::MAX;
    let mut r = Rig::enabled(0, params, CSP);
    for _ in 0..40 {
        r.target += 100;
        r.cycle();
    }
    assert_eq!(r.d.state(), State::OperationEnabled);
}

#[test]
fn an_impossible_setpoint_step_faults_at_once() {
    let params = p();
    let limit = params.max_speed_counts() * DT;
    let mut r = Rig::enabled(0, params, CSP);
    // Just within what the motor can move in a cycle (plus one count): taken.
    r.target = limit as i32;
    r.cycle();
    assert_eq!(r.d.state(), State::OperationEnabled);
    // A full motor turn and more per cycle back (the modulo bug's jump): refused.
    r.target -= 10 * params.counts_per_rev as i32;
    let i = r.cycle();
    assert_eq!(i.error, ERROR_SETPOINT_STEP, "{i:?}");
    assert_eq!(r.d.record().last_fault_code, ERROR_SETPOINT_STEP);
    assert_eq!(r.d.record().following_error_faults, 0);
    // It brakes (fault reaction: quick stop ramp), not towards the bad target.
    assert!(matches!(
        i.sw.state(),
        Some(State::FaultReactionActive | State::Fault)
    ));
    let i = r.cycles(100);
    assert_eq!(i.sw.state(), Some(State::Fault));
    assert!(i.position > 0, "never lunged back to the bad target: {i:?}");
    // 0x607F lower: 1 m counts/s allows 1001 counts per 1 ms period.
    let mut r = Rig::enabled(0, params, CSP);
    r.d.settings.max_profile_velocity = 1_000_000;
    r.target = 1001;
    r.cycle();
    r.target = 2002;
    assert_eq!(r.cycle().error, 0);
    r.target = 3004;
    assert_eq!(r.cycle().error, ERROR_SETPOINT_STEP);
    // The first target after enabling must be within a period's move of the load.
    let mut r = Rig::new(0, params);
    r.target = 20_000;
    for cw in [0x06, 0x07, 0x0F] {
        r.cw = cw;
        r.cycle();
    }
    assert_eq!(r.cycle().error, ERROR_SETPOINT_STEP);
}

#[test]
fn a_setpoint_sent_a_period_late_is_judged_over_the_periods_it_covers() {
    // At 50 rev/s, 6554 counts per period; the master misses a period (the drive takes
    // the same target twice), then sends the target that is two periods on: no fault.
    let mut r = Rig::enabled(0, p(), CSP);
    let per = (50.0 * f64::from(p().counts_per_rev) * DT) as i32;
    for k in 1..=200 {
        let v = per.min(per * k / 50);
        if k != 120 {
            r.target += v;
        } else {
            r.cycle();
            r.target += 2 * v;
        }
        r.cycle();
    }
    assert_eq!(r.d.record().faults, 0);
    assert_eq!(r.d.record().max_target_step_counts, 2 * per as u64);
    // More than 0x607F allows in one period (13 108 counts) is refused.
    r.target += 2 * per + 3;
    assert_eq!(r.cycle().error, ERROR_SETPOINT_STEP);
}

#[test]
fn setpoints_taken_with_no_run_between_them_are_judged_one_by_one() {
    // After a stall of its own the simulator may pass two SYNC0 edges before it runs the
    // drive again: each setpoint is one period's step (within 0x607F), both together
    // are not, and the drive must not take them for one step.
    let mut r = Rig::enabled(0, p(), CSP);
    let per = (80.0 * f64::from(p().counts_per_rev) * DT) as i32;
    for k in 1..=100 {
        r.target += per.min(per * k / 50);
        r.cycle();
    }
    assert!(
        f64::from(2 * per) > p().max_speed_counts() * DT,
        "the pair is too far"
    );
    for _ in 0..2 {
        r.target += per;
        let mut b = [0u8; 7];
        b[0..2].copy_from_slice(&r.cw.to_le_bytes());
        b[2] = r.mode as u8;
        b[3..7].copy_from_slice(&r.target.to_le_bytes());
        r.mem.pdi_write(PROCESS_RAM, &b);
        r.d.take_outputs(&r.mem);
    }
    r.d.run(DT);
    for _ in 0..20 {
        r.target += per;
        assert_eq!(r.cycle().error, 0);
    }
    assert_eq!(r.d.record().faults, 0);
    assert_eq!(r.d.record().max_target_step_counts, per as u64);
}

#[test]
fn positions_wrap_at_32_bits_and_targets_are_taken_the_short_way() {
    let mut r = Rig::enabled(i32::MAX - 50_000, p(), CSP);
    // 1000 counts per cycle (1 m counts/s) across +2³¹.
    for _ in 0..100 {
        r.target = r.target.wrapping_add(1000);
        r.cycle();
    }
    let i = r.cycles(50);
    assert_eq!(r.d.record().faults, 0);
    assert_eq!(i.position, (i32::MAX - 50_000).wrapping_add(100_000));
    assert!(i.position < 0, "wrapped");
    assert_eq!(r.d.position_counts(), i64::from(i32::MAX) + 50_000);
}

/// CSV at `v` counts/s until steady, then a controlword; what it reads after.
fn moving(params: ServoParams, v: i32) -> Rig {
    let mut r = Rig::enabled(0, params, CSV);
    r.velocity = v;
    let i = r.cycles(300);
    assert!((i.velocity - v).abs() < 2000, "{i:?}");
    r
}

/// Cycles until the velocity is 0 or `max` cycles; the deceleration measured between 80 %
/// and 20 % of `v0`, and the states seen.
fn brake(r: &mut Rig, v0: f64, max: usize) -> (f64, Vec<State>) {
    let mut states = vec![];
    let (mut t80, mut t20, mut t) = (None, None, 0.0);
    for _ in 0..max {
        let i = r.cycle();
        t += DT;
        let s = i.sw.state().unwrap();
        if states.last() != Some(&s) {
            states.push(s);
        }
        let v = f64::from(i.velocity);
        if t80.is_none() && v < 0.8 * v0 {
            t80 = Some(t);
        }
        if t20.is_none() && v < 0.2 * v0 {
            t20 = Some(t);
        }
    }
    let decel = match (t80, t20) {
        (Some(a), Some(b)) if b > a => 0.6 * v0 / (b - a),
        _ => 0.0,
    };
    (decel, states)
}

#[test]
fn quick_stop_decelerates_as_0x605a_says() {
    use State::*;
    let v0 = rpm(3000.0);
    let qs = f64::from(p().quick_stop_deceleration);
    let slow = f64::from(p().profile_deceleration);
    // Code 2: quick stop ramp, then Switch on disabled.
    let mut r = moving(p(), v0 as i32);
    r.cw = 0x02;
    let i = r.cycle();
    assert_eq!(i.sw.state(), Some(QuickStopActive));
    assert_eq!(
        i.sw.0 & statusword::QUICK_STOP,
        0,
        "bit 5 low: quick stop active"
    );
    let (decel, states) = brake(&mut r, v0, 500);
    assert!((decel - qs).abs() < 0.05 * qs, "{decel} vs {qs}");
    assert_eq!(states, [QuickStopActive, SwitchOnDisabled]);
    // Stopped in v²/2a (plus what the loop lag adds).
    let travel = r.d.position() - 0.0;
    assert!(travel > 0.0);
    // Code 6: quick stop ramp, stays in Quick stop active holding the position.
    let mut params = p();
    params.quick_stop_option_code = 6;
    let mut r = moving(params, v0 as i32);
    r.cw = 0x02;
    let (decel, states) = brake(&mut r, v0, 500);
    assert!((decel - qs).abs() < 0.05 * qs, "{decel}");
    assert_eq!(states, [QuickStopActive]);
    let held = r.inputs().position;
    assert_eq!(r.cycles(100).position, held, "holds");
    // Code 5: slow down ramp (0x6084).
    params.quick_stop_option_code = 5;
    let mut r = moving(params, v0 as i32);
    r.cw = 0x02;
    let (decel, _) = brake(&mut r, v0, 800);
    assert!((decel - slow).abs() < 0.05 * slow, "{decel} vs {slow}");
    // Code 3: at the current limit: the peak torque's deceleration.
    params.quick_stop_option_code = 3;
    let mut r = moving(params, v0 as i32);
    r.cw = 0x02;
    let (decel, states) = brake(&mut r, v0, 300);
    let a_peak = params.peak_torque_nm / torque_for(1.0);
    assert!(
        decel > 0.8 * a_peak && decel < 1.2 * a_peak,
        "{decel} vs {a_peak}"
    );
    assert_eq!(states, [QuickStopActive, SwitchOnDisabled]);
    // Code 0: power off at once; only friction slows the load.
    params.quick_stop_option_code = 0;
    let mut r = moving(params, v0 as i32);
    r.cw = 0x02;
    let i = r.cycle();
    assert_eq!(i.sw.state(), Some(SwitchOnDisabled));
    assert_eq!(i.torque, 0);
    let i = r.cycles(10);
    assert!(f64::from(i.velocity) > 0.9 * v0, "coasts: {i:?}");
}

#[test]
fn fault_reaction_brakes_as_0x605e_says_then_faults() {
    use State::*;
    let v0 = rpm(3000.0);
    let qs = f64::from(p().quick_stop_deceleration);
    // Default 2: quick stop ramp, Fault reaction active meanwhile.
    let mut r = moving(p(), v0 as i32);
    r.d.on_watchdog();
    let (decel, states) = brake(&mut r, v0, 500);
    assert!((decel - qs).abs() < 0.05 * qs, "{decel}");
    assert_eq!(states, [FaultReactionActive, Fault]);
    assert_eq!(r.inputs().error, ERROR_SYNC_WATCHDOG);
    assert_eq!(r.d.record().faults, 1);
    // 0: the power stage goes off: Fault at once and the load coasts.
    let mut params = p();
    params.fault_reaction_option_code = 0;
    let mut r = moving(params, v0 as i32);
    r.d.on_watchdog();
    let i = r.cycles(10);
    assert_eq!(i.sw.state(), Some(Fault));
    assert!(f64::from(i.velocity) > 0.9 * v0, "coasts: {i:?}");
    // A fault reset brings it to Switch on disabled with the code cleared.
    r.cw = 0x80;
    let i = r.cycle();
    assert_eq!((i.sw.state(), i.error), (Some(SwitchOnDisabled), 0));
}

#[test]
fn disable_operation_slows_down_first_and_shutdown_lets_it_coast() {
    use State::*;
    let v0 = rpm(1500.0);
    let slow = f64::from(p().profile_deceleration);
    // 0x605C = 1: stays in Operation enabled on the slow down ramp, then Switched on.
    let mut r = moving(p(), v0 as i32);
    r.cw = 0x07;
    let i = r.cycle();
    assert_eq!(i.sw.state(), Some(OperationEnabled));
    assert_eq!(
        i.sw.0 & statusword::MODE_SPECIFIC_12,
        0,
        "no longer follows"
    );
    let (decel, states) = brake(&mut r, v0, 600);
    assert!((decel - slow).abs() < 0.05 * slow, "{decel}");
    assert_eq!(states, [OperationEnabled, SwitchedOn]);
    // 0x605B = 0: shutdown switches the power stage off at once.
    let mut r = moving(p(), v0 as i32);
    r.cw = 0x06;
    let i = r.cycle();
    assert_eq!((i.sw.state(), i.torque), (Some(ReadyToSwitchOn), 0));
    assert!(f64::from(r.cycles(5).velocity) > 0.9 * v0, "coasts");
}

#[test]
fn torque_actual_is_inertia_times_acceleration_plus_friction() {
    let params = p();
    // CSP on a constant-acceleration parabola: a1 then a2; in each, the torque is
    // J·a + friction, so the difference is the inertia's alone.
    let (a1, a2) = (rpm(30_000.0), rpm(90_000.0));
    let torque_during = |a: f64| {
        let mut r = Rig::enabled(0, params, CSP);
        let mut sum = 0.0;
        let mut n = 0.0;
        for k in 1..=50 {
            let t = k as f64 * DT;
            r.target = (0.5 * a * t * t).round() as i32;
            let i = r.cycle();
            if k > 25 {
                sum += f64::from(i.torque);
                n += 1.0;
            }
        }
        assert_eq!(r.d.record().faults, 0);
        sum / n
    };
    // 500 and 1500 rev/s² (from 30 000 and 90 000 rpm/s); 75 rev/s at the end.
    let (t1, t2) = (torque_during(a1), torque_during(a2));
    let expected = torque_for(a2 - a1) / params.rated_torque_nm * 1000.0;
    assert!(
        ((t2 - t1) - expected).abs() < 0.05 * expected,
        "{t1} ‰, {t2} ‰: difference {} vs J·Δa = {expected}",
        t2 - t1
    );
    assert!(t1 > 0.0 && t2 > t1);
}

#[test]
fn at_constant_speed_the_torque_is_the_friction() {
    let params = p();
    let v = rpm(3000.0);
    let mut r = moving(params, v as i32);
    let i = r.cycles(200);
    let w = 3000.0 / 60.0 * 2.0 * core::f64::consts::PI;
    let friction = params.coulomb_friction_nm + params.viscous_friction_nm_s * w;
    let expected = friction / params.rated_torque_nm * 1000.0;
    assert!(
        (f64::from(i.torque) - expected).abs() < 2.0,
        "{} ‰ vs {expected} ‰",
        i.torque
    );
}

#[test]
fn csv_follows_the_target_velocity_and_cst_accelerates_with_torque() {
    let mut r = Rig::enabled(0, p(), CSV);
    r.velocity = 10_000;
    let i = r.cycles(1000);
    // 1 s at 10 000 counts/s, less the time the velocity loop took to get there.
    let pos = r.d.position();
    assert!((9_980.0..10_000.0).contains(&pos), "CSV: {pos}");
    assert_eq!(i.mode, CSV, "mode display");
    // An unsupported mode (interpolated position, 7) is not taken.
    r.mode = 7;
    assert_eq!(r.cycle().mode, CSV);
    // CST: 10 % torque accelerates; a = (T − Tc)/J.
    r.mode = CST;
    r.velocity = 0;
    r.torque = 100;
    let v0 = r.cycle().velocity;
    let v1 = r.cycles(50).velocity;
    let params = p();
    let a = (0.1 * params.rated_torque_nm - params.coulomb_friction_nm) / torque_for(1.0);
    let measured = f64::from(v1 - v0) / (50.0 * DT);
    assert!((measured - a).abs() < 0.05 * a, "{measured} vs {a}");
    assert_eq!(r.cycle().torque, 100, "torque actual = target");
    // A wrong commutation offset (90° electrical) gives no torque: it stands.
    let mut params = p();
    params.counts_per_rev = 20_000;
    params.commutation_offset = (params.counts_per_rev / params.pole_pairs / 4) as i32;
    let mut r = Rig::enabled(0, params, CST);
    assert!(r.d.torque_efficiency().abs() < 1e-9);
    r.torque = 100;
    let i = r.cycles(100);
    assert_eq!(r.d.position(), 0.0, "no torque at 90° electrical");
    assert_eq!(i.torque, 100, "though the current flows");
    r.d.commutation_setting = r.d.params.commutation_offset;
    assert!(
        (r.d.torque_efficiency() - 1.0).abs() < 1e-12,
        "commissioned"
    );
    r.cycles(10);
    assert!(r.d.position() > 0.0);
}

/// A servo whose home switch cam covers `from..=to` and limit switches lie far out.
fn with_switches(from: i64, to: i64) -> ServoParams {
    let cam = |input, from, to| crate::plant::switches::SwitchCam {
        input,
        from,
        to,
        normally_closed: false,
    };
    ServoParams {
        switches: probe::DriveSwitches::new(&[
            cam(0, i64::MIN, -1_000_000),
            cam(1, 1_000_000, i64::MAX),
            cam(2, from, to),
        ]),
        ..p()
    }
}

#[test]
fn digital_inputs_read_the_switch_cams_on_the_drive_s_travel() {
    let mut r = Rig::enabled(0, with_switches(50_000, 60_000), CSP);
    assert_eq!(r.cycle().digital_inputs, 0);
    let mut seen = Vec::new();
    while r.target < 1_100_000 {
        r.target += 5000;
        let i = r.cycle();
        seen.push((i.position, i.digital_inputs));
    }
    let i = r.cycles(50);
    assert_eq!(i.digital_inputs, objects::digital_inputs::POSITIVE_LIMIT);
    // The home bit is set exactly while the reported position is on the cam.
    for (p, di) in seen {
        let home = di & objects::digital_inputs::HOME_SWITCH != 0;
        assert_eq!(home, (50_000..=60_000).contains(&p), "at {p}: 0x{di:X}");
    }
    while r.target > -1_100_000 {
        r.target -= 5000;
        r.cycle();
    }
    let i = r.cycles(50);
    assert_eq!(i.digital_inputs, objects::digital_inputs::NEGATIVE_LIMIT);
    assert_eq!(r.d.record().faults, 0);
}

#[test]
fn touch_probes_latch_the_home_switch_edges_and_the_index_to_the_count() {
    // Probe 1: the probe input (the home switch), both edges; probe 2: the zero impulse.
    let probe_1 =
        probe::function::ENABLE | probe::function::POSITIVE_EDGE | probe::function::NEGATIVE_EDGE;
    let probe_2 = (probe::function::ENABLE
        | probe::function::SOURCE_ZERO_IMPULSE
        | probe::function::POSITIVE_EDGE)
        << 8;
    let rev = i64::from(p().counts_per_rev);
    // Slow, and close to the motor's top speed (6.5·10⁶ counts/s).
    for step in [700, 6000] {
        let mut r = Rig::enabled(0, with_switches(123_457, 150_001), CSP);
        r.tp = probe_1 | probe_2;
        r.cycle();
        // Up across the cam at `step` counts per millisecond: edges at the first count
        // on the cam and the first count past it; the first index after the rising edge
        // is not the first index passed, so probe 2 holds the first one (single event).
        while r.target < 300_000 {
            r.target += step;
            r.cycle();
        }
        let i = r.cycles(50);
        assert_eq!(i.tp_pos1, 123_457, "rising edge at {step}/ms");
        assert_eq!(i.tp_pos1_neg, 150_002, "falling edge at {step}/ms");
        assert_eq!(i64::from(i.tp_pos2), 1000, "first index");
        assert_eq!(
            i.tp_status, 0x43C7,
            "probe 1 both edges, probe 2 its positive edge stored, each toggled once: 0x{:04X}",
            i.tp_status
        );
        // Re-armed, back down: the edges are the first count of each new state going
        // down, the index the first one below the start.
        r.tp = 0;
        r.cycle();
        r.tp = probe_1 | probe_2;
        r.cycle();
        let start = i64::from(r.cycle().position);
        while r.target > 0 {
            r.target -= step.min(r.target);
            r.cycle();
        }
        let i = r.cycles(50);
        assert_eq!(i.tp_pos1, 150_001, "rising edge going down at {step}/ms");
        assert_eq!(
            i.tp_pos1_neg, 123_456,
            "falling edge going down at {step}/ms"
        );
        let below = 1000 + (start - 1000 - 1).div_euclid(rev) * rev;
        assert_eq!(i64::from(i.tp_pos2), below, "index going down at {step}/ms");
        assert_eq!(i.tp_pos2_neg, 0, "the zero impulse has no negative edge");
        assert_eq!(r.d.record().faults, 0);
    }
}

#[test]
fn touch_probe_latches_the_index_pulse_exactly() {
    let mut r = Rig::enabled(0, p(), CSP);
    // Armed (enable, zero impulse, positive edge), single event.
    r.tp = 0x0015;
    let i = r.cycle();
    assert_eq!(
        (i.tp_status, i.tp_pos1),
        (0x0001, 0),
        "enabled, nothing stored"
    );
    // Move past two index positions (1000 and 1000 + 2^17) at 2000 counts per cycle:
    // the first is stored.
    let rev = p().counts_per_rev as i32;
    while r.target < 200_000 {
        r.target += 2000;
        r.cycle();
    }
    let i = r.cycles(50);
    // Enabled, positive edge stored, its toggle bit flipped once.
    assert_eq!((i.tp_status, i.tp_pos1), (0x0043, 1000));
    // Re-arm (enable off, on) and come back: the crossing going down is stored too.
    r.tp = 0;
    r.cycle();
    r.tp = 0x0015;
    while r.target > 0 {
        r.target -= 2000;
        r.cycle();
    }
    let i = r.cycles(50);
    assert_eq!((i.tp_status, i.tp_pos1), (0x0043, 1000 + rev));
    assert_eq!(r.d.record().faults, 0);
}

#[test]
fn the_minimal_mapping_still_works() {
    // The power-up mapping: controlword + target / statusword + position actual.
    let mut mem = Memory::new();
    let mut d = ServoDrive::new(PROCESS_RAM, PROCESS_RAM + 0x100, 1000);
    let out = |mem: &mut Memory, cw: u16, target: i32| {
        let mut b = [0u8; 6];
        b[0..2].copy_from_slice(&cw.to_le_bytes());
        b[2..6].copy_from_slice(&target.to_le_bytes());
        mem.pdi_write(PROCESS_RAM, &b);
    };
    for cw in [0x06, 0x07, 0x0F, 0x0F] {
        out(&mut mem, cw, 1000);
        d.step(&mut mem, DT);
    }
    for k in 1..=100 {
        out(&mut mem, 0x0F, 1000 + 10 * k);
        d.step(&mut mem, DT);
    }
    for _ in 0..50 {
        d.step(&mut mem, DT);
    }
    let mut inp = [0u8; 6];
    mem.ecat_read(PROCESS_RAM + 0x100, &mut inp, false);
    let sw = Statusword(u16::from_le_bytes([inp[0], inp[1]]));
    assert_eq!(sw.state(), Some(State::OperationEnabled));
    assert_eq!(i32::from_le_bytes([inp[2], inp[3], inp[4], inp[5]]), 2000);
    // Taken in Operation enabled: the 4th enabling cycle's, 100 moving, 50 standing.
    assert_eq!(d.record().targets, 151);
    assert_eq!(d.record().max_target_step_counts, 10);
}

#[test]
fn sdo_reads_live_values_and_writes_settings_within_their_ranges() {
    use crate::coe::od::OdError;
    let mut r = Rig::enabled(0, p(), CSV);
    let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
    r.d.install_objects(&mut od);
    let read_u32 = |od: &ObjectDictionary, o: ObjectId| {
        let b = od.read(o.index, o.sub).unwrap();
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    };
    assert_eq!(read_u32(&od, MOTOR_RATED_TORQUE), 1270, "mN·m");
    assert_eq!(read_u32(&od, FOLLOWING_ERROR_WINDOW), 1 << 15);
    assert_eq!(
        read_u32(&od, MAX_PROFILE_VELOCITY),
        100 * p().counts_per_rev,
        "6000 rpm"
    );
    assert_eq!(
        od.write(0x6076, 0, &1u32.to_le_bytes()),
        Err(OdError::ReadOnly)
    );
    assert_eq!(
        od.write(0x6064, 0, &1i32.to_le_bytes()),
        Err(OdError::ReadOnly)
    );
    assert_eq!(
        od.write(0x605A, 0, &9i16.to_le_bytes()),
        Err(OdError::ValueRange)
    );
    assert_eq!(
        od.write(0x6060, 0, &[7]),
        Err(OdError::ValueRange),
        "no interpolated position"
    );
    od.write(0x6060, 0, &[6]).unwrap();
    od.write(0x6060, 0, &[8]).unwrap();
    let too_fast = p().max_speed_counts() as u32 + 1;
    assert_eq!(
        od.write(0x607F, 0, &too_fast.to_le_bytes()),
        Err(OdError::ValueRange)
    );
    // Moving: the actual values an upload reads are the drive's.
    r.velocity = 100_000;
    r.cycles(100);
    r.d.publish_objects(&mut od);
    let v = read_u32(&od, VELOCITY_ACTUAL_VALUE) as i32;
    assert!((v - 100_000).abs() < 100, "{v}");
    // Quick stop option code 6 by SDO: the drive now stays in Quick stop active.
    od.write(0x605A, 0, &6i16.to_le_bytes()).unwrap();
    od.write(0x6085, 0, &(1u32 << 30).to_le_bytes()).unwrap();
    r.d.take_objects(&od);
    r.cw = 0x02;
    let i = r.cycles(50);
    assert_eq!(i.sw.state(), Some(State::QuickStopActive));
    assert!(i.velocity.abs() < 100, "stopped and held: {i:?}");
}

#[test]
fn a_period_costs_bounded_work() {
    // 16 substeps per 1 ms; a 100 ms period is capped at 1600, a longer one too.
    let mut r = Rig::enabled(0, p(), CSP);
    let t = std::time::Instant::now();
    r.cycles(1000);
    let per_period = t.elapsed().as_secs_f64() / 1000.0;
    eprintln!("one 1 ms period of one servo: {:.1} µs", per_period * 1e6);
    r.d.run(10.0);
    assert_eq!(r.d.state(), State::OperationEnabled);
}

#[test]
fn a_missed_setpoint_is_extrapolated_and_the_next_interpolated_over_one_period() {
    // Taken at every period but one: the drive runs that period on, along the last slope.
    let params = p();
    let mut mem = Memory::new();
    let mut d = ServoDrive::with_params(PROCESS_RAM, PROCESS_RAM + 0x100, 0, params);
    let mut target = 0i32;
    let out = |mem: &mut Memory, cw: u16, target: i32| {
        let mut b = [0u8; 6];
        b[0..2].copy_from_slice(&cw.to_le_bytes());
        b[2..6].copy_from_slice(&target.to_le_bytes());
        mem.pdi_write(PROCESS_RAM, &b);
    };
    for cw in [0x06, 0x07, 0x0F, 0x0F] {
        out(&mut mem, cw, 0);
        d.step(&mut mem, DT);
    }
    let per = 3000;
    let (mut worst, mut before): (f64, f64) = (0.0, 0.0);
    for k in 1..=300 {
        target += per.min(per * k / 100);
        out(&mut mem, 0x0F, target);
        if k != 200 {
            d.take_outputs(&mem);
        }
        d.run(DT);
        let e = (d.demand() - d.position()).abs();
        if k < 190 {
            before = before.max(e);
        } else {
            worst = worst.max(e);
        }
        if k == 200 {
            // Missed: the demand went on one period along the slope.
            assert!(
                (d.demand() - f64::from(target)).abs() < 1.0,
                "{}",
                d.demand()
            );
        }
    }
    assert_eq!(d.record().faults, 0);
    assert_eq!(d.setpoint_period, Some(DT), "the gap is not the period");
    // The miss costs the loops nothing they notice: at constant speed around it, the
    // error stays below what the ramp's start and end cost before.
    assert!(
        worst < 10.0 && worst < before,
        "{worst} counts, {before} before"
    );
}

#[test]
fn without_setpoints_the_demand_stops_after_one_period() {
    let mut r = Rig::enabled(0, p(), CSP);
    for _ in 0..100 {
        r.target += 3000;
        r.cycle();
    }
    let last = f64::from(r.target);
    // The master stops sending: one period along the slope, then the demand stays.
    for _ in 0..50 {
        r.d.run(DT);
    }
    assert!(
        (r.d.demand() - (last + 3000.0)).abs() < 1.0,
        "{}",
        r.d.demand()
    );
    let off = r.d.position() - r.d.demand();
    assert!(off.abs() < 10.0, "{off}");
    // The safe outputs of a slave leaving Op (all zero) are no setpoint.
    let taken = r.d.record().targets;
    r.target = 0;
    r.cw = 0;
    r.cycle();
    assert_eq!(r.d.record().targets, taken);
    assert_eq!(r.d.record().max_target_step_counts, 3000);
}

#[test]
fn a_pause_between_setpoints_is_not_taken_for_the_period() {
    // The drive runs 300 ms before the master's first setpoint, and 300 ms more later:
    // it interpolates over its 1 ms cycle once two intervals agree, not over the pause
    // (measured from the first interval alone it crawled over 300 ms segments).
    let mut r = Rig::new(0, p());
    for _ in 0..300 {
        r.d.run(DT);
    }
    for cw in [0x06, 0x07, 0x0F, 0x0F] {
        r.cw = cw;
        r.cycle();
    }
    for _ in 0..300 {
        r.d.run(DT);
    }
    for _ in 0..50 {
        r.target += 1000;
        r.cycle();
    }
    assert_eq!(r.d.setpoint_period, Some(DT));
    // Followed at 1 m counts/s, not crawling over 300 ms segments: within a few counts at
    // the last setpoint.
    assert!(
        (r.inputs().position - r.target).abs() < 100,
        "{:?}",
        r.inputs()
    );
    let i = r.cycles(100);
    assert!((i.position - r.target).abs() <= 1, "{i:?}");
    assert_eq!(r.d.record().faults, 0);
}

/// Drive-side homing (CiA 402-2 §10.4) on the drive's own cams and index pulse: limit
/// switches beyond ±10 revolutions, the home cam from 2 to 2.4 revolutions, the index at
/// 1000 counts in every revolution. Each expected home position is worked out here from
/// that geometry and the method's diagram (not from the drive's plan): the first count of
/// the new state in the direction of the final approach, or the index count.
mod homing_mode {
    use super::*;
    use crate::plant::switches::SwitchCam;

    const REV: i64 = 131_072;
    const LIMIT: i64 = 10 * REV;
    /// The home cam: B (first count) and F (last count).
    const B: i64 = 262_144;
    const F: i64 = 314_572;
    const HM_MODE: i8 = 6;

    fn params() -> ServoParams {
        let cam = |input, from, to| SwitchCam {
            input,
            from,
            to,
            normally_closed: false,
        };
        ServoParams {
            switches: probe::DriveSwitches::new(&[
                cam(0, -100 * LIMIT, -LIMIT),
                cam(1, LIMIT, 100 * LIMIT),
                cam(2, B, F),
            ]),
            ..p()
        }
    }

    /// Index counts: 1000 + k·REV.
    fn index_at_or_below(x: i64) -> i64 {
        1000 + (x - 1000).div_euclid(REV) * REV
    }
    fn index_at_or_above(x: i64) -> i64 {
        index_at_or_below(x - 1) + REV
    }

    /// The home position of `method` from `start`, by the method's diagram; `None`:
    /// the method must end in a homing error from there.
    fn expected(method: i8, start: i64) -> Option<i64> {
        let on = (B..=F).contains(&start);
        let below = start < B;
        let above = start > F;
        Some(match method {
            1 => index_at_or_above(-LIMIT + 1),
            2 => index_at_or_below(LIMIT - 1),
            17 => -LIMIT + 1,
            18 => LIMIT - 1,
            // Positive home switch (edge B), index below / above it.
            3 if !above => index_at_or_below(B - 1),
            4 if !above => index_at_or_above(B),
            19 if !above => B - 1,
            20 if !above => B,
            // Negative home switch (edge F), index above / below it.
            5 if !below => index_at_or_above(F + 1),
            6 if !below => index_at_or_below(F),
            21 if !below => F + 1,
            22 if !below => F,
            3 | 4 | 5 | 6 | 19 | 20 | 21 | 22 => return None,
            // The cam between the limits: the index or edge on either side of B or F,
            // from any start.
            7 | 14 => index_at_or_below(B - 1),
            8 | 13 => index_at_or_above(B),
            9 | 12 => index_at_or_below(F),
            10 | 11 => index_at_or_above(F + 1),
            23 | 30 => B - 1,
            24 | 29 => B,
            25 | 28 => F,
            26 | 27 => F + 1,
            33 => index_at_or_below(start - 1),
            34 => index_at_or_above(start + 1),
            35 | 37 => start,
            _ => unreachable!("method {method}"),
        })
        .filter(|_| on || below || above)
    }

    /// Homing rig: enabled in HM at `start` with the method's objects set.
    fn rig(method: i8, start: i32, offset: i32) -> Rig {
        let mut r = Rig::enabled(start, params(), HM_MODE);
        let s = r.d.homing.settings_mut();
        s.method = method;
        s.speed_switch = 10 * REV as u32;
        s.speed_zero = REV as u32;
        s.acceleration = 100 * REV as u32;
        s.home_offset = offset;
        r
    }

    /// Starts homing (bit 4's rising edge) and cycles until bit 12, or 13 with 10 (the
    /// drive stopped after an error), or `max` cycles.
    fn home(r: &mut Rig, max: usize) -> Inputs {
        r.cw = 0x1F;
        for _ in 0..max {
            let sw = r.cycle().sw.0;
            if sw & (1 << 12) != 0 || sw & (1 << 13 | 1 << 10) == (1 << 13 | 1 << 10) {
                break;
            }
        }
        // Let it settle, then read.
        r.cycles(20)
    }

    #[test]
    fn every_method_homes_on_its_switch_edge_or_index_from_each_start() {
        let methods = (1..=14).chain(17..=30).chain(33..=35).chain([37]);
        let mut runs = 0;
        for method in methods {
            for start in [0i64, 290_000, 600_000] {
                let offset = 12_345;
                let mut r = rig(method, start as i32, offset);
                let i = home(&mut r, 8000);
                let sw = i.sw.0;
                let ctx = format!("method {method} from {start}: statusword {sw:#06x}");
                match expected(method, start) {
                    Some(home) => {
                        assert_eq!(sw & (1 << 13), 0, "{ctx}: homing error");
                        assert_ne!(sw & (1 << 12), 0, "{ctx}: not attained");
                        assert_ne!(sw & (1 << 10), 0, "{ctx}: target not reached");
                        let at = r.d.position_counts();
                        assert!((at - home).abs() <= 1, "{ctx}: stands at {at}, home {home}");
                        // The home position reads as minus the home offset.
                        let reads = i64::from(i.position) + (home - at);
                        assert_eq!(reads, -i64::from(offset), "{ctx}");
                        assert_eq!(i.mode, HM_MODE);
                    }
                    None => {
                        assert_ne!(sw & (1 << 13), 0, "{ctx}: no homing error");
                        assert_eq!(sw & (1 << 12), 0, "{ctx}");
                        assert_ne!(sw & (1 << 10), 0, "{ctx}: stands");
                        assert_eq!(r.d.position_shift(), 0, "{ctx}: position not set");
                    }
                }
                assert_eq!(r.d.error_code(), 0, "{ctx}: no drive fault");
                runs += 1;
            }
        }
        assert_eq!(runs, 32 * 3, "32 methods, 3 starts each");
    }

    /// 7–14 and 23–30 with no home cam between the limits: the reversal switch reached
    /// again is a homing error (the switch is never found).
    #[test]
    fn a_missing_home_switch_ends_in_a_homing_error_at_the_second_limit() {
        for method in [7, 11, 23, 30] {
            let cams = [
                SwitchCam {
                    input: 0,
                    from: -100 * LIMIT,
                    to: -LIMIT,
                    normally_closed: false,
                },
                SwitchCam {
                    input: 1,
                    from: LIMIT,
                    to: 100 * LIMIT,
                    normally_closed: false,
                },
            ];
            let params = ServoParams {
                switches: probe::DriveSwitches::new(&cams),
                ..params()
            };
            let mut r = Rig::enabled(0, params, HM_MODE);
            let s = r.d.homing.settings_mut();
            (s.method, s.speed_switch, s.acceleration) =
                (method, 10 * REV as u32, 100 * REV as u32);
            let i = home(&mut r, 10_000);
            assert_eq!(
                i.sw.0 & (1 << 13 | 1 << 12 | 1 << 10),
                1 << 13 | 1 << 10,
                "method {method}"
            );
            // It went to both limits.
            assert!(
                r.d.position_counts().abs() >= LIMIT - REV,
                "method {method}"
            );
        }
    }

    /// Bit 4 falling interrupts (bit 10 set, 12 clear once stopped); halt stops; a new
    /// rising edge starts over; the position is set only when attained.
    #[test]
    fn bit_4_falling_and_halt_interrupt_homing() {
        let mut r = rig(34, 0, 0);
        r.cw = 0x1F;
        let i = r.cycles(5);
        assert_eq!(i.sw.0 & (1 << 10 | 1 << 12 | 1 << 13), 0, "in progress");
        r.cw = 0x0F;
        let i = r.cycles(200);
        assert_eq!(
            i.sw.0 & (1 << 10 | 1 << 12 | 1 << 13),
            1 << 10,
            "interrupted"
        );
        assert_eq!(r.d.position_shift(), 0);
        let stood = r.d.position_counts();
        assert!(
            stood > 0 && stood < 1000,
            "stopped before the index: {stood}"
        );
        r.cw = 0x11F;
        let i = r.cycles(200);
        assert_eq!(i.sw.0 & (1 << 12), 0, "bit 4 with halt does not start");
        r.cw = 0x0F;
        r.cycle();
        let i = home(&mut r, 2000);
        assert_ne!(i.sw.0 & (1 << 12), 0);
        assert!((r.d.position_counts() - 1000).abs() <= 1);
    }

    /// The faults the field reports, injected: a drive that never sets homing attained
    /// (it homes, its statusword stays "in progress"), and one that refuses method 0.
    #[test]
    fn injected_faults_never_attain_and_refuse_method_0() {
        use crate::coe::od::OdError;
        let mut faults = homing::HomingFaults {
            never_attains: true,
            ..Default::default()
        };
        faults.refused.insert(0);
        let params = ServoParams {
            homing_faults: faults,
            ..params()
        };
        let mut r = Rig::enabled(0, params, HM_MODE);
        r.d.homing.settings_mut().method = 34;
        r.cw = 0x1F;
        let i = r.cycles(3000);
        assert_eq!(
            i.sw.0 & (1 << 10 | 1 << 12 | 1 << 13),
            0,
            "in progress forever"
        );
        assert!((r.d.position_counts() - 1000).abs() <= 1, "it did home");
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        r.d.install_objects(&mut od);
        assert_eq!(od.write(0x6098, 0, &[0]), Err(OdError::ValueRange));
        od.write(0x6098, 0, &[19]).unwrap();
        // Reserved and manufacturer-specific methods, on the plain drive too.
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        Rig::new(0, p()).d.install_objects(&mut od);
        od.write(0x6098, 0, &[0]).unwrap();
        for m in [15i8, 16, 31, 32, 36, 38, -1] {
            assert_eq!(
                od.write(0x6098, 0, &[m as u8]),
                Err(OdError::ValueRange),
                "{m}"
            );
        }
        od.write(0x6099, 1, &1000u32.to_le_bytes()).unwrap();
        assert_eq!(
            od.write(0x6099, 2, &0u32.to_le_bytes()),
            Err(OdError::ValueRange)
        );
        assert_eq!(od.read(0x6099, 0).unwrap(), &[2]);
    }

    /// Back to CSP after homing: the first target the master sends is the position actual
    /// value now (the homed frame), and the drive does not move or fault.
    #[test]
    fn back_in_csp_the_targets_count_in_the_homed_frame() {
        let mut r = rig(34, 0, -5000);
        let i = home(&mut r, 2000);
        assert_eq!(i.position, 5000);
        r.cw = 0x0F;
        r.mode = CSP;
        r.target = i.position;
        r.cycles(50);
        r.target = i.position + 1000;
        let i = r.cycles(300);
        assert_eq!(i.mode, CSP);
        assert_eq!(i.position, 6000);
        assert!((r.d.position_counts() - 2000).abs() <= 1);
        assert_eq!(r.d.error_code(), 0);
    }
}
