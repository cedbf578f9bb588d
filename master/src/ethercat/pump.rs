//! The frame pump: one thread that takes the frames ethercrab queues (`PduTx`), puts them
//! on a link, and hands the replies back (`PduRx`). The link is a simulated chain in this
//! process or a raw socket on an interface; the pump is the same, so both paths capture
//! to pcap the same way. We run our own pump rather than ethercrab's `tx_rx_task` to get
//! that capture and a plain blocking thread. The pump is started from the cycle thread
//! during bring-up, after that thread became real-time, so it inherits SCHED_FIFO at the
//! cycle's priority (and its CPU mask): a reply is never held up by ordinary threads.

use std::collections::VecDeque;
use std::io;
use std::os::fd::{AsRawFd, BorrowedFd};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Wake, Waker};
use std::thread::JoinHandle;
use std::time::Instant;

use ethercrab::{PduRx, PduTx};
use gantry_sim::chain::SlaveChain;
use gantry_sim::realtime::WallClock;
use gantry_sim::transport::raw_socket::RawSocket;

use super::coalesce::Coalescer;
use super::doorbell::Doorbell;
use crate::pcap::PcapWriter;

/// Where the pump's frames go.
pub enum Link {
    /// A simulated chain in this process: each frame passes it at once.
    Embedded {
        /// The chain (lock it to inspect or change slaves between exchanges).
        chain: Arc<Mutex<SlaveChain>>,
        /// Replies waiting to be handed back.
        replies: VecDeque<Vec<u8>>,
        /// Runs the chain on the wall clock (`None`: the caller advances it, lockstep).
        wall_clock: Option<WallClock>,
    },
    /// A raw socket on a network interface.
    Raw(RawSocket),
}

impl Link {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        match self {
            Link::Embedded {
                chain,
                replies,
                wall_clock,
            } => {
                let mut wire = frame.to_vec();
                let processed = chain
                    .lock()
                    .map(|mut c| {
                        if let Some(clock) = wall_clock {
                            clock.catch_up(&mut c);
                        }
                        c.process(&mut wire).is_ok()
                    })
                    .unwrap_or(false);
                // A frame the chain cannot parse is lost, as on a wire.
                if processed {
                    replies.push_back(wire);
                }
                Ok(())
            }
            Link::Raw(socket) => socket.send(frame),
        }
    }

    /// Nothing to send: a chain on the wall clock still lives on (its applications run,
    /// its timers run, the process-data watchdog trips when the master went silent).
    fn idle(&mut self) {
        if let Link::Embedded {
            chain,
            wall_clock: Some(clock),
            ..
        } = self
        {
            if let Ok(mut c) = chain.lock() {
                clock.catch_up(&mut c);
            }
        }
    }

    /// The next reply into `buf`, if one is waiting (never blocks): its length.
    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        match self {
            Link::Embedded { replies, .. } => Ok(replies.pop_front().map(|r| {
                let n = r.len().min(buf.len());
                if let (Some(dst), Some(src)) = (buf.get_mut(..n), r.get(..n)) {
                    dst.copy_from_slice(src);
                }
                n
            })),
            Link::Raw(socket) => socket.recv(buf, Some(std::time::Duration::ZERO)),
        }
    }

    fn fd(&self) -> Option<BorrowedFd<'_>> {
        match self {
            Link::Embedded { .. } => None,
            // SAFETY: the socket outlives the borrow (both live in the pump thread).
            Link::Raw(socket) => Some(unsafe { BorrowedFd::borrow_raw(socket.as_raw_fd()) }),
        }
    }
}

/// Takes every frame ethercrab queued into `joined`, sending through `send` what is full
/// and a frame that cannot be joined.
fn take_queued(tx: &mut PduTx<'static>, joined: &mut Coalescer, send: &mut impl FnMut(&[u8])) {
    while let Some(frame) = tx.next_sendable_frame() {
        let _ = frame.send_blocking(|bytes| {
            if !joined.push(bytes) {
                if !joined.is_empty() {
                    send(joined.frame());
                    joined.sent();
                }
                if !joined.push(bytes) {
                    send(bytes);
                }
            }
            Ok(bytes.len())
        });
    }
}

/// Name of the pump thread.
pub const PUMP_THREAD: &str = "ethercat-pump";

/// Largest frame we receive (jumbo frames included).
const RECV_BYTES: usize = 9100;

/// What the pump counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PumpStats {
    /// Frames sent on the link.
    pub sent: u64,
    /// Replies handed back to ethercrab.
    pub received: u64,
    /// Link errors (send or receive failed).
    pub errors: u64,
}

/// Holds the pump while the cycle queues the frames of one exchange, so that they go on
/// the wire as one frame (see `coalesce`): the pump takes what is queued but sends nothing
/// until released. Held for one poll of the cycle's futures (microseconds, no lock).
#[derive(Clone)]
pub struct FrameGate {
    /// Odd while held; moves at every hold and release.
    epoch: Arc<AtomicU64>,
    doorbell: Arc<Doorbell>,
}

