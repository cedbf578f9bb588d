//! SDO transfers while the cycle runs, on CANopen (`gantry sdo` on a CANopen drive):
//! through the [`Controller`] and the engine on four simulated nodes in lockstep at
//! 1 Mbit/s, the transfer on each node's default SDO channel (0x600/0x580 + node), one
//! request frame per cycle after the TPDOs. While two axes move, drives are read and
//! written — expedited both ways, segmented uploads (the device name, the software
//! version) — and the drives' records show every setpoint arrived (none missed, none
//! doubled), no TPDO was lost and the moves end where they should. An object the drive
//! does not have, or a read-only one written, is aborted with the drive's code and its
//! CiA 301 text; a node whose answers are lost times out with the time waited and the
//! next transfer works; what cannot start is refused at once.

use gantry::runtime::bus::CycleBus;
use gantry::runtime::controller::Controller;
use gantry::runtime::sdo::{SdoData, SdoError, SdoRequest, SdoResult};
use gantry_drives::canopen::sdo::abort::AbortCode;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_sim::plant::record::DriveRecord;
use gantry_tests::can_rig::{can_config, servos, CanRig};
use gantry_tests::invariant::{check_records, DriveUnderTest, TestConditions};

const NODES: [u8; 4] = [1, 2, 3, 4];

/// Runs `request` through the controller, cycling until it ends; its outcome and the
/// cycles it took.
fn transfer(rig: &mut CanRig, ctl: &Controller, request: SdoRequest) -> (SdoResult, u32) {
    let h = ctl.sdo(request).expect("queued");
    for cycles in 1..=5000 {
        rig.cycle();
        if let Some(r) = h.outcome() {
            return (r, cycles);
        }
    }
    panic!("the transfer never ended");
}

fn data(bytes: &[u8]) -> SdoData {
    SdoData::new(bytes).expect("fits")
}

fn records(rig: &CanRig) -> Vec<Option<DriveRecord>> {
    let sim = rig.sim();
    NODES
        .iter()
        .map(|&n| sim.node(n).servo().map(|s| *s.record()))
        .collect()
}

#[test]
fn sdo_transfers_beside_the_pdos_miss_no_setpoint() {
    let config = can_config(&NODES, 2000, "csp");
    let mut rig = CanRig::new(&config, servos(&NODES));
    let ctl = rig.ctl.clone();
    for axis in 0..NODES.len() {
        rig.enable_and_home(axis);
    }
    let a = rig.start_move(0, 100.0);
    let b = rig.start_move(3, -40.0);
    rig.run(20);

    // Expedited upload: the vendor id (0x1018:01) of the simulator's nodes. The request
    // goes after this cycle's TPDOs, the answer comes with the next exchange.
    let (r, cycles) = transfer(&mut rig, &ctl, SdoRequest::upload(0, 0x1018, 1));
    assert_eq!(r.unwrap().as_slice(), &0x0000_0A5Au32.to_le_bytes());
    assert!(cycles <= 2, "an expedited upload took {cycles} cycles");
    // The statusword of the moving drive: Operation enabled.
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(0, 0x6041, 0));
    let sw = u16::from_le_bytes(r.unwrap().as_slice().try_into().unwrap());
    assert_eq!(sw & 0x006F, 0x0027, "statusword 0x{sw:04X}");

    // Expedited download and the value read back: following error window 0x6065.
    let window = data(&50_000u32.to_le_bytes());
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::download(3, 0x6065, 0, window));
    assert_eq!(r, Ok(SdoData::EMPTY));
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(3, 0x6065, 0));
    assert_eq!(r.unwrap().as_slice(), &50_000u32.to_le_bytes());

    // Segmented uploads (7 bytes per confirmed segment, one exchange each).
    let (r, cycles) = transfer(&mut rig, &ctl, SdoRequest::upload(0, 0x1008, 0));
    let name = r.unwrap();
    assert_eq!(name.as_slice(), b"gantry-sim CiA 402 servo");
    // Initiate, then ceil(24 / 7) = 4 segments: 5 round trips, one per exchange.
    assert!((5..=6).contains(&cycles), "24 bytes took {cycles} cycles");
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(1, 0x100A, 0));
    assert!(!r.unwrap().is_empty());

    // Aborts: the drive's code, the CiA 301 text.
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(2, 0x2FFF, 0));
    let e = r.unwrap_err();
    assert_eq!(
        e,
        SdoError::Aborted {
            drive: 2,
            index: 0x2FFF,
            sub: 0,
            code: AbortCode::OBJECT_DOES_NOT_EXIST
        }
    );
    assert_eq!(
        e.to_string(),
        "drive 2: SDO 0x2FFF:00 aborted: 0x06020000 Object does not exist in the object \
         dictionary."
    );
    let (r, _) = transfer(
        &mut rig,
        &ctl,
        SdoRequest::download(2, 0x1018, 1, data(&[1, 2, 3, 4])),
    );
    assert!(
        matches!(r, Err(SdoError::Aborted { code, .. }) if code == AbortCode::READ_ONLY),
        "{r:?}"
    );

    // Refused at once: no such drive; another transfer running.
    let (r, cycles) = transfer(&mut rig, &ctl, SdoRequest::upload(9, 0x1000, 0));
    assert_eq!(r, Err(SdoError::NoDrive { drive: 9 }));
    assert_eq!(cycles, 1);
    // One at a time on the bus (the engine queues the application's requests; here the
    // bus is asked directly).
    rig.engine
        .bus
        .start_sdo(&SdoRequest::upload(1, 0x1000, 0), 0)
        .unwrap();
    assert_eq!(
        rig.engine
            .bus
            .start_sdo(&SdoRequest::upload(2, 0x1000, 0), 0),
        Err(SdoError::Busy)
    );
    // Its outcome goes to no one (the engine did not start it); the bus is free after.
    rig.run(3);
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(2, 0x1000, 0));
    assert_eq!(r.unwrap().as_slice(), &0x0002_0192u32.to_le_bytes());

    // The moves ran all along and end where they should.
    assert_eq!(rig.finish(&a, 10_000), CommandStatus::Done);
    assert_eq!(rig.finish(&b, 10_000), CommandStatus::Done);
    let sim = rig.sim();
    let x = sim.node(1).servo().unwrap().actual_counts();
    assert_eq!(i64::from(x), (100.0 / 5.0 * 131_072.0_f64).round() as i64);
    drop(sim);
    let bus = &rig.engine.bus;
    assert_eq!(bus.counters().lost, 0, "every TPDO in time");
    assert!(!bus.any_fault());
    let records = records(&rig);
    for (i, r) in records.iter().enumerate() {
        let r = r.as_ref().unwrap();
        assert_eq!((r.sync_missed, r.sync_doubled), (0, 0), "drive {i}: {r:?}");
        assert_eq!(r.faults, 0, "drive {i}: {r:?}");
    }
    let conditions = TestConditions {
        injects_following_error: false,
        phase_locked: true,
    };
    if let Err(e) = check_records(
        &records,
        &DriveUnderTest::of_config(&config),
        2e-3,
        conditions,
    ) {
        panic!("{e}");
    }
}

