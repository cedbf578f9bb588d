//! Links and the frame exchange over them. A [`Link`] moves whole Ethernet frames: a raw
//! socket on an interface (the production path, `raw.rs`), or whatever link the caller
//! plugs in — the `gantry` binary's wire to its in-process simulator, a test's chain —
//! through a [`LinkFactory`], so that this library knows no simulator. A
//! [`FrameIo`] takes the frames ethercrab queued (`PduTx`), sends them on its link and
//! hands the replies back (`PduRx`), capturing both to pcap when asked.
//!
//! The cycle thread owns its `FrameIo` and does this itself, between polls of the
//! exchange it waits for (see `doorbell::BlockOn`): no second thread carries its frames,
//! so the only thread the cycle's timing depends on is its own. A frame pump thread
//! (`pump.rs`) runs the same exchange for harnesses that drive ethercrab from an
//! ordinary thread (lockstep tests, the demo's lockstep bus).

use std::io;
use std::os::fd::BorrowedFd;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use ethercrab::{PduRx, PduTx};

use super::bus::StartError;
use super::coalesce::Coalescer;
use crate::config::Config;
use crate::pcap::PcapWriter;

/// Largest frame a link carries (an Ethernet frame without FCS is at most 1514 bytes;
/// ethercrab's frames here are smaller still).
pub const MAX_FRAME: usize = 1536;

/// Where frames go: whole Ethernet frames out, whole replies back.
pub trait Link: Send {
    /// Puts `frame` on the link.
    fn send(&mut self, frame: &[u8]) -> io::Result<()>;

    /// The next reply into `buf`, if one is waiting (never blocks): its length.
    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>>;

    /// A file that becomes readable when a reply may be waiting (`None`: replies are
    /// there as soon as `send` returns, or the link rings no file).
    fn readable(&self) -> Option<BorrowedFd<'_>>;

    /// Called when nothing was sent or received for a while (a simulated chain on the
    /// wall clock lives on: its timers, its watchdog).
    fn idle(&mut self) {}
}

/// Opens the links of configurations the library cannot open itself: the binary's
/// in-process simulator for `[bus] simulator`, a test's chain. The library opens
/// `[bus] interface` itself and asks its factory for anything else
/// (`EthercatBus::bring_up_from`, `service::run`).
pub trait LinkFactory: Send + Sync {
    /// The link for `config`'s bus, opened in the thread that will run the cycle (a
    /// simulator's thread started here inherits its scheduling and CPU); `None` when the
    /// configuration's bus is not one of this factory's.
    fn open(&self, config: &Config) -> Result<Option<Box<dyn Link>>, StartError>;

    /// The CAN link for a CANopen configuration without `[bus] interface` (the binary's
    /// in-process simulator); `None` when this factory has none.
    fn open_can(
        &self,
        config: &Config,
    ) -> Result<Option<Box<dyn crate::canopen::CanLink>>, crate::canopen::bring_up::StartError>
    {
        let _ = config;
        Ok(None)
    }

    /// The bus on the link this factory opened was shut down and its link closed: report
    /// what there is to report to `out` (the simulated drives' records).
    fn closed(&self, config: &Config, out: &mut (dyn std::io::Write + Send)) {
        let _ = (config, out);
    }
}

/// No links but the library's own: `[bus] interface`.
#[derive(Clone, Copy, Debug, Default)]
pub struct InterfaceOnly;

impl LinkFactory for InterfaceOnly {
    fn open(&self, _: &Config) -> Result<Option<Box<dyn Link>>, StartError> {
        Ok(None)
    }
}

/// A pcap file the frames are written to.
pub type Capture = PcapWriter<io::BufWriter<std::fs::File>>;

/// What an exchange counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames sent on the link.
    pub sent: u64,
    /// Replies handed back to ethercrab.
    pub received: u64,
    /// Link errors (send or receive failed).
    pub errors: u64,
}

