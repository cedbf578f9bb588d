//! Client ⇄ server in memory: every transfer kind and size edge, errors on both sides, a
//! lossy link for block retransmission, and random frames against both machines.

use super::dictionary::test_dictionary::TestDictionary;
use super::*;
use crate::canopen::cob_id::NodeId;
use crate::canopen::frame::CanFrame;
use proptest::prelude::*;

const NODE: u8 = 5;
const STEP_NS: u64 = 100_000;
const DOMAIN: Multiplexer = Multiplexer::new(0x2000, 0);
const U32: Multiplexer = Multiplexer::new(0x2001, 1);
const DEVICE_TYPE: Multiplexer = Multiplexer::new(0x1000, 0);
const WRITE_ONLY: Multiplexer = Multiplexer::new(0x2002, 0);
const SIZES: &[usize] = &[0, 1, 4, 5, 7, 8, 889, 127 * 7, 127 * 7 + 1];

fn node() -> NodeId {
    NodeId::new(NODE).unwrap()
}

fn dictionary() -> TestDictionary {
    TestDictionary::default()
        .with(
            0x1000,
            0,
            Access::Const,
            ObjectSize::Fixed(4),
            &[0x92, 0x01, 0x02, 0x00],
        )
        .with(
            0x2000,
            0,
            Access::ReadWrite,
            ObjectSize::Variable { max: 4096 },
            &[],
        )
        .with(0x2001, 1, Access::ReadWrite, ObjectSize::Fixed(4), &[0; 4])
        .with(0x2002, 0, Access::WriteOnly, ObjectSize::Fixed(2), &[0; 2])
}

fn pattern(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 7 + 3) as u8).collect()
}

/// Which way a frame goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dir {
    ToServer,
    ToClient,
}

/// A CAN link in memory: frames in order, one step of time per round; `alter` may drop
/// (None) or change a frame.
struct Rig {
    client: SdoClient<Vec<u8>>,
    server: SdoServer<Vec<u8>>,
    od: TestDictionary,
    now: u64,
    log: Vec<(Dir, CanFrame)>,
    client_outcome: Option<Outcome>,
    server_outcome: Option<Outcome>,
}

impl Rig {
    fn new(client: SdoConfig, server: SdoConfig) -> Self {
        Self {
            client: SdoClient::new(node(), client, vec![0; 4096]).unwrap(),
            server: SdoServer::new(node(), server, vec![0; 4096]).unwrap(),
            od: dictionary(),
            now: 0,
            log: Vec::new(),
            client_outcome: None,
            server_outcome: None,
        }
    }

    fn default() -> Self {
        Self::new(SdoConfig::default(), SdoConfig::default())
    }

    /// Runs until both sides are idle and nothing is in flight, at most 20 s.
    fn run(&mut self, mut alter: impl FnMut(Dir, usize, CanFrame) -> Option<CanFrame>) {
        let end = self.now + 20_000_000_000;
        let mut n = 0usize;
        while self.now < end {
            let mut moved = false;
            while let Some(f) = self.client.transmit() {
                moved = true;
                n += 1;
                self.log.push((Dir::ToServer, f));
                if let Some(f) = alter(Dir::ToServer, n, f) {
                    if let Some(o) = self.server.receive(&f, self.now, &mut self.od) {
                        self.server_outcome = Some(o);
                    }
                }
            }
            while let Some(f) = self.server.transmit() {
                moved = true;
                n += 1;
                self.log.push((Dir::ToClient, f));
                if let Some(f) = alter(Dir::ToClient, n, f) {
                    if let Some(o) = self.client.receive(&f, self.now) {
                        self.client_outcome = Some(o);
                    }
                }
            }
            if !moved && self.client.is_idle() && self.server.is_idle() {
                return;
            }
            self.now += STEP_NS;
            if let Some(o) = self.client.poll(self.now) {
                self.client_outcome = Some(o);
            }
            if let Some(o) = self.server.poll(self.now) {
                self.server_outcome = Some(o);
            }
        }
        panic!("transfer did not end in 20 s");
    }

    fn run_clean(&mut self) {
        self.run(|_, _, f| Some(f));
    }

    fn download(
        &mut self,
        mux: Multiplexer,
        data: &[u8],
        mode: DownloadMode,
    ) -> (Option<Outcome>, Option<Outcome>) {
        self.client_outcome = None;
        self.server_outcome = None;
        self.client.download(mux, data, mode, self.now).unwrap();
        self.run_clean();
        (self.client_outcome, self.server_outcome)
    }

    fn upload(&mut self, mux: Multiplexer, mode: UploadMode) -> (Option<Outcome>, Option<Outcome>) {
        self.client_outcome = None;
        self.server_outcome = None;
        self.client.upload(mux, mode, self.now).unwrap();
        self.run_clean();
        (self.client_outcome, self.server_outcome)
    }

    fn frames(&self, dir: Dir) -> usize {
        self.log.iter().filter(|(d, _)| *d == dir).count()
    }
}

fn aborted(mux: Multiplexer, code: AbortCode, by: Side) -> Option<Outcome> {
    Some(Outcome::Aborted { mux, code, by })
}

#[test]
fn every_kind_and_size_round_trips() {
    let downloads = [
        DownloadMode::Auto,
        DownloadMode::Segmented,
        DownloadMode::Block,
    ];
    let uploads = [UploadMode::Normal, UploadMode::Block];
    for &len in SIZES {
        for mode in downloads {
            for up in uploads {
                let mut rig = Rig::default();
                let data = pattern(len);
                let done = Some(Outcome::Downloaded { mux: DOMAIN, len });
                assert_eq!(
                    rig.download(DOMAIN, &data, mode),
                    (done, done),
                    "{len} {mode:?}"
                );
                assert_eq!(rig.od.value(0x2000, 0), &data[..], "{len} {mode:?}");
                let done = Some(Outcome::Uploaded { mux: DOMAIN, len });
                assert_eq!(rig.upload(DOMAIN, up), (done, done), "{len} {up:?}");
                assert_eq!(rig.client.data(), &data[..], "{len} {up:?}");
            }
        }
    }
}

#[test]
fn expedited_is_one_exchange_with_cia_bytes() {
    let mut rig = Rig::default();
    rig.download(U32, &[1, 2, 3, 4], DownloadMode::Expedited);
    assert_eq!(rig.log.len(), 2);
    assert_eq!(rig.log[0].1.id(), 0x605);
    assert_eq!(rig.log[0].1.data(), &[0x23, 0x01, 0x20, 0x01, 1, 2, 3, 4]);
    assert_eq!(rig.log[1].1.id(), 0x585);
    assert_eq!(rig.log[1].1.data(), &[0x60, 0x01, 0x20, 0x01, 0, 0, 0, 0]);
    rig.log.clear();
    assert_eq!(
        rig.upload(DEVICE_TYPE, UploadMode::Normal).0,
        Some(Outcome::Uploaded {
            mux: DEVICE_TYPE,
            len: 4
        })
    );
    assert_eq!(
        rig.log[1].1.data(),
        &[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]
    );
    assert_eq!(rig.client.data(), &[0x92, 0x01, 0x02, 0x00]);
}

