//! A raw SocketCAN socket (`CAN_RAW`, through the `socketcan` crate) bound to one CAN
//! interface: what gantry's CANopen master sends its NMT, SDO, PDO and SYNC frames on, and
//! what `gantry-sim --can` answers on (a `can`/`vcan` interface; vcan for tests).
//!
//! Non-blocking: [`CanSocket::send`] never waits (a full transmit queue is
//! [`CanSocketError::BufferFull`], for the caller to count as a lost frame, as the cycle
//! counts one on EtherCAT), and [`CanSocket::recv_until`] waits for the next frame at most
//! until a `CLOCK_MONOTONIC` deadline, so the cycle thread reads TPDOs until just before its
//! next deadline. Frames carry the kernel's receive time stamp (`SO_TIMESTAMPNS`) moved to
//! `CLOCK_MONOTONIC`, so a thread that was not scheduled for a while still knows when each
//! frame came. (Linux switches that stamping on lazily, by a work item scheduled when the
//! first socket asks: frames read in the first moments after the first such socket opened
//! may carry the time they were read instead.)
//!
//! Nothing allocates after [`CanSocket::open`]: frames are `Copy` values, errors carry the
//! interface name in a fixed array ([`InterfaceName`]) and OS error codes.
//!
//! The kernel's own loopback (`CAN_RAW_LOOPBACK`, on by default) hands every frame sent on
//! the interface to every other CAN socket on it on this host, which is how two processes
//! (master and simulator) talk over one vcan interface; a socket never receives its own
//! frames (`CAN_RAW_RECV_OWN_MSGS` stays off).

use std::cell::Cell;
use std::fmt;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::time::UNIX_EPOCH;

use gantry_drives::canopen::frame::MAX_STANDARD_ID;
use gantry_drives::canopen::CanFrame;
use socketcan::{EmbeddedFrame, Socket, SocketOptions, StandardId};
use thiserror::Error;

/// `ARPHRD_CAN` (`<linux/if_arp.h>`): the hardware type of every CAN interface (can, vcan,
/// vxcan, slcan).
pub const ARPHRD_CAN: u16 = 280;

/// Longest interface name Linux allows (`IFNAMSIZ` less the terminating NUL).
pub const MAX_INTERFACE_NAME: usize = libc::IFNAMSIZ - 1;

/// An interface name held without allocation, for errors raised on the cycle path.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct InterfaceName {
    bytes: [u8; MAX_INTERFACE_NAME],
    len: u8,
}

impl InterfaceName {
    /// The name, or None if Linux could not have made it (`dev_valid_name`): empty, `.`
    /// or `..`, longer than 15 bytes, or holding a NUL, `/`, `:` or white space.
    pub fn new(name: &str) -> Option<Self> {
        let raw = name.as_bytes();
        if raw.is_empty()
            || name == "."
            || name == ".."
            || raw.len() > MAX_INTERFACE_NAME
            || raw
                .iter()
                .any(|&b| b == 0 || b == b'/' || b == b':' || b.is_ascii_whitespace())
        {
            return None;
        }
        let mut bytes = [0u8; MAX_INTERFACE_NAME];
        for (dst, src) in bytes.iter_mut().zip(raw) {
            *dst = *src;
        }
        Some(Self {
            bytes,
            len: raw.len() as u8,
        })
    }

    /// The name.
    pub fn as_str(&self) -> &str {
        let bytes = self.bytes.get(..usize::from(self.len)).unwrap_or(&[]);
        // Built from a &str cut at its own length: always UTF-8.
        std::str::from_utf8(bytes).unwrap_or("?")
    }

    /// The name as `struct ifreq` wants it (NUL-terminated, `IFNAMSIZ` bytes).
    fn ifr_name(&self) -> [libc::c_char; libc::IFNAMSIZ] {
        let mut out = [0 as libc::c_char; libc::IFNAMSIZ];
        for (dst, src) in out.iter_mut().zip(self.bytes.iter().take(self.len.into())) {
            *dst = *src as libc::c_char;
        }
        out
    }
}

impl fmt::Display for InterfaceName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl fmt::Debug for InterfaceName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

