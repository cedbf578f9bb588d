//! PDO configuration over SDO with the CiA 301 rules (§7.5.2.35–.38) and every refusal's
//! abort code; PDOs at work: synchronous types, event-driven with inhibit time and event
//! timer, RPDO data taking effect at the next SYNC, a short RPDO refused with EMCY 0x8210.

mod canopen_common;

use canopen_common::*;
use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::canopen::nmt::NmtCommand;
use gantry_drives::canopen::sdo::AbortCode;
use gantry_drives::cia402::objects::{self, ObjectId};
use gantry_drives::cia402::pdo::mapping_entry;
use gantry_sim::canopen::{CanNode, CanNodeConfig};

const N: u8 = 9;
const INVALID: u32 = 1 << 31;

fn entry(o: ObjectId) -> [u8; 4] {
    mapping_entry(&o).to_le_bytes()
}

fn booted() -> Master {
    let mut m = Master::new(&[N]);
    m.step(0);
    m
}

/// Node `N` with `pdo_count` PDOs each way, booted.
fn booted_with(pdo_count: u8) -> Master {
    let node = CanNode::new(CanNodeConfig {
        pdo_count,
        ..CanNodeConfig::servo(id(N))
    })
    .unwrap();
    let mut m = Master::with_nodes(vec![node]);
    m.step(0);
    m
}

#[test]
fn mapping_rules_and_every_refusal() {
    let mut m = booted();
    let w = |m: &mut Master, i: u16, s: u8, d: &[u8]| m.write(N, i, s, d);
    // RPDO1 exists (power-on): its mapping may not change, nor its identifier.
    assert_eq!(
        w(&mut m, 0x1600, 0, &[0]),
        Err(AbortCode::CANNOT_STORE_DEVICE_STATE)
    );
    assert_eq!(
        w(&mut m, 0x1600, 1, &entry(objects::TARGET_VELOCITY)),
        Err(AbortCode::CANNOT_STORE_DEVICE_STATE)
    );
    assert_eq!(
        w(&mut m, 0x1400, 1, &0x305u32.to_le_bytes()),
        Err(AbortCode::INVALID_VALUE)
    );
    assert_eq!(
        w(&mut m, 0x1400, 1, &(1u32 << 29 | 0x209).to_le_bytes()),
        Err(AbortCode::INVALID_VALUE),
        "29-bit identifier"
    );
    // Step 1: invalidate.
    w(&mut m, 0x1400, 1, &(INVALID | 0x209).to_le_bytes()).unwrap();
    // Entries only once sub 0 is 0.
    assert_eq!(
        w(&mut m, 0x1600, 1, &entry(objects::TARGET_VELOCITY)),
        Err(AbortCode::CANNOT_STORE_DEVICE_STATE)
    );
    // Step 2.
    w(&mut m, 0x1600, 0, &[0]).unwrap();
    // Step 3 refusals: an input object, an unknown one, a wrong bit length, no sub 9.
    for bad in [
        entry(objects::STATUSWORD),
        0x2000_0010u32.to_le_bytes(),
        0x6040_0020u32.to_le_bytes(),
    ] {
        assert_eq!(
            w(&mut m, 0x1600, 1, &bad),
            Err(AbortCode::NOT_MAPPABLE),
            "{bad:02x?}"
        );
    }
    assert_eq!(
        w(&mut m, 0x1600, 9, &entry(objects::CONTROLWORD)),
        Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST)
    );
    // A TPDO takes inputs only.
    w(&mut m, 0x1800, 1, &(INVALID | 0x189).to_le_bytes()).unwrap();
    w(&mut m, 0x1A00, 0, &[0]).unwrap();
    assert_eq!(
        w(&mut m, 0x1A00, 1, &entry(objects::CONTROLWORD)),
        Err(AbortCode::NOT_MAPPABLE)
    );
    // 2 + 4 + 4 bytes exceed the 8 of a CAN frame; more than 8 entries is too high.
    for (s, o) in [
        objects::CONTROLWORD,
        objects::TARGET_POSITION,
        objects::TARGET_VELOCITY,
    ]
    .into_iter()
    .enumerate()
    {
        w(&mut m, 0x1600, s as u8 + 1, &entry(o)).unwrap();
    }
    assert_eq!(
        w(&mut m, 0x1600, 0, &[3]),
        Err(AbortCode::PDO_LENGTH_EXCEEDED)
    );
    assert_eq!(w(&mut m, 0x1600, 0, &[9]), Err(AbortCode::VALUE_TOO_HIGH));
    // A count over an empty entry.
    assert_eq!(w(&mut m, 0x1600, 0, &[4]), Err(AbortCode::NOT_MAPPABLE));
    // Step 4 and 5.
    w(&mut m, 0x1600, 0, &[2]).unwrap();
    w(&mut m, 0x1400, 1, &0x209u32.to_le_bytes()).unwrap();
    assert_eq!(m.read(N, 0x1600, 0).unwrap(), [2]);
    assert_eq!(
        m.read(N, 0x1600, 2).unwrap(),
        entry(objects::TARGET_POSITION)
    );
    // Transmission types: 241..=253 refused both ways.
    for t in [241u8, 251, 252, 253] {
        assert_eq!(
            w(&mut m, 0x1400, 2, &[t]),
            Err(AbortCode::INVALID_VALUE),
            "{t}"
        );
        assert_eq!(
            w(&mut m, 0x1800, 2, &[t]),
            Err(AbortCode::INVALID_VALUE),
            "{t}"
        );
    }
    // Inhibit time only while the TPDO does not exist.
    w(&mut m, 0x1801, 3, &10u16.to_le_bytes()).unwrap();
    w(&mut m, 0x1801, 1, &0x289u32.to_le_bytes()).unwrap();
    assert_eq!(
        w(&mut m, 0x1801, 3, &20u16.to_le_bytes()),
        Err(AbortCode::INVALID_VALUE)
    );
    assert_eq!(m.read(N, 0x1801, 3).unwrap(), 10u16.to_le_bytes());
    // Sub 0 of a communication record is read only.
    assert_eq!(w(&mut m, 0x1400, 0, &[2]), Err(AbortCode::READ_ONLY));
}

