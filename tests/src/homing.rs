//! Switches and homing end to end on either bus, in lockstep: the simulated servo's switch
//! cams reach the axis through its 0x60FD, its touch probes latch the home switch's edges
//! and the index pulse, and the kernel's MoveHome takes the reference from those latches —
//! exact to the count whatever the speed; a hardware limit switch stops the axis into
//! ErrorStop, after which it may only move away. `tests/tests/homing_ethercat.rs` and
//! `homing_canopen.rs` run [`scenario`] on each bus' rig.

use gantry_kernel::axis::command::{Command, MoveDirection, MovePtp, PositioningMode};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use gantry_kernel::homing::{HomingMode, LimitSide, MoveHome, MoveHomeCall, SwitchConfig};

pub use crate::servo_rig::ServoRig;

/// What the scenario needs of a rig with one axis (axis 0) on a simulated servo, on top of
/// [`ServoRig`] (every servo rig has it).
pub trait HomingRig: ServoRig {
    /// Sends `command` to the axis and cycles until it is final (at most `max` cycles).
    fn run_command(&mut self, command: Command, max: usize) -> CommandStatus {
        let h = self.ctl().command(0, command).expect("queued");
        self.finish(&h, max)
    }
    /// The simulated drive's load position (counts, not wrapped).
    fn drive_counts(&self) -> i64 {
        self.with_servo(|s| s.position_counts())
    }
    /// Faults the simulated drive recorded.
    fn drive_faults(&self) -> u32 {
        self.with_servo(|s| s.record().faults)
    }
}

impl<T: ServoRig> HomingRig for T {}

/// The simulated servo's switches (`[slave.switches]`, counts): limit switches beyond
/// ±50 mm, the home cam from 10 mm to just under 12 mm.
pub fn servo_switches_toml() -> String {
    format!(
        "[slave.switches]\n\
         negative_limit = [-9000000000, {NEGATIVE_LIMIT_AT}]\n\
         positive_limit = [{POSITIVE_LIMIT_AT}, 9000000000]\n\
         home = [{}, {}]\n",
        CAM.0, CAM.1
    )
}

/// The axis' switches (`[axis.switches]`): all three from the drive, and the simulated
/// drive's 0x60D0 values for its limit switch inputs (manufacturer-specific: −1 negative,
/// −2 positive) so that MoveHome can latch a limit switch's edge.
pub const AXIS_SWITCHES_TOML: &str = "[axis.switches]\nnegative_limit = \"drive\"\n\
     positive_limit = \"drive\"\nreference = \"drive\"\n\
     probe_source = { negative_limit = -1, positive_limit = -2 }\n";

/// A digital-input module (chain position 1, watching the servo at 0) with the same
/// switches on its inputs: 0 the home cam, 1 the positive and 2 the negative limit
/// switch, both normally closed (the input drops when actuated).
pub fn module_switches_toml() -> String {
    format!(
        "[[slave]]\nkind = \"switches\"\naxis = 0\n\
         [[slave.cam]]\ninput = 0\nfrom = {}\nto = {}\n\
         [[slave.cam]]\ninput = 1\nfrom = {POSITIVE_LIMIT_AT}\nto = 9000000000\nnormally_closed = true\n\
         [[slave.cam]]\ninput = 2\nfrom = -9000000000\nto = {NEGATIVE_LIMIT_AT}\nnormally_closed = true\n",
        CAM.0, CAM.1
    )
}

/// The axis' switches on the module of [`module_switches_toml`] (`[axis.switches]`); the
/// drive's touch probe stays mapped for the index pulse.
pub const AXIS_MODULE_SWITCHES_TOML: &str = "[axis.switches]\n\
     negative_limit = { from = \"module\", slave = 1, input = 2, normally_closed = true }\n\
     positive_limit = { from = \"module\", slave = 1, input = 1, normally_closed = true }\n\
     reference = { from = \"module\", slave = 1, input = 0 }\n";

/// Counts per mm: 2¹⁷ counts per motor revolution, 5 mm per revolution.
pub const COUNTS_PER_MM: f64 = 131_072.0 / 5.0;
/// The home cam: 10 mm to just under 12 mm (counts, both included).
const CAM: (i64, i64) = (262_144, 314_572);
/// The limit switches: beyond ±50 mm.
const NEGATIVE_LIMIT_AT: i64 = -1_310_720;
const POSITIVE_LIMIT_AT: i64 = 1_310_720;