#[test]
fn frame_counts_per_kind_for_889_bytes() {
    // Segmented: initiate + 127 segments, each confirmed.
    let mut rig = Rig::default();
    rig.download(DOMAIN, &pattern(889), DownloadMode::Segmented);
    assert_eq!(
        (rig.frames(Dir::ToServer), rig.frames(Dir::ToClient)),
        (128, 128)
    );
    // Block (127 per sub-block): initiate, 127 segments, end; server: initiate, 1 ack, end.
    let mut rig = Rig::default();
    rig.download(DOMAIN, &pattern(889), DownloadMode::Block);
    assert_eq!(
        (rig.frames(Dir::ToServer), rig.frames(Dir::ToClient)),
        (129, 3)
    );
    // 127×7 + 1 needs a second sub-block of one segment.
    let mut rig = Rig::default();
    rig.download(DOMAIN, &pattern(127 * 7 + 1), DownloadMode::Block);
    assert_eq!(
        (rig.frames(Dir::ToServer), rig.frames(Dir::ToClient)),
        (130, 4)
    );
    // Block upload of those 127×7 + 1 bytes: initiate, start, 2 acks, end response;
    // server: initiate, 127 + 1 segments, end.
    rig.log.clear();
    rig.upload(DOMAIN, UploadMode::Block);
    assert_eq!(
        (rig.frames(Dir::ToServer), rig.frames(Dir::ToClient)),
        (5, 130)
    );
}

#[test]
fn block_sizes_and_crc_negotiation() {
    for block_size in [1u8, 2, 7, 64, 127] {
        for (client_crc, server_crc) in [(true, true), (true, false), (false, true), (false, false)]
        {
            let c = SdoConfig {
                block_size,
                crc: client_crc,
                ..SdoConfig::default()
            };
            let s = SdoConfig {
                block_size,
                crc: server_crc,
                ..SdoConfig::default()
            };
            let mut rig = Rig::new(c, s);
            let data = pattern(1000);
            let d = Some(Outcome::Downloaded {
                mux: DOMAIN,
                len: 1000,
            });
            assert_eq!(rig.download(DOMAIN, &data, DownloadMode::Block), (d, d));
            let u = Some(Outcome::Uploaded {
                mux: DOMAIN,
                len: 1000,
            });
            assert_eq!(rig.upload(DOMAIN, UploadMode::Block), (u, u));
            assert_eq!(rig.client.data(), &data[..]);
            // The end frames carry the CRC only if both sides support it.
            let crc = if client_crc && server_crc {
                crc::Crc16::of(&data)
            } else {
                0
            };
            let ends: Vec<_> = rig
                .log
                .iter()
                .filter(|(_, f)| matches!(f.data()[0], 0xC1..=0xDD if f.data()[0] & 0xE3 == 0xC1))
                .map(|(_, f)| u16::from_le_bytes([f.data()[1], f.data()[2]]))
                .collect();
            assert_eq!(
                ends,
                [crc, crc],
                "bs {block_size} crc {client_crc}/{server_crc}"
            );
            // Sub-blocks: ⌈143 / block size⌉ acks each way.
            let acks = rig.log.iter().filter(|(_, f)| f.data()[0] == 0xA2).count();
            assert_eq!(acks, 2 * 143usize.div_ceil(block_size as usize));
        }
    }
}

#[test]
fn size_not_indicated() {
    let c = SdoConfig {
        indicate_size: false,
        ..SdoConfig::default()
    };
    for mode in [DownloadMode::Segmented, DownloadMode::Block] {
        let mut rig = Rig::new(c, SdoConfig::default());
        let data = pattern(50);
        let (co, so) = rig.download(DOMAIN, &data, mode);
        assert_eq!(
            co,
            Some(Outcome::Downloaded {
                mux: DOMAIN,
                len: 50
            })
        );
        assert_eq!(so, co);
        assert_eq!(rig.od.value(0x2000, 0), &data[..]);
        assert_eq!(rig.log[0].1.data()[0] & 0x01, 0, "s bit clear");
    }
}

#[test]
fn server_takes_expedited_without_size_from_object_size() {
    let mut server = SdoServer::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    let mut od = dictionary();
    // e = 1, s = 0 to 0x2002 (2 bytes): the object's size says 2.
    let f = CanFrame::new(0x605, &[0x22, 0x02, 0x20, 0x00, 0xAA, 0xBB, 0xCC, 0xDD]).unwrap();
    assert_eq!(
        server.receive(&f, 0, &mut od),
        Some(Outcome::Downloaded {
            mux: WRITE_ONLY,
            len: 2
        })
    );
    assert_eq!(od.value(0x2002, 0), &[0xAA, 0xBB]);
}

#[test]
fn client_takes_uploads_without_size() {
    // Expedited, size not indicated (e = 1, s = 0): the 4 bytes.
    let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    client.upload(U32, UploadMode::Normal, 0).unwrap();
    client.transmit();
    let f = CanFrame::new(0x585, &[0x42, 0x01, 0x20, 0x01, 1, 2, 3, 4]).unwrap();
    assert_eq!(
        client.receive(&f, 1),
        Some(Outcome::Uploaded { mux: U32, len: 4 })
    );
    assert_eq!(client.data(), &[1, 2, 3, 4]);
    // Segmented, size not indicated: the segments say when it ends.
    client.upload(DOMAIN, UploadMode::Normal, 2).unwrap();
    assert_eq!(client.transmit().unwrap().data()[0], 0x40);
    let f = |d: &[u8]| CanFrame::new(0x585, d).unwrap();
    assert_eq!(
        client.receive(&f(&[0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0]), 3),
        None
    );
    assert_eq!(client.transmit().unwrap().data()[0], 0x60);
    assert_eq!(client.receive(&f(&[0x00, 1, 2, 3, 4, 5, 6, 7]), 4), None);
    assert_eq!(client.transmit().unwrap().data()[0], 0x70);
    assert_eq!(
        client.receive(&f(&[0x1B, 8, 9, 0, 0, 0, 0, 0]), 5),
        Some(Outcome::Uploaded {
            mux: DOMAIN,
            len: 9
        })
    );
    assert_eq!(client.data(), &[1, 2, 3, 4, 5, 6, 7, 8, 9]);
    // Segmented with size 9 but 10 bytes arrive: too high.
    client.upload(DOMAIN, UploadMode::Normal, 6).unwrap();
    client.transmit();
    client.receive(&f(&[0x41, 0x00, 0x20, 0x00, 9, 0, 0, 0]), 7);
    client.transmit();
    client.receive(&f(&[0x00, 1, 2, 3, 4, 5, 6, 7]), 8);
    client.transmit();
    assert_eq!(
        client.receive(&f(&[0x19, 8, 9, 10, 0, 0, 0, 0]), 9),
        aborted(DOMAIN, AbortCode::LENGTH_TOO_HIGH, Side::Client)
    );
}

