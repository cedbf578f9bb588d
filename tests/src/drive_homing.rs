//! Drive-side homing (CiA 402 homing mode) end to end on either bus, in lockstep: the
//! master writes the homing objects by SDO beside the cycle, takes the simulated servo out
//! of CSP into homing mode, starts it, follows its statusword and hands it back in CSP;
//! the axis is homed on the drive's position. `tests/tests/drive_homing_ethercat.rs` and
//! `drive_homing_canopen.rs` run [`every_method`] and the failure paths on each bus' rig.
//!
//! The servo's cams are those of [`crate::homing`]: limit switches beyond ±50 mm (±10
//! revolutions), the home cam from 10 mm to just under 12 mm, the index at 1000 counts in
//! every revolution. Each expected home position is worked out here from that geometry and
//! the method's diagram in CiA 402-2 §10.4.3, independently of the simulator's plan.

use gantry::runtime::controller::CommandHandle;
use gantry::runtime::procedure::DriveProcedure;
use gantry_drives::cia402::homing::{DriveHoming, DriveHomingParams};
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;

use crate::homing::COUNTS_PER_MM;
use crate::servo_rig::ServoRig;

const REV: i64 = 131_072;
const LIMIT: i64 = 10 * REV;
/// The home cam's first and last count.
const B: i64 = 262_144;
const F: i64 = 314_572;

fn index_at_or_below(x: i64) -> i64 {
    1000 + (x - 1000).div_euclid(REV) * REV
}
fn index_at_or_above(x: i64) -> i64 {
    index_at_or_below(x - 1) + REV
}

/// The home position of `method` started at `start` (counts; below the cam or above it),
/// by the method's diagram.
pub fn expected_home(method: i8, start: i64) -> i64 {
    match method {
        1 => index_at_or_above(-LIMIT + 1),
        2 => index_at_or_below(LIMIT - 1),
        17 => -LIMIT + 1,
        18 => LIMIT - 1,
        3 | 7 | 14 => index_at_or_below(B - 1),
        4 | 8 | 13 => index_at_or_above(B),
        5 | 10 | 11 => index_at_or_above(F + 1),
        6 | 9 | 12 => index_at_or_below(F),
        19 | 23 | 30 => B - 1,
        20 | 24 | 29 => B,
        21 | 26 | 27 => F + 1,
        22 | 25 | 28 => F,
        33 => index_at_or_below(start - 1),
        34 => index_at_or_above(start + 1),
        _ => start,
    }
}

/// The methods of CiA 402-2 the drive has: 1–14, 17–30, 33–35, 37.
pub fn methods() -> impl Iterator<Item = i8> {
    (1..=14).chain(17..=30).chain(33..=35).chain([37])
}

/// Where each method starts (mm): below the cam, except those whose home switch is a
/// negative one (5, 6, 21, 22: from below they would run into the negative limit switch)
/// and 7–14/23–30 on every other method from above (they reverse at a limit switch).
fn start_mm(method: i8) -> f64 {
    match method {
        5 | 6 | 21 | 22 => 20.0,
        9..=12 | 25..=28 => 30.0,
        _ => 2.0,
    }
}

/// Runs drive homing with `params` and cycles until it ends.
pub fn drive_home(rig: &mut impl ServoRig, params: DriveHomingParams) -> CommandStatus {
    let h = rig
        .ctl()
        .drive_procedure(0, DriveProcedure::Homing(DriveHoming::new(params)))
        .expect("queued");
    let max = ((params.timeout_s + 5.0) / rig.cycle_s()) as usize;
    rig.finish(&h, max)
}

fn move_to(rig: &mut impl ServoRig, mm: f64) {
    let cmd = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, mm).speed(100.0));
    let h = rig.ctl().command(0, cmd).expect("queued");
    assert_eq!(rig.finish(&h, 20_000), CommandStatus::Done, "move to {mm}");
}

