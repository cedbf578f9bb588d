//! The homing matrix (issue 13 §6) on the simulated servo, in lockstep, on either bus:
//! every controller-side MoveHome mode × switch configuration × direction × start position
//! at a fast and a slow search speed, every Beckhoff MC_StepAbsoluteSwitch Direction ×
//! SwitchMode × start position of seed 003 (the cases the seed documents as failing in
//! TwinCAT included) at a normal and at small decelerations, and the error paths (a search
//! distance exceeded, a limit switch where the configuration has none, a limit switch hit
//! outside homing, a missing reference switch).
//!
//! **The judge is the simulator.** The drive records every switch edge and index pulse its
//! load crosses, at the count where it happened ([`gantry_sim::plant::servo::crossings`]).
//! Each run notes the crossings from its start to the cycle the axis reports "reference
//! found"; the master's reference — read back from where the axis stands and what it calls
//! that position (`NormalPosition − ReferenceOffset` for MoveHome, `Position` for
//! StepAbsoluteSwitch) — must equal the last crossing of what this case's semantics say
//! the reference is (the cam's negative or positive end, crossed which way; the index
//! pulse at that count) within one count. Where the axis ends must honour ReferenceOffset
//! and NormalPosition. Every cycle of every run the kernel's set velocity and acceleration
//! stay inside the run's own limits, and after each case the drive's record shows no
//! fault, no following error and no target step beyond `vmax · T` (what reached the drive).
//!
//! Geometry (drive frame, 26 214.4 counts/mm, index pulse at 1000 counts + every 5 mm):
//! negative limit switch at and below −10 mm, home cam 6 mm to 8 mm, positive limit
//! switch at and above 25 mm; starts ① 2 mm, ② 7 mm (on the cam), ③ 12 mm.

use gantry_kernel::axis::command::{
    Command, CommandError, MoveDirection, MovePtp, PositioningMode,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use gantry_kernel::homing::{
    HomeDirection, HomingError, HomingMode, LimitSide, MoveHome, MoveHomeCall, StepAbsoluteSwitch,
    SwitchConfig, SwitchMode,
};
use gantry_sim::plant::record::{max_step_counts, DriveRecord};
use gantry_sim::plant::servo::crossings::{Crossed, Crossing};

use std::time::Instant;

use crate::homing::{HomingRig, AXIS_SWITCHES_TOML, COUNTS_PER_MM};
use crate::rig::Rig;
use crate::servo_rig::EthercatServo;
use crate::{sim_config_text, DEFAULT_SYNC_ERROR_LIMIT};

/// What the matrix needs of a rig beyond [`HomingRig`]: the simulator's truth and a
/// command followed cycle by cycle.
pub trait MatrixRig: HomingRig {
    /// Sends `command` to the axis; the handle's id.
    fn send(&mut self, command: Command) -> u64 {
        self.ctl().command(0, command).expect("queued").id()
    }
    /// The number the drive's next crossing gets.
    fn next_crossing(&self) -> u64 {
        self.with_servo(|s| s.crossings().next_seq())
    }
    /// The drive's crossings numbered `seq` or later, and whether some were dropped.
    fn crossings_since(&self, seq: u64) -> (Vec<Crossing>, bool) {
        self.with_servo(|s| {
            let log = s.crossings();
            (log.since(seq).collect(), log.lost_since(seq))
        })
    }
    /// The drive's record of the setpoints it took.
    fn drive_record(&self) -> DriveRecord {
        self.with_servo(|s| *s.record())
    }
}

impl<T: HomingRig> MatrixRig for T {}

const MM: f64 = COUNTS_PER_MM;
/// The home cam (counts, both ends included): 6 mm to just under 8 mm.
pub const CAM: (i64, i64) = (157_286, 209_714);
/// The negative limit switch is active at and below this count (−10 mm).
pub const NEGATIVE_LIMIT_AT: i64 = -262_144;
/// The positive limit switch is active at and above this count (25 mm).
pub const POSITIVE_LIMIT_AT: i64 = 655_360;
/// The simulated encoder's index pulse: at 1000 counts in every revolution of 2¹⁷.
const INDEX_AT: i64 = 1000;
const REV: i64 = 131_072;

/// The axis' maxima (`max = { … }`): the homing runs stay well inside them.
pub const AXIS_MAX_TOML: &str = "max = { speed = 200.0, acceleration = 2000.0, jerk = 100000.0 }";
const VMAX: f64 = 200.0;

/// `[slave.switches]` of the matrix' servo; `home: false` leaves the home cam out (the
/// missing-switch case).
pub fn servo_switches_toml(home: bool) -> String {
    let mut s = format!(
        "[slave.switches]\n\
         negative_limit = [-9000000000, {NEGATIVE_LIMIT_AT}]\n\
         positive_limit = [{POSITIVE_LIMIT_AT}, 9000000000]\n"
    );
    if home {
        s += &format!("home = [{}, {}]\n", CAM.0, CAM.1);
    }
    s
}

/// The three start positions of seed 003 (drive frame, mm).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StartAt {
    /// ① between the negative limit switch and the cam.
    BelowCam,
    /// ② on the cam.
    OnCam,
    /// ③ between the cam and the positive limit switch.
    AboveCam,
}