#[test]
fn protocol_switch_below_pst() {
    let c = SdoConfig {
        pst: 8,
        ..SdoConfig::default()
    };
    let mut rig = Rig::new(c, SdoConfig::default());
    rig.download(DOMAIN, &pattern(8), DownloadMode::Auto);
    rig.log.clear();
    let u = Some(Outcome::Uploaded {
        mux: DOMAIN,
        len: 8,
    });
    assert_eq!(rig.upload(DOMAIN, UploadMode::Block), (u, u));
    assert_eq!(rig.client.data(), &pattern(8)[..]);
    assert_eq!(
        rig.log[1].1.data()[0],
        0x41,
        "normal initiate upload response"
    );
    // Above pst, a block transfer.
    rig.download(DOMAIN, &pattern(9), DownloadMode::Auto);
    rig.log.clear();
    rig.upload(DOMAIN, UploadMode::Block);
    assert_eq!(rig.log[1].1.data()[0], 0xC6);
    // Without pst offered, a normal answer to a block upload is a protocol error.
    let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    client.upload(DOMAIN, UploadMode::Block, 0).unwrap();
    client.transmit();
    let f = CanFrame::new(0x585, &[0x4F, 0x00, 0x20, 0x00, 1, 0, 0, 0]).unwrap();
    assert_eq!(
        client.receive(&f, 1),
        aborted(DOMAIN, AbortCode::INVALID_COMMAND_SPECIFIER, Side::Client)
    );
}

#[test]
fn unknown_object_and_sub_index() {
    let mut rig = Rig::default();
    let m = Multiplexer::new(0x2FFF, 0);
    let a = aborted(m, AbortCode::OBJECT_DOES_NOT_EXIST, Side::Server);
    assert_eq!(rig.upload(m, UploadMode::Normal), (a, a));
    assert_eq!(
        rig.log[1].1.data(),
        &[0x80, 0xFF, 0x2F, 0x00, 0x00, 0x00, 0x02, 0x06]
    );
    assert_eq!(rig.download(m, &[1], DownloadMode::Auto), (a, a));
    assert_eq!(rig.upload(m, UploadMode::Block), (a, a));
    let m = Multiplexer::new(0x2001, 9);
    let a = aborted(m, AbortCode::SUB_INDEX_DOES_NOT_EXIST, Side::Server);
    assert_eq!(rig.download(m, &pattern(20), DownloadMode::Block), (a, a));
}

#[test]
fn access_rights() {
    let mut rig = Rig::default();
    let a = aborted(DEVICE_TYPE, AbortCode::READ_ONLY, Side::Server);
    for mode in [
        DownloadMode::Expedited,
        DownloadMode::Segmented,
        DownloadMode::Block,
    ] {
        assert_eq!(
            rig.download(DEVICE_TYPE, &[1, 2, 3, 4], mode),
            (a, a),
            "{mode:?}"
        );
    }
    assert_eq!(rig.od.value(0x1000, 0), &[0x92, 0x01, 0x02, 0x00]);
    let a = aborted(WRITE_ONLY, AbortCode::WRITE_ONLY, Side::Server);
    assert_eq!(rig.upload(WRITE_ONLY, UploadMode::Normal), (a, a));
    assert_eq!(rig.upload(WRITE_ONLY, UploadMode::Block), (a, a));
    assert_eq!(rig.od.writes, 0);
}

#[test]
fn lengths_against_the_object() {
    let mut rig = Rig::default();
    for (len, code) in [
        (2, AbortCode::LENGTH_TOO_LOW),
        (5, AbortCode::LENGTH_TOO_HIGH),
    ] {
        for mode in [
            DownloadMode::Auto,
            DownloadMode::Segmented,
            DownloadMode::Block,
        ] {
            let a = aborted(U32, code, Side::Server);
            assert_eq!(
                rig.download(U32, &pattern(len), mode),
                (a, a),
                "{len} {mode:?}"
            );
        }
    }
    // Size not indicated: found at the end, nothing written.
    let c = SdoConfig {
        indicate_size: false,
        ..SdoConfig::default()
    };
    let mut rig = Rig::new(c, SdoConfig::default());
    let a = aborted(U32, AbortCode::LENGTH_TOO_HIGH, Side::Server);
    assert_eq!(rig.download(U32, &pattern(9), DownloadMode::Block), (a, a));
    assert_eq!(rig.od.writes, 0);
}

#[test]
fn out_of_memory_both_sides() {
    let mut rig = Rig::default();
    rig.server = SdoServer::new(node(), SdoConfig::default(), vec![0; 16]).unwrap();
    let a = aborted(DOMAIN, AbortCode::OUT_OF_MEMORY, Side::Server);
    assert_eq!(
        rig.download(DOMAIN, &pattern(17), DownloadMode::Segmented),
        (a, a)
    );
    assert_eq!(
        rig.download(DOMAIN, &pattern(17), DownloadMode::Block),
        (a, a)
    );
    let d = Some(Outcome::Downloaded {
        mux: DOMAIN,
        len: 16,
    });
    assert_eq!(
        rig.download(DOMAIN, &pattern(16), DownloadMode::Block),
        (d, d)
    );
    // Client buffer too small for the upload.
    rig.server = SdoServer::new(node(), SdoConfig::default(), vec![0; 4096]).unwrap();
    rig.download(DOMAIN, &pattern(100), DownloadMode::Block);
    rig.client = SdoClient::new(node(), SdoConfig::default(), vec![0; 99]).unwrap();
    let a = aborted(DOMAIN, AbortCode::OUT_OF_MEMORY, Side::Client);
    assert_eq!(rig.upload(DOMAIN, UploadMode::Normal), (a, a));
    assert_eq!(rig.upload(DOMAIN, UploadMode::Block), (a, a));
    // And the client refuses to start a download larger than its buffer.
    assert_eq!(
        rig.client
            .download(DOMAIN, &pattern(100), DownloadMode::Segmented, 0),
        Err(SdoClientError::TooLarge {
            node: node(),
            mux: DOMAIN,
            len: 100,
            capacity: 99
        })
    );
}

#[test]
fn wrong_toggle_from_the_server_aborts_the_client() {
    let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    client
        .download(DOMAIN, &pattern(20), DownloadMode::Segmented, 0)
        .unwrap();
    assert_eq!(client.transmit().unwrap().data()[0], 0x21);
    let resp = CanFrame::new(0x585, &[0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0]).unwrap();
    assert_eq!(client.receive(&resp, 1), None);
    assert_eq!(
        client.transmit().unwrap().data()[0],
        0x00,
        "first segment, toggle 0"
    );
    // The server confirms with toggle 1: not the segment sent.
    let bad = CanFrame::new(0x585, &[0x30, 0, 0, 0, 0, 0, 0, 0]).unwrap();
    assert_eq!(
        client.receive(&bad, 2),
        aborted(DOMAIN, AbortCode::TOGGLE_BIT_NOT_ALTERNATED, Side::Client)
    );
    assert_eq!(
        client.transmit().unwrap().data(),
        &[0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x03, 0x05]
    );
    assert!(client.is_idle());
    // A late answer while idle is ignored.
    assert_eq!(client.receive(&bad, 3), None);
    assert_eq!(client.transmit(), None);
}

