//! The real EtherCAT path: ethercrab's frames on a raw socket bound to a network
//! interface (a NIC wired to real slaves, or a veth end with `gantry-sim` on the other).

use ethercrab::{PduRx, PduTx};
use gantry_sim::transport::raw_socket::{RawSocket, RawSocketError};

use super::pump::{FramePump, Link, PumpStats};
use crate::pcap::PcapWriter;

/// ethercrab's frames on an interface.
pub struct RawBus {
    pump: FramePump,
}

impl RawBus {
    /// Opens `interface` and starts the pump (capturing to `capture` if given).
    pub fn open(
        interface: &str,
        tx: PduTx<'static>,
        rx: PduRx<'static>,
        capture: Option<PcapWriter<std::io::BufWriter<std::fs::File>>>,
    ) -> Result<Self, RawSocketError> {
        let socket = RawSocket::open(interface)?;
        let pump = FramePump::start(tx, rx, Link::Raw(socket), capture).map_err(|source| {
            RawSocketError::Io {
                interface: interface.into(),
                what: "starting the pump thread",
                source,
            }
        })?;
        Ok(Self { pump })
    }

    /// The gate that sends one exchange's frames as one.
    pub fn gate(&self) -> super::pump::FrameGate {
        self.pump.gate()
    }

    /// Replies handed to ethercrab so far.
    pub fn replies(&self) -> std::sync::Arc<std::sync::atomic::AtomicU64> {
        self.pump.replies()
    }

    /// Stops the pump; returns what it counted.
    pub fn stop(self) -> PumpStats {
        self.pump.stop()
    }
}
