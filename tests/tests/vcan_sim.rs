//! `gantry-sim --can vcan0` as its own process, driven over vcan0 by gantry's own CANopen
//! pieces — gantry-link's SocketCAN socket, gantry-drives' NMT frames and SDO client — as
//! the master will: NMT and boot-up, every SDO transfer kind both ways, a PDO configured by
//! the CiA 301 procedure and exchanged on SYNC.
//!
//! Needs vcan0 (built with `--features vcan`; deploy/test.sh runs it in the VM of
//! deploy/vm/, or on the host where its kernel has vcan). Without vcan0 it fails.

use std::sync::Mutex;
use std::time::Duration;

use gantry_drives::canopen::cob_id::{CobId, NodeId};
use gantry_drives::canopen::heartbeat::Heartbeat;
use gantry_drives::canopen::nmt::NmtCommand;
use gantry_drives::canopen::sdo::{AbortCode, DownloadMode, Outcome, Side, UploadMode};
use gantry_drives::canopen::sync::Sync;
use gantry_drives::canopen::CanFrame;
use gantry_tests::can::{CanMaster, CanSim};

const IFACE: &str = "vcan0";

/// Two servos, nodes 5 and 6.
const CHAIN: &str = "cycle_us = 1000\n\
    [[slave]]\nkind = \"servo\"\nnode = 5\n\
    [[slave]]\nkind = \"servo\"\nnode = 6\nstart_position = 4000\n";

/// One simulator on vcan0 at a time: two would answer for the same node ids.
static BUS: Mutex<()> = Mutex::new(());

/// Generous: an emulated VM (TCG) runs everything some ten times slower than the host.
const WAIT: Duration = Duration::from_secs(5);

fn node(id: u8) -> NodeId {
    NodeId::new(id).unwrap()
}

/// Starts the simulator and waits for the boot-up messages of both nodes.
fn start(master: &mut CanMaster) -> CanSim {
    let sim = CanSim::start(IFACE, CHAIN);
    let mut booted = Vec::new();
    while booted.len() < 2 {
        let f = master
            .wait_for(WAIT, |f| Heartbeat::parse(f).is_ok_and(|h| h.is_boot_up()))
            .unwrap_or_else(|| panic!("boot-ups seen: {booted:?} of nodes 5 and 6"));
        booted.push(Heartbeat::parse(&f).unwrap().node.get());
    }
    booted.sort();
    assert_eq!(booted, vec![5, 6]);
    sim
}

/// Stops the simulator and checks it ended well, with its summary.
fn stop(sim: CanSim) -> String {
    let (status, text) = sim.stop();
    assert!(status.success(), "gantry-sim ended {status}: {text}");
    assert!(
        text.contains("gantry-sim: CANopen nodes 5, 6 on vcan0"),
        "{text}"
    );
    assert!(text.contains("received "), "{text}");
    text
}

/// The NMT state a node's next heartbeat reports (CiA 301 §7.2.8.3.2.2: 0x04 stopped,
/// 0x05 operational, 0x7F pre-operational).
fn next_heartbeat_state(master: &mut CanMaster, id: u8) -> u8 {
    let hb = master
        .wait_for(WAIT, |f| f.id() == 0x700 + u16::from(id))
        .unwrap_or_else(|| panic!("no heartbeat of node {id}"));
    hb.data()[0]
}

