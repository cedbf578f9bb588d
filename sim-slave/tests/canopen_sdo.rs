//! SDO against the simulated CANopen node with the master's client
//! (`gantry_drives::canopen::SdoClient`): every transfer kind both ways and the refusals
//! with their CiA 301 Table 22 abort codes.

mod canopen_common;

use canopen_common::*;
use gantry_drives::canopen::sdo::{AbortCode, DownloadMode, UploadMode};
use gantry_sim::canopen::dictionary::{DEVICE_NAME_VALUE, DEVICE_TYPE_CIA402_SERVO};

fn booted() -> Master {
    let mut m = Master::new(&[6]);
    m.step(0);
    m
}

#[test]
fn uploads_of_every_kind() {
    let mut m = booted();
    for mode in [UploadMode::Normal, UploadMode::Block] {
        // 4 bytes: expedited (normal) or a one-segment block.
        assert_eq!(
            m.upload(6, 0x1000, 0, mode).unwrap(),
            DEVICE_TYPE_CIA402_SERVO.to_le_bytes(),
            "{mode:?}"
        );
        // 24 bytes: segmented (normal) or block.
        assert_eq!(
            m.upload(6, 0x1008, 0, mode).unwrap(),
            DEVICE_NAME_VALUE.as_bytes(),
            "{mode:?}"
        );
        // Identity, 0x1018:02 product code = 0x402 (CanNodeConfig::servo).
        assert_eq!(m.upload(6, 0x1018, 0, mode).unwrap(), [4]);
        assert_eq!(
            m.upload(6, 0x1018, 4, mode).unwrap(),
            6u32.to_le_bytes(),
            "serial = node id"
        );
    }
    // The servo's objects: statusword (Switch on disabled 0x0250 with remote), mode 8.
    let sw = m.read_u16(6, 0x6041, 0);
    assert_eq!(sw & 0x4F, 0x40, "switch on disabled: {sw:#06x}");
    assert_eq!(m.read(6, 0x6061, 0).unwrap(), [8]);
}

#[test]
fn downloads_of_every_kind() {
    let mut m = booted();
    let cases: [(DownloadMode, u32); 4] = [
        (DownloadMode::Expedited, 1000),
        (DownloadMode::Segmented, 2000),
        (DownloadMode::Block, 3000),
        (DownloadMode::Auto, 4000),
    ];
    for (mode, window) in cases {
        m.download(6, 0x6065, 0, &window.to_le_bytes(), mode)
            .unwrap();
        assert_eq!(
            m.upload(6, 0x6065, 0, UploadMode::Block).unwrap(),
            window.to_le_bytes(),
            "{mode:?}"
        );
    }
    // 0x1016:01 heartbeat consumer by block, read back segmented-capable normal upload.
    let v = (1u32 << 16) | 500;
    m.download(6, 0x1016, 1, &v.to_le_bytes(), DownloadMode::Block)
        .unwrap();
    assert_eq!(m.read(6, 0x1016, 1).unwrap(), v.to_le_bytes());
}

#[test]
fn refusals_carry_table_22_codes() {
    let mut m = booted();
    let e = |r: Result<(), AbortCode>| r.unwrap_err();
    assert_eq!(
        m.read(6, 0x2345, 0),
        Err(AbortCode::OBJECT_DOES_NOT_EXIST),
        "no such object"
    );
    assert_eq!(
        m.read(6, 0x1018, 5),
        Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST)
    );
    assert_eq!(
        m.read(6, 0x1800, 4),
        Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST),
        "TPDO sub 4 is reserved"
    );
    assert_eq!(
        e(m.write(6, 0x1000, 0, &[0, 0, 0, 0])),
        AbortCode::READ_ONLY
    );
    assert_eq!(e(m.write(6, 0x6041, 0, &[0, 0])), AbortCode::READ_ONLY);
    assert_eq!(e(m.write(6, 0x1008, 0, b"x")), AbortCode::READ_ONLY);
    assert_eq!(
        e(m.write(6, 0x1017, 0, &[1, 2, 3])),
        AbortCode::LENGTH_TOO_HIGH
    );
    assert_eq!(e(m.write(6, 0x6065, 0, &[1, 2])), AbortCode::LENGTH_TOO_LOW);
    // Out of the object's range: quick stop option code 0..=8, 0x6007 0..=1, 0x1029 0..=2.
    assert_eq!(
        e(m.write(6, 0x605A, 0, &9i16.to_le_bytes())),
        AbortCode::INVALID_VALUE
    );
    assert_eq!(
        e(m.write(6, 0x6007, 0, &2i16.to_le_bytes())),
        AbortCode::INVALID_VALUE
    );
    assert_eq!(e(m.write(6, 0x1029, 1, &[3])), AbortCode::INVALID_VALUE);
    // Heartbeat consumer: reserved bits 24..31 and node ids over 127.
    assert_eq!(
        e(m.write(6, 0x1016, 1, &(1u32 << 24 | 100).to_le_bytes())),
        AbortCode::INVALID_VALUE
    );
    assert_eq!(
        e(m.write(6, 0x1016, 1, &(128u32 << 16 | 100).to_le_bytes())),
        AbortCode::INVALID_VALUE
    );
    // Nothing of the refused writes stuck.
    assert_eq!(m.read(6, 0x605A, 0).unwrap(), 2i16.to_le_bytes());
    assert_eq!(m.read(6, 0x1016, 1).unwrap(), 0u32.to_le_bytes());
}

#[test]
fn a_silent_client_is_aborted_by_the_node_after_its_timeout() {
    use gantry_drives::canopen::sdo::command::ClientCommand;
    use gantry_drives::canopen::sdo::{Initiate, Multiplexer};
    let mut m = booted();
    // Initiate a segmented download and never send the segment.
    let init = ClientCommand::InitiateDownload {
        mux: Multiplexer::new(0x6065, 0),
        payload: Initiate::Segmented { size: Some(4) },
    }
    .emit();
    let got = m.send(&[frame(0x606, &init)]);
    assert_eq!(on(&got, 0x586).len(), 1, "initiate confirmed");
    m.take_inbox();
    for _ in 0..1100 {
        m.step(MS);
    }
    let answers = on(&m.take_inbox(), 0x586);
    assert_eq!(answers.len(), 1, "{answers:?}");
    let d = answers[0].data();
    assert_eq!(d[0], 0x80, "abort");
    assert_eq!(
        u32::from_le_bytes([d[4], d[5], d[6], d[7]]),
        AbortCode::TIMED_OUT.0
    );
}

#[test]
fn reset_communication_ends_a_transfer_in_progress() {
    use gantry_drives::canopen::nmt::NmtCommand;
    use gantry_drives::canopen::sdo::command::ClientCommand;
    use gantry_drives::canopen::sdo::{Initiate, Multiplexer};
    let init = ClientCommand::InitiateDownload {
        mux: Multiplexer::new(0x6065, 0),
        payload: Initiate::Segmented { size: Some(4) },
    }
    .emit();
    // Without a reset, a new request mid-transfer is refused.
    let mut m = booted();
    m.send(&[frame(0x606, &init)]);
    assert!(m.read(6, 0x1000, 0).is_err());
    // After reset communication the node serves at once.
    let mut m = booted();
    m.send(&[frame(0x606, &init)]);
    m.nmt(NmtCommand::ResetCommunication, Some(6));
    assert_eq!(
        m.read(6, 0x1000, 0).unwrap(),
        DEVICE_TYPE_CIA402_SERVO.to_le_bytes()
    );
}