#[test]
fn a_node_whose_answers_are_lost_times_out_and_the_next_transfer_works() {
    let config = can_config(&NODES, 2000, "csp");
    let mut rig = CanRig::new(&config, servos(&NODES));
    let ctl = rig.ctl.clone();
    // Node 2's SDO answers (0x582) never reach the master.
    rig.sim().drop_frames(0x582, true);
    let mut request = SdoRequest::upload(1, 0x1008, 0);
    request.timeout_ns = 100_000_000;
    let (r, cycles) = transfer(&mut rig, &ctl, request);
    assert_eq!(
        r,
        Err(SdoError::TimedOut {
            drive: 1,
            index: 0x1008,
            sub: 0,
            waited_ms: 100
        })
    );
    assert!((50..=52).contains(&cycles), "{cycles} cycles of 2 ms");
    assert!(rig.sim().dropped >= 1);
    // The answers come again: the next transfer works; the PDOs never stopped.
    rig.sim().drop_frames(0x582, false);
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(1, 0x1008, 0));
    assert_eq!(r.unwrap().as_slice(), b"gantry-sim CiA 402 servo");
    assert_eq!(rig.engine.bus.counters().lost, 0);
    assert!(!rig.engine.bus.any_fault());
}

#[test]
fn a_reset_of_the_node_ends_its_transfer_and_a_node_being_restored_refuses_one() {
    let config = can_config(&NODES, 2000, "csp");
    let mut rig = CanRig::new(&config, servos(&NODES));
    let ctl = rig.ctl.clone();
    // Node 2 falls silent to the master (heartbeats and SDO answers lost): its axis
    // stops with the heartbeat fault.
    rig.sim().drop_frames(0x702, true);
    rig.sim().drop_frames(0x582, true);
    rig.run(200);
    assert!(rig.bus_fault(1).is_some_and(|f| f.contains("no heartbeat")));
    // A transfer with it waits for an answer that does not come; the reset's NMT reset
    // communication ends it with the reason.
    let h = ctl.sdo(SdoRequest::upload(1, 0x1008, 0)).expect("queued");
    rig.run(5);
    assert!(h.outcome().is_none(), "still waiting");
    rig.sim().drop_frames(0x702, false);
    rig.sim().drop_frames(0x582, false);
    let reset = ctl.reset(1).expect("queued");
    rig.run(2);
    assert_eq!(
        h.outcome(),
        Some(Err(SdoError::Protocol {
            drive: 1,
            index: 0x1008,
            sub: 0,
            what: "the node was reset (NMT reset communication) during the transfer"
        }))
    );
    // While the node is being configured again, its SDO channel is the restore's.
    assert_eq!(
        rig.engine
            .bus
            .start_sdo(&SdoRequest::upload(1, 0x1000, 0), 0),
        Err(SdoError::Busy)
    );
    assert_eq!(rig.finish(&reset, 5000), CommandStatus::Done);
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(1, 0x1008, 0));
    assert_eq!(r.unwrap().as_slice(), b"gantry-sim CiA 402 servo");
}