impl StartAt {
    /// All three.
    pub const ALL: [Self; 3] = [Self::BelowCam, Self::OnCam, Self::AboveCam];

    fn mm(self) -> f64 {
        match self {
            Self::BelowCam => 2.0,
            Self::OnCam => 7.0,
            Self::AboveCam => 12.0,
        }
    }
}

/// An end of a cam.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum End {
    Low,
    High,
}

/// What a case must end with, by its semantics (not by what the kernel does).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    /// The reference is the last crossing of `what`'s `end` (crossed moving `moving`, if
    /// given) before "reference found".
    Edge {
        what: Crossed,
        end: End,
        moving: Option<i8>,
    },
    /// The reference is the index pulse at this count.
    Index(i64),
    /// The level holds at the start: the run ends at once where the axis stands.
    AtStart,
    /// The command is refused; the axis does not move.
    Refused,
    /// The run ends in ErrorStop with this fault, the axis stopped.
    Fails(AxisFault),
    /// The run ends in ErrorStop with this search distance exceeded while looking for
    /// this, the axis stopped.
    FailsDistance(&'static str, &'static str),
}

/// Whether the drive's touch probe latches the limit switch a `LimitSwitch` run homes on:
/// the master sets the probe's source to 0x60D0 (its limit switch input) for such a run,
/// and the simulated servo follows it. The matrix then expects the limit's edge (and the
/// index pulse beyond it) like every other configuration. `false` is for a drive whose
/// probe stays on the home switch: the kernel then takes no home-switch latch for the
/// limit's edge (a latch counts only when the limit's level changes in its cycle), so the
/// run crosses the limit switch, finds no edge and ends with its reference search
/// distance exceeded — a clear error, never a wrong reference.
pub const PROBE_ON_LIMIT_SWITCH: bool = true;

/// MoveHome's search distances (mm): far beyond the travel, except `LimitSwitch` today
/// (see [`PROBE_ON_LIMIT_SWITCH`]), which runs that far into the limit switch before it
/// gives up.
fn max_distance(cfg: SwitchConfig) -> f64 {
    if cfg == SwitchConfig::LimitSwitch && !PROBE_ON_LIMIT_SWITCH {
        30.0
    } else {
        200.0
    }
}

/// The count where crossing `end` of the cam `from..=to` moving `moving` happens (the
/// first count of the new state).
fn edge_count(from: i64, to: i64, end: End, moving: i8) -> i64 {
    match (end, moving > 0) {
        (End::Low, true) => from,
        (End::Low, false) => from - 1,
        (End::High, true) => to + 1,
        (End::High, false) => to,
    }
}

fn cam_of(what: Crossed) -> (i64, i64) {
    match what {
        Crossed::Home => CAM,
        Crossed::NegativeLimit => (i64::MIN / 2, NEGATIVE_LIMIT_AT),
        Crossed::PositiveLimit => (POSITIVE_LIMIT_AT, i64::MAX / 2),
        Crossed::Index => (0, 0),
    }
}

/// The first index pulse beyond `from` moving `d` (strictly).
fn index_beyond(from: i64, d: f64) -> i64 {
    let k = (from - INDEX_AT).div_euclid(REV);
    if d > 0.0 {
        INDEX_AT + (k + 1) * REV
    } else if (from - INDEX_AT).rem_euclid(REV) == 0 {
        INDEX_AT + (k - 1) * REV
    } else {
        INDEX_AT + k * REV
    }
}

