use super::*;
use crate::canopen::sdo::packet::SdoPacket;
use proptest::prelude::*;

const M: Multiplexer = Multiplexer::new(0x1018, 0x01);

fn seg(toggle: bool, last: bool, bytes: &[u8]) -> Segment {
    Segment::new(toggle, last, bytes)
}

/// Client → server fixtures, byte layouts of CiA 301 §7.2.4.3.3–.17 (multiplexer
/// 0x1018:01 = 18 10 01).
fn client_fixtures() -> Vec<([u8; 8], ClientCommand)> {
    use ClientCommand as C;
    vec![
        // Initiate download, expedited, size indicated: n = 4 − len, e = 1, s = 1.
        (
            [0x23, 0x18, 0x10, 0x01, 1, 2, 3, 4],
            C::InitiateDownload {
                mux: M,
                payload: Initiate::expedited(&[1, 2, 3, 4]).unwrap(),
            },
        ),
        (
            [0x27, 0x18, 0x10, 0x01, 1, 2, 3, 0],
            C::InitiateDownload {
                mux: M,
                payload: Initiate::expedited(&[1, 2, 3]).unwrap(),
            },
        ),
        (
            [0x2B, 0x18, 0x10, 0x01, 1, 2, 0, 0],
            C::InitiateDownload {
                mux: M,
                payload: Initiate::expedited(&[1, 2]).unwrap(),
            },
        ),
        (
            [0x2F, 0x18, 0x10, 0x01, 1, 0, 0, 0],
            C::InitiateDownload {
                mux: M,
                payload: Initiate::expedited(&[1]).unwrap(),
            },
        ),
        // Expedited, size not indicated (e = 1, s = 0).
        (
            [0x22, 0x18, 0x10, 0x01, 9, 8, 7, 6],
            C::InitiateDownload {
                mux: M,
                payload: Initiate::Expedited {
                    data: [9, 8, 7, 6],
                    len: None,
                },
            },
        ),
        // Segmented with size 889 (0x379) and without size.
        (
            [0x21, 0x18, 0x10, 0x01, 0x79, 0x03, 0, 0],
            C::InitiateDownload {
                mux: M,
                payload: Initiate::Segmented { size: Some(889) },
            },
        ),
        (
            [0x20, 0x18, 0x10, 0x01, 0, 0, 0, 0],
            C::InitiateDownload {
                mux: M,
                payload: Initiate::Segmented { size: None },
            },
        ),
        // Download segments: t n n n c.
        (
            [0x00, 1, 2, 3, 4, 5, 6, 7],
            C::DownloadSegment(seg(false, false, &[1, 2, 3, 4, 5, 6, 7])),
        ),
        (
            [0x10, 1, 2, 3, 4, 5, 6, 7],
            C::DownloadSegment(seg(true, false, &[1, 2, 3, 4, 5, 6, 7])),
        ),
        (
            [0x09, 1, 2, 3, 0, 0, 0, 0],
            C::DownloadSegment(seg(false, true, &[1, 2, 3])),
        ),
        (
            [0x1D, 1, 0, 0, 0, 0, 0, 0],
            C::DownloadSegment(seg(true, true, &[1])),
        ),
        // Upload.
        (
            [0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0],
            C::InitiateUpload { mux: M },
        ),
        (
            [0x60, 0, 0, 0, 0, 0, 0, 0],
            C::UploadSegment { toggle: false },
        ),
        (
            [0x70, 0, 0, 0, 0, 0, 0, 0],
            C::UploadSegment { toggle: true },
        ),
        // Abort: code little-endian in bytes 4–7.
        (
            [0x80, 0x18, 0x10, 0x01, 0x00, 0x00, 0x02, 0x06],
            C::Abort {
                mux: M,
                code: AbortCode::OBJECT_DOES_NOT_EXIST,
            },
        ),
        // Block download: initiate with cc and s, end with n = 3 and CRC 0x31C3.
        (
            [0xC6, 0x18, 0x10, 0x01, 0x79, 0x03, 0, 0],
            C::BlockDownloadInitiate {
                mux: M,
                crc: true,
                size: Some(889),
            },
        ),
        (
            [0xC0, 0x18, 0x10, 0x01, 0, 0, 0, 0],
            C::BlockDownloadInitiate {
                mux: M,
                crc: false,
                size: None,
            },
        ),
        (
            [0xCD, 0xC3, 0x31, 0, 0, 0, 0, 0],
            C::BlockDownloadEnd {
                unused: 3,
                crc: 0x31C3,
            },
        ),
        // Block upload: initiate (cc, blksize 127, pst 0), start, sub-block response, end.
        (
            [0xA4, 0x18, 0x10, 0x01, 127, 0, 0, 0],
            C::BlockUploadInitiate {
                mux: M,
                crc: true,
                block_size: 127,
                pst: 0,
            },
        ),
        (
            [0xA0, 0x18, 0x10, 0x01, 4, 21, 0, 0],
            C::BlockUploadInitiate {
                mux: M,
                crc: false,
                block_size: 4,
                pst: 21,
            },
        ),
        ([0xA3, 0, 0, 0, 0, 0, 0, 0], C::BlockUploadStart),
        (
            [0xA2, 5, 127, 0, 0, 0, 0, 0],
            C::BlockUploadAck {
                ackseq: 5,
                block_size: 127,
            },
        ),
        ([0xA1, 0, 0, 0, 0, 0, 0, 0], C::BlockUploadEnd),
    ]
}

