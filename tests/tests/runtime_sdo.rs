//! SDO transfers while the cycle runs (`gantry sdo`), through the [`Controller`] and the
//! engine on the in-process simulator in lockstep: CoE through each slave's mailbox, one
//! mailbox register access per cycle beside the process data. While an axis moves, its
//! drive is read and written — expedited, normal and segmented, both ways, up to a 64 KiB
//! object every byte of which is checked — and its records show every setpoint arrived
//! (none missed, none doubled, with the strict 0x10F1:02 = 4), the move ends exactly
//! where it should. An object the drive does not have is aborted with the drive's code
//! and its CiA 301 text; one larger than a transfer carries is refused naming its size; a
//! drive that never answers times out; what the bus cannot do is refused at once.

use gantry::runtime::bus::CycleBus;
use gantry::runtime::controller::Controller;
use gantry::runtime::sdo::{ObjectBytes, SdoData, SdoError, SdoRequest, SdoResult, SDO_MAX_BYTES};
use gantry_drives::canopen::sdo::abort::AbortCode;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::rig::Rig;

/// An object the test adds to a drive: longer than its 128-byte mailbox carries in one
/// message (112 bytes), so both ways go in segments. (Not 0x2100/0x2101: the simulated
/// servo's commutation offset and pole pairs.)
const LONG: u16 = 0x2E00;
/// One that fits a single message (normal, not expedited, not segmented).
const MEDIUM: u16 = 0x2E01;
/// A 64 KiB object, the most a transfer carries by default: 555 messages each way.
const BIG: u16 = 0x2E03;
/// One byte more than a transfer carries.
const TOO_BIG: u16 = 0x2E04;

/// Byte `i` of the big object's `round`th content: no period a misplaced segment could
/// hide in.
fn big_byte(i: usize, round: usize) -> u8 {
    ((i as u32 + round as u32).wrapping_mul(2_654_435_761) >> 24) as u8
}

/// The drives' firmware takes this long to answer a mailbox request: the master polls.
const MAILBOX_MS: u64 = 3;

fn rig(axes: usize) -> (Rig, gantry::config::Config) {
    // As strict as drives ship (0x10F1:02 = 4: two SYNC0 periods without a setpoint
    // take a drive out of Op), and slow to answer their mailbox, as real ones are.
    let config = gantry_tests::sim_config_with(
        axes,
        1000,
        &format!(
            "[slave.al]\nsync_error_limit = {}\nmailbox_ms = {MAILBOX_MS}\n",
            gantry_tests::DEFAULT_SYNC_ERROR_LIMIT
        ),
    );
    let rig = Rig::new(&config);
    {
        let mut chain = rig.chain.lock().unwrap();
        for i in 0..axes {
            let od = chain
                .slave_mut(i)
                .and_then(|s| s.object_dictionary_mut())
                .expect("a servo with CoE");
            let long: Vec<u8> = (0..200u32).map(|i| (i * 3) as u8).collect();
            od.insert(LONG, 0, &long, true);
            od.insert(MEDIUM, 0, b"gantry simulated servo", true);
            let big: Vec<u8> = (0..SDO_MAX_BYTES).map(|i| big_byte(i, 0)).collect();
            od.insert(BIG, 0, &big, true);
            od.insert(TOO_BIG, 0, &vec![7u8; SDO_MAX_BYTES + 1], false);
        }
    }
    (rig, config)
}

/// Runs `request` through the controller, cycling until it ends; its outcome and the
/// cycles it took. Bounded by the host's clock, not by a number of cycles: the bus times
/// a transfer out on CLOCK_MONOTONIC (see the timeout case), and a release build runs
/// thousands of lockstep cycles in less than a timeout.
fn transfer(rig: &mut Rig, ctl: &Controller, request: SdoRequest) -> (SdoResult, u32) {
    let h = ctl.sdo(request).expect("queued");
    let end = std::time::Instant::now() + std::time::Duration::from_secs(30);
    let mut cycles = 0;
    while std::time::Instant::now() < end {
        rig.cycle();
        cycles += 1;
        if let Some(r) = h.outcome() {
            return (r, cycles);
        }
    }
    panic!(
        "the transfer never ended in 30 s ({cycles} cycles; lost frames {})",
        rig.engine.bus().health().lost_total
    );
}