/// Why the socket could not be opened, or a frame not sent or received.
#[derive(Debug, Error)]
pub enum CanSocketError {
    /// The name cannot be an interface name.
    #[error(
        "{name:?} is not a valid network interface name (1 to 15 bytes, no '/', NUL or space)"
    )]
    BadName {
        /// The name given.
        name: String,
    },
    /// No interface of that name (or it went away).
    #[error(
        "no network interface named {interface} (a CAN interface, e.g. \
         `ip link add dev {interface} type vcan && ip link set {interface} up`)"
    )]
    NoInterface {
        /// The interface.
        interface: InterfaceName,
    },
    /// The interface is not a CAN interface.
    #[error(
        "{interface} is not a CAN interface (its hardware type is {hardware_type}, \
         CAN is {ARPHRD_CAN})"
    )]
    NotCan {
        /// The interface.
        interface: InterfaceName,
        /// Its `ARPHRD_*` type.
        hardware_type: u16,
    },
    /// The interface is down.
    #[error("CAN interface {interface} is down (`ip link set {interface} up`)")]
    Down {
        /// The interface.
        interface: InterfaceName,
    },
    /// The kernel has no CAN support (no `can`/`can-raw` modules).
    #[error("CAN interface {interface}: this kernel has no SocketCAN support ({source}; modprobe can-raw)")]
    NoCanSupport {
        /// The interface.
        interface: InterfaceName,
        /// What the kernel said.
        source: io::Error,
    },
    /// The interface's transmit queue is full: the frame was not sent.
    #[error("CAN interface {interface}: transmit queue full, frame 0x{id:03X} not sent")]
    BufferFull {
        /// The interface.
        interface: InterfaceName,
        /// The frame's identifier.
        id: u16,
    },
    /// Any other failure.
    #[error("CAN interface {interface}: {what}: {source}")]
    Io {
        /// The interface.
        interface: InterfaceName,
        /// The call that failed.
        what: &'static str,
        /// Why.
        source: io::Error,
    },
}

/// As an `io::Error` (for a link trait that speaks `io::Result`). The errors of the cycle
/// path — transmit queue full (`ENOBUFS`), interface down (`ENETDOWN`), gone (`ENODEV`),
/// any other OS error — convert without allocating, as their OS error codes (the interface
/// name stays with the socket: [`CanSocket::interface`]); the errors of
/// [`CanSocket::open`] keep their whole message.
impl From<CanSocketError> for io::Error {
    fn from(e: CanSocketError) -> Self {
        match e {
            CanSocketError::BufferFull { .. } => io::Error::from_raw_os_error(libc::ENOBUFS),
            CanSocketError::Down { .. } => io::Error::from_raw_os_error(libc::ENETDOWN),
            CanSocketError::NoInterface { .. } => io::Error::from_raw_os_error(libc::ENODEV),
            CanSocketError::Io { source, .. } => source,
            e @ (CanSocketError::BadName { .. }
            | CanSocketError::NotCan { .. }
            | CanSocketError::NoCanSupport { .. }) => {
                io::Error::new(io::ErrorKind::InvalidInput, e.to_string())
            }
        }
    }
}

/// A frame received, with when it came.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Received {
    /// The frame.
    pub frame: CanFrame,
    /// When the kernel received it, `CLOCK_MONOTONIC` ns (from its `SO_TIMESTAMPNS`
    /// stamp); None when the kernel gave no stamp.
    pub stamp_ns: Option<u64>,
}

/// A raw CAN socket on one interface, non-blocking.
#[derive(Debug)]
pub struct CanSocket {
    socket: socketcan::CanSocket,
    interface: InterfaceName,
    /// Frames skipped because they cannot be CANopen frames (29-bit identifiers).
    skipped: Cell<u64>,
}

/// `CLOCK_MONOTONIC` now, ns (the clock of [`CanSocket::recv_until`]'s deadline).
pub fn monotonic_ns() -> u64 {
    clock_ns(libc::CLOCK_MONOTONIC)
}