/// Server → client fixtures.
fn server_fixtures() -> Vec<([u8; 8], ServerCommand)> {
    use ServerCommand as S;
    vec![
        (
            [0x60, 0x18, 0x10, 0x01, 0, 0, 0, 0],
            S::InitiateDownload { mux: M },
        ),
        (
            [0x20, 0, 0, 0, 0, 0, 0, 0],
            S::DownloadSegment { toggle: false },
        ),
        (
            [0x30, 0, 0, 0, 0, 0, 0, 0],
            S::DownloadSegment { toggle: true },
        ),
        (
            [0x43, 0x18, 0x10, 0x01, 0x92, 0x01, 0x02, 0x00],
            S::InitiateUpload {
                mux: M,
                payload: Initiate::expedited(&[0x92, 0x01, 0x02, 0x00]).unwrap(),
            },
        ),
        (
            [0x4F, 0x18, 0x10, 0x01, 0x05, 0, 0, 0],
            S::InitiateUpload {
                mux: M,
                payload: Initiate::expedited(&[5]).unwrap(),
            },
        ),
        (
            [0x4B, 0x18, 0x10, 0x01, 0x34, 0x12, 0, 0],
            S::InitiateUpload {
                mux: M,
                payload: Initiate::expedited(&[0x34, 0x12]).unwrap(),
            },
        ),
        (
            [0x41, 0x18, 0x10, 0x01, 0x1A, 0, 0, 0],
            S::InitiateUpload {
                mux: M,
                payload: Initiate::Segmented { size: Some(26) },
            },
        ),
        (
            [0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0],
            S::InitiateUpload {
                mux: M,
                payload: Initiate::Segmented { size: None },
            },
        ),
        (
            [0x00, b'g', b'a', b'n', b't', b'r', b'y', b' '],
            S::UploadSegment(seg(false, false, b"gantry ")),
        ),
        (
            [0x1B, b'o', b'k', 0, 0, 0, 0, 0],
            S::UploadSegment(seg(true, true, b"ok")),
        ),
        (
            [0x80, 0x18, 0x10, 0x01, 0x02, 0x00, 0x01, 0x06],
            S::Abort {
                mux: M,
                code: AbortCode::READ_ONLY,
            },
        ),
        (
            [0xA4, 0x18, 0x10, 0x01, 127, 0, 0, 0],
            S::BlockDownloadInitiate {
                mux: M,
                crc: true,
                block_size: 127,
            },
        ),
        (
            [0xA2, 127, 127, 0, 0, 0, 0, 0],
            S::BlockDownloadAck {
                ackseq: 127,
                block_size: 127,
            },
        ),
        ([0xA1, 0, 0, 0, 0, 0, 0, 0], S::BlockDownloadEnd),
        (
            [0xC6, 0x18, 0x10, 0x01, 0x00, 0x00, 0x01, 0x00],
            S::BlockUploadInitiate {
                mux: M,
                crc: true,
                size: Some(65536),
            },
        ),
        (
            [0xC0, 0x18, 0x10, 0x01, 0, 0, 0, 0],
            S::BlockUploadInitiate {
                mux: M,
                crc: false,
                size: None,
            },
        ),
        (
            [0xD9, 0x34, 0x12, 0, 0, 0, 0, 0],
            S::BlockUploadEnd {
                unused: 6,
                crc: 0x1234,
            },
        ),
    ]
}

#[test]
fn client_fixtures_parse_and_emit() {
    for (bytes, repr) in client_fixtures() {
        assert_eq!(ClientCommand::parse(&bytes), Ok(repr), "{bytes:02X?}");
        assert_eq!(repr.emit(), bytes, "{repr:?}");
    }
}