/// Maps the PDO of `comm`/`mapping` on `cob` with `objects`, transmission type `tt`.
fn map(m: &mut Master, comm: u16, mapping: u16, cob: u32, objects: &[ObjectId], tt: u8) {
    m.write(N, comm, 1, &(INVALID | cob).to_le_bytes()).unwrap();
    m.write(N, mapping, 0, &[0]).unwrap();
    for (s, o) in objects.iter().enumerate() {
        m.write(N, mapping, s as u8 + 1, &entry(*o)).unwrap();
    }
    m.write(N, mapping, 0, &[objects.len() as u8]).unwrap();
    m.write(N, comm, 2, &[tt]).unwrap();
    m.write(N, comm, 1, &cob.to_le_bytes()).unwrap();
}

#[test]
fn synchronous_types_and_rpdo_data_at_the_next_sync() {
    let mut m = booted();
    // RPDO2: target velocity; TPDO2: velocity actual + following error, every 2nd SYNC.
    map(
        &mut m,
        0x1401,
        0x1601,
        0x309,
        &[objects::TARGET_VELOCITY],
        1,
    );
    map(
        &mut m,
        0x1801,
        0x1A01,
        0x289,
        &[
            objects::VELOCITY_ACTUAL_VALUE,
            objects::FOLLOWING_ERROR_ACTUAL_VALUE,
        ],
        2,
    );
    m.nmt(NmtCommand::Start, Some(N));
    m.take_inbox();
    // The RPDO arrives; until the next SYNC the drive has not taken it.
    m.send(&[frame(0x309, &12345i32.to_le_bytes())]);
    assert_eq!(m.read(N, 0x60FF, 0).unwrap(), 0i32.to_le_bytes());
    let sync = m.sync_frame();
    m.send(&[sync]);
    assert_eq!(m.read(N, 0x60FF, 0).unwrap(), 12345i32.to_le_bytes());
    m.take_inbox();
    for _ in 0..6 {
        m.step(MS);
        let sync = m.sync_frame();
        m.send(&[sync]);
    }
    let got = m.take_inbox();
    assert_eq!(on(&got, 0x189).len(), 6, "TPDO1 every SYNC");
    let tpdo2 = on(&got, 0x289);
    assert_eq!(tpdo2.len(), 3, "TPDO2 every 2nd SYNC");
    assert!(tpdo2.iter().all(|f| f.len() == 8));
    // Acyclic (0): at a SYNC only when a value changed; the drive stands: once.
    m.nmt(NmtCommand::EnterPreOperational, Some(N));
    m.write(N, 0x1801, 2, &[0]).unwrap();
    m.nmt(NmtCommand::Start, Some(N));
    m.take_inbox();
    for _ in 0..5 {
        m.step(MS);
        let sync = m.sync_frame();
        m.send(&[sync]);
    }
    assert_eq!(on(&m.take_inbox(), 0x289).len(), 1);
}

