//! The embedded EtherCAT bus: ethercrab's frames handed to a simulated slave chain in this
//! process (no network interface, no root).
//!
//! Two links reach a chain: [`ChainLink`] passes each frame through the chain in the
//! thread that sends it (a pump thread's, for the lockstep harnesses and the demo's
//! lockstep bus: [`EmbeddedBus`]); [`SimWire`] is a wire to a thread of the simulator's
//! own (`gantry run` with `[bus] simulator`): the cycle thread sends on it as it sends on a
//! raw socket, and the chain — a device on the other end, locked by whoever inspects it —
//! never runs in the cycle thread.

use std::collections::VecDeque;
use std::io;
use std::os::fd::{AsFd, BorrowedFd};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::Wake;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ethercrab::{PduRx, PduTx};
use gantry_sim::chain::SlaveChain;
use gantry_sim::realtime::WallClock;
use nix::sys::eventfd::{EfdFlags, EventFd};

use gantry::ethercat::doorbell::Doorbell;
use gantry::ethercat::link::{Capture, FrameIo, Link, MAX_FRAME};
use gantry::ethercat::pump::FramePump;

/// A simulated chain as a link: each frame passes it in the sending thread.
pub struct ChainLink {
    /// The chain (lock it to inspect or change slaves between exchanges).
    pub chain: Arc<Mutex<SlaveChain>>,
    /// Replies waiting to be handed back.
    replies: VecDeque<Vec<u8>>,
    /// Runs the chain on the wall clock (`None`: the caller advances it, lockstep).
    wall_clock: Option<HostTime>,
}

impl ChainLink {
    /// A link to `chain` whose time follows the host's until `time` is stopped; from then
    /// on whoever holds the chain advances it ([`SlaveChain::run_until`]): lockstep.
    pub fn new(chain: Arc<Mutex<SlaveChain>>, time: HostTime) -> Self {
        Self {
            chain,
            replies: VecDeque::new(),
            wall_clock: Some(time),
        }
    }
}

/// A chain's time on the host's clock until [`HostTime::stop`]: a bring-up needs time to
/// pass (the slaves' state changes take their firmware time), a lockstep test then steps
/// the chain one cycle at a time, so that no stall of the host is ever a stall of the bus.
#[derive(Clone, Debug)]
pub struct HostTime {
    clock: WallClock,
    on: Arc<AtomicBool>,
}

impl HostTime {
    /// Time follows the host's from now on, from where `chain` is; the applications run
    /// every `period`.
    pub fn start(chain: &SlaveChain, period: Duration) -> Self {
        Self {
            clock: WallClock::start(chain, period),
            on: Arc::new(AtomicBool::new(true)),
        }
    }

    /// From now on the chain's time stands still but for its holder's steps.
    pub fn stop(&self) {
        self.on.store(false, Ordering::Release);
    }

    fn catch_up(&self, chain: &mut SlaveChain) {
        if self.on.load(Ordering::Acquire) {
            self.clock.catch_up(chain);
        }
    }
}

impl Link for ChainLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        let mut wire = frame.to_vec();
        let processed = self
            .chain
            .lock()
            .map(|mut c| {
                if let Some(time) = &self.wall_clock {
                    time.catch_up(&mut c);
                }
                c.process(&mut wire).is_ok()
            })
            .unwrap_or(false);
        // A frame the chain cannot parse is lost, as on a wire.
        if processed {
            self.replies.push_back(wire);
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        Ok(self.replies.pop_front().map(|r| copy_frame(&r, buf)))
    }

    fn readable(&self) -> Option<BorrowedFd<'_>> {
        None
    }

    fn idle(&mut self) {
        if let (Some(time), Ok(mut c)) = (&self.wall_clock, self.chain.lock()) {
            time.catch_up(&mut c);
        }
    }
}