#[test]
fn server_fixtures_parse_and_emit() {
    for (bytes, repr) in server_fixtures() {
        assert_eq!(ServerCommand::parse(&bytes), Ok(repr), "{bytes:02X?}");
        assert_eq!(repr.emit(), bytes, "{repr:?}");
    }
}

#[test]
fn segment_lengths_follow_n() {
    let s = match ClientCommand::parse(&[0x0B, 1, 2, 3, 9, 9, 9, 9]).unwrap() {
        ClientCommand::DownloadSegment(s) => s,
        other => panic!("{other:?}"),
    };
    // n = (0x0B >> 1) & 7 = 5: two data bytes.
    assert_eq!(s.bytes(), &[1, 2]);
}

#[test]
fn block_segment_fixtures() {
    let s = BlockSegment::parse(&[0x01, 1, 2, 3, 4, 5, 6, 7]).unwrap();
    assert_eq!((s.seqno, s.last), (1, false));
    assert_eq!(s.emit(), [0x01, 1, 2, 3, 4, 5, 6, 7]);
    let s = BlockSegment::parse(&[0xFF, 0, 0, 0, 0, 0, 0, 0]).unwrap();
    assert_eq!((s.seqno, s.last), (127, true));
    assert_eq!(
        BlockSegment::parse(&[0x80, 0, 0, 0, 0, 0, 0, 0]),
        Err(SdoWireError::SequenceNumber(0x80))
    );
    assert_eq!(ABORT_BYTE0, 0x80);
}

#[test]
fn refuses_bad_frames_naming_the_byte() {
    assert_eq!(
        ClientCommand::parse(&[0x40; 7]),
        Err(SdoWireError::Length(7))
    );
    assert_eq!(
        ServerCommand::parse(&[0x60; 9]),
        Err(SdoWireError::Length(9))
    );
    assert_eq!(BlockSegment::parse(&[]), Err(SdoWireError::Length(0)));
    assert_eq!(
        ClientCommand::parse(&[0xE0, 0, 0, 0, 0, 0, 0, 0]),
        Err(SdoWireError::CommandSpecifier {
            direction: "request",
            byte: 0xE0,
            cs: 7
        })
    );
    assert_eq!(
        ServerCommand::parse(&[0xE0, 0, 0, 0, 0, 0, 0, 0]),
        Err(SdoWireError::CommandSpecifier {
            direction: "response",
            byte: 0xE0,
            cs: 7
        })
    );
    // scs 5 with ss = 3 is not defined.
    assert_eq!(
        ServerCommand::parse(&[0xA3, 0, 0, 0, 0, 0, 0, 0]),
        Err(SdoWireError::CommandSpecifier {
            direction: "response",
            byte: 0xA3,
            cs: 5
        })
    );
    let text = ClientCommand::parse(&[0xE0, 0, 0, 0, 0, 0, 0, 0])
        .unwrap_err()
        .to_string();
    assert!(text.contains("byte 0 = 0xE0"), "{text}");
}

proptest! {
    #[test]
    fn any_bytes_parse_or_err_and_reparse_identically(data in proptest::collection::vec(any::<u8>(), 0..=10)) {
        if let Ok(c) = ClientCommand::parse(&data) {
            prop_assert_eq!(ClientCommand::parse(&c.emit()), Ok(c));
        }
        if let Ok(s) = ServerCommand::parse(&data) {
            prop_assert_eq!(ServerCommand::parse(&s.emit()), Ok(s));
        }
        if let Ok(b) = BlockSegment::parse(&data) {
            let bytes = b.emit();
            prop_assert_eq!(&bytes[..], &data[..]);
        }
    }
}

#[test]
fn emit_into_writes_every_byte_over_a5() {
    for (bytes, repr) in client_fixtures() {
        let mut buf = [0xA5u8; 8];
        repr.emit_into(&mut SdoPacket::new_unchecked(&mut buf[..]));
        assert_eq!(buf, bytes, "{repr:?}");
    }
    for (bytes, repr) in server_fixtures() {
        let mut buf = [0xA5u8; 8];
        repr.emit_into(&mut SdoPacket::new_unchecked(&mut buf[..]));
        assert_eq!(buf, bytes, "{repr:?}");
    }
    let seg = BlockSegment {
        seqno: 3,
        last: true,
        data: [1, 2, 3, 4, 5, 6, 7],
    };
    let mut buf = [0xA5u8; 8];
    seg.emit_into(&mut SdoPacket::new_unchecked(&mut buf[..]));
    assert_eq!(buf, [0x83, 1, 2, 3, 4, 5, 6, 7]);
}