#[test]
fn wrong_toggle_from_the_client_aborts_the_server() {
    let mut rig = Rig::default();
    let mut od = dictionary();
    let f = |d: &[u8]| CanFrame::new(0x605, d).unwrap();
    let s = &mut rig.server;
    assert_eq!(
        s.receive(&f(&[0x21, 0x00, 0x20, 0x00, 14, 0, 0, 0]), 0, &mut od),
        None
    );
    assert_eq!(s.transmit().unwrap().data()[0], 0x60);
    assert_eq!(
        s.receive(&f(&[0x00, 1, 2, 3, 4, 5, 6, 7]), 1, &mut od),
        None
    );
    assert_eq!(s.transmit().unwrap().data()[0], 0x20);
    // Second segment with toggle 0 again.
    assert_eq!(
        s.receive(&f(&[0x01, 1, 2, 3, 4, 5, 6, 7]), 2, &mut od),
        aborted(DOMAIN, AbortCode::TOGGLE_BIT_NOT_ALTERNATED, Side::Server)
    );
    assert_eq!(
        s.transmit().unwrap().data(),
        &[0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x03, 0x05]
    );
    assert_eq!(od.writes, 0);
    // Upload side: the client asks for a segment with toggle 1 first.
    od.write(DOMAIN, &pattern(20)).unwrap();
    assert_eq!(
        s.receive(&f(&[0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0]), 3, &mut od),
        None
    );
    assert_eq!(s.transmit().unwrap().data()[0], 0x41);
    assert_eq!(
        s.receive(&f(&[0x70, 0, 0, 0, 0, 0, 0, 0]), 4, &mut od),
        aborted(DOMAIN, AbortCode::TOGGLE_BIT_NOT_ALTERNATED, Side::Server)
    );
}

/// Flips one data byte of the `k`-th block segment going `dir`.
fn corrupt(dir: Dir, k: usize) -> impl FnMut(Dir, usize, CanFrame) -> Option<CanFrame> {
    let mut seen = 0;
    move |d, _, f| {
        let b0 = f.data()[0];
        let is_segment = d == dir && b0 & 0x7F != 0 && f.data().len() == 8;
        if is_segment {
            seen += 1;
            if seen == k {
                let mut bytes = *f.raw();
                bytes[3] ^= 0x40;
                return Some(CanFrame::new(f.id() as u32, &bytes).unwrap());
            }
        }
        Some(f)
    }
}

#[test]
fn wrong_crc_both_ways() {
    let mut rig = Rig::default();
    rig.client
        .download(DOMAIN, &pattern(300), DownloadMode::Block, 0)
        .unwrap();
    // Frame 1 is the initiate; segments follow from the 2nd frame to the server.
    rig.run(corrupt(Dir::ToServer, 5));
    let a = aborted(DOMAIN, AbortCode::CRC_ERROR, Side::Server);
    assert_eq!((rig.client_outcome, rig.server_outcome), (a, a));
    assert_eq!(rig.od.writes, 0);

    let mut rig = Rig::default();
    rig.download(DOMAIN, &pattern(300), DownloadMode::Block);
    rig.client_outcome = None;
    rig.server_outcome = None;
    rig.client
        .upload(DOMAIN, UploadMode::Block, rig.now)
        .unwrap();
    // The server's initiate response (0xC6) counts as a "segment" by its byte 0, so the
    // 4th is the 3rd data segment.
    rig.run(corrupt(Dir::ToClient, 4));
    let a = aborted(DOMAIN, AbortCode::CRC_ERROR, Side::Client);
    assert_eq!((rig.client_outcome, rig.server_outcome), (a, a));
}

#[test]
fn client_timeout_when_the_server_never_answers() {
    let config = SdoConfig {
        timeout_ns: 500_000_000,
        ..SdoConfig::default()
    };
    let mut client = SdoClient::new(node(), config, vec![0u8; 64]).unwrap();
    client.upload(U32, UploadMode::Normal, 1_000).unwrap();
    assert!(client.transmit().is_some());
    assert_eq!(client.poll(500_000_999), None);
    assert_eq!(
        client.poll(500_001_000),
        aborted(U32, AbortCode::TIMED_OUT, Side::Client)
    );
    assert_eq!(
        client.transmit().unwrap().data(),
        &[0x80, 0x01, 0x20, 0x01, 0x00, 0x00, 0x04, 0x05]
    );
    assert!(client.is_idle());
    assert_eq!(client.poll(u64::MAX), None);
}

#[test]
fn server_timeout_when_the_client_goes_silent() {
    for mode in [DownloadMode::Segmented, DownloadMode::Block] {
        let mut rig = Rig::default();
        rig.client.download(DOMAIN, &pattern(100), mode, 0).unwrap();
        // The link dies after the first two frames.
        rig.run(|_, n, f| (n <= 2).then_some(f));
        assert_eq!(
            rig.server_outcome,
            aborted(DOMAIN, AbortCode::TIMED_OUT, Side::Server),
            "{mode:?}"
        );
        assert_eq!(
            rig.client_outcome,
            aborted(DOMAIN, AbortCode::TIMED_OUT, Side::Client),
            "{mode:?}"
        );
        assert_eq!(rig.od.writes, 0);
    }
}

#[test]
fn abort_from_either_side() {
    // The client aborts mid-transfer: the server drops it and writes nothing.
    let mut rig = Rig::default();
    rig.client
        .download(DOMAIN, &pattern(100), DownloadMode::Segmented, 0)
        .unwrap();
    let mut aborted_once = false;
    let mut client_outcome = None;
    {
        let client = &mut rig.client;
        let server = &mut rig.server;
        let od = &mut rig.od;
        for round in 0..10 {
            while let Some(f) = client.transmit() {
                if let Some(o) = server.receive(&f, round, od) {
                    rig.server_outcome = Some(o);
                }
            }
            while let Some(f) = server.transmit() {
                client.receive(&f, round);
            }
            if round == 3 && !aborted_once {
                client_outcome = client.abort(AbortCode::CANNOT_STORE_LOCAL_CONTROL);
                aborted_once = true;
            }
        }
    }
    assert_eq!(
        client_outcome,
        aborted(DOMAIN, AbortCode::CANNOT_STORE_LOCAL_CONTROL, Side::Client)
    );
    assert_eq!(rig.server_outcome, client_outcome);
    assert!(rig.server.is_idle());
    assert_eq!(rig.od.writes, 0);

    // The server's dictionary refuses the value: the client learns why.
    struct Refusing(TestDictionary);
    impl ObjectDictionary for Refusing {
        fn entry(&self, mux: Multiplexer) -> Result<EntryInfo, AbortCode> {
            self.0.entry(mux)
        }
        fn read(&mut self, mux: Multiplexer, out: &mut [u8]) -> Result<usize, AbortCode> {
            self.0.read(mux, out)
        }
        fn write(&mut self, _: Multiplexer, _: &[u8]) -> Result<(), AbortCode> {
            Err(AbortCode::VALUE_TOO_HIGH)
        }
    }
    let mut od = Refusing(dictionary());
    let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    let mut server = SdoServer::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    client
        .download(DOMAIN, &pattern(30), DownloadMode::Block, 0)
        .unwrap();
    let mut outcome = None;
    for t in 0..10 {
        while let Some(f) = client.transmit() {
            server.receive(&f, t, &mut od);
        }
        while let Some(f) = server.transmit() {
            if let Some(o) = client.receive(&f, t) {
                outcome = Some(o);
            }
        }
    }
    assert_eq!(
        outcome,
        aborted(DOMAIN, AbortCode::VALUE_TOO_HIGH, Side::Server)
    );
}