#[test]
fn event_driven_tpdo_keeps_inhibit_time_and_event_timer() {
    let mut m = booted();
    // TPDO3: statusword, type 255, inhibit 5 ms (50 × 100 µs), event timer 20 ms.
    m.write(N, 0x1802, 1, &(INVALID | 0x389).to_le_bytes())
        .unwrap();
    m.write(N, 0x1802, 3, &50u16.to_le_bytes()).unwrap();
    m.write(N, 0x1802, 5, &20u16.to_le_bytes()).unwrap();
    map(&mut m, 0x1802, 0x1A02, 0x389, &[objects::STATUSWORD], 255);
    m.nmt(NmtCommand::Start, Some(N));
    m.take_inbox();
    let t0 = m.now;
    for _ in 0..200 {
        m.step(MS);
    }
    let got: Vec<u64> = m
        .take_inbox()
        .iter()
        .filter(|d| d.frame.id() == 0x389)
        .map(|d| (d.at_ns - t0) / MS)
        .collect();
    // Nothing changes: the first at once (the first tick), then every 20 ms.
    assert_eq!(got, (0..10).map(|k| 1 + 20 * k).collect::<Vec<_>>());
    // A change (Shutdown by SDO: statusword goes to Ready to switch on) is sent at once,
    // not before the inhibit time has passed since the last.
    m.write(N, 0x6040, 0, &6u16.to_le_bytes()).unwrap();
    let t1 = m.now;
    for _ in 0..30 {
        m.step(MS);
    }
    let frames: Vec<(u64, u16)> = m
        .take_inbox()
        .iter()
        .filter(|d| d.frame.id() == 0x389)
        .map(|d| {
            (
                d.at_ns,
                u16::from_le_bytes([d.frame.data()[0], d.frame.data()[1]]),
            )
        })
        .collect();
    let change = frames
        .iter()
        .find(|(_, sw)| sw & 0x6F == 0x21)
        .expect("ready to switch on sent");
    // The loops run every 10 ms without SYNC: the change is seen within 10 ms.
    assert!(change.0 - t1 <= 11 * MS, "{frames:?}");
    for w in frames.windows(2) {
        assert!(w[1].0 - w[0].0 >= 5 * MS, "inhibit time kept: {frames:?}");
    }
}

#[test]
fn short_rpdo_is_not_processed_and_raises_emcy_8210() {
    let mut m = booted();
    m.nmt(NmtCommand::Start, Some(N));
    m.take_inbox();
    // RPDO1 maps 6 bytes; 3 arrive.
    let got = m.send(&[frame(0x209, &[0x06, 0, 0])]);
    let emcy: Vec<Emergency> = on(&got, 0x089)
        .iter()
        .map(|f| Emergency::parse(f).unwrap())
        .collect();
    assert_eq!(emcy.len(), 1);
    assert_eq!(emcy[0].error_code, 0x8210);
    assert_eq!(
        emcy[0].error_register & 0x11,
        0x11,
        "generic + communication"
    );
    let sync = m.sync_frame();
    m.send(&[sync]);
    assert_eq!(m.node(0).counters().rpdos, 0);
    assert_eq!(m.read(N, 0x6040, 0).unwrap(), [0, 0]);
    // 8 bytes where 6 are mapped: processed (the first 6 count).
    m.send(&[frame(0x209, &[0x06, 0, 1, 0, 0, 0, 0xAA, 0xBB])]);
    let sync = m.sync_frame();
    m.send(&[sync]);
    assert_eq!(m.node(0).counters().rpdos, 1);
    assert_eq!(m.read(N, 0x6040, 0).unwrap(), [6, 0]);
}