fn data(bytes: &[u8]) -> SdoData {
    SdoData::new(bytes)
}

/// Every setpoint reached the drives: none missed or doubled at SYNC0, no target step
/// beyond the axis' speed; no frame lost or incomplete.
fn every_setpoint_arrived(rig: &Rig, config: &gantry::config::Config) {
    assert_drive_invariants(
        &rig.chain.lock().unwrap(),
        &DriveUnderTest::of_config(config),
        1e-3,
        TestConditions {
            injects_following_error: false,
            phase_locked: true,
        },
    );
    let counters = rig.engine.bus().counters();
    assert_eq!((counters.lost, counters.incomplete), (0, 0));
}

/// One bus per process (ethercrab's frame storage is static): the cases run in turn on
/// one rig, the ones that break the drives' record (a lost frame, a pulled cable) after
/// the record is judged.
#[test]
fn sdo_transfers_beside_the_cycle() {
    let (mut rig, config) = rig(2);
    reads_and_writes_while_an_axis_moves_miss_no_setpoint(&mut rig, &config);
    a_64_kib_object_goes_both_ways_beside_a_move(&mut rig, &config);
    an_object_the_drive_does_not_have_is_aborted_with_its_code_and_text(&mut rig);
    what_the_bus_cannot_do_is_refused_at_once(&mut rig);
    a_lost_frame_mid_transfer_costs_a_retry_not_the_transfer(&mut rig);
    a_drive_that_never_answers_times_out_and_the_next_transfer_works(&mut rig);
}

