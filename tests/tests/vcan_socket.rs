//! gantry-link's SocketCAN socket on real vcan interfaces: frames cross between two
//! sockets with a kernel receive stamp on CLOCK_MONOTONIC, a socket never hears itself,
//! `recv_until` keeps its deadline, frames CANopen does not use are skipped, sending and
//! receiving allocate nothing, and each mistake (no interface, interface down, not CAN)
//! gets its error naming the interface.
//!
//! Needs root and vcan (built with `--features vcan`; deploy/test.sh runs it in the VM of
//! deploy/vm/). Without vcan0 it fails.

use std::process::Command;
use std::sync::Mutex;

use gantry_drives::canopen::CanFrame;
use gantry_link::can_socket::{monotonic_ns, CanSocket, CanSocketError};

mod counting {
    include!("../../kernel/tests/common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

const IFACE: &str = "vcan0";

/// The tests share vcan0: one at a time.
static BUS: Mutex<()> = Mutex::new(());

fn open(iface: &str) -> CanSocket {
    CanSocket::open(iface).unwrap_or_else(|e| panic!("{e} — run through deploy/vm/run"))
}

fn ip(args: &[&str]) {
    let status = Command::new("ip").args(args).status().unwrap();
    assert!(status.success(), "ip {args:?}: {status}");
}

/// Linux turns its receive stamping on lazily: the first socket that asks for stamps
/// schedules a work item that enables it, and until it ran a frame is stamped when it is
/// read, not when it came. Waits (1 s at most) until a frame read 20 ms after it was sent
/// carries its arrival time.
fn wait_for_arrival_stamps(a: &CanSocket, b: &CanSocket) {
    let probe = CanFrame::new(0x7E5, &[0]).unwrap();
    for _ in 0..50 {
        a.send(&probe).unwrap();
        let sent = monotonic_ns();
        std::thread::sleep(std::time::Duration::from_millis(20));
        let got = b
            .recv_until(monotonic_ns() + 1_000_000_000)
            .unwrap()
            .expect("probe");
        if got.stamp_ns.is_some_and(|s| s <= sent + 1_000_000) {
            return;
        }
    }
    panic!("frames are still stamped when read, not when they came, after 1 s");
}

#[test]
fn vcan_socket_frames_cross_with_monotonic_stamps_and_not_back_to_the_sender() {
    let _bus = BUS.lock().unwrap_or_else(|e| e.into_inner());
    let (a, b) = (open(IFACE), open(IFACE));
    assert_eq!(a.interface().as_str(), IFACE);
    wait_for_arrival_stamps(&a, &b);
    let frames = [
        CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap(),
        CanFrame::new(0x080, &[]).unwrap(),
        CanFrame::new_remote(0x705, 1).unwrap(),
    ];
    let before = monotonic_ns();
    for f in &frames {
        a.send(f).unwrap();
    }
    let after = monotonic_ns();
    // Read 50 ms later: the stamps still say when the frames came.
    std::thread::sleep(std::time::Duration::from_millis(50));
    for f in &frames {
        let got = b
            .recv_until(monotonic_ns() + 2_000_000_000)
            .unwrap()
            .expect("frame");
        assert_eq!(got.frame, *f);
        let stamp = got.stamp_ns.expect("vcan frames carry a kernel stamp");
        // The stamp is taken on CLOCK_REALTIME and moved: allow 1 ms for the conversion.
        assert!(
            stamp + 1_000_000 >= before && stamp <= after + 1_000_000,
            "stamp {stamp} outside [{before}, {after}]"
        );
    }
    assert_eq!(
        a.try_recv().unwrap(),
        None,
        "a socket does not hear its own frames"
    );
    assert_eq!(b.try_recv().unwrap(), None);
}

#[test]
fn vcan_socket_recv_until_keeps_its_deadline() {
    let _bus = BUS.lock().unwrap_or_else(|e| e.into_inner());
    let s = open(IFACE);
    for wait_ms in [0u64, 20, 100] {
        let deadline = monotonic_ns() + wait_ms * 1_000_000;
        assert_eq!(s.recv_until(deadline).unwrap(), None);
        let now = monotonic_ns();
        assert!(now >= deadline, "returned {} ns early", deadline - now);
    }
}

#[test]
fn vcan_socket_skips_29_bit_frames() {
    let _bus = BUS.lock().unwrap_or_else(|e| e.into_inner());
    let s = open(IFACE);
    // can-utils' cansend: an extended-format frame, then a base-format one.
    for frame in ["12345678#01", "123#02"] {
        let status = Command::new("cansend")
            .args([IFACE, frame])
            .status()
            .unwrap();
        assert!(status.success(), "cansend {frame}: {status}");
    }
    let got = s
        .recv_until(monotonic_ns() + 2_000_000_000)
        .unwrap()
        .expect("frame");
    assert_eq!(got.frame, CanFrame::new(0x123, &[0x02]).unwrap());
    assert_eq!(s.skipped(), 1);
}

#[test]
fn vcan_socket_sends_and_receives_without_allocating() {
    let _bus = BUS.lock().unwrap_or_else(|e| e.into_inner());
    let (a, b) = (open(IFACE), open(IFACE));
    let frame = CanFrame::new(0x181, &[1, 2, 3, 4, 5, 6]).unwrap();
    // The counter counts: one allocation while watching is seen.
    counting::watch(true);
    std::hint::black_box(vec![1u8; 16]);
    counting::watch(false);
    assert_eq!(counting::take_count(), 1, "the counting allocator works");
    let mut received = 0;
    counting::watch(true);
    for _ in 0..1000 {
        a.send(&frame).unwrap();
        if let Ok(Some(r)) = b.recv_until(monotonic_ns() + 1_000_000_000) {
            received += usize::from(r.frame == frame);
        }
        let _ = b.try_recv();
    }
    counting::watch(false);
    assert_eq!(
        counting::take_count(),
        0,
        "allocations while sending and receiving"
    );
    assert_eq!(received, 1000);
}

#[test]
fn vcan_socket_errors_name_the_interface() {
    let _bus = BUS.lock().unwrap_or_else(|e| e.into_inner());
    // A vcan interface of our own, down as it is made.
    let name = "gantry-vcdown";
    let _ = Command::new("ip")
        .args(["link", "del", name])
        .stderr(std::process::Stdio::null())
        .status();
    ip(&["link", "add", "dev", name, "type", "vcan"]);
    let down = CanSocket::open(name).unwrap_err();
    assert!(matches!(down, CanSocketError::Down { .. }), "{down:?}");
    assert_eq!(
        down.to_string(),
        "CAN interface gantry-vcdown is down (`ip link set gantry-vcdown up`)"
    );
    // Up, it opens; taken down under an open socket, sending says so.
    ip(&["link", "set", name, "up"]);
    let s = open(name);
    s.send(&CanFrame::new(0x100, &[1]).unwrap()).unwrap();
    ip(&["link", "set", name, "down"]);
    let e = s.send(&CanFrame::new(0x100, &[1]).unwrap()).unwrap_err();
    assert!(matches!(e, CanSocketError::Down { .. }), "{e:?}");
    ip(&["link", "del", name]);
    let gone = CanSocket::open(name).unwrap_err();
    assert!(
        matches!(gone, CanSocketError::NoInterface { .. }),
        "{gone:?}"
    );
    assert!(
        gone.to_string()
            .contains("no network interface named gantry-vcdown"),
        "{gone}"
    );
    let not_can = CanSocket::open("lo").unwrap_err();
    assert!(
        matches!(not_can, CanSocketError::NotCan { .. }),
        "{not_can:?}"
    );
}