#[test]
fn invalid_block_sizes() {
    let mut server = SdoServer::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    let mut od = dictionary();
    for bs in [0u8, 128] {
        let f = CanFrame::new(0x605, &[0xA4, 0x00, 0x10, 0x00, bs, 0, 0, 0]).unwrap();
        assert_eq!(
            server.receive(&f, 0, &mut od),
            aborted(DEVICE_TYPE, AbortCode::INVALID_BLOCK_SIZE, Side::Server)
        );
        assert_eq!(
            server.transmit().unwrap().data()[4..],
            [0x02, 0x00, 0x04, 0x05]
        );
    }
    let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    client
        .download(DOMAIN, &pattern(30), DownloadMode::Block, 0)
        .unwrap();
    client.transmit();
    let f = CanFrame::new(0x585, &[0xA4, 0x00, 0x20, 0x00, 128, 0, 0, 0]).unwrap();
    assert_eq!(
        client.receive(&f, 0),
        aborted(DOMAIN, AbortCode::INVALID_BLOCK_SIZE, Side::Client)
    );
    assert!(SdoConfig {
        block_size: 0,
        ..SdoConfig::default()
    }
    .validate()
    .is_err());
    assert!(SdoClient::new(
        node(),
        SdoConfig {
            block_size: 128,
            ..SdoConfig::default()
        },
        vec![0u8; 1]
    )
    .is_err());
}

#[test]
fn invalid_sequence_number_and_ack() {
    // A segment numbered past the block size.
    let mut rig = Rig::new(
        SdoConfig::default(),
        SdoConfig {
            block_size: 4,
            ..SdoConfig::default()
        },
    );
    let mut od = dictionary();
    let s = &mut rig.server;
    let f = |d: &[u8]| CanFrame::new(0x605, d).unwrap();
    s.receive(&f(&[0xC6, 0x00, 0x20, 0x00, 100, 0, 0, 0]), 0, &mut od);
    assert_eq!(
        s.transmit().unwrap().data()[..5],
        [0xA4, 0x00, 0x20, 0x00, 4]
    );
    assert_eq!(
        s.receive(&f(&[0x05, 0, 0, 0, 0, 0, 0, 0]), 1, &mut od),
        aborted(DOMAIN, AbortCode::INVALID_SEQUENCE_NUMBER, Side::Server)
    );
    // An ack for more segments than were sent.
    let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    client
        .download(DOMAIN, &pattern(14), DownloadMode::Block, 0)
        .unwrap();
    client.transmit();
    client.receive(
        &CanFrame::new(0x585, &[0xA4, 0x00, 0x20, 0x00, 127, 0, 0, 0]).unwrap(),
        0,
    );
    assert_eq!(std::iter::from_fn(|| client.transmit()).count(), 2);
    let ack = CanFrame::new(0x585, &[0xA2, 3, 127, 0, 0, 0, 0, 0]).unwrap();
    assert_eq!(
        client.receive(&ack, 1),
        aborted(DOMAIN, AbortCode::INVALID_SEQUENCE_NUMBER, Side::Client)
    );
}

#[test]
fn wrong_multiplexer_in_answer() {
    let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    client.upload(U32, UploadMode::Normal, 0).unwrap();
    client.transmit();
    let f = CanFrame::new(0x585, &[0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4]).unwrap();
    assert_eq!(
        client.receive(&f, 0),
        aborted(U32, AbortCode::PARAMETER_INCOMPATIBILITY, Side::Client)
    );
}

#[test]
fn malformed_frames_are_answered_with_an_abort() {
    let mut server = SdoServer::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    let mut od = dictionary();
    let any = Multiplexer::new(0, 0);
    // Unknown ccs 7.
    let f = CanFrame::new(0x605, &[0xE0, 0, 0, 0, 0, 0, 0, 0]).unwrap();
    assert_eq!(
        server.receive(&f, 0, &mut od),
        aborted(any, AbortCode::INVALID_COMMAND_SPECIFIER, Side::Server)
    );
    assert_eq!(
        server.transmit().unwrap().data(),
        &[0x80, 0, 0, 0, 0x01, 0x00, 0x04, 0x05]
    );
    // DLC 4.
    let f = CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00]).unwrap();
    assert_eq!(
        server.receive(&f, 0, &mut od),
        aborted(any, AbortCode::INVALID_COMMAND_SPECIFIER, Side::Server)
    );
    // A segment while idle.
    let f = CanFrame::new(0x605, &[0x60, 0, 0, 0, 0, 0, 0, 0]).unwrap();
    assert_eq!(
        server.receive(&f, 0, &mut od),
        aborted(any, AbortCode::INVALID_COMMAND_SPECIFIER, Side::Server)
    );
    // Another node's frames, remote frames and an abort while idle: ignored, no answer.
    server.transmit();
    for f in [
        CanFrame::new(0x606, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap(),
        CanFrame::new_remote(0x605, 8).unwrap(),
        CanFrame::new(0x605, &[0x80, 0, 0, 0, 0, 0, 0, 0]).unwrap(),
    ] {
        assert_eq!(server.receive(&f, 0, &mut od), None);
        assert_eq!(server.transmit(), None);
    }
    // A new initiate mid-transfer.
    let f = CanFrame::new(0x605, &[0x21, 0x00, 0x20, 0x00, 30, 0, 0, 0]).unwrap();
    assert_eq!(server.receive(&f, 0, &mut od), None);
    server.transmit();
    let f = CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap();
    assert_eq!(
        server.receive(&f, 0, &mut od),
        aborted(DOMAIN, AbortCode::INVALID_COMMAND_SPECIFIER, Side::Server)
    );
}