fn clock_ns(clock: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec to write to; both clocks always exist on Linux.
    unsafe { libc::clock_gettime(clock, &mut ts) };
    (ts.tv_sec.max(0) as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(ts.tv_nsec.max(0) as u64)
}

impl CanSocket {
    /// Opens a raw CAN socket bound to `interface`, non-blocking, with receive time stamps.
    ///
    /// Checks first that the interface exists, is a CAN interface and is up, so each of
    /// those mistakes gets its own error (the kernel says ENODEV to the first two).
    pub fn open(interface: &str) -> Result<Self, CanSocketError> {
        let name = InterfaceName::new(interface).ok_or_else(|| CanSocketError::BadName {
            name: interface.into(),
        })?;
        let io = |what, source: io::Error| CanSocketError::Io {
            interface: name,
            what,
            source,
        };
        let ifindex = interface_index(&name)?;
        let (hardware_type, flags) = interface_kind(&name)?;
        if hardware_type != ARPHRD_CAN {
            return Err(CanSocketError::NotCan {
                interface: name,
                hardware_type,
            });
        }
        if flags & libc::IFF_UP == 0 {
            return Err(CanSocketError::Down { interface: name });
        }
        let socket = socketcan::CanSocket::open_iface(ifindex).map_err(|source| {
            match source.raw_os_error() {
                Some(libc::EAFNOSUPPORT | libc::EPROTONOSUPPORT) => CanSocketError::NoCanSupport {
                    interface: name,
                    source,
                },
                Some(libc::ENODEV) => CanSocketError::NoInterface { interface: name },
                _ => io("socket/bind", source),
            }
        })?;
        socket
            .set_nonblocking(true)
            .map_err(|e| io("O_NONBLOCK", e))?;
        socket
            .set_recv_timestamp(true)
            .map_err(|e| io("SO_TIMESTAMPNS", e))?;
        Ok(Self {
            socket,
            interface: name,
            skipped: Cell::new(0),
        })
    }

    /// The interface the socket is bound to.
    pub fn interface(&self) -> InterfaceName {
        self.interface
    }

    /// Frames received and skipped so far because they were not base-format (11-bit)
    /// frames, the only ones CANopen's predefined connection set uses.
    pub fn skipped(&self) -> u64 {
        self.skipped.get()
    }

    /// Sends one frame without waiting. A full transmit queue is
    /// [`CanSocketError::BufferFull`]: the frame is lost, nothing is queued for later.
    pub fn send(&self, frame: &CanFrame) -> Result<(), CanSocketError> {
        let wire = to_socketcan(frame);
        self.socket
            .write_frame(&wire)
            .map_err(|source| match source.raw_os_error() {
                Some(libc::ENOBUFS | libc::EAGAIN) => CanSocketError::BufferFull {
                    interface: self.interface,
                    id: frame.id(),
                },
                Some(libc::ENETDOWN) => CanSocketError::Down {
                    interface: self.interface,
                },
                Some(libc::ENODEV | libc::ENXIO) => CanSocketError::NoInterface {
                    interface: self.interface,
                },
                _ => CanSocketError::Io {
                    interface: self.interface,
                    what: "send",
                    source,
                },
            })
    }

    /// The next frame already received, if any; never waits.
    pub fn try_recv(&self) -> Result<Option<Received>, CanSocketError> {
        loop {
            match self.socket.read_frame_with_timestamps() {
                Ok((frame, stamps)) => {
                    if let Some(frame) = from_socketcan(&frame) {
                        let stamp_ns = stamps.socket.map(to_monotonic);
                        return Ok(Some(Received { frame, stamp_ns }));
                    }
                    // A 29-bit or error frame shares the bus; not ours.
                    self.skipped.set(self.skipped.get() + 1);
                }
                Err(e) => {
                    return match e.raw_os_error() {
                        Some(libc::EAGAIN) => Ok(None),
                        Some(libc::EINTR) => continue,
                        Some(libc::ENETDOWN) => Err(CanSocketError::Down {
                            interface: self.interface,
                        }),
                        Some(libc::ENODEV | libc::ENXIO) => Err(CanSocketError::NoInterface {
                            interface: self.interface,
                        }),
                        _ => Err(CanSocketError::Io {
                            interface: self.interface,
                            what: "receive",
                            source: e,
                        }),
                    }
                }
            }
        }
    }

    /// The next frame, waiting for it at most until `deadline_ns` on `CLOCK_MONOTONIC`
    /// (see [`monotonic_ns`]); None when none came by then. A deadline already past
    /// still returns a frame that is waiting.
    pub fn recv_until(&self, deadline_ns: u64) -> Result<Option<Received>, CanSocketError> {
        loop {
            if let Some(received) = self.try_recv()? {
                return Ok(Some(received));
            }
            let now = monotonic_ns();
            if now >= deadline_ns {
                return Ok(None);
            }
            self.wait_readable(deadline_ns - now)?;
        }
    }

    /// Waits up to `ns` for the socket to become readable (or an error to be pending).
    fn wait_readable(&self, ns: u64) -> Result<(), CanSocketError> {
        let mut pfd = libc::pollfd {
            fd: self.socket.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ts = libc::timespec {
            tv_sec: (ns / 1_000_000_000) as libc::time_t,
            tv_nsec: (ns % 1_000_000_000) as libc::c_long,
        };
        // SAFETY: one valid pollfd and a live timespec.
        let n = unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
        if n < 0 {
            let e = io::Error::last_os_error();
            if e.raw_os_error() != Some(libc::EINTR) {
                return Err(CanSocketError::Io {
                    interface: self.interface,
                    what: "poll",
                    source: e,
                });
            }
        }
        Ok(())
    }
}

impl AsRawFd for CanSocket {
    fn as_raw_fd(&self) -> RawFd {
        self.socket.as_raw_fd()
    }
}

/// Our frame on the wire: base format, data or remote.
fn to_socketcan(frame: &CanFrame) -> socketcan::CanFrame {
    // CanFrame's invariants (id ≤ 0x7FF, len ≤ 8) make both constructors succeed; the
    // fallback (a zero-length frame of the same id) is unreachable.
    let id = StandardId::new(frame.id() & MAX_STANDARD_ID).unwrap_or(StandardId::ZERO);
    let made = if frame.is_remote() {
        socketcan::CanFrame::new_remote(id, frame.len())
    } else {
        socketcan::CanFrame::new(id, frame.data())
    };
    made.or_else(|| socketcan::CanFrame::new(id, &[]))
        .unwrap_or_else(|| socketcan::CanFrame::Data(socketcan::CanDataFrame::default()))
}

/// A received frame as ours; None for frames CANopen does not use (29-bit identifiers,
/// error frames).
fn from_socketcan(frame: &socketcan::CanFrame) -> Option<CanFrame> {
    use socketcan::Frame;
    if frame.is_extended() || frame.is_error_frame() {
        return None;
    }
    let id = frame.raw_id();
    if frame.is_remote_frame() {
        CanFrame::new_remote(id, frame.dlc()).ok()
    } else {
        CanFrame::new(id, frame.data()).ok()
    }
}

/// Tries at reading both clocks together (see [`to_monotonic`]).
const CLOCK_PAIR_TRIES: usize = 4;

/// A `CLOCK_REALTIME` kernel stamp moved to `CLOCK_MONOTONIC`: the offset between the
/// clocks is read as a real-time reading bracketed by two monotonic ones, the narrowest
/// bracket of a few tries (a thread preempted between two readings would otherwise shift
/// the result by the time it lost); never later than now.
fn to_monotonic(stamp: std::time::SystemTime) -> u64 {
    let stamp_ns = stamp
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    let mut best: Option<(u64, u64, u64)> = None;
    for _ in 0..CLOCK_PAIR_TRIES {
        let before = monotonic_ns();
        let real = clock_ns(libc::CLOCK_REALTIME);
        let after = monotonic_ns();
        let width = after.saturating_sub(before);
        if best.is_none_or(|(w, _, _)| width < w) {
            best = Some((width, before + width / 2, real));
        }
        if width < 20_000 {
            break;
        }
    }
    let (_, mono, real) = best.unwrap_or((0, monotonic_ns(), clock_ns(libc::CLOCK_REALTIME)));
    mono.saturating_sub(real.saturating_sub(stamp_ns))
}

fn interface_index(name: &InterfaceName) -> Result<u32, CanSocketError> {
    let c = name.ifr_name();
    // SAFETY: `c` is NUL-terminated (IFNAMSIZ bytes, the name at most 15).
    let index = unsafe { libc::if_nametoindex(c.as_ptr()) };
    if index == 0 {
        return Err(CanSocketError::NoInterface { interface: *name });
    }
    Ok(index)
}

/// The interface's hardware type (`SIOCGIFHWADDR`) and flags (`SIOCGIFFLAGS`), asked on
/// a throw-away datagram socket (these ioctls work on any socket, and AF_INET exists where
/// AF_CAN may not).
fn interface_kind(name: &InterfaceName) -> Result<(u16, libc::c_int), CanSocketError> {
    let io = |what| {
        let source = io::Error::last_os_error();
        match source.raw_os_error() {
            Some(libc::ENODEV | libc::ENXIO) => CanSocketError::NoInterface { interface: *name },
            _ => CanSocketError::Io {
                interface: *name,
                what,
                source,
            },
        }
    };
    // SAFETY: plain syscall; the descriptor is owned right after.
    let raw = unsafe { libc::socket(libc::AF_INET, libc::SOCK_DGRAM | libc::SOCK_CLOEXEC, 0) };
    if raw < 0 {
        return Err(io("socket(AF_INET) for interface queries"));
    }
    // SAFETY: `raw` is a fresh descriptor nobody else owns.
    let fd = unsafe { OwnedFd::from_raw_fd(raw) };
    // SAFETY: a zeroed ifreq is valid; the name is NUL-terminated.
    let mut req: libc::ifreq = unsafe { std::mem::zeroed() };
    req.ifr_name = name.ifr_name();
    // SAFETY: SIOCGIFHWADDR fills the ifreq's union with a sockaddr.
    if unsafe { libc::ioctl(fd.as_raw_fd(), libc::SIOCGIFHWADDR, &mut req) } < 0 {
        return Err(io("SIOCGIFHWADDR"));
    }
    // SAFETY: the kernel wrote ifru_hwaddr.
    let hardware_type = unsafe { req.ifr_ifru.ifru_hwaddr.sa_family };
    // SAFETY: SIOCGIFFLAGS fills the ifreq's union with the flags.
    if unsafe { libc::ioctl(fd.as_raw_fd(), libc::SIOCGIFFLAGS, &mut req) } < 0 {
        return Err(io("SIOCGIFFLAGS"));
    }
    // SAFETY: the kernel wrote ifru_flags.
    let flags = libc::c_int::from(unsafe { req.ifr_ifru.ifru_flags });
    Ok((hardware_type, flags))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interface_names_are_checked_like_linux_does() {
        assert_eq!(InterfaceName::new("vcan0").unwrap().as_str(), "vcan0");
        assert_eq!(
            InterfaceName::new("fifteen-bytes-x").unwrap().to_string(),
            "fifteen-bytes-x"
        );
        for bad in [
            "",
            ".",
            "..",
            "sixteen-bytes-xx",
            "a/b",
            "a:1",
            "a b",
            "a\0b",
        ] {
            assert!(InterfaceName::new(bad).is_none(), "{bad:?}");
        }
        let e = CanSocket::open("a/b").unwrap_err().to_string();
        assert!(e.contains("\"a/b\" is not a valid"), "{e}");
    }

    #[test]
    fn a_missing_interface_is_named() {
        let e = CanSocket::open("gantry-nope0").unwrap_err();
        assert!(matches!(e, CanSocketError::NoInterface { .. }), "{e:?}");
        assert!(
            e.to_string()
                .contains("no network interface named gantry-nope0"),
            "{e}"
        );
    }

    #[test]
    fn a_non_can_interface_is_refused_with_its_type() {
        // The loopback interface exists everywhere (ARPHRD_LOOPBACK = 772).
        let e = CanSocket::open("lo").unwrap_err();
        assert!(
            matches!(
                e,
                CanSocketError::NotCan {
                    hardware_type: 772,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("lo is not a CAN interface"), "{e}");
    }

    #[test]
    fn cycle_errors_become_os_errors_and_open_errors_keep_their_text() {
        let vcan0 = InterfaceName::new("vcan0").unwrap();
        let full: io::Error = CanSocketError::BufferFull {
            interface: vcan0,
            id: 0x80,
        }
        .into();
        assert_eq!(full.raw_os_error(), Some(libc::ENOBUFS));
        let down: io::Error = CanSocketError::Down { interface: vcan0 }.into();
        assert_eq!(down.raw_os_error(), Some(libc::ENETDOWN));
        let not_can: io::Error = CanSocketError::NotCan {
            interface: InterfaceName::new("lo").unwrap(),
            hardware_type: 772,
        }
        .into();
        assert_eq!(not_can.kind(), io::ErrorKind::InvalidInput);
        assert!(
            not_can.to_string().contains("lo is not a CAN interface"),
            "{not_can}"
        );
    }

    #[test]
    fn frames_cross_to_socketcan_and_back_unchanged() {
        for frame in [
            CanFrame::new(0x601, &[0x40, 0x00, 0x10, 0x00, 1, 2, 3, 4]).unwrap(),
            CanFrame::new(0x080, &[]).unwrap(),
            CanFrame::new(0x7FF, &[9]).unwrap(),
            CanFrame::new_remote(0x705, 1).unwrap(),
        ] {
            let wire = to_socketcan(&frame);
            assert_eq!(from_socketcan(&wire), Some(frame));
        }
        let extended =
            socketcan::CanFrame::new(socketcan::ExtendedId::new(0x601).unwrap(), &[1, 2]).unwrap();
        assert_eq!(
            from_socketcan(&extended),
            None,
            "29-bit frames are not ours"
        );
    }

    #[test]
    fn kernel_stamps_land_on_the_monotonic_clock() {
        let before = monotonic_ns();
        let stamp = to_monotonic(std::time::SystemTime::now());
        let after = monotonic_ns();
        assert!(
            before <= stamp + 1_000_000 && stamp <= after,
            "{before} {stamp} {after}"
        );
        let old = to_monotonic(std::time::SystemTime::now() - std::time::Duration::from_secs(2));
        assert!(
            old + 1_900_000_000 <= monotonic_ns(),
            "a stamp 2 s old is 2 s back"
        );
    }
}