fn limit_fault(d: f64) -> AxisFault {
    AxisFault::LimitSwitch {
        side: LimitSide::towards(d),
    }
}

/// MoveHome's outcome by seed 000 §6.3.2 and the reference definitions of
/// `gantry_kernel::homing::move_home` (CiA 402 methods 1–14 for the zero pulse after a
/// switch): the reference edge is the cam's end facing against the search; with ZeroPulse
/// the first index pulse beyond it; RefSwitch has no limit switches to reverse at.
fn move_home_expect(mode: HomingMode, cfg: SwitchConfig, d: f64, start: StartAt) -> Expect {
    let zero = matches!(
        mode,
        HomingMode::ZeroPulse1Phase | HomingMode::ZeroPulse2Phase
    );
    let start_counts = (start.mm() * MM).round() as i64;
    let (what, end) = match cfg {
        SwitchConfig::NoSwitch if zero => return Expect::Index(index_beyond(start_counts, d)),
        SwitchConfig::NoSwitch => return Expect::Refused,
        SwitchConfig::LimitSwitch if !PROBE_ON_LIMIT_SWITCH => {
            return Expect::FailsDistance(
                "MaxDistanceReferenceSearch",
                if d > 0.0 {
                    "positive limit switch"
                } else {
                    "negative limit switch"
                },
            )
        }
        SwitchConfig::LimitSwitch if d > 0.0 => (Crossed::PositiveLimit, End::Low),
        SwitchConfig::LimitSwitch => (Crossed::NegativeLimit, End::High),
        SwitchConfig::RefSwitch
            if (d > 0.0 && start == StartAt::AboveCam)
                || (d < 0.0 && start == StartAt::BelowCam) =>
        {
            return Expect::Fails(limit_fault(d))
        }
        _ if d > 0.0 => (Crossed::Home, End::Low),
        _ => (Crossed::Home, End::High),
    };
    if zero {
        let (from, to) = cam_of(what);
        // Beyond the edge, leaving the cam against the search direction.
        let edge = if d > 0.0 { from } else { to };
        return Expect::Index(index_beyond(edge, -d));
    }
    Expect::Edge {
        what,
        end,
        moving: None,
    }
}

/// MC_StepAbsoluteSwitch's outcome as seed 003 describes each SwitchMode (its expected
/// paths where TwinCAT 3.0.23.0 deviates).
fn step_switch_expect(dir: HomeDirection, mode: SwitchMode, start: StartAt) -> Expect {
    let d = dir.sign() as i8;
    let on = start == StartAt::OnCam;
    let switch_dir = matches!(
        dir,
        HomeDirection::SwitchPositive | HomeDirection::SwitchNegative
    );
    let edge = |end, moving: i8| Expect::Edge {
        what: Crossed::Home,
        end,
        moving: Some(moving),
    };
    // Rising moving positive is the cam's low end; rising moving negative its high end.
    let rising = |m: i8| edge(if m > 0 { End::Low } else { End::High }, m);
    let falling = |m: i8| edge(if m > 0 { End::High } else { End::Low }, m);
    match mode {
        SwitchMode::RisingEdge => rising(d),
        SwitchMode::FallingEdge => falling(d),
        SwitchMode::RisingEdgeInverse => rising(-d),
        SwitchMode::FallingEdgeInverse => falling(-d),
        // Always the low end: ① reached moving positive, ② and ③ moving negative.
        SwitchMode::EdgeSwitchPositive => match start {
            StartAt::BelowCam => edge(End::Low, 1),
            _ => edge(End::Low, -1),
        },
        // Always the high end: ① and ② moving positive, ③ moving negative.
        SwitchMode::EdgeSwitchNegative => match start {
            StartAt::AboveCam => edge(End::High, -1),
            _ => edge(End::High, 1),
        },
        // Ends when the cam is on: off the cam, the first end reached (after reversing at
        // a limit switch); on it with Positive/Negative at once; with a Switch… direction
        // it leaves against the direction first and comes back.
        SwitchMode::On => match start {
            StartAt::BelowCam => edge(End::Low, 1),
            StartAt::AboveCam => edge(End::High, -1),
            StartAt::OnCam if !switch_dir => Expect::AtStart,
            StartAt::OnCam if d > 0 => edge(End::Low, 1),
            StartAt::OnCam => edge(End::High, -1),
        },
        // Ends when the cam is off: off it at once; on it at the end it leaves over
        // (a Switch… direction leaves against the direction).
        SwitchMode::Off if !on => Expect::AtStart,
        SwitchMode::Off => {
            let leaves = if switch_dir { -d } else { d };
            edge(if leaves > 0 { End::High } else { End::Low }, leaves)
        }
    }
}