/// Sends `command` and cycles until it is final (homing at 1 mm/s takes seconds).
fn run(rig: &mut impl HomingRig, command: Command) -> CommandStatus {
    rig.run_command(command, 60_000)
}

/// Where drive position `mm` (drive frame) is in the axis' frame now.
fn axis_frame(rig: &impl HomingRig, mm: f64) -> f64 {
    let actual = rig.status().actual_position;
    mm + actual - drive_counts(rig) as f64 / COUNTS_PER_MM
}

fn drive_counts(rig: &impl HomingRig) -> i64 {
    rig.drive_counts()
}

fn move_home(direction: MoveDirection, mode: HomingMode, fast: f64, slow: f64) -> Command {
    Command::MoveHome(MoveHomeCall::all(home_params(direction, mode, fast, slow)))
}

/// MoveHome on the reference switch (reversing at the limit switches).
fn home_params(direction: MoveDirection, mode: HomingMode, fast: f64, slow: f64) -> MoveHome {
    MoveHome {
        direction,
        switch_config: SwitchConfig::RefAndLimitSwitch,
        mode,
        acceleration: 500.0,
        jerk: 20_000.0,
        speed_switch_search: fast,
        max_distance_switch_search: 200.0,
        speed_reference_search: slow,
        max_distance_reference_search: 50.0,
        reference_offset: 0.0,
        normal_position: 0.0,
    }
}

/// The switches as the axis sees them, through the drive's process data.
/// The whole scenario on `rig` (enabled, not homed, the drive at 0): the switches seen,
/// a limit switch stop and the move-away rule, MoveHome on the home switch's rising edge
/// at three speeds, MoveHome on the index pulse; no drive fault anywhere.
pub fn scenario(rig: &mut impl HomingRig) {
    the_drive_s_switches_reach_the_axis(rig);
    a_limit_switch_stops_the_axis_and_lets_it_only_move_away(rig);
    move_home_takes_the_edge_from_the_touch_probe_to_the_count(rig);
    move_home_on_the_index_pulse(rig);
    move_home_on_a_limit_switch_edge(rig);
    assert_eq!(rig.drive_faults(), 0);
}

/// The scenario with the switches on an I/O module ([`AXIS_MODULE_SWITCHES_TOML`]): they
/// reach the axis every cycle and a limit switch stops it as the drive's do; MoveHome on
/// the reference switch's edge (and ZeroPulse after it, which starts at that edge) is
/// refused — the probe cannot latch a module input — and the axis goes on; MoveHome on
/// the index pulse alone runs.
pub fn module_scenario(rig: &mut impl HomingRig) {
    the_drive_s_switches_reach_the_axis(rig);
    a_limit_switch_stops_the_axis_and_lets_it_only_move_away(rig);
    for mode in [HomingMode::SwitchingEdge1Phase, HomingMode::ZeroPulse1Phase] {
        let status = run(rig, move_home(MoveDirection::Positive, mode, 10.0, 2.0));
        let CommandStatus::Error(e) = status else {
            panic!("{mode:?}: {status:?}, not refused");
        };
        assert!(
            e.to_string()
                .contains("needs the reference switch's edge from the drive's touch probe"),
            "{mode:?}: {e}"
        );
        assert_eq!(rig.status().state, AxisState::Standstill);
    }
    // ZeroPulse without a switch: the index pulse (probe 2) only.
    let below = axis_frame(rig, -20.0);
    let to = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, below).speed(50.0));
    assert_eq!(run(rig, to), CommandStatus::Done);
    let params = MoveHome {
        switch_config: SwitchConfig::NoSwitch,
        ..home_params(
            MoveDirection::Positive,
            HomingMode::ZeroPulse1Phase,
            5.0,
            5.0,
        )
    };
    let status = run(rig, Command::MoveHome(MoveHomeCall::all(params)));
    assert_eq!(status, CommandStatus::Done, "{:?}", rig.status().error);
    rig.cycles(200);
    let at = drive_counts(rig);
    let index = 1000 + (at - 1000 + 65_536).div_euclid(131_072) * 131_072;
    assert!(
        (at - index).abs() <= 1,
        "stands at {at}, nearest index {index}"
    );
    assert_eq!(rig.drive_faults(), 0);
}