#[test]
fn sync_start_values_spread_tpdos_over_the_sync_counter() {
    let mut m = booted();
    // 0x1019: counter 1..=2; rules first.
    assert_eq!(m.write(N, 0x1019, 0, &[1]), Err(AbortCode::INVALID_VALUE));
    assert_eq!(m.write(N, 0x1019, 0, &[241]), Err(AbortCode::INVALID_VALUE));
    m.write(N, 0x1006, 0, &1000u32.to_le_bytes()).unwrap();
    assert_eq!(
        m.write(N, 0x1019, 0, &[2]),
        Err(AbortCode::CANNOT_STORE_DEVICE_STATE),
        "only while 0x1006 is 0"
    );
    m.write(N, 0x1006, 0, &0u32.to_le_bytes()).unwrap();
    m.write(N, 0x1019, 0, &[2]).unwrap();
    // TPDO1 every 2nd SYNC from counter 2, TPDO2 (statusword) every 2nd from counter 1.
    m.write(N, 0x1800, 1, &(INVALID | 0x189).to_le_bytes())
        .unwrap();
    assert_eq!(m.write(N, 0x1800, 6, &[241]), Err(AbortCode::INVALID_VALUE));
    m.write(N, 0x1800, 6, &[2]).unwrap();
    m.write(N, 0x1800, 2, &[2]).unwrap();
    m.write(N, 0x1800, 1, &0x189u32.to_le_bytes()).unwrap();
    assert_eq!(
        m.write(N, 0x1800, 6, &[1]),
        Err(AbortCode::INVALID_VALUE),
        "start value while the TPDO exists"
    );
    m.write(N, 0x1801, 6, &[1]).unwrap();
    map(&mut m, 0x1801, 0x1A01, 0x289, &[objects::STATUSWORD], 2);
    assert_eq!(m.read(N, 0x1801, 0).unwrap(), [6]);
    m.nmt(NmtCommand::Start, Some(N));
    m.sync_overflow = 2;
    m.take_inbox();
    let mut seen = Vec::new();
    for _ in 0..8 {
        m.step(MS);
        let sync = m.sync_frame();
        let counter = sync.data()[0];
        let got = m.send(&[sync]);
        let ids: Vec<u16> = got.iter().map(|d| d.frame.id()).collect();
        seen.push((counter, ids));
    }
    for (counter, ids) in &seen {
        let want = if *counter == 2 {
            vec![0x189]
        } else {
            vec![0x289]
        };
        assert_eq!(ids, &want, "counter {counter}: {seen:?}");
    }
}

#[test]
fn sync_of_the_wrong_length_for_0x1019_is_reported_once() {
    let mut m = booted();
    let emcys = |got: &[gantry_sim::canopen::bus::Delivered]| -> Vec<u16> {
        on(got, 0x089)
            .iter()
            .map(|f| Emergency::parse(f).unwrap().error_code)
            .collect()
    };
    // 0x1019 = 0: SYNCs without counter expected; three with a counter: one EMCY.
    let mut got = Vec::new();
    for c in 1..=3u8 {
        got.extend(m.send(&[frame(0x080, &[c])]));
    }
    assert_eq!(emcys(&got), vec![0x8240]);
    assert_eq!(m.node(0).counters().syncs, 3, "still taken");
    // A right one clears it; a wrong one reports again.
    let got = m.send(&[frame(0x080, &[])]);
    assert!(emcys(&got).is_empty());
    let got = m.send(&[frame(0x080, &[1, 2])]);
    assert_eq!(emcys(&got), vec![0x8240]);
}

#[test]
fn event_driven_rpdo_takes_effect_at_once() {
    let mut m = booted();
    // RPDO3: modes of operation + target torque, type 255.
    map(
        &mut m,
        0x1402,
        0x1602,
        0x409,
        &[objects::MODES_OF_OPERATION, objects::TARGET_TORQUE],
        255,
    );
    m.nmt(NmtCommand::Start, Some(N));
    let mut d = [10u8, 0, 0];
    d[1..].copy_from_slice(&(-300i16).to_le_bytes());
    m.send(&[frame(0x409, &d)]);
    // No SYNC: the drive took it on reception.
    assert_eq!(m.read(N, 0x6061, 0).unwrap(), [10], "CST");
    assert_eq!(m.read(N, 0x6071, 0).unwrap(), (-300i16).to_le_bytes());
    assert_eq!(m.node(0).counters().rpdos, 1);
    // A mode the drive does not have is not taken (0x6061 keeps CST).
    m.send(&[frame(0x409, &[1, 0, 0])]);
    assert_eq!(m.read(N, 0x6061, 0).unwrap(), [10]);
}

