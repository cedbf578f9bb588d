//! The embedded EtherCAT bus: ethercrab's frames handed to a simulated slave chain in this
//! process (no network interface, no root). Used by `gantry demo --bus ethercat` and the tests.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Wake, Waker};
use std::thread::{JoinHandle, Thread};
use std::time::Duration;

use ethercrab::{PduRx, PduTx};
use gantry_sim::chain::SlaveChain;

use crate::pcap::PcapWriter;

struct Unpark(Thread);

impl Wake for Unpark {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }
}

/// ethercrab's frames handed to a simulated chain in this process: a thread takes every
/// frame ethercrab sends, passes it through the chain and hands the reply back (only after
/// `send_blocking` has returned, as ethercrab requires).
pub struct EmbeddedBus {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<u64>>,
    /// The chain (lock it to inspect or change slave memory between exchanges).
    pub chain: Arc<Mutex<SlaveChain>>,
}

impl EmbeddedBus {
    /// Starts the exchange thread.
    pub fn start(tx: PduTx<'static>, rx: PduRx<'static>, chain: SlaveChain) -> Self {
        Self::start_with_capture(tx, rx, chain, None)
    }

    /// Starts the exchange thread, writing every frame sent and every reply to `capture`.
    pub fn start_with_capture(
        mut tx: PduTx<'static>,
        mut rx: PduRx<'static>,
        chain: SlaveChain,
        mut capture: Option<PcapWriter<std::io::BufWriter<std::fs::File>>>,
    ) -> Self {
        let started = std::time::Instant::now();
        let chain = Arc::new(Mutex::new(chain));
        let stop = Arc::new(AtomicBool::new(false));
        let (stop_io, chain_io) = (stop.clone(), chain.clone());
        let thread = std::thread::spawn(move || {
            let waker = Waker::from(Arc::new(Unpark(std::thread::current())));
            let mut frames = 0u64;
            while !stop_io.load(Ordering::Relaxed) {
                tx.replace_waker(&waker);
                let mut sent = false;
                while let Some(frame) = tx.next_sendable_frame() {
                    let mut wire = Vec::new();
                    let ok = frame.send_blocking(|bytes| {
                        wire.extend_from_slice(bytes);
                        Ok(bytes.len())
                    });
                    if ok.is_err() {
                        continue;
                    }
                    let t = started.elapsed().as_micros() as u64;
                    if let Some(c) = capture.as_mut() {
                        let _ = c.frame(t, &wire);
                    }
                    let processed = chain_io
                        .lock()
                        .map(|mut c| c.process(&mut wire).is_ok())
                        .unwrap_or(false);
                    if processed {
                        if let Some(c) = capture.as_mut() {
                            let _ = c.frame(t, &wire);
                        }
                        let _ = rx.receive_frame(&wire);
                        frames += 1;
                    }
                    sent = true;
                }
                if !sent {
                    std::thread::park_timeout(Duration::from_millis(1));
                }
            }
            if let Some(c) = capture {
                let _ = c.finish();
            }
            frames
        });
        Self {
            stop,
            thread: Some(thread),
            chain,
        }
    }

    /// Stops the thread; returns how many frames went through the chain.
    pub fn stop(mut self) -> u64 {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().and_then(|t| t.join().ok()).unwrap_or(0)
    }
}
