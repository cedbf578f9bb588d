//! What the CANopen bus talks through: send a CAN frame, receive the next one. A SocketCAN
//! socket (`gantry-link`) is one; an in-memory bus of simulated nodes (the tests' lockstep
//! link) is another. Kept small so that an adapter is a few lines.

use std::io;

use gantry_drives::canopen::CanFrame;

/// A received frame, with when it arrived if the link knows (a socket's receive
/// timestamp, the in-memory bus' time its last bit was on the wire).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Received {
    /// The frame.
    pub frame: CanFrame,
    /// Receive time on the link's clock ([`CanLink::now_ns`]), when known.
    pub at_ns: Option<u64>,
}

/// A CAN link. Every method may run in the cycle thread: an implementation does not
/// allocate or take a lock another thread may hold while the cycle runs.
pub trait CanLink: Send {
    /// Queues `frame` for sending without blocking (a full transmit queue is an error,
    /// e.g. `ENOBUFS` on SocketCAN).
    fn send(&mut self, frame: &CanFrame) -> io::Result<()>;

    /// The next received frame, waiting for it until `deadline_ns` on the link's clock at
    /// most; `None` if none came by then (a deadline already past: only what is waiting).
    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>>;

    /// The link's clock (ns): CLOCK_MONOTONIC, the cycle's clock, unless the link runs on
    /// a clock of its own (a lockstep bus' simulated time). The bus times heartbeats, SDO
    /// answers and its restores on it, and bring-up sets its deadlines by it.
    fn now_ns(&self) -> u64 {
        crate::runtime::clock::now_ns()
    }
}

impl<L: CanLink + ?Sized> CanLink for Box<L> {
    fn send(&mut self, frame: &CanFrame) -> io::Result<()> {
        (**self).send(frame)
    }

    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>> {
        (**self).receive(deadline_ns)
    }

    fn now_ns(&self) -> u64 {
        (**self).now_ns()
    }
}