fn the_drive_s_switches_reach_the_axis<R: HomingRig>(rig: &mut R) {
    let sw = |rig: &R| rig.status().switches;
    assert!(!sw(rig).reference);
    run(
        rig,
        Command::SetPosition {
            position: 0.0,
            relative: false,
        },
    );
    // Onto the cam (11 mm) and off it again.
    let to = |p| Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, p).speed(50.0));
    assert_eq!(run(rig, to(11.0)), CommandStatus::Done);
    rig.cycles(5);
    assert!(sw(rig).reference, "on the cam at {}", drive_counts(rig));
    assert!(!sw(rig).positive_limit && !sw(rig).negative_limit);
    assert_eq!(run(rig, to(20.0)), CommandStatus::Done);
    rig.cycles(5);
    assert!(!sw(rig).reference);
}

/// MoveHome on the home switch's rising edge, from below the cam: the reference is the
/// first count on the cam, exact at a slow and at a fast search speed (the cycle-sampled
/// position would be off by the distance of a cycle: 26 counts at 1 mm/s, 1300 at 50).
fn move_home_takes_the_edge_from_the_touch_probe_to_the_count(rig: &mut impl HomingRig) {
    for (mode, fast, slow) in [
        (HomingMode::SwitchingEdge1Phase, 1.0, 1.0),
        (HomingMode::SwitchingEdge1Phase, 50.0, 50.0),
        (HomingMode::SwitchingEdge2Phase, 50.0, 2.0),
    ] {
        // From 2 mm below the cam.
        let below = axis_frame(rig, CAM.0 as f64 / COUNTS_PER_MM - 2.0);
        let to = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, below).speed(50.0));
        assert_eq!(run(rig, to), CommandStatus::Done);
        let status = run(rig, move_home(MoveDirection::Positive, mode, fast, slow));
        let st = rig.status();
        assert_eq!(
            status,
            CommandStatus::Done,
            "{mode:?} at {fast}/{slow} mm/s: {:?}",
            st.error
        );
        assert!(st.homing.reference_set, "{mode:?}: {:?}", st.homing);
        rig.cycles(200);
        // NormalPosition 0 = ReferenceOffset 0: the axis stands on the edge.
        let at = drive_counts(rig);
        assert!(
            (at - CAM.0).abs() <= 1,
            "{mode:?} at {fast}/{slow} mm/s: stands at {at} counts, the edge is at {}",
            CAM.0
        );
        let actual = rig.status().actual_position;
        assert!(
            actual.abs() <= 1.0 / COUNTS_PER_MM,
            "{mode:?}: actual {actual}"
        );
    }
}

/// MoveHome on the index pulse after the switch: the reference is an index position.
fn move_home_on_the_index_pulse(rig: &mut impl HomingRig) {
    let below = axis_frame(rig, -20.0);
    let to = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, below).speed(50.0));
    assert_eq!(run(rig, to), CommandStatus::Done);
    let status = run(
        rig,
        move_home(
            MoveDirection::Positive,
            HomingMode::ZeroPulse2Phase,
            50.0,
            2.0,
        ),
    );
    let st = rig.status();
    assert_eq!(status, CommandStatus::Done, "{:?}", st.error);
    rig.cycles(200);
    let at = drive_counts(rig);
    // The simulated encoder's index is at 1000 counts in every revolution.
    let index = 1000 + (at - 1000 + 65_536).div_euclid(131_072) * 131_072;
    assert!(
        (at - index).abs() <= 1,
        "stands at {at}, nearest index {index}"
    );
}

