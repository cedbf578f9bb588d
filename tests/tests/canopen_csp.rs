//! Four CiA 402 drives on CANopen, moved through the engine and the controller as `gantry
//! run` moves them, in lockstep on the in-memory bus at 1 Mbit/s with its frame timing:
//! every 2 ms the cycle sends the RPDOs, then the SYNC, and reads the TPDOs the drives
//! sample at the SYNC (the full CSP layout: 1 RPDO and 2 TPDOs per drive, 1602 bits of the
//! 1950 µs the cycle waits). Judged by what the simulated drives recorded: no setpoint
//! missed or doubled, no target step beyond vmax·T, no fault, and each drive standing
//! exactly on its target's count at the end.

use gantry::runtime::bus::CycleBus;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::plant::record::DriveRecord;
use gantry_tests::can_rig::{can_config, servos, CanRig};
use gantry_tests::invariant::{check_records, DriveUnderTest, TestConditions};

const NODES: [u8; 4] = [1, 2, 3, 4];

fn records(rig: &CanRig) -> Vec<Option<DriveRecord>> {
    let sim = rig.sim();
    NODES
        .iter()
        .map(|&n| sim.node(n).servo().map(|s| *s.record()))
        .collect()
}

#[test]
fn four_drives_move_ptp_on_sync_with_no_setpoint_missed() {
    let config = can_config(&NODES, 2000, "csp");
    let drives = DriveUnderTest::of_config(&config);
    let mut rig = CanRig::new(&config, servos(&NODES));
    for axis in 0..NODES.len() {
        rig.enable_and_home(axis);
    }
    let targets = [[100.0, -40.0, 12.5, 250.0], [0.0, 33.3, -7.25, 1.0]];
    for round in targets {
        for (axis, h) in rig.start_moves(&round).iter().enumerate() {
            let status = rig.finish(h, 10_000);
            assert_eq!(
                status,
                CommandStatus::Done,
                "axis {axis}: {:?}, bus fault {:?}",
                rig.engine.cycle.kernel.axis_status(axis),
                rig.bus_fault(axis)
            );
        }
        // Each drive stands on its target's count: 2^17 counts per 5 mm.
        for (axis, &to) in round.iter().enumerate() {
            let counts = (to / 5.0 * 131_072.0_f64).round() as i64;
            let sim = rig.sim();
            let servo = sim.node(NODES[axis]).servo().expect("a servo node");
            assert_eq!(
                i64::from(servo.actual_counts()),
                counts,
                "axis {axis} on its target"
            );
        }
    }
    for axis in 0..NODES.len() {
        assert_eq!(rig.state(axis), AxisState::Standstill);
    }
    let bus = &rig.engine.bus;
    assert_eq!(bus.counters().lost, 0, "every TPDO in time");
    assert_eq!(bus.malformed(), 0);
    assert!(!bus.any_fault());
    let sim = rig.sim();
    for &n in &NODES {
        let c = sim.node(n).counters();
        assert_eq!(
            c.syncs,
            rig.engine.bus.exchanges(),
            "one SYNC per cycle, node {n}"
        );
        assert_eq!(c.missed_in_row, 0);
        assert_eq!(c.emcys, 0, "no EMCY from node {n}");
        assert_eq!(c.dropped, 0);
    }
    drop(sim);
    let records = records(&rig);
    for (i, r) in records.iter().enumerate() {
        let r = r.as_ref().unwrap();
        assert!(r.targets > 1000, "drive {i} took {} targets", r.targets);
        assert_eq!(r.faults, 0, "drive {i}: {r:?}");
        assert_eq!((r.sync_missed, r.sync_doubled), (0, 0), "drive {i}: {r:?}");
    }
    let conditions = TestConditions {
        injects_following_error: false,
        phase_locked: true,
    };
    if let Err(e) = check_records(&records, &drives, 2e-3, conditions) {
        panic!("{e}");
    }
}

/// What the bus-load check guards against: the same four drives on a bus that really
/// runs at 500 kbit/s (the configuration says 1 Mbit/s): a cycle's 1602 bits take 3.2 ms
/// of each 2 ms, the frames queue up behind one another, and every drive's TPDOs come
/// later each cycle, past the 1.95 ms the cycle waits — lost frames, not stale inputs
/// taken for fresh — until every drive is faulted, named.
#[test]
fn tpdos_that_miss_the_reply_window_are_lost_frames() {
    let config = can_config(&NODES, 2000, "csp");
    let mut rig = CanRig::on_bitrate(&config, servos(&NODES), Some(500_000))
        .unwrap_or_else(|e| panic!("{e}"));
    rig.run(20);
    let bus = &rig.engine.bus;
    assert!(bus.counters().lost >= 10, "{:?}", bus.counters());
    let faulted: Vec<String> = (0..NODES.len()).filter_map(|a| rig.bus_fault(a)).collect();
    assert_eq!(faulted.len(), NODES.len(), "{faulted:?}");
    assert!(
        faulted
            .iter()
            .all(|f| f.starts_with("CANopen node ") && f.ends_with(" cycles in a row")),
        "{faulted:?}"
    );
    for drive in 0..NODES.len() {
        assert!(
            !rig.engine.bus.inputs_fresh(drive),
            "drive {drive}: late TPDOs are no fresh inputs"
        );
    }
}