fn reads_and_writes_while_an_axis_moves_miss_no_setpoint(
    rig: &mut Rig,
    config: &gantry::config::Config,
) {
    let ctl = rig.ctl.clone();
    rig.enable_and_home(0);
    rig.enable_and_home(1);
    let target = 100.0;
    let moving = rig.start_move(0, target);
    let other = rig.start_move(1, -40.0);
    rig.run(50);

    // Expedited upload: the vendor id the simulator's servo has (0x1018:01). Each cycle
    // of it sends one frame, as a cycle without it does: the mailbox access goes in the
    // process data's frame.
    let h = ctl.sdo(SdoRequest::upload(0, 0x1018, 1)).expect("queued");
    let mut frames = Vec::new();
    while h.outcome().is_none() {
        let before = rig.engine.bus().replies();
        rig.cycle();
        frames.push(rig.engine.bus().replies() - before);
    }
    assert!(
        frames.iter().all(|&f| f == 1),
        "frames per cycle: {frames:?}"
    );
    let (r, cycles) = transfer(rig, &ctl, SdoRequest::upload(0, 0x1018, 1));
    let vendor = r.expect("0x1018:01");
    assert_eq!(vendor.len(), 4);
    // Write the request, poll SM1's status until the firmware answered (3 ms), read SM1:
    // one access per cycle.
    eprintln!("an expedited upload took {cycles} cycles");
    assert!(
        (MAILBOX_MS as u32 + 1..=MAILBOX_MS as u32 + 3).contains(&cycles),
        "an expedited upload took {cycles} cycles"
    );

    // Expedited download and the value read back: modes of operation 0x6060 (CSP, 8).
    let (r, _) = transfer(rig, &ctl, SdoRequest::download(0, 0x6060, 0, data(&[8])));
    assert_eq!(r, Ok(SdoData::EMPTY));
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, 0x6060, 0));
    assert_eq!(r.unwrap().as_slice(), &[8]);

    // Normal (one message, size indicated) both ways.
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, MEDIUM, 0));
    assert_eq!(r.unwrap().as_slice(), b"gantry simulated servo");
    let name = b"axis a0, left gantry beam";
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, MEDIUM, 0));
    assert!(r.is_ok());
    let (r, _) = transfer(rig, &ctl, SdoRequest::download(0, MEDIUM, 0, data(name)));
    // The object keeps its length (22 bytes): the drive refuses another with the code.
    assert_eq!(
        r,
        Err(SdoError::Aborted {
            drive: 0,
            index: MEDIUM,
            sub: 0,
            code: AbortCode::LENGTH_MISMATCH
        })
    );
    let same_length = b"gantry simulated SERVO";
    let request = SdoRequest::download(0, MEDIUM, 0, data(same_length));
    let (r, _) = transfer(rig, &ctl, request);
    assert_eq!(r, Ok(SdoData::EMPTY));
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, MEDIUM, 0));
    assert_eq!(r.unwrap().as_slice(), same_length);

    // Segmented both ways: 200 bytes through a 128-byte mailbox.
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, LONG, 0));
    let long: Vec<u8> = (0..200u32).map(|i| (i * 3) as u8).collect();
    assert_eq!(r.unwrap().as_slice(), &long[..]);
    let new: Vec<u8> = (0..200u32).map(|i| (255 - i) as u8).collect();
    let (r, _) = transfer(rig, &ctl, SdoRequest::download(0, LONG, 0, data(&new)));
    assert_eq!(r, Ok(SdoData::EMPTY));
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, LONG, 0));
    assert_eq!(r.unwrap().as_slice(), &new[..]);
    {
        let chain = rig.chain.lock().unwrap();
        let od = chain.slaves()[0].object_dictionary().unwrap();
        assert_eq!(
            od.read(LONG, 0).unwrap(),
            &new[..],
            "what reached the drive"
        );
    }

    // The move was running all along and ends where it should.
    assert!(
        rig.status_now(&moving).is_none_or(|s| !s.is_final()),
        "the transfers ran during the move"
    );
    assert_eq!(rig.finish(&moving, 5000), CommandStatus::Done);
    assert_eq!(rig.finish(&other, 5000), CommandStatus::Done);
    rig.run(20);
    let actual = rig.snapshot().axes[0].actual_position;
    assert!((actual - target).abs() < 1e-3, "ended at {actual}");
    let actual = rig.snapshot().axes[1].actual_position;
    assert!((actual + 40.0).abs() < 1e-3, "ended at {actual}");
    every_setpoint_arrived(rig, config);
}