#[test]
fn vcan_sim_boots_and_obeys_nmt() {
    let _bus = BUS.lock().unwrap_or_else(|e| e.into_inner());
    let mut master = CanMaster::open(IFACE);
    let sim = start(&mut master);
    // Heartbeats every 100 ms (0x1017 at power-on) in Pre-operational.
    assert_eq!(next_heartbeat_state(&mut master, 5), 0x7F);
    master.nmt(NmtCommand::Start, node(5));
    // The first heartbeat after the command may have left before it: the one after.
    let _ = next_heartbeat_state(&mut master, 5);
    assert_eq!(next_heartbeat_state(&mut master, 5), 0x05, "operational");
    assert_eq!(
        next_heartbeat_state(&mut master, 6),
        0x7F,
        "node 6 was not addressed"
    );
    master.nmt(NmtCommand::Stop, node(5));
    let _ = next_heartbeat_state(&mut master, 5);
    assert_eq!(next_heartbeat_state(&mut master, 5), 0x04, "stopped");
    // Stopped: no SDO (CiA 301 Table 83); the request is not answered.
    let asked = master.download(
        node(5),
        0x6065,
        0,
        &7u32.to_le_bytes(),
        DownloadMode::Expedited,
    );
    assert!(
        matches!(
            asked,
            Err(Outcome::Aborted {
                code: AbortCode::TIMED_OUT,
                by: Side::Client,
                ..
            })
        ),
        "{asked:?}"
    );
    // Reset node: boot-up of node 5 alone, then Pre-operational again.
    let from = master.seen.len();
    master.nmt(NmtCommand::ResetNode, node(5));
    let boot = master
        .wait_for(WAIT, |f| Heartbeat::parse(f).is_ok_and(|h| h.is_boot_up()))
        .expect("boot-up after reset node");
    assert_eq!(boot.id(), 0x705);
    assert_eq!(boot.data(), &[0x00]);
    assert_eq!(next_heartbeat_state(&mut master, 5), 0x7F);
    let other_boots = master.seen[from..]
        .iter()
        .filter(|r| r.frame.id() == 0x706 && r.frame.data() == [0])
        .count();
    assert_eq!(other_boots, 0, "node 6 did not reset");
    stop(sim);
}

#[test]
fn vcan_sim_sdo_every_transfer_kind() {
    let _bus = BUS.lock().unwrap_or_else(|e| e.into_inner());
    let mut master = CanMaster::open(IFACE);
    let sim = start(&mut master);
    let n6 = node(6);
    // Expedited upload: 0x1000 device type, a CiA 402 servo.
    let device_type = master.upload(n6, 0x1000, 0, UploadMode::Normal).unwrap();
    assert_eq!(device_type, 0x0002_0192u32.to_le_bytes());
    // Segmented upload (the server answers a 24-byte string segmented), then block
    // upload with CRC of the same object.
    let name = b"gantry-sim CiA 402 servo".to_vec();
    assert_eq!(
        master.upload(n6, 0x1008, 0, UploadMode::Normal).unwrap(),
        name
    );
    let segments = master
        .seen
        .iter()
        .filter(|r| r.frame.id() == 0x586 && r.frame.data()[0] & 0xE0 == 0x00)
        .count();
    assert_eq!(segments, 4, "24 bytes in 4 segments of up to 7");
    assert_eq!(
        master.upload(n6, 0x1008, 0, UploadMode::Block).unwrap(),
        name
    );
    // Downloads of every kind to 0x6065 (following error window, UNSIGNED32), each read
    // back.
    for (mode, value) in [
        (DownloadMode::Expedited, 1111u32),
        (DownloadMode::Segmented, 2222),
        (DownloadMode::Block, 3333),
    ] {
        master
            .download(n6, 0x6065, 0, &value.to_le_bytes(), mode)
            .unwrap_or_else(|o| panic!("{mode:?}: {o:?}"));
        let back = master.upload(n6, 0x6065, 0, UploadMode::Normal).unwrap();
        assert_eq!(back, value.to_le_bytes(), "{mode:?}");
    }
    // Node 5 kept its own value: each node has its own dictionary.
    let five = master
        .upload(node(5), 0x6065, 0, UploadMode::Normal)
        .unwrap();
    assert_ne!(five, 3333u32.to_le_bytes());
    // Aborts from the server, with CiA 301 codes: no such object; a read-only object.
    let missing = master.upload(n6, 0x5FFF, 0, UploadMode::Normal);
    assert!(
        matches!(missing, Err(Outcome::Aborted { code, by: Side::Server, .. }) if code == AbortCode::OBJECT_DOES_NOT_EXIST),
        "{missing:?}"
    );
    let read_only = master.download(n6, 0x1000, 0, &[0, 0, 0, 0], DownloadMode::Expedited);
    assert!(
        matches!(read_only, Err(Outcome::Aborted { code, by: Side::Server, .. }) if code == AbortCode::READ_ONLY),
        "{read_only:?}"
    );
    stop(sim);
}

