//! SDO transfers while the cycle runs, on CANopen (`gantry sdo` on a CANopen drive):
//! through the [`Controller`] and the engine on four simulated nodes in lockstep at
//! 1 Mbit/s, the transfer on each node's default SDO channel (0x600/0x580 + node), its
//! frames after the TPDOs. While two axes move, drives are read and written — expedited
//! both ways, segmented uploads (the device name, the software version), 64 KiB both
//! ways by block — and the drives' records show every setpoint arrived (none missed,
//! none doubled), no TPDO was lost and the moves end where they should. An object the
//! drive does not have, or a read-only one written, is aborted with the drive's code and
//! its CiA 301 text; one larger than a transfer carries is refused with its size; a node
//! whose answers are lost times out with the time waited and the next transfer works; a
//! node without block transfer is served the normal way; what cannot start is refused at
//! once.

use gantry::runtime::bus::CycleBus;
use gantry::runtime::controller::Controller;
use gantry::runtime::sdo::{
    ObjectBytes, SdoBuffer, SdoData, SdoError, SdoRequest, SdoResult, SdoTransfer, SDO_MAX_BYTES,
};
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
    for cycles in 1..=20_000 {
        rig.cycle();
        if let Some(r) = h.outcome() {
            return (r, cycles);
        }
    }
    panic!("the transfer never ended");
}

fn data(bytes: &[u8]) -> SdoData {
    SdoData::new(bytes)
}

/// A buffer for a transfer started on the bus directly.
fn buffer() -> SdoBuffer {
    SdoBuffer::with_capacity(256)
}

fn records(rig: &CanRig) -> Vec<Option<DriveRecord>> {
    let sim = rig.sim();
    NODES
        .iter()
        .map(|&n| sim.node(n).servo().map(|s| *s.record()))
        .collect()
}

/// No TPDO was lost, no drive faulted, and every drive took each setpoint once, never a
/// step beyond its axis' speed.
fn every_tpdo_in_time_no_setpoint_missed(rig: &CanRig, config: &gantry::config::Config) {
    let bus = &rig.engine.bus;
    assert_eq!(bus.counters().lost, 0, "every TPDO in time");
    assert!(!bus.any_fault());
    let records = records(rig);
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
        &DriveUnderTest::of_config(config),
        2e-3,
        conditions,
    ) {
        panic!("{e}");
    }
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
        .start_sdo(&SdoTransfer::upload(1, 0x1000, 0), buffer(), 0)
        .unwrap();
    let refused = rig
        .engine
        .bus
        .start_sdo(&SdoTransfer::upload(2, 0x1000, 0), buffer(), 0)
        .unwrap_err();
    assert_eq!(refused.result, Err(SdoError::Busy));
    assert_eq!(refused.buffer.capacity(), 256, "the buffer handed back");
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
    every_tpdo_in_time_no_setpoint_missed(&rig, &config);
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
    let refused = rig
        .engine
        .bus
        .start_sdo(&SdoTransfer::upload(1, 0x1000, 0), buffer(), 0)
        .unwrap_err();
    assert_eq!(refused.result, Err(SdoError::Busy));
    assert_eq!(rig.finish(&reset, 5000), CommandStatus::Done);
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(1, 0x1008, 0));
    assert_eq!(r.unwrap().as_slice(), b"gantry-sim CiA 402 servo");
}