/// The largest object a transfer carries by default, read and written while both axes
/// move: 64 KiB through the 128-byte mailbox, one mailbox access in each cycle's one
/// frame, every byte checked at both ends; the moves miss no setpoint.
fn a_64_kib_object_goes_both_ways_beside_a_move(rig: &mut Rig, config: &gantry::config::Config) {
    let ctl = rig.ctl.clone();
    // Long moves (15 s at the axes' 200 units/s): still running when the transfers end.
    let moving = rig.start_move(0, 3000.0);
    let other = rig.start_move(1, -3000.0);
    rig.run(20);
    let before = rig.engine.bus().replies();
    let (r, up_cycles) = transfer(rig, &ctl, SdoRequest::upload(0, BIG, 0));
    let got = r.expect("the 64 KiB upload");
    assert_eq!(got.len(), SDO_MAX_BYTES);
    let first_bad = (0..SDO_MAX_BYTES).find(|&i| got.as_slice()[i] != big_byte(i, 0));
    assert_eq!(first_bad, None, "the upload's bytes");
    let new: Vec<u8> = (0..SDO_MAX_BYTES).map(|i| big_byte(i, 1)).collect();
    let (r, down_cycles) = transfer(rig, &ctl, SdoRequest::download(0, BIG, 0, data(&new)));
    assert_eq!(r, Ok(SdoData::EMPTY));
    // One frame per cycle all along: the mailbox accesses rode in the cyclic frame.
    let frames = rig.engine.bus().replies() - before;
    assert_eq!(
        frames,
        u64::from(up_cycles + down_cycles),
        "frames in {up_cycles} + {down_cycles} cycles"
    );
    eprintln!("64 KiB: upload {up_cycles} cycles, download {down_cycles} cycles");
    {
        let chain = rig.chain.lock().unwrap();
        let od = chain.slaves()[0].object_dictionary().unwrap();
        let there = od.read(BIG, 0).unwrap();
        let first_bad = (0..SDO_MAX_BYTES).find(|&i| there[i] != new[i]);
        assert_eq!(first_bad, None, "what reached the drive");
    }
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, BIG, 0));
    assert_eq!(r.unwrap().as_slice(), &new[..], "read back");
    assert!(
        rig.status_now(&moving).is_none_or(|s| !s.is_final()),
        "the transfers ran during the move"
    );
    assert_eq!(rig.finish(&moving, 40_000), CommandStatus::Done);
    assert_eq!(rig.finish(&other, 40_000), CommandStatus::Done);
    every_setpoint_arrived(rig, config);
}

fn an_object_the_drive_does_not_have_is_aborted_with_its_code_and_text(rig: &mut Rig) {
    let ctl = rig.ctl.clone();
    rig.run(50);
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, 0x2000, 0));
    let e = r.unwrap_err();
    assert_eq!(
        e,
        SdoError::Aborted {
            drive: 0,
            index: 0x2000,
            sub: 0,
            code: AbortCode::OBJECT_DOES_NOT_EXIST
        }
    );
    assert_eq!(
        e.to_string(),
        "drive 0: SDO 0x2000:00 aborted: 0x06020000 Object does not exist in the object \
         dictionary."
    );
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, 0x1018, 9));
    assert_eq!(
        r.unwrap_err().to_string(),
        "drive 0: SDO 0x1018:09 aborted: 0x06090011 Sub-index does not exist."
    );
    let (r, _) = transfer(rig, &ctl, SdoRequest::download(0, 0x1000, 0, data(&[0; 4])));
    assert!(
        matches!(r, Err(SdoError::Aborted { code, .. }) if code == AbortCode::READ_ONLY),
        "{r:?}"
    );
    // The mailbox works on after aborts.
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, 0x6060, 0));
    assert_eq!(r.unwrap().as_slice(), &[8]);
}

fn a_drive_that_never_answers_times_out_and_the_next_transfer_works(rig: &mut Rig) {
    let ctl = rig.ctl.clone();
    rig.run(50);
    // The cable behind drive 0 is pulled: drive 1 gets nothing.
    rig.chain.lock().unwrap().cut_before(Some(1));
    let mut request = SdoRequest::upload(1, 0x1018, 1);
    request.timeout_ns = 200_000_000;
    let (r, _) = transfer(rig, &ctl, request);
    // The bus times transfers on the host's clock (CLOCK_MONOTONIC, as its resets), not
    // the lockstep network's: the wait is at least the timeout, and said.
    let Err(SdoError::TimedOut {
        drive: 1,
        index: 0x1018,
        sub: 1,
        waited_ms,
    }) = r
    else {
        panic!("{r:?}");
    };
    assert!(waited_ms >= 200, "gave up after {waited_ms} ms");
    assert_eq!(
        r.unwrap_err().to_string(),
        format!("drive 1: SDO 0x1018:01: no answer within {waited_ms} ms")
    );
    // Drive 0 answers meanwhile.
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, 0x6060, 0));
    assert_eq!(r.unwrap().as_slice(), &[8]);
}

