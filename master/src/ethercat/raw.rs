//! The real EtherCAT path: ethercrab's frames on a raw socket bound to a network
//! interface (a NIC wired to real slaves, or a veth end with `gantry-sim` on the other).
//! The cycle thread sends and receives on it itself (see `link.rs`).

use std::io;
use std::os::fd::{AsRawFd, BorrowedFd};

use ethercrab::{PduRx, PduTx};
use gantry_link::raw_socket::{RawSocket, RawSocketError};

use super::link::{Capture, FrameIo, Link, LinkStats};
use super::pump::FramePump;

/// A raw socket on an interface, as a link.
pub struct RawLink(RawSocket);

impl RawLink {
    /// Opens `interface` (needs CAP_NET_RAW).
    pub fn open(interface: &str) -> Result<Self, RawSocketError> {
        RawSocket::open(interface).map(Self)
    }
}

impl Link for RawLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.0.send(frame)
    }

    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        self.0.recv(buf, Some(std::time::Duration::ZERO))
    }

    fn readable(&self) -> Option<BorrowedFd<'_>> {
        // SAFETY: the socket lives as long as `self`, and so does the borrow.
        Some(unsafe { BorrowedFd::borrow_raw(self.0.as_raw_fd()) })
    }
}

/// ethercrab's frames on an interface through a pump thread, for tools that drive
/// ethercrab from an ordinary thread with its own executor (`gantry scan`).
pub struct RawBus {
    pump: FramePump,
}

impl RawBus {
    /// Opens `interface` and starts the pump (capturing to `capture` if given).
    pub fn open(
        interface: &str,
        tx: PduTx<'static>,
        rx: PduRx<'static>,
        capture: Option<Capture>,
    ) -> Result<Self, RawSocketError> {
        let link = RawLink::open(interface)?;
        let pump =
            FramePump::start(FrameIo::new(tx, rx, Box::new(link), capture)).map_err(|source| {
                RawSocketError::Io {
                    interface: interface.into(),
                    what: "starting the pump thread",
                    source,
                }
            })?;
        Ok(Self { pump })
    }

    /// Stops the pump; returns what it counted.
    pub fn stop(self) -> LinkStats {
        self.pump.stop()
    }
}