/// The largest object a transfer carries by default, both ways by block while two axes
/// move at 2 ms on a 1 Mbit/s bus the four drives' PDOs fill to 82 %: the recorder 0x2F00
/// (64 KiB of known content) read from node 1 and 64 KiB written to its scratch 0x2F01,
/// every byte checked at both ends. The master puts into a cycle at most the frames the
/// bus load leaves room for (2 here; also the sub-block it asks of the node), so the SYNC
/// keeps its time — late by at most one frame a node had begun (CAN does not break into
/// a frame) —, no TPDO is lost and no setpoint missed. A node without block transfer
/// (node 4) refuses it once and is served the normal way; an object larger than a
/// transfer carries (node 2's recorder) is refused with its size.
#[test]
fn a_64_kib_object_goes_both_ways_by_block_beside_the_pdos() {
    use gantry_drives::canopen::frame::frame_bits;
    use gantry_drives::canopen::sdo::SdoConfig;
    use gantry_drives::canopen::NodeId;
    use gantry_sim::canopen::bus::Sender;
    use gantry_sim::canopen::dictionary::recorder_byte;
    use gantry_sim::canopen::{CanNode, CanNodeConfig};
    let config = can_config(&NODES, 2000, "csp");
    let nodes = NODES
        .iter()
        .map(|&n| {
            let mut c = CanNodeConfig::servo(NodeId::new(n).unwrap());
            match n {
                1 => {
                    c.recorder_bytes = SDO_MAX_BYTES;
                    c.scratch_bytes = SDO_MAX_BYTES;
                }
                2 => c.recorder_bytes = SDO_MAX_BYTES + 1,
                4 => {
                    c.scratch_bytes = 1000;
                    c.sdo = SdoConfig {
                        block: false,
                        ..c.sdo
                    };
                }
                _ => {}
            }
            CanNode::new(c).unwrap()
        })
        .collect();
    let mut rig = CanRig::new(&config, nodes);
    // SYNC and PDOs take 1595 of the window's 1950 bits: 355 left, two frames a cycle
    // (none in a cycle with the heartbeats); a sub-block of one segment beside its
    // acknowledgement.
    assert_eq!(rig.engine.bus.sdo_spare_bits(), 355);
    assert_eq!(rig.engine.bus.sdo_block_size(), 1);
    let ctl = rig.ctl.clone();
    for axis in 0..NODES.len() {
        rig.enable_and_home(axis);
    }
    // Moves of 40 s at the axes' 200 units/s: still running when the transfers end.
    let a = rig.start_move(0, 8000.0);
    let b = rig.start_move(3, -8000.0);
    rig.run(20);
    let quiet_from = rig.sim().bus.log().len();
    rig.run(200);
    let busy_from = rig.sim().bus.log().len();

    let (r, up_cycles) = transfer(&mut rig, &ctl, SdoRequest::upload(0, 0x2F00, 0));
    let got = r.expect("the recorder");
    assert_eq!(got.len(), SDO_MAX_BYTES);
    let first_bad = (0..SDO_MAX_BYTES).find(|&i| got.as_slice()[i] != recorder_byte(i));
    assert_eq!(first_bad, None, "the upload's bytes");
    let new: Vec<u8> = (0..SDO_MAX_BYTES).map(|i| recorder_byte(i + 7)).collect();
    let (r, down_cycles) = transfer(
        &mut rig,
        &ctl,
        SdoRequest::download(0, 0x2F01, 0, data(&new)),
    );
    assert_eq!(r, Ok(SdoData::EMPTY));
    assert_eq!(
        rig.sim().node(1).dictionary().scratch(),
        &new[..],
        "what reached the node"
    );
    eprintln!("64 KiB by block: upload {up_cycles} cycles, download {down_cycles} cycles");
    // Two frames a cycle, none in the two cycles around each heartbeat (every 50): the
    // 9363 segments one a cycle beside its acknowledgement up, two a cycle down.
    assert!((9363..9363 * 105 / 100).contains(&up_cycles), "{up_cycles}");
    assert!(
        (4682..4682 * 105 / 100).contains(&down_cycles),
        "{down_cycles}"
    );
    let busy_to = rig.sim().bus.log().len();

    // The SYNC's place in the cycle: unmoved in quiet cycles, late by at most one 8-byte
    // frame during the transfers.
    let frame_ns = frame_bits(8) * 1000;
    let (quiet, busy) = {
        let sim = rig.sim();
        let log = sim.bus.log();
        let syncs = |from: usize, to: usize| -> Vec<u64> {
            log[from..to]
                .iter()
                .filter(|d| d.from == Sender::Master && d.frame.id() == 0x080)
                .map(|d| d.at_ns)
                .collect()
        };
        (syncs(quiet_from, busy_from), syncs(busy_from, busy_to))
    };
    // Where in its cycle each SYNC went (ns from the first one's place, ± half a cycle).
    let t0 = quiet[0] as i64;
    let place = |t: u64| (t as i64 - t0 + 1_000_000).rem_euclid(2_000_000) - 1_000_000;
    let range = |ts: &[u64]| {
        let p: Vec<i64> = ts.iter().map(|&t| place(t)).collect();
        (*p.iter().min().unwrap(), *p.iter().max().unwrap())
    };
    let (quiet_early, quiet_late) = range(&quiet);
    let (busy_early, busy_late) = range(&busy);
    eprintln!(
        "the SYNC's place in its cycle: {quiet_early}..={quiet_late} ns quiet, \
         {busy_early}..={busy_late} ns during the transfers"
    );
    if busy_late > quiet_late + frame_ns as i64 {
        // What the bus carried up to the latest SYNC, for the failure below.
        let sim = rig.sim();
        let log = &sim.bus.log()[busy_from..busy_to];
        let k = log
            .iter()
            .position(|d| {
                d.from == Sender::Master && d.frame.id() == 0x080 && place(d.at_ns) == busy_late
            })
            .unwrap();
        for d in &log[k.saturating_sub(40)..=k] {
            eprintln!(
                "{:>12} {:?} {:03X} {:02X?}",
                d.at_ns,
                d.from,
                d.frame.id(),
                d.frame.data()
            );
        }
    }
    assert!(
        busy_late <= quiet_late + frame_ns as i64,
        "a SYNC {busy_late} ns late during the transfers (at most {quiet_late} when quiet)"
    );
    assert!(
        busy.len() as u32 >= up_cycles + down_cycles - 2,
        "a SYNC every cycle"
    );
    // The master's SDO frames: at most two between one SYNC and the next.
    let most = {
        let sim = rig.sim();
        let mut most = 0;
        let mut here = 0;
        for d in &sim.bus.log()[busy_from..busy_to] {
            match (d.from, d.frame.id()) {
                (Sender::Master, 0x080) => here = 0,
                (Sender::Master, 0x601) => {
                    here += 1;
                    most = most.max(here);
                }
                _ => {}
            }
        }
        most
    };
    assert_eq!(most, 2, "the master's SDO frames in a cycle");

    // A node without block transfer: refused once, then served the normal way.
    let small: Vec<u8> = (0..1000).map(|i| recorder_byte(3 * i)).collect();
    let (r, _) = transfer(
        &mut rig,
        &ctl,
        SdoRequest::download(3, 0x2F01, 0, data(&small)),
    );
    assert_eq!(r, Ok(SdoData::EMPTY));
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(3, 0x2F01, 0));
    assert_eq!(r.unwrap().as_slice(), &small[..]);
    let refusals = rig
        .sim()
        .bus
        .log()
        .iter()
        .filter(|d| {
            d.from == Sender::Node(3)
                && d.frame.data()[0] == 0x80
                && d.frame.data()[4..8] == 0x0504_0001u32.to_le_bytes()
        })
        .count();
    assert_eq!(refusals, 1, "block refused once, not asked for again");

    // Larger than a transfer carries: aborted once the node says the size.
    let (r, _) = transfer(&mut rig, &ctl, SdoRequest::upload(1, 0x2F00, 0));
    assert_eq!(
        r,
        Err(SdoError::TooLarge {
            drive: 1,
            index: 0x2F00,
            sub: 0,
            size: ObjectBytes(Some(SDO_MAX_BYTES as u32 + 1)),
            max: SDO_MAX_BYTES,
        })
    );

    assert!(
        a.status().is_none_or(|s| !s.is_final()),
        "the transfers ran during the moves"
    );
    assert_eq!(rig.finish(&a, 20_000), CommandStatus::Done);
    assert_eq!(rig.finish(&b, 20_000), CommandStatus::Done);
    every_tpdo_in_time_no_setpoint_missed(&rig, &config);
}
