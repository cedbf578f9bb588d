//! The CANopen bus on a SocketCAN interface: gantry-link's raw CAN socket behind the
//! bus' [`CanLink`]. Its receive stamps are CLOCK_MONOTONIC, the cycle's clock.

use std::io;

use gantry_drives::canopen::CanFrame;
use gantry_link::can_socket::{CanSocket, CanSocketError};

use super::link::{CanLink, Received};

/// A raw CAN socket as the bus' link.
#[derive(Debug)]
pub struct SocketLink(CanSocket);

impl SocketLink {
    /// Opens `interface` (non-blocking; errors name the interface and what to do).
    pub fn open(interface: &str) -> Result<Self, CanSocketError> {
        CanSocket::open(interface).map(Self)
    }
}

/// The socket's error as an I/O error of its kind, made without allocating (the cycle
/// thread sends and receives: an interface gone mid-run fails every call). The opening
/// error ([`SocketLink::open`]) carries the full text.
fn io_error(e: CanSocketError) -> io::Error {
    match e {
        CanSocketError::BufferFull { .. } => io::ErrorKind::WouldBlock.into(),
        CanSocketError::NoInterface { .. } => io::ErrorKind::NotFound.into(),
        CanSocketError::Down { .. } => io::ErrorKind::NetworkDown.into(),
        CanSocketError::Io { source, .. } | CanSocketError::NoCanSupport { source, .. } => source,
        _ => io::ErrorKind::Other.into(),
    }
}

impl CanLink for SocketLink {
    fn send(&mut self, frame: &CanFrame) -> io::Result<()> {
        self.0.send(frame).map_err(io_error)
    }

    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>> {
        Ok(self
            .0
            .recv_until(deadline_ns)
            .map_err(io_error)?
            .map(|r| Received {
                frame: r.frame,
                at_ns: r.stamp_ns,
            }))
    }
}