#[test]
fn vcan_sim_pdo_configured_and_exchanged_on_sync() {
    let _bus = BUS.lock().unwrap_or_else(|e| e.into_inner());
    let mut master = CanMaster::open(IFACE);
    let sim = start(&mut master);
    let n5 = node(5);
    // TPDO2 of node 5 by the CiA 301 §7.5.2.37 procedure: invalidate, clear the mapping,
    // map position actual value and statusword, count them, synchronous every SYNC,
    // validate.
    let cob = u32::from(CobId::tpdo(2, n5).unwrap().id());
    master.write(n5, 0x1801, 1, &(cob | 1 << 31).to_le_bytes());
    master.write(n5, 0x1801, 2, &[1]);
    master.write(n5, 0x1A01, 0, &[0]);
    master.write(n5, 0x1A01, 1, &0x6064_0020u32.to_le_bytes());
    master.write(n5, 0x1A01, 2, &0x6041_0010u32.to_le_bytes());
    master.write(n5, 0x1A01, 0, &[2]);
    master.write(n5, 0x1801, 1, &cob.to_le_bytes());
    // Changing a mapping while the PDO is valid is refused (0x08000022 there).
    let refused = master.download(n5, 0x1A01, 0, &[1], DownloadMode::Expedited);
    assert!(
        matches!(refused, Err(Outcome::Aborted { code, by: Side::Server, .. }) if code == AbortCode::CANNOT_STORE_DEVICE_STATE),
        "{refused:?}"
    );
    master.nmt(NmtCommand::Start, n5);
    master.nmt(NmtCommand::Start, node(6));
    // No SYNC, no synchronous TPDO.
    let quiet = master.listen(Duration::from_millis(300));
    assert!(
        !quiet
            .iter()
            .any(|f| (0x185..=0x186).contains(&f.id()) || f.id() == 0x285),
        "synchronous TPDOs without SYNC: {quiet:?}"
    );
    // RPDO1 (controlword, target position) of both nodes, then SYNC: the drives answer
    // with TPDO1 (statusword, position actual) and node 5 with TPDO2 too.
    let cycle = |master: &mut CanMaster, controlword: u16| -> Vec<CanFrame> {
        for (id, target) in [(5u16, 0i32), (6, 4000)] {
            let mut data = [0u8; 6];
            data[..2].copy_from_slice(&controlword.to_le_bytes());
            data[2..].copy_from_slice(&target.to_le_bytes());
            master.send(&CanFrame::new(u32::from(0x200 + id), &data).unwrap());
        }
        master.send(&Sync::new().emit());
        let mut got = Vec::new();
        for _ in 0..3 {
            match master.wait_for(WAIT, |f| [0x185, 0x186, 0x285].contains(&f.id())) {
                Some(f) => got.push(f),
                None => break,
            }
        }
        got.sort_by_key(CanFrame::id);
        got
    };
    let statusword = |f: &CanFrame| u16::from_le_bytes([f.data()[0], f.data()[1]]);
    let first = cycle(&mut master, 0x0000);
    assert_eq!(
        first.iter().map(CanFrame::id).collect::<Vec<_>>(),
        vec![0x185, 0x186, 0x285],
        "{first:?}"
    );
    // TPDO2 carries position actual then statusword: the same values as TPDO1, swapped.
    let (t1, t2) = (&first[0], &first[2]);
    assert_eq!(t2.len(), 6);
    assert_eq!(t2.data()[..4], t1.data()[2..6], "position actual value");
    assert_eq!(t2.data()[4..6], t1.data()[..2], "statusword");
    // Node 6 reports its own start position.
    assert_eq!(first[1].data()[2..6], 4000i32.to_le_bytes());
    // Switch on disabled (xxxx xxxx x1xx 0000, CiA 402 Table 30).
    assert_eq!(statusword(t1) & 0x4F, 0x40, "{t1:?}");
    // Shutdown (0x0006) taken at the SYNC: Ready to switch on (x01x 0001) within a few
    // cycles.
    let mut ready = false;
    for _ in 0..20 {
        let got = cycle(&mut master, 0x0006);
        if got
            .first()
            .is_some_and(|f| f.id() == 0x185 && statusword(f) & 0x6F == 0x21)
        {
            ready = true;
            break;
        }
    }
    assert!(ready, "node 5 never reached Ready to switch on");
    let text = stop(sim);
    assert!(!text.contains("lost 1"), "{text}");
}