fn a_lost_frame_mid_transfer_costs_a_retry_not_the_transfer(rig: &mut Rig) {
    let ctl = rig.ctl.clone();
    // Lose one frame at each step of a segmented download and of the upload after it,
    // on the way out (nothing happened) and on the way back (the access happened, its
    // reply is lost): a write goes again with the same counter (the slave discards it if
    // it had arrived); an answer whose read was lost is asked for again (SM1's repeat
    // request, ESC datasheet section I §8.6).
    //
    // Two replies lost in a row on the way back: the write arrived, and so did its repeat,
    // which waits in SM0 behind the answer in SM1; the next repeat is refused (SM0 full),
    // so the master must read the answer rather than write again (it would never be
    // taken: the slave takes SM0 only once SM1 is read).
    for (lost, on_the_way_back) in [(1, false), (1, true), (2, true), (3, true)] {
        for lose_at in 0..12u8 {
            let new: Vec<u8> = (0..200u32).map(|i| (i as u8) ^ lose_at).collect();
            let download = ctl
                .sdo(SdoRequest::download(0, LONG, 0, data(&new)))
                .expect("queued");
            let upload = ctl.sdo(SdoRequest::upload(0, LONG, 0)).expect("queued");
            for _ in 0..lose_at {
                rig.cycle();
            }
            {
                let mut chain = rig.chain.lock().unwrap();
                if on_the_way_back {
                    chain.drop_replies(lost);
                } else {
                    chain.drop_frames(lost);
                }
            }
            let mut outcomes = (None, None);
            for _ in 0..1000 {
                rig.cycle();
                outcomes.0 = outcomes.0.or_else(|| download.outcome());
                outcomes.1 = outcomes.1.or_else(|| upload.outcome());
                if outcomes.1.is_some() {
                    break;
                }
            }
            let case =
                format!("frames {lose_at}.. lost: {lost} (on the way back: {on_the_way_back})");
            assert_eq!(outcomes.0, Some(Ok(SdoData::EMPTY)), "{case}");
            let got = outcomes.1.expect("the upload ended").expect(&case);
            assert_eq!(got.as_slice(), &new[..], "{case}");
        }
    }
}

fn what_the_bus_cannot_do_is_refused_at_once(rig: &mut Rig) {
    let ctl = rig.ctl.clone();
    rig.run(20);
    let (r, cycles) = transfer(rig, &ctl, SdoRequest::upload(5, 0x1018, 1));
    assert_eq!((r, cycles), (Err(SdoError::NoDrive { drive: 5 }), 1));
    // An upload larger than a transfer carries: aborted at the drive once it says the
    // size, and the size said.
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, TOO_BIG, 0));
    let too_big = SdoError::TooLarge {
        drive: 0,
        index: TOO_BIG,
        sub: 0,
        size: ObjectBytes(Some(SDO_MAX_BYTES as u32 + 1)),
        max: SDO_MAX_BYTES,
    };
    assert_eq!(r, Err(too_big));
    assert_eq!(
        too_big.to_string(),
        "drive 0: SDO 0x2E04:00: the object has 65537 bytes, more than the 65536 bytes a \
         transfer carries here (`[bus] sdo_max_bytes`)"
    );
    // A download of as much: refused before anything is sent (no cycle has run).
    let request = SdoRequest::download(0, BIG, 0, data(&vec![1; SDO_MAX_BYTES + 1]));
    let h = ctl.sdo(request).expect("answered");
    assert_eq!(
        h.outcome(),
        Some(Err(SdoError::TooLarge {
            drive: 0,
            index: BIG,
            sub: 0,
            size: ObjectBytes(Some(SDO_MAX_BYTES as u32 + 1)),
            max: SDO_MAX_BYTES,
        }))
    );
    // The drive's segmented transfer was aborted: the next one starts clean.
    let (r, _) = transfer(rig, &ctl, SdoRequest::upload(0, 0x6060, 0));
    assert_eq!(r.unwrap().as_slice(), &[8]);
}