/// Every method from its start: the drive stands on the home position worked out from
/// the cams and index (±1 count), the axis is homed and reads minus the home offset
/// there, it is back in CSP, and the first CSP target after the hand-back was the drive's
/// position actual value (no setpoint jump; no drive fault anywhere).
pub fn every_method(rig: &mut impl ServoRig, base: DriveHomingParams) {
    let offset_mm = f64::from(base.home_offset) / COUNTS_PER_MM;
    for method in methods() {
        // Start in the axis' frame: before the first homing it is the drive's.
        let status = rig.status();
        let drive_mm = rig.with_servo(|s| s.position_counts()) as f64 / COUNTS_PER_MM;
        let to = start_mm(method) + status.actual_position - drive_mm;
        move_to(rig, to);
        rig.cycles(20);
        let start = rig.with_servo(|s| s.position_counts());
        let params = DriveHomingParams { method, ..base };
        let result = drive_home(rig, params);
        let st = rig.status();
        assert_eq!(
            result,
            CommandStatus::Done,
            "method {method}: {:?}",
            st.error
        );
        rig.cycles(20);
        let home = expected_home(method, start);
        let at = rig.with_servo(|s| s.position_counts());
        assert!(
            (at - home).abs() <= 1,
            "method {method} from {start}: stands at {at}, home {home}"
        );
        let st = rig.status();
        assert!(st.bits.homed, "method {method}: homed");
        assert_eq!(st.state, AxisState::Standstill, "method {method}");
        // The home position reads as minus the home offset.
        let expect_mm = -offset_mm + (at - home) as f64 / COUNTS_PER_MM;
        assert!(
            (st.actual_position - expect_mm).abs() <= 1.01 / COUNTS_PER_MM,
            "method {method}: the axis reads {} mm, expected {expect_mm}",
            st.actual_position
        );
        let (mode, takeover, faults) =
            rig.with_servo(|s| (s.mode(), s.takeover(), s.record().faults));
        assert_eq!(mode, 8, "method {method}: back in CSP");
        let (target, actual) = takeover.expect("a CSP target after the hand-back");
        assert!(
            (i64::from(target) - i64::from(actual)).abs() <= 1,
            "method {method}: first CSP target {target}, the drive stood at {actual}"
        );
        assert_eq!(faults, 0, "method {method}: drive faults");
    }
    // And it moves on the homed frame: 0 mm is the home position plus the offset.
    move_to(rig, 0.0);
    rig.cycles(50);
    let st = rig.status();
    assert!(
        st.actual_position.abs() < 2.0 / COUNTS_PER_MM,
        "{}",
        st.actual_position
    );
    assert_eq!(rig.with_servo(|s| s.record().faults), 0);
}

/// A drive that never reports homing attained: the error names the method and what was
/// missing after the timeout; the drive was halted and handed back in CSP; the axis is in
/// Standstill, not homed.
pub fn timeout_path(rig: &mut impl ServoRig, base: DriveHomingParams) {
    let params = DriveHomingParams {
        method: 34,
        timeout_s: 2.0,
        ..base
    };
    let status = drive_home(rig, params);
    let CommandStatus::Error(e) = status else {
        panic!("expected the timeout, got {status:?}");
    };
    assert_eq!(
        e.to_string(),
        "drive homing method 34: did not report homing attained within 2 s"
    );
    rig.cycles(20);
    let st = rig.status();
    assert_eq!(st.state, AxisState::Standstill);
    assert!(!st.bits.homed);
    assert_eq!(rig.with_servo(|s| (s.mode(), s.record().faults)), (8, 0));
    // The axis is the master's again.
    move_to(rig, st.actual_position + 1.0);
}

/// A method the drive refuses (SDO abort 0x06090030 on 0x6098): the error says so, the
/// drive never left CSP.
pub fn refused_method(rig: &mut impl ServoRig, base: DriveHomingParams, method: i8) {
    let status = drive_home(rig, DriveHomingParams { method, ..base });
    let CommandStatus::Error(e) = status else {
        panic!("expected the refusal, got {status:?}");
    };
    let text = e.to_string();
    assert!(
        text.starts_with(&format!(
            "drive homing method {method}: the drive refused 0x6098:00 = {method} (SDO abort \
             0x06090030"
        )),
        "{text}"
    );
    let st = rig.status();
    assert_eq!(st.state, AxisState::Standstill);
    assert_eq!(rig.with_servo(|s| (s.mode(), s.record().faults)), (8, 0));
}

/// Skip (an absolute drive): homed at once on the drive's position, nothing moves.
pub fn skip(rig: &mut impl ServoRig, base: DriveHomingParams) {
    let before = rig.with_servo(|s| s.position_counts());
    let status = drive_home(rig, DriveHomingParams { skip: true, ..base });
    assert_eq!(status, CommandStatus::Done);
    rig.cycles(10);
    let st = rig.status();
    assert!(st.bits.homed);
    assert_eq!(rig.with_servo(|s| s.position_counts()), before);
    let reads = rig.with_servo(|s| i64::from(s.actual_counts()));
    assert!((st.actual_position - reads as f64 / COUNTS_PER_MM).abs() < 1e-6);
}

/// Starts drive homing with `params` without waiting.
fn start(rig: &mut impl ServoRig, params: DriveHomingParams) -> CommandHandle {
    rig.ctl()
        .drive_procedure(0, DriveProcedure::Homing(DriveHoming::new(params)))
        .expect("queued")
}

