//! An `AF_PACKET` raw socket bound to one interface for the EtherCAT EtherType: what the
//! simulator listens on (one end of a veth pair), and what gantry's master sends on.
//! Needs `CAP_NET_RAW`, not root.

use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::time::Duration;

use thiserror::Error;

/// The EtherType of EtherCAT frames (ETG.1000.4 §5.3.1: an Ethernet II frame of type 0x88A4): the
/// only frames the socket receives.
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;

/// `PACKET_IGNORE_OUTGOING` (Linux ≥ 4.20): do not hand our own frames back to us.
const PACKET_IGNORE_OUTGOING: libc::c_int = 23;

/// Why the socket could not be opened.
#[derive(Debug, Error)]
pub enum RawSocketError {
    /// No interface of that name.
    #[error("no network interface named {0:?}")]
    NoInterface(String),
    /// The process lacks `CAP_NET_RAW`.
    #[error(
        "opening a raw socket on {0} needs CAP_NET_RAW: run as root or grant it \
         (setcap cap_net_raw,cap_net_admin+ep on the binary)"
    )]
    Permission(String),
    /// Any other failure.
    #[error("raw socket on {interface}: {what}: {source}")]
    Io {
        /// The interface.
        interface: String,
        /// The call that failed.
        what: &'static str,
        /// Why.
        source: io::Error,
    },
}

/// A raw socket for EtherCAT frames on one interface.
#[derive(Debug)]
pub struct RawSocket {
    fd: OwnedFd,
}

