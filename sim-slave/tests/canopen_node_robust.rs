//! The CANopen node sans-I/O: nothing allocates after construction (a counting global
//! allocator over a CSP cycle with SDO in between), any frame in any NMT state is taken
//! without a panic, and the bus delivers in arbitration order, the same frames to all.

mod canopen_common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use canopen_common::*;
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::sdo::command::ClientCommand;
use gantry_drives::canopen::sdo::{Initiate, Multiplexer};
use gantry_drives::canopen::sync::Sync;
use gantry_drives::canopen::CanFrame;
use gantry_sim::canopen::bus::Sender;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use proptest::prelude::*;

struct Counting;

thread_local! {
    /// Allocations of this thread (the test harness runs the other tests beside it).
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

fn count() {
    // `try_with`: the thread's slot may be gone while the thread ends.
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn nmt(command: NmtCommand) -> CanFrame {
    NmtFrame {
        command,
        target: NmtTarget::All,
    }
    .emit()
}

#[test]
fn no_allocation_after_construction() {
    let mut node = CanNode::new(CanNodeConfig::servo(id(8))).unwrap();
    let rpdo = |cw: u16, t: i32| {
        let mut d = [0u8; 6];
        d[..2].copy_from_slice(&cw.to_le_bytes());
        d[2..].copy_from_slice(&t.to_le_bytes());
        frame(0x208, &d)
    };
    let read = frame(
        0x608,
        &ClientCommand::InitiateUpload {
            mux: Multiplexer::new(0x6064, 0),
        }
        .emit(),
    );
    let write = frame(
        0x608,
        &ClientCommand::InitiateDownload {
            mux: Multiplexer::new(0x6065, 0),
            payload: Initiate::expedited(&5000u32.to_le_bytes()).unwrap(),
        }
        .emit(),
    );
    let before = allocations();
    let mut t = 0;
    let mut frames = 0usize;
    frames += node.tick(t).len();
    frames += node.receive(&nmt(NmtCommand::Start), t).len();
    let mut sw = 0u16;
    let mut pos = 0i32;
    for k in 0..2000u64 {
        t += MS;
        frames += node.tick(t).len();
        let cw = match sw & 0x6F {
            0x21 => 0x07,
            0x23 | 0x27 => 0x0F,
            _ => 0x06,
        };
        let target = if sw & 0x6F == 0x27 {
            pos.wrapping_add(50)
        } else {
            pos
        };
        frames += node.receive(&rpdo(cw, target), t).len();
        let out = node.receive(&Sync::new().emit(), t);
        frames += out.len();
        if let Some(f) = out.iter().find(|f| f.id() == 0x188) {
            let b = f.data();
            sw = u16::from_le_bytes([b[0], b[1]]);
            pos = i32::from_le_bytes([b[2], b[3], b[4], b[5]]);
        }
        if k % 100 == 0 {
            frames += node.receive(&read, t).len();
            frames += node.receive(&write, t).len();
        }
    }
    frames += node.receive(&nmt(NmtCommand::ResetNode), t).len();
    let after = allocations();
    assert_eq!(after - before, 0, "allocations in 2000 cycles");
    // 2000 TPDOs, 40 SDO answers, heartbeats, boot-ups.
    assert!(frames >= 2040, "{frames} frames");
    assert_eq!(node.servo().unwrap().record().sync_missed, 0);
    assert!(node.servo().unwrap().record().targets > 1900);
    assert_eq!(node.servo().unwrap().record().faults, 0);
}

fn any_frame() -> impl Strategy<Value = CanFrame> {
    (
        prop_oneof![
            Just(0u32),
            Just(0x80),
            Just(0x208),
            Just(0x608),
            Just(0x701),
            0u32..0x800
        ],
        proptest::collection::vec(any::<u8>(), 0..=8),
        any::<bool>(),
    )
        .prop_map(|(id, data, rtr)| {
            if rtr {
                CanFrame::new_remote(id, data.len()).unwrap()
            } else {
                CanFrame::new(id, &data).unwrap()
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn any_frames_in_any_state_never_panic_and_sdo_still_answers(
        frames in proptest::collection::vec(any_frame(), 1..200),
    ) {
        let mut node = CanNode::new(CanNodeConfig::servo(id(8))).unwrap();
        let mut t = 0;
        node.tick(t);
        for f in &frames {
            t += 100_000;
            let _ = node.receive(f, t);
            let _ = node.tick(t);
        }
        // Whatever state it was left in: to pre-operational, let a pending SDO transfer
        // time out, and the node answers an upload of 0x1000.
        node.receive(&nmt(NmtCommand::EnterPreOperational), t);
        t += 2_000_000_000;
        node.tick(t);
        let req = frame(0x608, &ClientCommand::InitiateUpload { mux: Multiplexer::new(0x1000, 0) }.emit());
        let out = node.receive(&req, t).to_vec();
        prop_assert!(out.iter().any(|f| f.id() == 0x588 && f.data()[4..8] == 0x0002_0192u32.to_le_bytes()), "{out:?}");
    }
}

#[test]
fn bus_arbitrates_by_id_and_delivers_the_same_frames_to_every_node() {
    let mut m = Master::new(&[3, 2, 4]);
    m.step(0);
    m.nmt(NmtCommand::Start, None);
    m.take_inbox();
    let sync = m.sync_frame();
    let got = m.send(&[sync]);
    // All three answer the SYNC with TPDO1 at once: the lowest identifier goes first,
    // whatever the order the nodes sit on the bus.
    let ids: Vec<u16> = got.iter().map(|d| d.frame.id()).collect();
    assert_eq!(ids, vec![0x182, 0x183, 0x184]);
    assert_eq!(got[0].from, Sender::Node(1));
    for i in 0..3 {
        assert_eq!(m.node(i).counters().syncs, 1, "node {i} got the SYNC");
    }
    // A master frame queued after another leaves after it even with a lower id (a
    // sender's frames keep their order): the RPDO 0x203, then the SYNC 0x080.
    m.bus.send(frame(0x203, &[0x06, 0, 0, 0, 0, 0]));
    let sync = m.sync_frame();
    m.bus.send(sync);
    m.step(0);
    let log: Vec<u16> = m
        .bus
        .log()
        .iter()
        .rev()
        .take(5)
        .map(|d| d.frame.id())
        .collect();
    assert_eq!(log, vec![0x184, 0x183, 0x182, 0x080, 0x203]);
    assert_eq!(m.node(0).counters().rpdos, 1);
}