/// ethercrab's frames on a link. Made once before the cycle starts; an exchange allocates
/// nothing.
pub struct FrameIo {
    tx: PduTx<'static>,
    rx: PduRx<'static>,
    link: Box<dyn Link>,
    capture: Option<Capture>,
    buf: Box<[u8; MAX_FRAME]>,
    started: Instant,
    stats: LinkStats,
    /// Replies handed back so far, shared with whoever watches the bus for silence.
    replies: Arc<AtomicU64>,
    /// The frames queued since the last exchange, joined into one (see `coalesce`).
    joined: Coalescer,
}

impl FrameIo {
    /// ethercrab's queues on `link`, capturing to `capture` if given.
    pub fn new(
        tx: PduTx<'static>,
        rx: PduRx<'static>,
        link: Box<dyn Link>,
        capture: Option<Capture>,
    ) -> Self {
        Self {
            tx,
            rx,
            link,
            capture,
            buf: Box::new([0; MAX_FRAME]),
            started: Instant::now(),
            stats: LinkStats::default(),
            replies: Arc::new(AtomicU64::new(0)),
            joined: Coalescer::default(),
        }
    }

    /// Sends every frame ethercrab queued — joined into one Ethernet frame as far as they
    /// fit (`coalesce`): the frames one poll of the cycle queued (LRW, AL-status BRD, DC
    /// FRMW) leave as one — then hands back every reply waiting, split into the replies of
    /// the frames joined; whether a reply came (the caller polls its future again at once).
    pub fn exchange(&mut self) -> bool {
        let Self {
            tx,
            rx,
            link,
            capture,
            buf,
            started,
            stats,
            replies,
            joined,
        } = self;
        // The frame goes on the wire first, the capture after it (a file write must not
        // delay the frame); stamped with the time it was sent.
        let mut send = |bytes: &[u8]| {
            let at_us = started.elapsed().as_micros() as u64;
            match link.send(bytes) {
                Ok(()) => stats.sent += 1,
                Err(_) => stats.errors += 1,
            }
            if let Some(c) = capture.as_mut() {
                let _ = c.frame(at_us, bytes);
            }
        };
        while let Some(frame) = tx.next_sendable_frame() {
            let _ = frame.send_blocking(|bytes| {
                if !joined.push(bytes) {
                    // Full, or not one to join: what is waiting goes first.
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
        if !joined.is_empty() {
            send(joined.frame());
            joined.sent();
        }
        let mut got = false;
        loop {
            match link.recv(&mut buf[..]) {
                Ok(Some(n)) => {
                    let frame = buf.get(..n).unwrap_or_default();
                    let at_us = started.elapsed().as_micros() as u64;
                    // Counted before ethercrab sees it (and wakes the waiting future), so
                    // whoever got its reply also sees the count.
                    replies.fetch_add(1, Ordering::Release);
                    joined.split(frame, |part| {
                        if rx.receive_frame(part).is_ok() {
                            stats.received += 1;
                            got = true;
                        }
                    });
                    if let Some(c) = capture.as_mut() {
                        let _ = c.frame(at_us, frame);
                    }
                }
                Ok(None) => break,
                Err(_) => {
                    stats.errors += 1;
                    break;
                }
            }
        }
        got
    }

    /// The link's file to wait on for replies.
    pub fn readable(&self) -> Option<BorrowedFd<'_>> {
        self.link.readable()
    }

    /// Nothing happened for a while: see [`Link::idle`].
    pub fn idle(&mut self) {
        self.link.idle();
    }

    /// Replies handed back so far (shared: bring-up watches it for silence).
    pub fn replies(&self) -> Arc<AtomicU64> {
        self.replies.clone()
    }

    /// Makes ethercrab ring `waker` when it queues a frame (for a pump thread that sleeps
    /// until there is something to send).
    pub fn wake_on_send(&self, waker: &std::task::Waker) {
        self.tx.replace_waker(waker);
    }

    /// What was counted so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Ends the exchange: the capture is flushed, the link closed.
    pub fn finish(self) -> LinkStats {
        if let Some(c) = self.capture {
            let _ = c.finish();
        }
        self.stats
    }
}