impl RawSocket {
    /// Opens and binds the socket on `interface`.
    pub fn open(interface: &str) -> Result<Self, RawSocketError> {
        let io = |what| {
            let source = io::Error::last_os_error();
            if source.kind() == io::ErrorKind::PermissionDenied {
                RawSocketError::Permission(interface.into())
            } else {
                RawSocketError::Io {
                    interface: interface.into(),
                    what,
                    source,
                }
            }
        };
        let name =
            CString::new(interface).map_err(|_| RawSocketError::NoInterface(interface.into()))?;
        // SAFETY: `name` is a valid NUL-terminated string.
        let ifindex = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if ifindex == 0 {
            return Err(RawSocketError::NoInterface(interface.into()));
        }
        let protocol = ETHERTYPE_ETHERCAT.to_be();
        // SAFETY: plain syscall; the descriptor is owned right after.
        let raw = unsafe {
            libc::socket(
                libc::AF_PACKET,
                libc::SOCK_RAW | libc::SOCK_CLOEXEC,
                libc::c_int::from(protocol),
            )
        };
        if raw < 0 {
            return Err(io("socket"));
        }
        // SAFETY: `raw` is a fresh descriptor nobody else owns.
        let fd = unsafe { OwnedFd::from_raw_fd(raw) };
        let address = libc::sockaddr_ll {
            sll_family: libc::AF_PACKET as u16,
            sll_protocol: protocol,
            sll_ifindex: ifindex as i32,
            sll_hatype: 0,
            sll_pkttype: 0,
            sll_halen: 0,
            sll_addr: [0; 8],
        };
        // SAFETY: `address` is a valid sockaddr_ll of the size given.
        let bound = unsafe {
            libc::bind(
                fd.as_raw_fd(),
                (&address as *const libc::sockaddr_ll).cast(),
                std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        };
        if bound < 0 {
            return Err(io("bind"));
        }
        let one: libc::c_int = 1;
        // SAFETY: option value is a c_int of the size given. Old kernels lack the option;
        // then our own frames come back and are filtered by the caller.
        unsafe {
            libc::setsockopt(
                fd.as_raw_fd(),
                libc::SOL_PACKET,
                PACKET_IGNORE_OUTGOING,
                (&one as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            );
        }
        Ok(Self { fd })
    }

    /// Sends one whole Ethernet frame.
    pub fn send(&self, frame: &[u8]) -> io::Result<()> {
        // SAFETY: `frame` is valid for reads of its length.
        let n = unsafe { libc::send(self.fd.as_raw_fd(), frame.as_ptr().cast(), frame.len(), 0) };
        match n {
            n if n < 0 => Err(io::Error::last_os_error()),
            n if n as usize != frame.len() => Err(io::Error::new(
                io::ErrorKind::WriteZero,
                format!("sent {n} of {} bytes", frame.len()),
            )),
            _ => Ok(()),
        }
    }

    /// Waits up to `timeout` (`None`: forever) for a frame and receives it into `buf`;
    /// `Ok(None)` when none came. A frame longer than `buf` is truncated to it.
    pub fn recv(&self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<Option<usize>> {
        if !self.wait_readable(timeout)? {
            return Ok(None);
        }
        // SAFETY: `buf` is valid for writes of its length.
        let n = unsafe {
            libc::recv(
                self.fd.as_raw_fd(),
                buf.as_mut_ptr().cast(),
                buf.len(),
                libc::MSG_DONTWAIT,
            )
        };
        if n < 0 {
            let e = io::Error::last_os_error();
            return match e.kind() {
                io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted => Ok(None),
                _ => Err(e),
            };
        }
        Ok(Some(n as usize))
    }

    /// Asks the kernel to stamp every received frame with its arrival time
    /// (`SO_TIMESTAMPNS`, CLOCK_REALTIME), for [`RawSocket::recv_stamped`].
    pub fn stamp_arrivals(&self) -> io::Result<()> {
        let one: libc::c_int = 1;
        // SAFETY: option value is a c_int of the size given.
        let r = unsafe {
            libc::setsockopt(
                self.fd.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_TIMESTAMPNS,
                (&one as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if r < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    }

    /// As [`RawSocket::recv`], with how long ago the frame arrived (from its kernel time
    /// stamp, see [`RawSocket::stamp_arrivals`]; zero when it has none). A process that
    /// was not scheduled for a while finds frames that waited: their age says when they
    /// really came.
    pub fn recv_stamped(
        &self,
        buf: &mut [u8],
        timeout: Option<Duration>,
    ) -> io::Result<Option<(usize, Duration)>> {
        if !self.wait_readable(timeout)? {
            return Ok(None);
        }
        let mut iov = libc::iovec {
            iov_base: buf.as_mut_ptr().cast(),
            iov_len: buf.len(),
        };
        // Room for one SCM_TIMESTAMPNS control message (a timespec), aligned for cmsghdr.
        let mut control = [0u64; 8];
        // SAFETY: a zeroed msghdr is valid; the pointers set below outlive the call.
        let mut msg: libc::msghdr = unsafe { std::mem::zeroed() };
        msg.msg_iov = &mut iov;
        msg.msg_iovlen = 1;
        msg.msg_control = control.as_mut_ptr().cast();
        msg.msg_controllen = std::mem::size_of_val(&control);
        // SAFETY: msg points to a valid buffer and control area of the sizes given.
        let n = unsafe { libc::recvmsg(self.fd.as_raw_fd(), &mut msg, libc::MSG_DONTWAIT) };
        if n < 0 {
            let e = io::Error::last_os_error();
            return match e.kind() {
                io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted => Ok(None),
                _ => Err(e),
            };
        }
        let mut age = Duration::ZERO;
        // SAFETY: the CMSG macros walk the control area the kernel filled in, within
        // msg_controllen; the timespec is read unaligned.
        unsafe {
            let mut c = libc::CMSG_FIRSTHDR(&msg);
            while !c.is_null() {
                if (*c).cmsg_level == libc::SOL_SOCKET && (*c).cmsg_type == libc::SCM_TIMESTAMPNS {
                    let ts: libc::timespec =
                        std::ptr::read_unaligned(libc::CMSG_DATA(c).cast::<libc::timespec>());
                    let at = Duration::new(
                        ts.tv_sec.max(0) as u64,
                        ts.tv_nsec.clamp(0, 999_999_999) as u32,
                    );
                    let now = std::time::SystemTime::now()
                        .duration_since(std::time::UNIX_EPOCH)
                        .unwrap_or_default();
                    age = now.saturating_sub(at);
                }
                c = libc::CMSG_NXTHDR(&msg, c);
            }
        }
        Ok(Some((n as usize, age)))
    }

    fn wait_readable(&self, timeout: Option<Duration>) -> io::Result<bool> {
        let mut pfd = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ts = timeout.map(|t| libc::timespec {
            tv_sec: t.as_secs() as libc::time_t,
            tv_nsec: t.subsec_nanos() as libc::c_long,
        });
        let ts_ptr = ts
            .as_ref()
            .map_or(std::ptr::null(), |t| t as *const libc::timespec);
        // SAFETY: one valid pollfd; ts_ptr is null or points to a live timespec.
        let n = unsafe { libc::ppoll(&mut pfd, 1, ts_ptr, std::ptr::null()) };
        if n < 0 {
            let e = io::Error::last_os_error();
            return if e.kind() == io::ErrorKind::Interrupted {
                Ok(false)
            } else {
                Err(e)
            };
        }
        Ok(n > 0 && pfd.revents & libc::POLLIN != 0)
    }
}

impl AsRawFd for RawSocket {
    fn as_raw_fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }
}
