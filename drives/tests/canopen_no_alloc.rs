//! The SDO machines allocate nothing once built: a counting global allocator watches this
//! thread while a client and a server, each on a buffer made before, move 64 KiB by block
//! download and block upload over a link that drops segments (so retransmission runs),
//! and 1 000 expedited and segmented transfers; the NMT, SYNC, heartbeat and EMCY views
//! parse and emit on the same thread.

use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::canopen::heartbeat::{Heartbeat, NmtState};
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::sdo::{
    AbortCode, Access, DownloadMode, EntryInfo, Multiplexer, ObjectDictionary, ObjectSize, Outcome,
    SdoClient, SdoConfig, SdoServer, UploadMode,
};
use gantry_drives::canopen::sync::Sync;
use gantry_drives::canopen::{CanFrame, NodeId};

mod counting {
    include!("../../kernel/tests/common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

const SIZE: usize = 64 * 1024;
const DOMAIN: Multiplexer = Multiplexer::new(0x2000, 0);
const U32: Multiplexer = Multiplexer::new(0x2001, 0);

/// One 64 KiB domain and one UNSIGNED32, in fixed storage.
struct Od {
    domain: Box<[u8]>,
    domain_len: usize,
    u32: [u8; 4],
}

impl ObjectDictionary for Od {
    fn entry(&self, mux: Multiplexer) -> Result<EntryInfo, AbortCode> {
        match mux {
            DOMAIN => Ok(EntryInfo {
                access: Access::ReadWrite,
                size: ObjectSize::Variable { max: SIZE },
            }),
            U32 => Ok(EntryInfo {
                access: Access::ReadWrite,
                size: ObjectSize::Fixed(4),
            }),
            _ => Err(AbortCode::OBJECT_DOES_NOT_EXIST),
        }
    }

    fn read(&mut self, mux: Multiplexer, out: &mut [u8]) -> Result<usize, AbortCode> {
        let src = match mux {
            DOMAIN => &self.domain[..self.domain_len],
            _ => &self.u32[..],
        };
        out.get_mut(..src.len())
            .ok_or(AbortCode::OUT_OF_MEMORY)?
            .copy_from_slice(src);
        Ok(src.len())
    }

    fn write(&mut self, mux: Multiplexer, data: &[u8]) -> Result<(), AbortCode> {
        match mux {
            DOMAIN => {
                self.domain[..data.len()].copy_from_slice(data);
                self.domain_len = data.len();
            }
            _ => self.u32.copy_from_slice(data),
        }
        Ok(())
    }
}

/// Whether a lossy link drops this frame: every 97th frame sent, if it is a block
/// segment before the last (byte 0 = sequence number 1..=127, `c` clear; every other SDO
/// frame of a block transfer has bit 7 set). CiA 301 recovers lost segments, not lost
/// initiate, acknowledge or end frames (those end in a timeout).
fn dropped(lossy: bool, n: u32, f: &CanFrame) -> bool {
    lossy && n % 97 == 0 && f.data().first().is_some_and(|b| *b < 0x80)
}

/// Runs one transfer to its end in lockstep over a link that drops segments if `lossy`;
/// returns the client's outcome.
fn run(
    client: &mut SdoClient<Box<[u8]>>,
    server: &mut SdoServer<Box<[u8]>>,
    od: &mut Od,
    now: &mut u64,
    lossy: bool,
) -> (Option<Outcome>, u32) {
    let mut outcome = None;
    let mut n = 0u32;
    let mut drops = 0u32;
    for _ in 0..1_000_000 {
        let mut moved = false;
        while let Some(f) = client.transmit() {
            moved = true;
            n += 1;
            if dropped(lossy, n, &f) {
                drops += 1;
            } else {
                server.receive(&f, *now, od);
            }
        }
        while let Some(f) = server.transmit() {
            moved = true;
            n += 1;
            if dropped(lossy, n, &f) {
                drops += 1;
            } else if let Some(o) = client.receive(&f, *now) {
                outcome = Some(o);
            }
        }
        if !moved && client.is_idle() && server.is_idle() {
            break;
        }
        *now += 100_000;
        if let Some(o) = client.poll(*now) {
            outcome = Some(o);
        }
        server.poll(*now);
    }
    (outcome, drops)
}

#[test]
fn sdo_transfers_and_views_do_not_allocate() {
    let node = NodeId::new(9).unwrap();
    let config = SdoConfig {
        sub_block_timeout_ns: Some(1_000_000),
        ..SdoConfig::default()
    };
    let mut client = SdoClient::new(node, config, vec![0u8; SIZE].into_boxed_slice()).unwrap();
    let mut server = SdoServer::new(node, config, vec![0u8; SIZE].into_boxed_slice()).unwrap();
    let mut od = Od {
        domain: vec![0u8; SIZE].into_boxed_slice(),
        domain_len: 0,
        u32: [0; 4],
    };
    let data: Box<[u8]> = (0..SIZE).map(|i| (i * 31 + 7) as u8).collect();
    let mut now = 0u64;

    counting::watch(true);
    client
        .download(DOMAIN, &data, DownloadMode::Block, now)
        .unwrap();
    let (down, down_dropped) = run(&mut client, &mut server, &mut od, &mut now, true);
    client.upload(DOMAIN, UploadMode::Block, now).unwrap();
    let (up, up_dropped) = run(&mut client, &mut server, &mut od, &mut now, true);
    let uploaded_intact = client.data() == &data[..];
    let mut small = 0;
    for i in 0..1_000u32 {
        let mode = if i % 2 == 0 {
            DownloadMode::Expedited
        } else {
            DownloadMode::Segmented
        };
        client.download(U32, &i.to_le_bytes(), mode, now).unwrap();
        if let (Some(Outcome::Downloaded { .. }), _) =
            run(&mut client, &mut server, &mut od, &mut now, false)
        {
            small += 1;
        }
    }
    let node_frames = [
        NmtFrame {
            command: NmtCommand::Start,
            target: NmtTarget::All,
        }
        .emit(),
        Heartbeat::new(node, NmtState::Operational).emit(),
        Sync::with_counter(7).unwrap().emit(),
        Emergency {
            node,
            error_code: 0x8611,
            error_register: 0x21,
            manufacturer: [0; 5],
        }
        .emit(),
    ];
    let parsed = NmtFrame::parse(&node_frames[0]).is_ok()
        && Heartbeat::parse(&node_frames[1]).is_ok()
        && Sync::parse(&node_frames[2]).is_ok()
        && Emergency::parse(&node_frames[3]).is_ok()
        && CanFrame::new(0x80, &[1]).is_ok();
    counting::watch(false);

    assert_eq!(counting::take_count(), 0, "allocations in the SDO machines");
    assert_eq!(
        down,
        Some(Outcome::Downloaded {
            mux: DOMAIN,
            len: SIZE
        })
    );
    assert_eq!(
        up,
        Some(Outcome::Uploaded {
            mux: DOMAIN,
            len: SIZE
        })
    );
    assert!(uploaded_intact, "block upload returned other bytes");
    assert!(
        od.domain[..] == data[..],
        "block download wrote other bytes"
    );
    assert!(
        client.data().is_empty(),
        "a download clears the last upload"
    );
    assert_eq!(small, 1_000);
    assert_eq!(od.u32, 999u32.to_le_bytes());
    assert!(parsed);
    // The link did drop segments, so retransmission ran, both ways.
    assert!(
        down_dropped > 10 && up_dropped > 10,
        "{down_dropped} {up_dropped}"
    );
}