/// QuickStop while the drive homes: the master gives the drive the Quick stop command, so
/// it brakes on its quick-stop ramp (0x6085: ten times the homing acceleration here, a
/// tenth of the distance), then enables it and hands it back (the lending's handle ends
/// naming QuickStop); the drive stands, in CSP, unfaulted,
/// the first CSP target its own position; the axis in Standstill, not homed. Then power
/// off while the drive homes: the lending ends at once (Aborted), the drive is switched
/// off and set back to CSP (by SDO where the layout has no 0x6060), and enables and moves
/// again.
pub fn cancel_and_power_off(rig: &mut impl ServoRig, base: DriveHomingParams) {
    // Method 1: a long way to the negative limit switch.
    let params = DriveHomingParams { method: 1, ..base };
    let h = start(rig, params);
    rig.cycles((0.5 / rig.cycle_s()) as usize);
    let moving = rig.with_servo(|s| s.velocity().abs());
    assert!(moving > 1000.0, "homing runs: {moving} counts/s");
    let from = rig.with_servo(|s| s.position_counts());
    let q = rig.ctl().command(0, Command::QuickStop).expect("queued");
    assert_eq!(rig.finish(&q, 100), CommandStatus::Done);
    let status = rig.finish(&h, (10.0 / rig.cycle_s()) as usize);
    // The distance it took to stand: its quick-stop ramp's, plus the travel of the few
    // cycles the command takes to reach it; on the homing acceleration it would be ten
    // times the ramp's.
    let stopped = (rig.with_servo(|s| s.position_counts()) - from).abs() as f64;
    let qs_decel =
        f64::from(gantry_sim::plant::servo::ServoParams::default().quick_stop_deceleration);
    let homing_decel = f64::from(params.acceleration);
    let ramp = moving * moving / (2.0 * qs_decel);
    let bound = ramp + moving * 6.0 * rig.cycle_s() + 2.0;
    eprintln!(
        "QuickStop during drive homing: stood after {stopped:.0} counts at {moving:.0} \
         counts/s (quick-stop ramp {ramp:.0}, bound {bound:.0}; the homing acceleration's \
         {:.0})",
        moving * moving / (2.0 * homing_decel)
    );
    assert!(
        stopped <= bound && stopped < moving * moving / (2.0 * homing_decel) / 2.0,
        "stood after {stopped} counts (bound {bound})"
    );
    let CommandStatus::Error(e) = status else {
        panic!("expected the cancel, got {status:?}");
    };
    assert_eq!(
        e.to_string(),
        "drive homing method 1: cancelled by QuickStop"
    );
    rig.cycles(20);
    let st = rig.status();
    assert_eq!(st.state, AxisState::Standstill);
    assert!(!st.bits.homed);
    let (mode, velocity, takeover, faults) =
        rig.with_servo(|s| (s.mode(), s.velocity(), s.takeover(), s.record().faults));
    assert_eq!((mode, faults), (8, 0));
    assert!(velocity.abs() < 100.0, "stands: {velocity}");
    let (target, actual) = takeover.expect("a CSP target");
    assert!(
        (i64::from(target) - i64::from(actual)).abs() <= 1,
        "first CSP target {target}, the drive stood at {actual}"
    );
    // Power off in the middle of it.
    let h = start(rig, params);
    rig.cycles((0.3 / rig.cycle_s()) as usize);
    let off = rig
        .ctl()
        .command(
            0,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Disable),
        )
        .expect("queued");
    rig.finish(&off, 2000);
    assert_eq!(rig.finish(&h, 10), CommandStatus::Aborted);
    rig.cycles((1.0 / rig.cycle_s()) as usize);
    assert_eq!(rig.status().state, AxisState::Disabled);
    assert_eq!(rig.with_servo(|s| s.mode()), 8, "set back to CSP");
    let on = rig
        .ctl()
        .command(
            0,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
        )
        .expect("queued");
    assert_eq!(rig.finish(&on, 5000), CommandStatus::Done);
    let here = rig.status().actual_position;
    move_to(rig, here + 1.0);
    assert_eq!(rig.with_servo(|s| s.record().faults), 0);
}

/// An EtherCAT rig (1 ms) whose servo has the switch cams and `homing` in `[slave.homing]`, the axis
/// mapped `pdo`, with `[axis.drive_homing]`.
pub fn ethercat_rig(
    homing: &str,
    pdo: &str,
) -> (crate::servo_rig::EthercatServo, gantry::config::Config) {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = {}\n{}\
         [slave.homing]\n{homing}\n",
        crate::DEFAULT_SYNC_ERROR_LIMIT,
        crate::homing::servo_switches_toml()
    );
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\npdo = \"{pdo}\"\nhoming_required = false\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
         max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n\
         [axis.drive_homing]\nmethod = 19\nspeed_switch = 50.0\nspeed_zero = 5.0\n\
         acceleration = 500.0\nhome_offset = 2.0\ntimeout = 10.0\n"
    );
    let config = crate::sim_config_text(1000, &slaves, "", &axes);
    let mut rig = crate::servo_rig::EthercatServo {
        rig: crate::rig::Rig::new(&config),
        cycle_s: 1e-3,
    };
    let h = rig
        .rig
        .ctl
        .command(
            0,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
        )
        .expect("queued");
    assert_eq!(rig.rig.finish(&h, 5000), CommandStatus::Done);
    (rig, config)
}