/// The search speeds of the matrix: (switch search, reference search), mm/s.
pub const SPEEDS: [(f64, f64); 2] = [(100.0, 20.0), (10.0, 2.0)];

/// Every MoveHome mode.
pub const MODES: [HomingMode; 4] = [
    HomingMode::ZeroPulse1Phase,
    HomingMode::ZeroPulse2Phase,
    HomingMode::SwitchingEdge1Phase,
    HomingMode::SwitchingEdge2Phase,
];

/// Every switch configuration.
pub const CONFIGS: [SwitchConfig; 4] = [
    SwitchConfig::RefAndLimitSwitch,
    SwitchConfig::RefSwitch,
    SwitchConfig::LimitSwitch,
    SwitchConfig::NoSwitch,
];

/// What a matrix run found out, for the summary.
#[derive(Debug, Default)]
pub struct Tally {
    /// Cases run.
    pub cases: usize,
    /// Cycles run.
    pub cycles: u64,
    /// Cases whose outcome was not what the semantics say (with why), when the caller
    /// collects instead of failing at the first.
    pub failures: Vec<String>,
}

/// One case's parameters, for messages.
struct Case {
    name: String,
    command: Command,
    expect: Expect,
    /// The axis value the reference gets.
    reference_value: f64,
    /// Where the axis ends relative to the reference (mm; `None`: past it, braking).
    offset: Option<f64>,
    /// The run's own limits: speed and acceleration.
    vmax: f64,
    amax: f64,
    start: StartAt,
}

/// Where drive position `mm` is in the axis' frame now.
fn axis_frame(rig: &impl MatrixRig, mm: f64) -> f64 {
    mm + rig.status().actual_position - rig.drive_counts() as f64 / MM
}

/// Brings the axis to `start` (resetting an ErrorStop first); the drive's counts there.
fn go_to(rig: &mut impl MatrixRig, start: StartAt) -> i64 {
    if rig.status().state == AxisState::ErrorStop {
        assert_eq!(rig.run_command(Command::Reset, 5000), CommandStatus::Done);
    }
    if !rig.status().bits.homed {
        // After a failed run: keep the frame, allow positioning again.
        let keep = Command::SetPosition {
            position: rig.status().set.p,
            relative: false,
        };
        assert_eq!(rig.run_command(keep, 5000), CommandStatus::Done);
    }
    let to = axis_frame(rig, start.mm());
    let m = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, to).speed(100.0));
    let s = rig.run_command(m, 20_000);
    assert_eq!(
        s,
        CommandStatus::Done,
        "to {start:?}: {:?}",
        rig.status().error
    );
    rig.cycles(20);
    rig.drive_counts()
}