impl FrameGate {
    /// The frames queued from now on wait for [`FrameGate::release`].
    pub fn hold(&self) {
        self.epoch.fetch_add(1, Ordering::AcqRel);
    }

    /// Sends what was queued since [`FrameGate::hold`], together.
    pub fn release(&self) {
        self.epoch.fetch_add(1, Ordering::AcqRel);
        self.doorbell.wake_by_ref();
    }
}

/// A running pump thread.
pub struct FramePump {
    epoch: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    replies: Arc<AtomicU64>,
    doorbell: Arc<Doorbell>,
    thread: Option<JoinHandle<PumpStats>>,
}

impl FramePump {
    /// Starts the pump on `link`, writing every frame sent and received to `capture`.
    pub fn start(
        mut tx: PduTx<'static>,
        mut rx: PduRx<'static>,
        mut link: Link,
        mut capture: Option<PcapWriter<io::BufWriter<std::fs::File>>>,
    ) -> io::Result<Self> {
        let doorbell = Doorbell::new()?;
        let stop = Arc::new(AtomicBool::new(false));
        let epoch = Arc::new(AtomicU64::new(0));
        let replies = Arc::new(AtomicU64::new(0));
        let (stop_io, bell, replied) = (stop.clone(), doorbell.clone(), replies.clone());
        let epoch_io = epoch.clone();
        let thread = std::thread::Builder::new()
            .name(PUMP_THREAD.into())
            .spawn(move || {
                let waker = Waker::from(bell.clone());
                let started = Instant::now();
                let mut stats = PumpStats::default();
                let mut buf = vec![0u8; RECV_BYTES];
                let mut joined = Coalescer::default();
                let record = |capture: &mut Option<PcapWriter<_>>, at_us: u64, frame: &[u8]| {
                    if let Some(c) = capture.as_mut() {
                        let _ = c.frame(at_us, frame);
                    }
                };
                while !stop_io.load(Ordering::Relaxed) {
                    tx.replace_waker(&waker);
                    {
                        // Sends one frame: on the wire first, the capture after it (a file
                        // write must not delay the frame); stamped with the time it was
                        // sent.
                        let mut send = |bytes: &[u8]| {
                            let at_us = started.elapsed().as_micros() as u64;
                            match link.send(bytes) {
                                Ok(()) => stats.sent += 1,
                                Err(_) => stats.errors += 1,
                            }
                            record(&mut capture, at_us, bytes);
                        };
                        // Every queued frame into one. While the cycle holds the gate
                        // (odd epoch) nothing is sent; a take is complete when no hold or
                        // release happened during it (the epoch did not move): then it saw
                        // all of an exchange's frames or none.
                        loop {
                            let epoch = epoch_io.load(Ordering::Acquire);
                            take_queued(&mut tx, &mut joined, &mut send);
                            if epoch % 2 == 1 {
                                bell.wait(None, Some(std::time::Duration::from_millis(1)));
                                continue;
                            }
                            if epoch_io.load(Ordering::Acquire) == epoch {
                                break;
                            }
                        }
                        if !joined.is_empty() {
                            send(joined.frame());
                            joined.sent();
                        }
                    }
                    loop {
                        match link.recv(&mut buf) {
                            Ok(Some(n)) => {
                                let frame = buf.get(..n).unwrap_or_default();
                                let at_us = started.elapsed().as_micros() as u64;
                                // Counted before ethercrab sees it (and wakes the
                                // cycle), so a cycle that got its reply also sees the
                                // count. Then the reply to ethercrab, then the capture.
                                replied.fetch_add(1, Ordering::Release);
                                joined.split(frame, |part| {
                                    if rx.receive_frame(part).is_ok() {
                                        stats.received += 1;
                                    }
                                });
                                record(&mut capture, at_us, frame);
                            }
                            Ok(None) => break,
                            Err(_) => {
                                stats.errors += 1;
                                break;
                            }
                        }
                    }
                    // Until ethercrab queues a frame, a reply arrives, or 1 ms passes.
                    bell.wait(link.fd(), Some(std::time::Duration::from_millis(1)));
                    link.idle();
                }
                if let Some(c) = capture {
                    let _ = c.finish();
                }
                stats
            })?;
        Ok(Self {
            epoch,
            stop,
            replies,
            doorbell,
            thread: Some(thread),
        })
    }

    /// Frames that came back from the link so far (counted as they come, before
    /// ethercrab sees them: bring-up watches it to tell a silent bus from a slow step).
    pub fn replies(&self) -> Arc<AtomicU64> {
        self.replies.clone()
    }

    /// The gate the cycle holds while it queues one exchange's frames.
    pub fn gate(&self) -> FrameGate {
        FrameGate {
            epoch: self.epoch.clone(),
            doorbell: self.doorbell.clone(),
        }
    }

    /// Stops the thread; returns what it counted.
    pub fn stop(mut self) -> PumpStats {
        self.stop.store(true, Ordering::Relaxed);
        self.doorbell.wake_by_ref();
        self.thread
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default()
    }
}

impl Drop for FramePump {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.doorbell.wake_by_ref();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