/// Copies `frame` into `buf` (truncated to it); the length copied.
fn copy_frame(frame: &[u8], buf: &mut [u8]) -> usize {
    let n = frame.len().min(buf.len());
    if let (Some(dst), Some(src)) = (buf.get_mut(..n), frame.get(..n)) {
        dst.copy_from_slice(src);
    }
    n
}

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
        capture: Option<Capture>,
    ) -> Self {
        let chain = Arc::new(Mutex::new(chain));
        let link = ChainLink {
            chain: chain.clone(),
            replies: VecDeque::new(),
            wall_clock: None,
        };
        let pump = FramePump::start(FrameIo::new(tx, rx, Box::new(link), capture))
            .expect("eventfd and a thread for the embedded bus");
        Self { pump, chain }
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

/// Name of the simulator's thread behind a [`SimWire`].
pub const SIM_THREAD: &str = "gantry-sim";

/// Frames in flight each way on a [`SimWire`] (ethercrab has at most 16 frames).
const WIRE_FRAMES: usize = 16;

/// One frame on a [`SimWire`] (fixed size: the queues allocate once), with the time it
/// went on the wire: a real slave controller latches a frame's arrival in hardware, so the
/// simulated chain takes it at that time and not when its thread got round to it.
#[derive(Clone, Copy)]
struct WireFrame {
    len: usize,
    data: [u8; MAX_FRAME],
    sent: Instant,
}

impl WireFrame {
    fn of(frame: &[u8]) -> Self {
        let mut w = Self {
            len: 0,
            data: [0; MAX_FRAME],
            sent: Instant::now(),
        };
        w.len = copy_frame(frame, &mut w.data);
        w
    }

    fn bytes(&self) -> &[u8] {
        self.data.get(..self.len).unwrap_or_default()
    }
}

/// The master's end of a wire to a simulated chain served by a thread of its own, on the
/// wall clock: frames go over wait-free queues, each way with an eventfd rung after the
/// frame is in. Sending and receiving allocate nothing and take no lock.
pub struct SimWire {
    to_sim: rtrb::Producer<WireFrame>,
    from_sim: rtrb::Consumer<WireFrame>,
    /// Rung by the master after a frame is queued.
    sim_bell: Arc<Doorbell>,
    /// Rung by the simulator after a reply is queued.
    replied: Arc<EventFd>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl SimWire {
    /// Starts the simulator's thread on `chain`, its time tied to the host's with the
    /// applications every `period`. The thread inherits the caller's scheduling and CPU
    /// (gantry starts it from the real-time cycle thread: the simulated drives answer as
    /// promptly as the cycle asks).
    pub fn start(chain: Arc<Mutex<SlaveChain>>, period: Duration) -> io::Result<Self> {
        let (to_sim, mut frames) = rtrb::RingBuffer::<WireFrame>::new(WIRE_FRAMES);
        let (mut replies, from_sim) = rtrb::RingBuffer::<WireFrame>::new(WIRE_FRAMES);
        let sim_bell = Doorbell::new()?;
        let replied = Arc::new(EventFd::from_flags(
            EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC,
        )?);
        let stop = Arc::new(AtomicBool::new(false));
        let clock = chain
            .lock()
            .map(|c| WallClock::start(&c, period))
            .map_err(|_| io::Error::other("the simulated chain's lock is poisoned"))?;
        let (bell, ring, stopping) = (sim_bell.clone(), replied.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name(SIM_THREAD.into())
            .spawn(move || {
                let mut wire = [0u8; MAX_FRAME];
                while !stopping.load(Ordering::Relaxed) {
                    if let Ok(mut c) = chain.lock() {
                        while let Ok(f) = frames.pop() {
                            // The SYNC0 edges and the reference clock as the frame met
                            // them: the drives judge the master's timing, not this
                            // thread's wake-up.
                            clock.catch_up_to_arrival(&mut c, f.sent.elapsed());
                            let n = copy_frame(f.bytes(), &mut wire);
                            let frame = wire.get_mut(..n).unwrap_or_default();
                            // A frame the chain cannot parse is lost, as on a wire; so is
                            // a reply with no room (the master stopped reading).
                            if c.process(frame).is_ok()
                                && replies.push(WireFrame::of(frame)).is_ok()
                            {
                                let _ = ring.write(1);
                            }
                        }
                        // Idle, time goes on: the devices' timers and watchdogs.
                        clock.catch_up(&mut c);
                    }
                    // Until a frame comes, or the next application period starts.
                    let until = chain
                        .lock()
                        .map(|c| clock.until_next_period(&c))
                        .unwrap_or(period);
                    bell.wait(None, Some(until.min(period)));
                }
            })?;
        Ok(Self {
            to_sim,
            from_sim,
            sim_bell,
            replied,
            stop,
            thread: Some(thread),
        })
    }
}

impl Link for SimWire {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.to_sim
            .push(WireFrame::of(frame))
            .map_err(|_| io::Error::from(io::ErrorKind::WouldBlock))?;
        self.sim_bell.wake_by_ref();
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        if let Ok(f) = self.from_sim.pop() {
            return Ok(Some(copy_frame(f.bytes(), buf)));
        }
        // Cleared before looking again: a reply queued after this look rings anew.
        let _ = self.replied.read();
        Ok(self.from_sim.pop().ok().map(|f| copy_frame(f.bytes(), buf)))
    }

    fn readable(&self) -> Option<BorrowedFd<'_>> {
        Some(self.replied.as_fd())
    }
}

impl Drop for SimWire {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.sim_bell.wake_by_ref();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
