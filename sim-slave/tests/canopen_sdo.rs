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

/// The recorder 0x2F00 (chain `recorder_bytes`): a read-only DOMAIN of known content that
/// the SDO benchmark uploads. 64 KiB segmented (9363 segments of 7 bytes) and by block
/// (sub-blocks of 127 with CRC) arrive byte for byte; it refuses writes and other
/// sub-indices, a node without it has no object, and one larger than 1 MiB is refused.
#[test]
fn the_recorder_uploads_64_kib_segmented_and_by_block() {
    use gantry_drives::canopen::NodeId;
    use gantry_sim::canopen::dictionary::{recorder_byte, RECORDER_MAX_BYTES};
    use gantry_sim::canopen::{CanNode, CanNodeConfig, CanNodeError};
    const BYTES: usize = 65_536;
    let node = |id: u8, recorder_bytes| CanNodeConfig {
        recorder_bytes,
        ..CanNodeConfig::servo(NodeId::new(id).unwrap())
    };
    let mut m = Master::with_nodes(vec![
        CanNode::new(node(6, BYTES)).unwrap(),
        CanNode::new(node(7, 0)).unwrap(),
    ]);
    m.step(0);
    let want: Vec<u8> = (0..BYTES).map(recorder_byte).collect();
    // Not periodic at 256: a segment in the wrong place would show.
    assert_ne!(want[..256], want[256..512]);
    for mode in [UploadMode::Normal, UploadMode::Block] {
        let got = m.upload(6, 0x2F00, 0, mode).unwrap();
        assert_eq!(got.len(), BYTES, "{mode:?}");
        let first_bad = got.iter().zip(&want).position(|(a, b)| a != b);
        assert_eq!(first_bad, None, "{mode:?}");
    }
    assert_eq!(m.write(6, 0x2F00, 0, &[1, 2, 3]), Err(AbortCode::READ_ONLY));
    assert_eq!(
        m.read(6, 0x2F00, 1),
        Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST)
    );
    assert_eq!(m.read(7, 0x2F00, 0), Err(AbortCode::OBJECT_DOES_NOT_EXIST));
    let too_big = CanNode::new(node(8, RECORDER_MAX_BYTES + 1)).unwrap_err();
    assert!(
        matches!(too_big, CanNodeError::DomainSize { .. }),
        "{too_big}"
    );
    assert!(
        too_big.to_string().contains("recorder_bytes = 1048577"),
        "{too_big}"
    );
}

/// The scratch 0x2F01 (chain `scratch_bytes`): a read-write DOMAIN that reads back what
/// was last written. 64 KiB written segmented and by block read back byte for byte (by
/// block and segmented), a shorter write reads back shorter, one longer than it holds is
/// refused with 0x06070012 before any data moves, reset application empties it, and one
/// larger than 1 MiB is refused.
#[test]
fn the_scratch_takes_64_kib_and_reads_it_back() {
    use gantry_drives::canopen::nmt::NmtCommand;
    use gantry_drives::canopen::NodeId;
    use gantry_sim::canopen::dictionary::{recorder_byte, RECORDER_MAX_BYTES};
    use gantry_sim::canopen::{CanNode, CanNodeConfig, CanNodeError};
    const BYTES: usize = 65_536;
    let node = |id: u8, scratch_bytes| CanNodeConfig {
        scratch_bytes,
        ..CanNodeConfig::servo(NodeId::new(id).unwrap())
    };
    let mut m = Master::with_nodes(vec![
        CanNode::new(node(6, BYTES)).unwrap(),
        CanNode::new(node(7, 0)).unwrap(),
        CanNode::new(node(9, 100)).unwrap(),
    ]);
    m.step(0);
    assert_eq!(m.read(6, 0x2F01, 0), Ok(vec![]), "empty at power-on");
    for (k, mode) in [DownloadMode::Segmented, DownloadMode::Block]
        .into_iter()
        .enumerate()
    {
        let data: Vec<u8> = (0..BYTES).map(|i| recorder_byte(i + k)).collect();
        m.download(6, 0x2F01, 0, &data, mode).unwrap();
        for up in [UploadMode::Block, UploadMode::Normal] {
            let got = m.upload(6, 0x2F01, 0, up).unwrap();
            assert_eq!(got.len(), BYTES, "{mode:?} {up:?}");
            let first_bad = got.iter().zip(&data).position(|(a, b)| a != b);
            assert_eq!(first_bad, None, "{mode:?} {up:?}");
        }
    }
    m.write(6, 0x2F01, 0, b"short").unwrap();
    assert_eq!(m.read(6, 0x2F01, 0), Ok(b"short".to_vec()));
    m.write(9, 0x2F01, 0, b"short").unwrap();
    for mode in [DownloadMode::Segmented, DownloadMode::Block] {
        assert_eq!(
            m.download(9, 0x2F01, 0, &[1; 101], mode),
            Err(AbortCode::LENGTH_TOO_HIGH),
            "{mode:?}"
        );
    }
    assert_eq!(m.read(9, 0x2F01, 0), Ok(b"short".to_vec()), "unchanged");
    assert_eq!(
        m.read(6, 0x2F01, 1),
        Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST)
    );
    assert_eq!(m.read(7, 0x2F01, 0), Err(AbortCode::OBJECT_DOES_NOT_EXIST));
    m.nmt(NmtCommand::ResetNode, Some(6));
    m.step(0);
    assert_eq!(
        m.read(6, 0x2F01, 0),
        Ok(vec![]),
        "empty after reset application"
    );
    let too_big = CanNode::new(node(8, RECORDER_MAX_BYTES + 1)).unwrap_err();
    assert!(
        matches!(too_big, CanNodeError::DomainSize { .. }),
        "{too_big}"
    );
    assert!(
        too_big
            .to_string()
            .contains("scratch_bytes = 1048577: the scratch 0x2F01 holds at most 1048576"),
        "{too_big}"
    );
}