/// Runs `case` from its start; `Err` says how it broke the semantics or an invariant.
fn run_case(rig: &mut impl MatrixRig, case: &Case, tally: &mut Tally) -> Result<(), String> {
    let at_start = go_to(rig, case.start);
    let faults = rig.drive_faults();
    let lost = rig.lost_frames();
    let seq = rig.next_crossing();
    let id = rig.send(case.command);
    let mut found_at: Option<u64> = None;
    let mut status = None;
    let tol_v = 1e-6 * case.vmax.max(1.0);
    // Generous: the slowest run travels ~40 mm at 2 mm/s.
    let max_cycles = (60.0 / rig.cycle_s()) as usize;
    for n in 0..max_cycles {
        rig.cycles(1);
        tally.cycles += 1;
        let st = rig.status();
        if st.homing.reference_found && found_at.is_none() {
            found_at = Some(rig.next_crossing());
        }
        if st.state == AxisState::Homing {
            let (v, a) = (st.set.v.abs(), st.set.a.abs());
            if v > case.vmax + tol_v || a > case.amax * (1.0 + 1e-6) + 1e-6 {
                return Err(format!(
                    "cycle {n}: set v {v} a {a} beyond the run's {} / {}",
                    case.vmax, case.amax
                ));
            }
        }
        if let Some(s) = rig.command_status(id).filter(CommandStatus::is_final) {
            status = Some(s);
            break;
        }
    }
    let status = status.ok_or_else(|| format!("not finished in {max_cycles} cycles"))?;
    // Standing: the axis and the drive settle.
    rig.cycles(150);
    tally.cycles += 150;
    let st = rig.status();
    if rig.lost_frames() != lost {
        return Err(format!("{} frames lost", rig.lost_frames() - lost));
    }
    let (crossings, dropped) = rig.crossings_since(seq);
    if dropped {
        return Err("the drive's crossing log overflowed".into());
    }
    let counts = rig.drive_counts();
    if rig.drive_faults() != faults {
        return Err(format!("the drive faulted: {:?}", rig.drive_record()));
    }
    let rec = rig.drive_record();
    let bound = max_step_counts(VMAX * MM, rig.cycle_s());
    if rec.following_error_faults != 0
        || rec.max_target_step_counts > bound
        || rec.sync_missed != 0
        || rec.sync_doubled != 0
    {
        return Err(format!(
            "drive invariant broken: {rec:?}, step bound {bound}"
        ));
    }
    let ok = |s: &CommandStatus| *s == CommandStatus::Done;
    match case.expect {
        Expect::Refused => {
            let mode_refused = matches!(
                status,
                CommandStatus::Error(CommandError::HomingParameter {
                    parameter: "Mode",
                    ..
                })
            );
            if !mode_refused || !crossings.is_empty() || (counts - at_start).abs() > 2 {
                return Err(format!(
                    "not refused: {status:?}, moved {} counts",
                    counts - at_start
                ));
            }
            Ok(())
        }
        Expect::Fails(_) | Expect::FailsDistance(..) => {
            let right = match (case.expect, st.error) {
                (Expect::Fails(f), Some(e)) => f == e,
                (
                    Expect::FailsDistance(distance, looking_for),
                    Some(AxisFault::Command(CommandError::Homing(HomingError::DistanceExceeded {
                        distance: d,
                        looking_for: l,
                        ..
                    }))),
                ) => (d, l) == (distance, looking_for),
                _ => false,
            };
            if ok(&status) || st.state != AxisState::ErrorStop || !right {
                let fault = case.expect;
                return Err(format!(
                    "expected {fault:?} in ErrorStop: {status:?}, {:?} {:?}",
                    st.state, st.error
                ));
            }
            let still = rig.drive_counts();
            rig.cycles(20);
            tally.cycles += 20;
            if rig.drive_counts() != still || st.set.v != 0.0 {
                return Err("the axis is not stopped".into());
            }
            Ok(())
        }
        Expect::AtStart | Expect::Edge { .. } | Expect::Index(_) => {
            if !ok(&status) {
                return Err(format!("{status:?}: {:?}", st.error));
            }
            if !st.homing.reference_set || !st.bits.homed {
                return Err(format!("not homed: {:?}", st.homing));
            }
            // The reference the master took, read back in drive counts.
            let reference = counts as f64 + (case.reference_value - st.actual_position) * MM;
            let truth = match case.expect {
                Expect::AtStart => {
                    if !crossings.is_empty() {
                        return Err(format!("moved although the level held: {crossings:?}"));
                    }
                    at_start
                }
                Expect::Index(at) => {
                    let mark = found_at.ok_or("reference never found")?;
                    let last = crossings
                        .iter()
                        .rfind(|c| c.seq < mark && c.what == Crossed::Index)
                        .ok_or("the drive crossed no index pulse")?;
                    if last.at != at {
                        return Err(format!(
                            "the last index pulse crossed before the reference was found is at {}, the case's is at {at}",
                            last.at
                        ));
                    }
                    last.at
                }
                Expect::Edge { what, end, moving } => {
                    let mark = found_at.ok_or("reference never found")?;
                    let (from, to) = cam_of(what);
                    let is_end = |c: &&Crossing| {
                        c.what == what
                            && c.seq < mark
                            && c.at == edge_count(from, to, end, c.moving)
                            && moving.is_none_or(|m| m == c.moving)
                    };
                    let last = crossings.iter().rfind(is_end).ok_or_else(|| {
                        format!("the drive never crossed {what:?}'s {end:?} end moving {moving:?} before the reference was found: {crossings:?}")
                    })?;
                    last.at
                }
                _ => unreachable!(),
            };
            if (reference - truth as f64).abs() > 1.0 + 1e-6 {
                return Err(format!(
                    "reference at {reference:.2} counts, the simulated {:?} at {truth} ({crossings:?})",
                    case.expect
                ));
            }
            if let Some(offset) = case.offset {
                // ReferenceOffset: the axis stands there; NormalPosition: it is called that.
                let want = truth as f64 + offset * MM;
                if (counts as f64 - want).abs() > 1.0 + 1e-6 {
                    return Err(format!(
                        "stands at {counts}, reference {truth} + offset {offset} mm = {want:.1}"
                    ));
                }
                let np = case.reference_value + offset;
                if (st.actual_position - np).abs() > 1.0 / MM + 1e-9 {
                    return Err(format!(
                        "actual {} is not NormalPosition {np}",
                        st.actual_position
                    ));
                }
            }
            Ok(())
        }
    }
}