#[test]
fn dummy_entries_skip_bytes_of_an_rpdo() {
    let mut m = booted();
    // RPDO2: a 16-bit dummy, then the target velocity: bytes 0–1 are someone else's.
    map(
        &mut m,
        0x1401,
        0x1601,
        0x309,
        &[
            gantry_sim::canopen::pdo::DUMMIES[1],
            objects::TARGET_VELOCITY,
        ],
        255,
    );
    // Not into a TPDO.
    m.write(N, 0x1801, 1, &(INVALID | 0x289).to_le_bytes())
        .unwrap();
    m.write(N, 0x1A01, 0, &[0]).unwrap();
    assert_eq!(
        m.write(N, 0x1A01, 1, &0x0006_0010u32.to_le_bytes()),
        Err(AbortCode::NOT_MAPPABLE)
    );
    // A dummy of the wrong length.
    m.write(N, 0x1401, 1, &(INVALID | 0x309).to_le_bytes())
        .unwrap();
    m.write(N, 0x1601, 0, &[0]).unwrap();
    assert_eq!(
        m.write(N, 0x1601, 1, &0x0003_0020u32.to_le_bytes()),
        Err(AbortCode::NOT_MAPPABLE)
    );
    m.write(N, 0x1601, 0, &[2]).unwrap();
    m.write(N, 0x1401, 1, &0x309u32.to_le_bytes()).unwrap();
    m.nmt(NmtCommand::Start, Some(N));
    let mut d = [0xAAu8, 0xBB, 0, 0, 0, 0];
    d[2..].copy_from_slice(&777i32.to_le_bytes());
    m.send(&[frame(0x309, &d)]);
    assert_eq!(m.read(N, 0x60FF, 0).unwrap(), 777i32.to_le_bytes());
    assert_eq!(
        m.read(N, 0x6040, 0).unwrap(),
        [0, 0],
        "the dummy bytes went nowhere"
    );
}

#[test]
fn emcy_cob_id_and_inhibit_time() {
    let mut m = booted();
    m.write(N, 0x1015, 0, &100u16.to_le_bytes()).unwrap();
    m.nmt(NmtCommand::Start, Some(N));
    m.take_inbox();
    // Three EMCYs (short RPDOs) 1 ms apart: the 10 ms inhibit time spaces them.
    let t0 = m.now;
    for _ in 0..3 {
        m.send(&[frame(0x209, &[1])]);
        m.step(MS);
    }
    for _ in 0..30 {
        m.step(MS);
    }
    let at: Vec<u64> = m
        .take_inbox()
        .iter()
        .filter(|d| d.frame.id() == 0x089)
        .map(|d| (d.at_ns - t0) / 100_000)
        .collect();
    // In 0.1 ms (no bit timing on this bus): at once, then at 10 and 20 ms, not before.
    assert_eq!(at, vec![0, 100, 200]);
    assert_eq!(m.read(N, 0x1003, 0).unwrap(), [3]);
    // The identifier changes only while bit 31 is set; 29-bit ones are refused.
    assert_eq!(
        m.write(N, 0x1014, 0, &0xFFu32.to_le_bytes()),
        Err(AbortCode::INVALID_VALUE)
    );
    assert_eq!(
        m.write(N, 0x1014, 0, &(INVALID | 1 << 29 | 0xFF).to_le_bytes()),
        Err(AbortCode::INVALID_VALUE)
    );
    m.write(N, 0x1014, 0, &(INVALID | 0x89).to_le_bytes())
        .unwrap();
    // No EMCY exists: none is sent, 0x1003 still records.
    m.step(20 * MS);
    let got = m.send(&[frame(0x209, &[1])]);
    assert!(on(&got, 0x089).is_empty());
    assert_eq!(m.read(N, 0x1003, 0).unwrap(), [4]);
    m.write(N, 0x1014, 0, &(INVALID | 0xFF).to_le_bytes())
        .unwrap();
    m.write(N, 0x1014, 0, &0xFFu32.to_le_bytes()).unwrap();
    m.step(20 * MS);
    let got = m.send(&[frame(0x209, &[1])]);
    assert_eq!(on(&got, 0x0FF).len(), 1);
    assert_eq!(
        Emergency::parse(&on(&got, 0x0FF)[0]).unwrap().error_code,
        0x8210
    );
}

