//! The embedded EtherCAT bus: ethercrab's frames handed to a simulated slave chain in this
//! process (no network interface, no root). Used by `gantry demo --bus ethercat` and the tests.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use ethercrab::{PduRx, PduTx};
use gantry_sim::chain::SlaveChain;
use gantry_sim::realtime::WallClock;

use super::pump::{FramePump, Link};
use crate::pcap::PcapWriter;

/// ethercrab's frames passed through a simulated chain in this process by a pump thread.
pub struct EmbeddedBus {
    pump: FramePump,
    /// The chain (lock it to inspect or change slave memory between exchanges).
    pub chain: Arc<Mutex<SlaveChain>>,
}

impl EmbeddedBus {
    /// Starts the exchange thread.
    pub fn start(tx: PduTx<'static>, rx: PduRx<'static>, chain: SlaveChain) -> Self {
        Self::start_with_capture(tx, rx, chain, None)
    }

    /// Starts the exchange thread, writing every frame sent and every reply to `capture`.
    ///
    /// # Panics
    /// When the process cannot create an eventfd or a thread (out of resources at start-up).
    pub fn start_with_capture(
        tx: PduTx<'static>,
        rx: PduRx<'static>,
        chain: SlaveChain,
        capture: Option<PcapWriter<std::io::BufWriter<std::fs::File>>>,
    ) -> Self {
        Self::start_with(tx, rx, chain, capture, None)
    }

    /// Starts the exchange thread with the chain on the wall clock: its DC clocks follow
    /// the host's, its applications run every `period` (for real-time runs on the
    /// simulator, e.g. `gantry run`).
    pub fn start_realtime(
        tx: PduTx<'static>,
        rx: PduRx<'static>,
        chain: SlaveChain,
        capture: Option<PcapWriter<std::io::BufWriter<std::fs::File>>>,
        period: std::time::Duration,
    ) -> Self {
        let clock = WallClock::start(&chain, period);
        Self::start_with(tx, rx, chain, capture, Some(clock))
    }

    fn start_with(
        tx: PduTx<'static>,
        rx: PduRx<'static>,
        chain: SlaveChain,
        capture: Option<PcapWriter<std::io::BufWriter<std::fs::File>>>,
        wall_clock: Option<WallClock>,
    ) -> Self {
        let chain = Arc::new(Mutex::new(chain));
        let link = Link::Embedded {
            chain: chain.clone(),
            replies: VecDeque::new(),
            wall_clock,
        };
        let pump = FramePump::start(tx, rx, link, capture)
            .expect("eventfd and a thread for the embedded bus");
        Self { pump, chain }
    }

    /// The gate that sends one exchange's frames as one.
    pub fn gate(&self) -> super::pump::FrameGate {
        self.pump.gate()
    }

    /// Replies handed to ethercrab so far.
    pub fn replies(&self) -> Arc<std::sync::atomic::AtomicU64> {
        self.pump.replies()
    }

    /// Stops the thread; returns how many frames went through the chain.
    pub fn stop(self) -> u64 {
        self.pump.stop().received
    }
}