fn record(rig: &mut impl MatrixRig, case: Case, tally: &mut Tally, collect: bool) {
    tally.cases += 1;
    if let Err(e) = run_case(rig, &case, tally) {
        let msg = format!("{}: {e}", case.name);
        if collect {
            eprintln!("FAIL {msg}");
            tally.failures.push(msg);
        } else {
            panic!("{msg}");
        }
    }
}

/// The matrix' MoveHome: every mode × switch configuration × direction × start × speed.
/// `only` filters by case name (a substring; empty: all); `collect` collects failures
/// into the tally instead of panicking at the first.
pub fn move_home_matrix(rig: &mut impl MatrixRig, only: &str, collect: bool) -> Tally {
    let mut tally = Tally::default();
    let mut k = 0usize;
    for (fast, slow) in SPEEDS {
        for mode in MODES {
            for cfg in CONFIGS {
                for direction in [MoveDirection::Positive, MoveDirection::Negative] {
                    for start in StartAt::ALL {
                        k += 1;
                        let name = format!(
                            "MoveHome {mode:?} {cfg:?} {direction:?} from {start:?} at {fast}/{slow} mm/s"
                        );
                        if !name.contains(only) {
                            continue;
                        }
                        // Offsets and normal positions differ from case to case.
                        let offset = [0.0, 0.75, -0.5][k % 3];
                        let normal_position = 100.0 + k as f64 * 0.25;
                        let p = MoveHome {
                            direction,
                            switch_config: cfg,
                            mode,
                            acceleration: 1000.0,
                            jerk: 50_000.0,
                            speed_switch_search: fast,
                            max_distance_switch_search: max_distance(cfg),
                            speed_reference_search: slow,
                            max_distance_reference_search: max_distance(cfg),
                            reference_offset: offset,
                            normal_position,
                        };
                        let expect = move_home_expect(mode, cfg, direction.sign(), start);
                        let amax = match expect {
                            // The stop at a limit switch brakes with the quick stop.
                            Expect::Fails(_) | Expect::FailsDistance(..) => 2000.0,
                            _ => p.acceleration,
                        };
                        let case = Case {
                            name,
                            command: Command::MoveHome(MoveHomeCall::all(p)),
                            expect,
                            reference_value: normal_position - offset,
                            offset: Some(offset),
                            vmax: fast.max(slow),
                            amax,
                            start,
                        };
                        record(rig, case, &mut tally, collect);
                    }
                }
            }
        }
    }
    tally
}

/// Seed 003 on the simulator: every Direction × SwitchMode × start, at deceleration
/// `deceleration` (mm/s², at 20 mm/s; small ones brake past the 2 mm cam).
pub fn step_switch_matrix(
    rig: &mut impl MatrixRig,
    deceleration: f64,
    only: &str,
    collect: bool,
) -> Tally {
    let mut tally = Tally::default();
    let mut k = 0usize;
    for dir in HomeDirection::ALL {
        for mode in SwitchMode::ALL {
            for start in StartAt::ALL {
                k += 1;
                let name = format!(
                    "StepAbsoluteSwitch {dir:?} {mode:?} from {start:?} decelerating at {deceleration} mm/s²"
                );
                if !name.contains(only) {
                    continue;
                }
                let position = -50.0 + k as f64 * 0.5;
                let p = StepAbsoluteSwitch {
                    direction: dir,
                    switch_mode: mode,
                    position,
                    velocity: 20.0,
                    acceleration: 1000.0,
                    deceleration,
                    jerk: 50_000.0,
                    distance_limit: f64::INFINITY,
                };
                let case = Case {
                    name,
                    command: Command::StepAbsoluteSwitch(p),
                    expect: step_switch_expect(dir, mode, start),
                    reference_value: position,
                    offset: None,
                    vmax: 20.0,
                    amax: deceleration.max(1000.0),
                    start,
                };
                record(rig, case, &mut tally, collect);
            }
        }
    }
    tally
}

