//! Switches and homing end to end over EtherCAT, in lockstep (`gantry_tests::rig`): the
//! simulated servo's switch cams reach the axis through its 0x60FD, its touch probes
//! latch the home switch's edges and the index pulse, and the kernel's MoveHome takes the
//! reference from those latches — exact to the count whatever the speed; a hardware limit
//! switch stops the axis into ErrorStop, after which it may only move away.
//!
//! One test: the EtherCAT bus starts once per process.

use gantry_kernel::axis::command::{
    Command, MoveDirection, MovePtp, PositioningMode, PowerCommand,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use gantry_kernel::homing::{HomingMode, LimitSide, MoveHome, MoveHomeCall, SwitchConfig};
use gantry_tests::rig::Rig;
use gantry_tests::{sim_config_text, DEFAULT_SYNC_ERROR_LIMIT};

/// Counts per mm: 2¹⁷ counts per motor revolution, 5 mm per revolution.
const COUNTS_PER_MM: f64 = 131_072.0 / 5.0;
/// The home cam: 10 mm to just under 12 mm (counts, both included).
const CAM: (i64, i64) = (262_144, 314_572);
/// The limit switches: beyond ±50 mm.
const NEGATIVE_LIMIT_AT: i64 = -1_310_720;
const POSITIVE_LIMIT_AT: i64 = 1_310_720;

fn rig() -> Rig {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n\
         [slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}\n\
         [slave.switches]\n\
         negative_limit = [-9000000000, {NEGATIVE_LIMIT_AT}]\n\
         positive_limit = [{POSITIVE_LIMIT_AT}, 9000000000]\n\
         home = [{}, {}]\n",
        CAM.0, CAM.1
    );
    // csp-minimal: with the switches and the probe its TxPDO has 7 entries (the simulated
    // drive, as many real ones, takes at most 10 in one PDO; "csp" would need 11).
    let axes = "[[axis]]\nname = \"x\"\ndrive = 0\npdo = \"csp-minimal\"\n\
                scaling = { counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }\n\
                max = { speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }\n\
                [axis.switches]\n\
                negative_limit = \"drive\"\npositive_limit = \"drive\"\nreference = \"drive\"\n";
    let config = sim_config_text(1000, &slaves, "", axes);
    let mut rig = Rig::new(&config);
    assert_eq!(
        rig.command(0, Command::Power(PowerCommand::Enable)),
        CommandStatus::Done
    );
    rig
}

/// Sends `command` and cycles until it is final (homing at 1 mm/s takes seconds).
fn run(rig: &mut Rig, command: Command) -> CommandStatus {
    let h = rig.ctl.command(0, command).expect("queued");
    rig.finish(&h, 60_000)
}

/// Where drive position `mm` (drive frame) is in the axis' frame now.
fn axis_frame(rig: &Rig, mm: f64) -> f64 {
    let actual = rig
        .engine
        .cycle
        .kernel
        .axis_status(0)
        .unwrap()
        .actual_position;
    mm + actual - drive_counts(rig) as f64 / COUNTS_PER_MM
}

fn drive_counts(rig: &Rig) -> i64 {
    rig.servo(0, |s| s.position_counts())
}

fn move_home(direction: MoveDirection, mode: HomingMode, fast: f64, slow: f64) -> Command {
    Command::MoveHome(MoveHomeCall::all(MoveHome {
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
    }))
}

/// The switches as the axis sees them, through the drive's process data.
#[test]
fn switches_limit_switches_and_move_home_over_ethercat() {
    let mut rig = rig();
    the_drive_s_switches_reach_the_axis(&mut rig);
    a_limit_switch_stops_the_axis_and_lets_it_only_move_away(&mut rig);
    move_home_takes_the_edge_from_the_touch_probe_to_the_count(&mut rig);
    move_home_on_the_index_pulse(&mut rig);
    assert_eq!(rig.servo(0, |s| s.record().faults), 0);
}

fn the_drive_s_switches_reach_the_axis(rig: &mut Rig) {
    let sw = |rig: &Rig| rig.engine.cycle.kernel.axis_status(0).unwrap().switches;
    assert!(!sw(rig).reference);
    rig.command(
        0,
        Command::SetPosition {
            position: 0.0,
            relative: false,
        },
    );
    // Onto the cam (11 mm) and off it again.
    let to = |p| Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, p).speed(50.0));
    assert_eq!(rig.command(0, to(11.0)), CommandStatus::Done);
    rig.run(5);
    assert!(sw(rig).reference, "on the cam at {}", drive_counts(rig));
    assert!(!sw(rig).positive_limit && !sw(rig).negative_limit);
    assert_eq!(rig.command(0, to(20.0)), CommandStatus::Done);
    rig.run(5);
    assert!(!sw(rig).reference);
}

/// MoveHome on the home switch's rising edge, from below the cam: the reference is the
/// first count on the cam, exact at a slow and at a fast search speed (the cycle-sampled
/// position would be off by the distance of a cycle: 26 counts at 1 mm/s, 1300 at 50).
fn move_home_takes_the_edge_from_the_touch_probe_to_the_count(rig: &mut Rig) {
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
        let st = rig.engine.cycle.kernel.axis_status(0).unwrap();
        assert_eq!(
            status,
            CommandStatus::Done,
            "{mode:?} at {fast}/{slow} mm/s: {:?}",
            st.error
        );
        assert!(st.homing.reference_set, "{mode:?}: {:?}", st.homing);
        rig.run(200);
        // NormalPosition 0 = ReferenceOffset 0: the axis stands on the edge.
        let at = drive_counts(rig);
        assert!(
            (at - CAM.0).abs() <= 1,
            "{mode:?} at {fast}/{slow} mm/s: stands at {at} counts, the edge is at {}",
            CAM.0
        );
        let actual = rig
            .engine
            .cycle
            .kernel
            .axis_status(0)
            .unwrap()
            .actual_position;
        assert!(
            actual.abs() <= 1.0 / COUNTS_PER_MM,
            "{mode:?}: actual {actual}"
        );
    }
}

/// MoveHome on the index pulse after the switch: the reference is an index position.
fn move_home_on_the_index_pulse(rig: &mut Rig) {
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
    let st = rig.engine.cycle.kernel.axis_status(0).unwrap();
    assert_eq!(status, CommandStatus::Done, "{:?}", st.error);
    rig.run(200);
    let at = drive_counts(rig);
    // The simulated encoder's index is at 1000 counts in every revolution.
    let index = 1000 + (at - 1000 + 65_536).div_euclid(131_072) * 131_072;
    assert!(
        (at - index).abs() <= 1,
        "stands at {at}, nearest index {index}"
    );
}

/// A move into the positive limit switch: quick stop into ErrorStop naming the switch;
/// after Reset, a move further on is refused and one away from it runs.
fn a_limit_switch_stops_the_axis_and_lets_it_only_move_away(rig: &mut Rig) {
    let to = |p| Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, p).speed(50.0));
    let status = rig.command(0, to(70.0));
    assert_ne!(status, CommandStatus::Done, "ran through the limit switch");
    rig.run(500);
    let st = rig.engine.cycle.kernel.axis_status(0).unwrap();
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
    assert_eq!(rig.command(0, Command::Reset), CommandStatus::Done);
    assert_ne!(rig.command(0, to(80.0)), CommandStatus::Done, "further on");
    assert_eq!(rig.command(0, to(0.0)), CommandStatus::Done, "away from it");
}