#[test]
fn client_refuses_to_start_twice_or_expedite_five_bytes() {
    let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 64]).unwrap();
    assert_eq!(
        client.download(U32, &[1, 2, 3, 4, 5], DownloadMode::Expedited, 0),
        Err(SdoClientError::ExpeditedLength {
            node: node(),
            mux: U32,
            len: 5
        })
    );
    assert_eq!(
        client.download(U32, &[], DownloadMode::Expedited, 0),
        Err(SdoClientError::ExpeditedLength {
            node: node(),
            mux: U32,
            len: 0
        })
    );
    client.upload(U32, UploadMode::Normal, 0).unwrap();
    let e = client.upload(DOMAIN, UploadMode::Normal, 0).unwrap_err();
    assert_eq!(
        e,
        SdoClientError::Busy {
            node: node(),
            busy: U32,
            mux: DOMAIN
        }
    );
    assert!(e.to_string().contains("0x2001:01"), "{e}");
}

/// Drops the block segments going `dir` whose position (1-based) is in `lost`. With a
/// block size of at most 16, a segment's byte 0 has a sequence number 1..=16, which no
/// initiate or end frame has (their bits 6–0 are 0x41 or more).
fn lossy(dir: Dir, lost: &'static [usize]) -> impl FnMut(Dir, usize, CanFrame) -> Option<CanFrame> {
    let mut k = 0;
    move |d, _, f| {
        let seqno = f.data()[0] & 0x7F;
        if d == dir && (1..=16).contains(&seqno) {
            k += 1;
            if lost.contains(&k) {
                return None;
            }
        }
        Some(f)
    }
}

#[test]
fn lossy_link_block_download_retransmits() {
    // Sub-blocks of 10: segment 3 lost (resend from 3), a sub-block's last (10th) lost
    // (the server acknowledges after its silence timeout), and the transfer's last lost.
    let server = SdoConfig {
        block_size: 10,
        sub_block_timeout_ns: Some(1_000_000),
        ..SdoConfig::default()
    };
    let mut rig = Rig::new(SdoConfig::default(), server);
    let data = pattern(127 * 7 + 1);
    rig.client
        .download(DOMAIN, &data, DownloadMode::Block, 0)
        .unwrap();
    rig.run(lossy(Dir::ToServer, &[3, 18, 40, 41, 141]));
    let d = Some(Outcome::Downloaded {
        mux: DOMAIN,
        len: data.len(),
    });
    assert_eq!((rig.client_outcome, rig.server_outcome), (d, d));
    assert_eq!(rig.od.value(0x2000, 0), &data[..]);
    let sent = rig.log.iter().filter(|(d, _)| *d == Dir::ToServer).count();
    assert!(sent > 128 + 2, "segments were sent again: {sent}");
}

#[test]
fn lossy_link_block_upload_retransmits() {
    let client = SdoConfig {
        block_size: 16,
        sub_block_timeout_ns: Some(1_000_000),
        ..SdoConfig::default()
    };
    let mut rig = Rig::new(client, SdoConfig::default());
    let data = pattern(127 * 7);
    rig.download(DOMAIN, &data, DownloadMode::Segmented);
    rig.client_outcome = None;
    rig.log.clear();
    rig.client
        .upload(DOMAIN, UploadMode::Block, rig.now)
        .unwrap();
    rig.run(lossy(Dir::ToClient, &[1, 16, 17, 50, 127]));
    let u = Some(Outcome::Uploaded {
        mux: DOMAIN,
        len: data.len(),
    });
    assert_eq!((rig.client_outcome, rig.server_outcome), (u, u));
    assert_eq!(rig.client.data(), &data[..]);
    let sent = rig.log.iter().filter(|(d, _)| *d == Dir::ToClient).count();
    assert!(sent > 127 + 2, "segments were sent again: {sent}");
}