/// The error paths on the matrix' geometry: each search distance exceeded, a limit switch
/// hit by a move outside homing; each ends in ErrorStop with its documented fault and the
/// axis stopped.
pub fn error_cases(rig: &mut impl MatrixRig) -> Tally {
    let mut tally = Tally::default();
    let base = MoveHome {
        direction: MoveDirection::Positive,
        switch_config: SwitchConfig::RefAndLimitSwitch,
        mode: HomingMode::SwitchingEdge2Phase,
        acceleration: 1000.0,
        jerk: 50_000.0,
        speed_switch_search: 50.0,
        max_distance_switch_search: 1.0,
        speed_reference_search: 5.0,
        max_distance_reference_search: 200.0,
        reference_offset: 0.0,
        normal_position: 0.0,
    };
    for (p, (distance, limit, looking_for)) in [
        // The cam is 4 mm away: the switch search gives up after 1 mm.
        (base, ("MaxDistanceSwitchSearch", 1.0, "reference switch")),
        // The next index pulse is 3 mm away (5.04 mm): the search gives up after 1 mm.
        (
            MoveHome {
                switch_config: SwitchConfig::NoSwitch,
                mode: HomingMode::ZeroPulse1Phase,
                max_distance_switch_search: 200.0,
                max_distance_reference_search: 1.0,
                ..base
            },
            ("MaxDistanceReferenceSearch", 1.0, "index pulse"),
        ),
    ] {
        tally.cases += 1;
        go_to(rig, StartAt::BelowCam);
        let faults = rig.drive_faults();
        let s = rig.run_command(Command::MoveHome(MoveHomeCall::all(p)), 20_000);
        rig.cycles(300);
        let st = rig.status();
        let Some(AxisFault::Command(CommandError::Homing(HomingError::DistanceExceeded {
            command,
            distance: d,
            limit: l,
            travelled,
            looking_for: lf,
        }))) = st.error
        else {
            panic!(
                "{distance}: expected the distance exceeded, got {s:?} {:?}",
                st.error
            );
        };
        assert_eq!(
            (command, d, l, lf),
            ("MoveHome", distance, limit, looking_for)
        );
        assert!(
            travelled > limit && travelled < limit + 0.5,
            "{distance}: travelled {travelled}"
        );
        assert_eq!(st.state, AxisState::ErrorStop, "{distance}");
        assert!(
            matches!(
                s,
                CommandStatus::Error(CommandError::Homing(HomingError::DistanceExceeded { .. }))
            ),
            "{distance}: {s:?}"
        );
        assert_stopped(rig, distance);
        assert_eq!(rig.drive_faults(), faults);
        assert!(!st.bits.homed, "{distance}: not homed after a failed run");
    }
    // A limit switch outside homing: quick stop into ErrorStop naming it.
    tally.cases += 1;
    go_to(rig, StartAt::AboveCam);
    let to = axis_frame(rig, 40.0);
    let s = rig.run_command(
        Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, to).speed(100.0)),
        20_000,
    );
    assert_ne!(
        s,
        CommandStatus::Done,
        "ran through the positive limit switch"
    );
    rig.cycles(300);
    let st = rig.status();
    assert_eq!(st.state, AxisState::ErrorStop);
    assert_eq!(st.error, Some(limit_fault(1.0)));
    // Where it may stand: past the edge by what it travels until the drive's input comes
    // back in the process data (up to 4 cycles at 100 mm/s) and the jerk-limited quick
    // stop (deceleration 2000 mm/s², jerk 100000 mm/s³ of AXIS_MAX_TOML: v²/2a + v·a/2j =
    // 3.5 mm): 3.9 mm at 1 ms, 5.1 mm at 4 ms.
    let (v, a, j) = (100.0, 2000.0, 100_000.0);
    let beyond = v * 4.0 * rig.cycle_s() + v * v / (2.0 * a) + v * a / (2.0 * j);
    let at = rig.drive_counts();
    assert!(
        (POSITIVE_LIMIT_AT..(POSITIVE_LIMIT_AT as f64 + beyond * MM) as i64).contains(&at),
        "stopped on the switch, within {beyond:.1} mm of its edge: {at}"
    );
    assert_stopped(rig, "limit switch outside homing");
    tally
}