/// PDOs 5 and up (chain `pdo_count`, here 8): their objects exist up to the count and no
/// further (0x06020000), they power up invalid with no identifier (0x80000000: CiA 301
/// predefines four), they become valid only on an identifier that is not restricted
/// (CiA 301 §7.3.5), their mapping follows the same procedure as the first four's, they
/// carry data on SYNC like them, and reset communication takes them back to power-on.
#[test]
fn pdos_5_to_8_power_up_without_an_identifier_and_work_like_the_first_four() {
    let mut m = booted_with(8);
    let w = |m: &mut Master, i: u16, s: u8, d: &[u8]| m.write(N, i, s, d);
    for index in [0x1404u16, 0x1407, 0x1804, 0x1807] {
        assert_eq!(
            m.read(N, index, 1).unwrap(),
            INVALID.to_le_bytes(),
            "0x{index:04X}"
        );
    }
    for index in [0x1604u16, 0x1A07] {
        assert_eq!(
            m.read(N, index, 0).unwrap(),
            [0],
            "0x{index:04X} maps nothing"
        );
    }
    for index in [0x1408u16, 0x1608, 0x1808, 0x1A08] {
        assert_eq!(
            m.read(N, index, 1),
            Err(AbortCode::OBJECT_DOES_NOT_EXIST),
            "0x{index:04X}"
        );
    }
    // Valid without an identifier, or on a restricted one: refused.
    for bad in [
        0x000u32, 0x005, 0x101, 0x180, 0x589, 0x609, 0x6E0, 0x709, 0x7E5,
    ] {
        assert_eq!(
            w(&mut m, 0x1804, 1, &bad.to_le_bytes()),
            Err(AbortCode::INVALID_VALUE),
            "0x{bad:03X}"
        );
    }
    // TPDO5 on 0x1FE (TPDO1 of node 126), RPDO5 on 0x27E (RPDO1 of node 126).
    map(
        &mut m,
        0x1804,
        0x1A04,
        0x1FE,
        &[objects::STATUSWORD, objects::VELOCITY_ACTUAL_VALUE],
        1,
    );
    map(
        &mut m,
        0x1404,
        0x1604,
        0x27E,
        &[objects::TARGET_VELOCITY],
        1,
    );
    // Valid: identifier and mapping fixed, as for the first four.
    assert_eq!(
        w(&mut m, 0x1804, 1, &0x1FDu32.to_le_bytes()),
        Err(AbortCode::INVALID_VALUE)
    );
    assert_eq!(
        w(&mut m, 0x1A04, 0, &[0]),
        Err(AbortCode::CANNOT_STORE_DEVICE_STATE)
    );
    assert_eq!(m.read(N, 0x1A04, 0).unwrap(), [2]);
    m.nmt(NmtCommand::Start, Some(N));
    m.take_inbox();
    m.send(&[frame(0x27E, &4321i32.to_le_bytes())]);
    let sync = m.sync_frame();
    m.send(&[sync]);
    assert_eq!(m.read(N, 0x60FF, 0).unwrap(), 4321i32.to_le_bytes());
    let got = m.take_inbox();
    let tpdo5 = on(&got, 0x1FE);
    assert_eq!(tpdo5.len(), 1, "TPDO5 at the SYNC");
    assert_eq!(tpdo5[0].len(), 6, "statusword + velocity actual value");
    // Reset communication: back to power-on, no identifier.
    m.nmt(NmtCommand::ResetCommunication, Some(N));
    assert_eq!(m.read(N, 0x1804, 1).unwrap(), INVALID.to_le_bytes());
    assert_eq!(m.read(N, 0x1A04, 0).unwrap(), [0]);
    assert_eq!(m.read(N, 0x1404, 1).unwrap(), INVALID.to_le_bytes());
}

/// A node has the four PDOs of the predefined connection set by default; 1 to 8 may be
/// asked for, others are refused naming the node.
#[test]
fn the_pdo_count_defaults_to_four_and_is_bounded() {
    let mut m = booted();
    m.read(N, 0x1803, 1).unwrap();
    assert_eq!(m.read(N, 0x1804, 1), Err(AbortCode::OBJECT_DOES_NOT_EXIST));
    assert_eq!(
        m.write(N, 0x1404, 1, &INVALID.to_le_bytes()),
        Err(AbortCode::OBJECT_DOES_NOT_EXIST)
    );
    for bad in [0u8, 9] {
        let e = CanNode::new(CanNodeConfig {
            pdo_count: bad,
            ..CanNodeConfig::servo(id(N))
        })
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("CANopen node 9: pdo_count = {bad}: a simulated node has 1 to 8 PDOs each way")
        );
    }
    let mut m = booted_with(2);
    m.read(N, 0x1A01, 0).unwrap();
    assert_eq!(m.read(N, 0x1A02, 0), Err(AbortCode::OBJECT_DOES_NOT_EXIST));
}