#[test]
fn lost_last_segment_without_sub_block_timeout_is_a_timeout() {
    let server = SdoConfig {
        block_size: 10,
        sub_block_timeout_ns: None,
        ..SdoConfig::default()
    };
    let mut rig = Rig::new(SdoConfig::default(), server);
    rig.client
        .download(DOMAIN, &pattern(70), DownloadMode::Block, 0)
        .unwrap();
    rig.run(lossy(Dir::ToServer, &[10]));
    assert_eq!(
        rig.client_outcome,
        aborted(DOMAIN, AbortCode::TIMED_OUT, Side::Client)
    );
    assert_eq!(rig.od.writes, 0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Random frames on the SDO COB-IDs, mid-transfer or not: no panic, every outcome
    /// an abort with a Table 22 code or a completed transfer, and the machines recover.
    #[test]
    fn random_frames_never_panic(
        frames in proptest::collection::vec((any::<bool>(), 0usize..=8, any::<[u8; 8]>()), 0..60),
        start in 0u8..6,
    ) {
        let mut client = SdoClient::new(node(), SdoConfig::default(), vec![0u8; 256]).unwrap();
        let mut server = SdoServer::new(node(), SdoConfig::default(), vec![0u8; 256]).unwrap();
        let mut od = dictionary();
        let _ = match start {
            0 => client.download(DOMAIN, &pattern(100), DownloadMode::Block, 0),
            1 => client.download(DOMAIN, &pattern(100), DownloadMode::Segmented, 0),
            2 => client.upload(DOMAIN, UploadMode::Block, 0),
            3 => client.upload(DOMAIN, UploadMode::Normal, 0),
            4 => client.download(U32, &[1, 2, 3, 4], DownloadMode::Auto, 0),
            _ => Ok(()),
        };
        for (t, (to_server, len, bytes)) in frames.iter().enumerate() {
            let t = t as u64 * 1_000_000;
            let id = if *to_server { 0x605 } else { 0x585 };
            let f = CanFrame::new(id, &bytes[..*len]).unwrap();
            let server_side = [server.receive(&f, t, &mut od), server.poll(t)];
            let client_side = [client.receive(&f, t), client.poll(t)];
            // Whatever a peer sends, this side's own aborts carry a Table 22 code.
            for (o, me) in server_side.iter().map(|o| (o, Side::Server)).chain(client_side.iter().map(|o| (o, Side::Client))) {
                if let Some(Outcome::Aborted { code, by, .. }) = o {
                    if *by == me {
                        prop_assert!(code.known_text().is_some(), "{o:?}");
                    }
                }
            }
            while let Some(f) = client.transmit() {
                prop_assert_eq!(f.len(), 8);
                server.receive(&f, t, &mut od);
            }
            while let Some(f) = server.transmit() {
                prop_assert_eq!(f.len(), 8);
                client.receive(&f, t);
            }
        }
        // Both time out or finish: nothing stays busy forever.
        client.poll(u64::MAX / 2);
        server.poll(u64::MAX / 2);
        prop_assert!(client.is_idle() && server.is_idle());
    }

    /// Any length, kind and block sizes over a clean link: the exact bytes, both ways.
    #[test]
    fn random_transfers_round_trip(
        len in 0usize..2000,
        kind in 0u8..3,
        up_block in any::<bool>(),
        client_bs in 1u8..=127,
        server_bs in 1u8..=127,
        crc in any::<(bool, bool)>(),
    ) {
        let c = SdoConfig { block_size: client_bs, crc: crc.0, ..SdoConfig::default() };
        let s = SdoConfig { block_size: server_bs, crc: crc.1, ..SdoConfig::default() };
        let mut rig = Rig::new(c, s);
        let data: Vec<u8> = (0..len).map(|i| (i * 13 + len) as u8).collect();
        let mode = [DownloadMode::Auto, DownloadMode::Segmented, DownloadMode::Block][kind as usize];
        let d = Some(Outcome::Downloaded { mux: DOMAIN, len });
        prop_assert_eq!(rig.download(DOMAIN, &data, mode), (d, d));
        prop_assert_eq!(rig.od.value(0x2000, 0), &data[..]);
        let up = if up_block { UploadMode::Block } else { UploadMode::Normal };
        let u = Some(Outcome::Uploaded { mux: DOMAIN, len });
        prop_assert_eq!(rig.upload(DOMAIN, up), (u, u));
        prop_assert_eq!(rig.client.data(), &data[..]);
    }

    /// Any length and block size through a link that drops random block segments: the
    /// data arrives intact or the transfer times out — never wrong data.
    #[test]
    fn block_transfers_over_a_random_lossy_link(
        len in 0usize..1200,
        block_size in 1u8..=127,
        drops in proptest::collection::vec(any::<bool>(), 0..400),
        upload in any::<bool>(),
    ) {
        let config = SdoConfig { block_size, sub_block_timeout_ns: Some(1_000_000), ..SdoConfig::default() };
        let mut rig = Rig::new(config, config);
        let data = pattern(len);
        rig.download(DOMAIN, &data, DownloadMode::Segmented);
        rig.client_outcome = None;
        rig.server_outcome = None;
        // Drop only block segments (byte 0 = c | seqno), at most one in five.
        let mut k = 0usize;
        let mut dropper = |_: Dir, _: usize, f: CanFrame| {
            let b0 = f.data()[0];
            if b0 & 0x7F != 0 && !matches!(b0, 0xA0..=0xA7 | 0xC0..=0xDF) {
                k += 1;
                if k % 5 == 0 && drops.get(k / 5).copied().unwrap_or(false) {
                    return None;
                }
            }
            Some(f)
        };
        if upload {
            rig.client.upload(DOMAIN, UploadMode::Block, rig.now).unwrap();
        } else {
            rig.od.write(DOMAIN, &[]).unwrap();
            rig.client.download(DOMAIN, &data, DownloadMode::Block, rig.now).unwrap();
        }
        rig.run(&mut dropper);
        match rig.client_outcome {
            Some(Outcome::Uploaded { len: l, .. }) => { prop_assert_eq!(l, len); prop_assert_eq!(rig.client.data(), &data[..]); }
            Some(Outcome::Downloaded { len: l, .. }) => { prop_assert_eq!(l, len); prop_assert_eq!(rig.od.value(0x2000, 0), &data[..]); }
            Some(Outcome::Aborted { code, .. }) => prop_assert_eq!(code, AbortCode::TIMED_OUT),
            None => prop_assert!(false, "no outcome"),
        }
    }
}

/// Runs a block upload of `len` bytes over a link that delays the server's frames from
/// its `stall_from`th on by `stall_ns` (a stalled sender: frames late, none lost; each
/// direction stays in order), returns the client's outcome and data.
fn upload_through_a_stall(
    client: SdoConfig,
    len: usize,
    stall_from: usize,
    stall_ns: u64,
) -> (Option<Outcome>, Vec<u8>) {
    let mut rig = Rig::new(client, SdoConfig::default());
    let data = pattern(len);
    rig.download(DOMAIN, &data, DownloadMode::Segmented);
    rig.client_outcome = None;
    rig.client
        .upload(DOMAIN, UploadMode::Block, rig.now)
        .unwrap();
    let mut to_server = std::collections::VecDeque::new();
    let mut to_client: std::collections::VecDeque<(u64, CanFrame)> = Default::default();
    let mut from_server = 0usize;
    let end = rig.now + 20_000_000_000;
    while rig.now < end {
        while let Some(f) = rig.client.transmit() {
            to_server.push_back(f);
        }
        while let Some(f) = rig.server.transmit() {
            from_server += 1;
            let late = if from_server >= stall_from {
                stall_ns
            } else {
                0
            };
            let after = to_client.back().map_or(0, |(at, _)| *at);
            to_client.push_back(((rig.now + late).max(after), f));
        }
        while let Some(f) = to_server.pop_front() {
            if let Some(o) = rig.server.receive(&f, rig.now, &mut rig.od) {
                rig.server_outcome = Some(o);
            }
        }
        while to_client.front().is_some_and(|(at, _)| *at <= rig.now) {
            let (_, f) = to_client.pop_front().unwrap();
            if let Some(o) = rig.client.receive(&f, rig.now) {
                rig.client_outcome = Some(o);
            }
        }
        if rig.client.is_idle() && to_client.is_empty() && to_server.is_empty() {
            break;
        }
        rig.now += STEP_NS;
        if let Some(o) = rig.client.poll(rig.now) {
            rig.client_outcome = Some(o);
        }
        if let Some(o) = rig.server.poll(rig.now) {
            rig.server_outcome = Some(o);
        }
    }
    (rig.client_outcome, rig.client.data().to_vec())
}

#[test]
fn a_stalled_sub_block_is_waited_for_not_acknowledged_early() {
    // The server stalls 150 ms after its 30th segment of the first sub-block: late, not
    // lost. The default client waits (its timeout is 1 s) and gets every byte.
    let len = 127 * 7 * 2;
    let (outcome, got) = upload_through_a_stall(SdoConfig::default(), len, 30, 150_000_000);
    assert_eq!(outcome, Some(Outcome::Uploaded { mux: DOMAIN, len }));
    assert_eq!(got, pattern(len));
    // An early acknowledgement after 100 ms of silence takes the late segments of the
    // old sub-block for the new one's: the transfer fails. This is why it is off by
    // default.
    let early = SdoConfig {
        sub_block_timeout_ns: Some(100_000_000),
        ..SdoConfig::default()
    };
    let (outcome, got) = upload_through_a_stall(early, len, 30, 150_000_000);
    assert!(
        outcome != Some(Outcome::Uploaded { mux: DOMAIN, len }) || got != pattern(len),
        "{outcome:?}"
    );
}

/// A download of data already in the client's buffer (a buffer lent for the transfer):
/// every mode, the same frames and the same bytes at the server as a copied download.
#[test]
fn a_buffered_download_sends_the_buffer_as_it_is() {
    let modes = [
        DownloadMode::Auto,
        DownloadMode::Segmented,
        DownloadMode::Block,
    ];
    for &len in SIZES {
        for mode in modes {
            let data = pattern(len);
            let mut copied = Rig::default();
            let expected = copied.download(DOMAIN, &data, mode);
            let mut rig = Rig::default();
            rig.client.buffer_mut()[..len].copy_from_slice(&data);
            rig.client
                .download_buffered(DOMAIN, len, mode, rig.now)
                .unwrap();
            rig.run_clean();
            let case = format!("{len} bytes, {mode:?}");
            assert_eq!((rig.client_outcome, rig.server_outcome), expected, "{case}");
            assert_eq!(rig.od.value(DOMAIN.index, DOMAIN.sub), &data[..], "{case}");
            assert_eq!(rig.log, copied.log, "{case}: the same frames");
        }
    }
    // Expedited: 1 to 4 bytes from the buffer; more is refused, as for a copied one.
    let mut rig = Rig::default();
    rig.client.buffer_mut()[..4].copy_from_slice(&[1, 2, 3, 4]);
    rig.client
        .download_buffered(U32, 4, DownloadMode::Expedited, 0)
        .unwrap();
    rig.run_clean();
    assert_eq!(rig.od.value(U32.index, U32.sub), &[1, 2, 3, 4]);
    assert!(matches!(
        rig.client
            .download_buffered(U32, 5, DownloadMode::Expedited, 0),
        Err(SdoClientError::ExpeditedLength { len: 5, .. })
    ));
    assert!(matches!(
        rig.client
            .download_buffered(DOMAIN, 4097, DownloadMode::Block, 0),
        Err(SdoClientError::TooLarge {
            len: 4097,
            capacity: 4096,
            ..
        })
    ));
    // The buffer comes back with the client.
    assert_eq!(rig.client.into_buffer().len(), 4096);
}

/// A block download paced by its caller (a few segments per cycle): the server's silence
/// is timed from the last segment sent, so a sub-block sent over longer than the timeout
/// still completes; without pacing the wait runs from the server's last answer.
#[test]
fn a_paced_block_download_times_the_server_from_its_last_segment() {
    for paced in [true, false] {
        let config = SdoConfig {
            timeout_ns: 1_000_000,
            ..SdoConfig::default()
        };
        let mut rig = Rig::new(config, SdoConfig::default());
        let data = pattern(127 * 7 * 2);
        rig.client
            .download(DOMAIN, &data, DownloadMode::Block, 0)
            .unwrap();
        let mut now = 0u64;
        let (mut segments, mut requests) = (0, 0);
        loop {
            // One frame each 100 µs: a sub-block of 127 takes 12.7 ms, the timeout is 1 ms.
            now += 100_000;
            if let Some(o) = rig.client.poll(now) {
                rig.client_outcome = Some(o);
                break;
            }
            let answers = rig.client.answers_to_next();
            let sent = if paced {
                rig.client.transmit_at(now)
            } else {
                rig.client.transmit()
            };
            if let Some(f) = sent {
                if answers == 0 {
                    segments += 1;
                } else {
                    requests += 1;
                }
                if let Some(o) = rig.server.receive(&f, now, &mut rig.od) {
                    rig.server_outcome = Some(o);
                }
            }
            while let Some(f) = rig.server.transmit() {
                if let Some(o) = rig.client.receive(&f, now) {
                    rig.client_outcome = Some(o);
                }
            }
            if rig.client_outcome.is_some() {
                break;
            }
            assert!(now < 1_000_000_000, "never ended");
        }
        if paced {
            let len = data.len();
            // Answered: the initiate, the two sub-blocks' last segments, the end.
            assert_eq!((segments, requests), (len.div_ceil(7) - 2, 4));
            assert_eq!(
                rig.client_outcome,
                Some(Outcome::Downloaded { mux: DOMAIN, len })
            );
            assert_eq!(rig.od.value(DOMAIN.index, DOMAIN.sub), &data[..]);
        } else {
            assert_eq!(
                rig.client_outcome,
                aborted(DOMAIN, AbortCode::TIMED_OUT, Side::Client)
            );
        }
    }
}

/// A server without block transfer (CiA 301 makes it optional) refuses a block request
/// either way with 0x05040001 and serves the same object the normal way.
#[test]
fn a_server_without_block_transfer_refuses_it_with_0x05040001() {
    let server = SdoConfig {
        block: false,
        ..SdoConfig::default()
    };
    let mut rig = Rig::new(SdoConfig::default(), server);
    let data = pattern(100);
    let refused = aborted(DOMAIN, AbortCode::INVALID_COMMAND_SPECIFIER, Side::Server);
    let (client, _) = rig.download(DOMAIN, &data, DownloadMode::Block);
    assert_eq!(client, refused);
    assert_eq!(
        rig.od.value(DOMAIN.index, DOMAIN.sub),
        &[] as &[u8],
        "nothing written"
    );
    let (client, _) = rig.upload(DOMAIN, UploadMode::Block);
    assert_eq!(client, refused);
    let (client, _) = rig.download(DOMAIN, &data, DownloadMode::Segmented);
    assert_eq!(
        client,
        Some(Outcome::Downloaded {
            mux: DOMAIN,
            len: 100
        })
    );
    let (client, _) = rig.upload(DOMAIN, UploadMode::Normal);
    assert_eq!(
        client,
        Some(Outcome::Uploaded {
            mux: DOMAIN,
            len: 100
        })
    );
    assert_eq!(rig.client.data(), &data[..]);
}

/// What the client says the server will answer to each frame it sends adds up to what
/// the server sent, for every kind and size of transfer both ways.
#[test]
fn the_client_foretells_how_many_frames_the_server_answers() {
    let downloads = [
        DownloadMode::Auto,
        DownloadMode::Segmented,
        DownloadMode::Block,
    ];
    for &len in SIZES {
        for k in 0..5 {
            let mut rig = Rig::new(
                SdoConfig {
                    block_size: 5,
                    pst: if k == 4 { 8 } else { 0 },
                    ..SdoConfig::default()
                },
                SdoConfig {
                    block_size: 7,
                    ..SdoConfig::default()
                },
            );
            let data = pattern(len);
            match downloads.get(k) {
                Some(&mode) => rig.client.download(DOMAIN, &data, mode, 0).unwrap(),
                None => {
                    rig.od.write(DOMAIN, &data).unwrap();
                    let mode = if k == 3 {
                        UploadMode::Normal
                    } else {
                        UploadMode::Block
                    };
                    rig.client.upload(DOMAIN, mode, 0).unwrap();
                }
            }
            let (mut foretold, mut answered) = (0u32, 0u32);
            for _ in 0..10_000 {
                let answers = rig.client.answers_to_next();
                let Some(f) = rig.client.transmit() else {
                    break;
                };
                foretold += u32::from(answers);
                if let Some(o) = rig.server.receive(&f, 0, &mut rig.od) {
                    rig.server_outcome = Some(o);
                }
                while let Some(f) = rig.server.transmit() {
                    answered += 1;
                    if let Some(o) = rig.client.receive(&f, 0) {
                        rig.client_outcome = Some(o);
                    }
                }
            }
            assert!(
                rig.client.is_idle() && rig.server.is_idle(),
                "{len} bytes, case {k}"
            );
            assert!(
                matches!(
                    rig.client_outcome,
                    Some(Outcome::Downloaded { .. } | Outcome::Uploaded { .. })
                ),
                "{len} bytes, case {k}: {:?}",
                rig.client_outcome
            );
            assert_eq!(foretold, answered, "{len} bytes, case {k}");
        }
    }
}