/// A run with no home cam on the travel: RefAndLimitSwitch reverses at both limit
/// switches and fails naming the reference switch; RefSwitch fails at the first limit.
pub fn missing_reference_switch(rig: &mut impl MatrixRig) -> Tally {
    let mut tally = Tally::default();
    for (cfg, want) in [
        (
            SwitchConfig::RefAndLimitSwitch,
            AxisFault::Command(CommandError::Homing(HomingError::NotFoundBetweenLimits {
                command: "MoveHome",
                looking_for: "reference switch",
            })),
        ),
        (SwitchConfig::RefSwitch, limit_fault(1.0)),
    ] {
        for mode in [
            HomingMode::SwitchingEdge1Phase,
            HomingMode::SwitchingEdge2Phase,
        ] {
            tally.cases += 1;
            go_to(rig, StartAt::OnCam);
            let p = MoveHome {
                direction: MoveDirection::Positive,
                switch_config: cfg,
                mode,
                acceleration: 1000.0,
                jerk: 50_000.0,
                speed_switch_search: 100.0,
                max_distance_switch_search: 500.0,
                speed_reference_search: 20.0,
                max_distance_reference_search: 500.0,
                reference_offset: 0.0,
                normal_position: 0.0,
            };
            let s = rig.run_command(Command::MoveHome(MoveHomeCall::all(p)), 60_000);
            rig.cycles(300);
            let st = rig.status();
            assert_ne!(s, CommandStatus::Done, "{cfg:?} {mode:?}");
            assert_eq!(st.state, AxisState::ErrorStop, "{cfg:?} {mode:?}");
            assert_eq!(st.error, Some(want), "{cfg:?} {mode:?}");
            assert_stopped(rig, "missing reference switch");
        }
    }
    tally
}

fn assert_stopped(rig: &mut impl MatrixRig, what: &str) {
    let at = rig.drive_counts();
    rig.cycles(20);
    assert_eq!(rig.drive_counts(), at, "{what}: the axis still moves");
    assert_eq!(rig.status().set.v, 0.0, "{what}: set velocity");
}

/// Prints a part's figures.
pub fn report(part: &str, t: &Tally, since: Instant) {
    eprintln!(
        "{part}: {} cases, {} cycles, {:.1} s",
        t.cases,
        t.cycles,
        since.elapsed().as_secs_f64()
    );
}

/// The whole matrix over EtherCAT at a `cycle_us` cycle (once per process: the EtherCAT
/// bus starts once per process).
pub fn over_ethercat(cycle_us: u32) {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}\n{}",
        servo_switches_toml(true)
    );
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\npdo = \"csp-minimal\"\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
         {AXIS_MAX_TOML}\n{AXIS_SWITCHES_TOML}"
    );
    let config = sim_config_text(cycle_us, &slaves, "", &axes);
    let mut rig = EthercatServo {
        rig: Rig::new(&config),
        cycle_s: f64::from(cycle_us) * 1e-6,
    };
    assert_eq!(
        rig.run_command(
            Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
            5000
        ),
        CommandStatus::Done
    );
    let only = std::env::var("HOMING_MATRIX_ONLY").unwrap_or_default();
    let mut failures = Vec::new();
    let mut cases = 0;
    let t = Instant::now();
    let m = move_home_matrix(&mut rig, &only, true);
    report("MoveHome", &m, t);
    let t = Instant::now();
    let mut s = step_switch_matrix(&mut rig, 1000.0, &only, true);
    let small = step_switch_matrix(&mut rig, 40.0, &only, true);
    s.cases += small.cases;
    s.cycles += small.cycles;
    s.failures.extend(small.failures);
    report("StepAbsoluteSwitch", &s, t);
    for tally in [m, s] {
        cases += tally.cases;
        failures.extend(tally.failures);
    }
    if only.is_empty() {
        let t = Instant::now();
        let e = error_cases(&mut rig);
        report("errors", &e, t);
        cases += e.cases;
    }
    assert!(cases > 0, "no case matches {only:?}");
    assert!(
        failures.is_empty(),
        "{} of {cases} cases failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