/// MoveHome with `LimitSwitch` on the limit switch's edge, both ways: the master routes
/// the drive's touch probe to that switch by 0x60D0 (probe 1 on the negative, probe 2 on
/// the positive one) for the run, so the reference is the limit cam's first count, exact
/// at 1 and at 50 mm/s; ReferenceOffset backs the axis 2 mm off the switch.
fn move_home_on_a_limit_switch_edge(rig: &mut impl HomingRig) {
    for (direction, edge, speed) in [
        (MoveDirection::Positive, POSITIVE_LIMIT_AT, 1.0),
        (MoveDirection::Positive, POSITIVE_LIMIT_AT, 50.0),
        (MoveDirection::Negative, NEGATIVE_LIMIT_AT, 50.0),
    ] {
        let sign = direction.sign();
        // From 5 mm before the switch.
        let start = axis_frame(rig, edge as f64 / COUNTS_PER_MM - sign * 5.0);
        let to = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, start).speed(50.0));
        assert_eq!(run(rig, to), CommandStatus::Done, "to {start}");
        let params = MoveHome {
            switch_config: SwitchConfig::LimitSwitch,
            reference_offset: -sign * 2.0,
            ..home_params(direction, HomingMode::SwitchingEdge1Phase, speed, speed)
        };
        let status = run(rig, Command::MoveHome(MoveHomeCall::all(params)));
        let st = rig.status();
        assert_eq!(
            status,
            CommandStatus::Done,
            "{direction:?} at {speed} mm/s: {:?}",
            st.error
        );
        assert!(st.homing.reference_set, "{:?}", st.homing);
        rig.cycles(200);
        let at = drive_counts(rig);
        let expected = edge - (sign * 2.0 * COUNTS_PER_MM).round() as i64;
        assert!(
            (at - expected).abs() <= 1,
            "{direction:?} at {speed} mm/s: stands at {at} counts, the limit switch's edge \
             is at {edge}, 2 mm off it is {expected}"
        );
        let st = rig.status();
        assert!(st.actual_position.abs() <= 1.0 / COUNTS_PER_MM, "{st:?}");
        assert!(!st.switches.negative_limit && !st.switches.positive_limit);
        assert_ne!(st.state, AxisState::ErrorStop, "{:?}", st.error);
    }
    // ZeroPulse on the positive limit switch: its edge from probe 2 (0x60D0:2), the index
    // pulse from probe 1 meanwhile; the reference is the first index pulse back from the
    // edge (at 1000 counts in every revolution: 1 180 648, 5 mm before the switch).
    let start = axis_frame(rig, POSITIVE_LIMIT_AT as f64 / COUNTS_PER_MM - 8.0);
    let to = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, start).speed(50.0));
    assert_eq!(run(rig, to), CommandStatus::Done);
    let params = MoveHome {
        switch_config: SwitchConfig::LimitSwitch,
        ..home_params(
            MoveDirection::Positive,
            HomingMode::ZeroPulse1Phase,
            5.0,
            5.0,
        )
    };
    let status = run(rig, Command::MoveHome(MoveHomeCall::all(params)));
    assert_eq!(status, CommandStatus::Done, "{:?}", rig.status().error);
    rig.cycles(200);
    let index = 1000 + (POSITIVE_LIMIT_AT - 1001).div_euclid(131_072) * 131_072;
    let at = drive_counts(rig);
    assert!(
        (at - index).abs() <= 1,
        "stands at {at}, the index before the limit switch is at {index}"
    );
}

/// A move into the positive limit switch: quick stop into ErrorStop naming the switch;
/// after Reset, a move further on is refused and one away from it runs.
fn a_limit_switch_stops_the_axis_and_lets_it_only_move_away(rig: &mut impl HomingRig) {
    let to = |p| Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, p).speed(50.0));
    let status = run(rig, to(70.0));
    assert_ne!(status, CommandStatus::Done, "ran through the limit switch");
    rig.cycles(500);
    let st = rig.status();
    assert_eq!(st.state, AxisState::ErrorStop);
    assert_eq!(
        st.error,
        Some(AxisFault::LimitSwitch {
            side: LimitSide::Positive
        })
    );
    let at = drive_counts(rig);
    assert!(at >= POSITIVE_LIMIT_AT, "stopped on the switch: {at}");
    assert!(
        (at as f64) < 70.0 * COUNTS_PER_MM,
        "stopped well before the target: {at}"
    );
    assert_eq!(run(rig, Command::Reset), CommandStatus::Done);
    assert_ne!(run(rig, to(80.0)), CommandStatus::Done, "further on");
    assert_eq!(run(rig, to(0.0)), CommandStatus::Done, "away from it");
}
