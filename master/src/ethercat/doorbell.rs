//! A doorbell: an eventfd that a waker rings and one thread sleeps on. The cycle thread
//! sleeps on one (and on its link's file) until its frame's reply is in; a pump thread
//! until ethercrab queues a frame. A parker (what `futures_lite::block_on` uses) waits on
//! a mutex and condition variable; the doorbell takes no lock, so the only thing the
//! real-time cycle waits for is the bus, and a test can prove it never enters a futex.

use std::cell::RefCell;
use std::future::Future;
use std::io;
use std::os::fd::{AsFd, BorrowedFd};
use std::pin::pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll, Wake, Waker};
use std::time::Duration;

use nix::poll::{ppoll, PollFd, PollFlags};
use nix::sys::eventfd::{EfdFlags, EventFd};
use nix::sys::time::TimeSpec;

use super::link::{FrameIo, LinkStats};
use crate::runtime::clock::now_ns;

/// An eventfd that wakers ring.
#[derive(Debug)]
pub struct Doorbell(EventFd);

impl Doorbell {
    /// A new doorbell (non-blocking, closed on exec).
    pub fn new() -> io::Result<Arc<Self>> {
        Ok(Arc::new(Self(EventFd::from_flags(
            EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC,
        )?)))
    }

    /// Sleeps until the bell rings or `also` (another file, e.g. a socket) is readable,
    /// at most `timeout` (`None`: no limit); then clears the bell.
    pub fn wait(&self, also: Option<BorrowedFd<'_>>, timeout: Option<Duration>) {
        let mut fds = [
            PollFd::new(self.0.as_fd(), PollFlags::POLLIN),
            PollFd::new(also.unwrap_or(self.0.as_fd()), PollFlags::POLLIN),
        ];
        let _ = ppoll(&mut fds, timeout.map(TimeSpec::from_duration), None);
        let _ = self.0.read();
    }
}

impl Wake for Doorbell {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        let _ = self.0.write(1);
    }
}

/// Runs futures to completion on the calling thread, sleeping on a doorbell in between.
/// With a [`FrameIo`] it also does the frame exchange itself: after each poll it sends
/// what ethercrab queued and hands back the replies that came, and it sleeps on the
/// doorbell and the link's file together. Made once before the cycle starts: running a
/// future allocates nothing.
pub struct BlockOn {
    bell: Arc<Doorbell>,
    waker: Waker,
    io: RefCell<Option<FrameIo>>,
}

impl std::fmt::Debug for BlockOn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BlockOn")
            .field("bell", &self.bell)
            .field("exchanges_frames", &self.io.borrow().is_some())
            .finish()
    }
}

impl BlockOn {
    /// A runner with its own doorbell; another thread carries the frames.
    pub fn new() -> io::Result<Self> {
        let bell = Doorbell::new()?;
        Ok(Self {
            waker: Waker::from(bell.clone()),
            bell,
            io: RefCell::new(None),
        })
    }

    /// A runner that exchanges the frames on `io` itself.
    pub fn with_io(io: FrameIo) -> io::Result<Self> {
        let runner = Self::new()?;
        *runner.io.borrow_mut() = Some(io);
        Ok(runner)
    }

    /// Ends the exchange (see [`FrameIo::finish`]); what it counted.
    pub fn finish_io(&self) -> Option<LinkStats> {
        self.io.borrow_mut().take().map(FrameIo::finish)
    }

    /// Sends what ethercrab queued and hands back the replies waiting: whether one came
    /// (then the future is polled again at once).
    fn exchange(&self) -> bool {
        self.io.borrow_mut().as_mut().is_some_and(FrameIo::exchange)
    }

    /// Sleeps until the bell rings, a reply may be in, or `timeout` passed.
    fn sleep(&self, timeout: Option<Duration>) {
        let io = self.io.borrow();
        self.bell
            .wait(io.as_ref().and_then(FrameIo::readable), timeout);
    }

    /// Polls `future` until it is ready. ethercrab's futures end by themselves (their
    /// timeouts wake the bell too), so this returns once the reply or the timeout is in.
    pub fn run<F: Future>(&self, future: F) -> F::Output {
        let mut future = pin!(future);
        let mut cx = Context::from_waker(&self.waker);
        loop {
            if let Poll::Ready(out) = future.as_mut().poll(&mut cx) {
                return out;
            }
            if !self.exchange() {
                self.sleep(None);
            }
        }
    }

    /// Polls `future` until it is ready or CLOCK_MONOTONIC reaches `deadline_ns`; then it
    /// is dropped, which for ethercrab's frames is its own timeout (the frame is released
    /// and a late reply ignored). The cycle waits for its reply no longer than its period.
    pub fn run_until<F: Future>(&self, future: F, deadline_ns: u64) -> Option<F::Output> {
        let mut future = pin!(future);
        let mut cx = Context::from_waker(&self.waker);
        loop {
            if let Poll::Ready(out) = future.as_mut().poll(&mut cx) {
                return Some(out);
            }
            if self.exchange() {
                continue;
            }
            let left = deadline_ns.checked_sub(now_ns()).filter(|&ns| ns > 0)?;
            self.sleep(Some(Duration::from_nanos(left)));
        }
    }
}

impl BlockOn {
    /// Polls `a` and, if given, `b` side by side until both are ready or CLOCK_MONOTONIC
    /// reaches `deadline_ns`; returns what finished (an unfinished future is dropped, see
    /// [`BlockOn::run_until`]). The cycle's process data and a recovery's register access
    /// share one deadline this way, and one finishing does not wait for the other.
    pub fn run_both_until<A: Future, B: Future>(
        &self,
        a: A,
        b: Option<B>,
        deadline_ns: u64,
    ) -> (Option<A::Output>, Option<B::Output>) {
        let mut a = pin!(a);
        let mut b = pin!(b);
        let mut cx = Context::from_waker(&self.waker);
        let (mut out_a, mut out_b) = (None, None);
        loop {
            if out_a.is_none() {
                if let Poll::Ready(out) = a.as_mut().poll(&mut cx) {
                    out_a = Some(out);
                }
            }
            if let (None, Some(b)) = (&out_b, b.as_mut().as_pin_mut()) {
                if let Poll::Ready(out) = b.poll(&mut cx) {
                    out_b = Some(out);
                }
            }
            let b_done = out_b.is_some() || b.is_none();
            if out_a.is_some() && b_done {
                return (out_a, out_b);
            }
            if self.exchange() {
                continue;
            }
            let Some(left) = deadline_ns.checked_sub(now_ns()).filter(|&ns| ns > 0) else {
                return (out_a, out_b);
            };
            self.sleep(Some(Duration::from_nanos(left)));
        }
    }
}

/// Why a bring-up step ([`BlockOn::run_step`]) gave up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StepStalled {
    /// Frames were in flight and no reply came for this long: nothing answers.
    #[error("no reply for {ms} ms (is a slave connected and powered?)")]
    Silent {
        /// The silence (ms).
        ms: u64,
    },
    /// Replies kept coming but the step did not finish in time.
    #[error("not finished within {s} s")]
    TooLong {
        /// The step's limit (s).
        s: u64,
    },
}

impl BlockOn {
    /// Runs a step of the bring-up (many frames): gives up when `replies` (the pump's count
    /// of replies handed to ethercrab) stands still for `silence_ns` — ethercrab's futures
    /// only wait for frames, so that is a frame nobody answered, ethercrab's PDU timeout
    /// done here — or when the whole step takes longer than `limit_ns`.
    ///
    /// The future is made by `make` here and kept on the heap: ethercrab's bring-up
    /// futures are large (hundreds of kB in debug builds), and made in the caller's frame
    /// each step would stay on the stack for the whole bring-up. A step runs once,
    /// outside the cycle.
    #[inline(never)]
    pub fn run_step<F: Future>(
        &self,
        make: impl FnOnce() -> F,
        replies: &AtomicU64,
        silence_ns: u64,
        limit_ns: u64,
    ) -> Result<F::Output, StepStalled> {
        let mut future = Box::pin(make());
        let mut cx = Context::from_waker(&self.waker);
        let start = now_ns();
        let (mut seen, mut quiet_since) = (replies.load(Ordering::Acquire), start);
        loop {
            if let Poll::Ready(out) = future.as_mut().poll(&mut cx) {
                return Ok(out);
            }
            let now = now_ns();
            let count = replies.load(Ordering::Acquire);
            if count != seen {
                (seen, quiet_since) = (count, now);
            }
            let (silent_at, end_at) = (quiet_since + silence_ns, start + limit_ns);
            if now >= end_at {
                return Err(StepStalled::TooLong {
                    s: limit_ns / 1_000_000_000,
                });
            }
            if now >= silent_at {
                return Err(StepStalled::Silent {
                    ms: silence_ns / 1_000_000,
                });
            }
            if self.exchange() {
                continue;
            }
            let left = silent_at.min(end_at) - now;
            self.sleep(Some(Duration::from_nanos(left)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_future_woken_from_another_thread_completes() {
        let runner = BlockOn::new().unwrap();
        let (tx, rx) = one_shot();
        let sender = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            tx.send(7).unwrap();
        });
        assert_eq!(runner.run(rx), 7);
        sender.join().unwrap();
    }

    #[test]
    fn a_future_that_never_ends_is_dropped_at_the_deadline() {
        let runner = BlockOn::new().unwrap();
        let start = now_ns();
        let (_tx, rx) = one_shot();
        assert_eq!(runner.run_until(rx, start + 5_000_000), None);
        let waited = now_ns() - start;
        assert!(waited >= 5_000_000, "waited {waited} ns");
        let (tx, rx) = one_shot();
        tx.send(3).unwrap();
        assert_eq!(
            runner.run_until(rx, start),
            Some(3),
            "ready before the deadline"
        );
    }

    #[test]
    fn a_step_gives_up_on_silence_and_on_its_limit() {
        let runner = BlockOn::new().unwrap();
        let replies = AtomicU64::new(0);
        let (_tx, rx) = one_shot();
        assert_eq!(
            runner.run_step(|| rx, &replies, 5_000_000, 1_000_000_000),
            Err(StepStalled::Silent { ms: 5 })
        );
        // Replies keep coming (another thread counts them), the step never ends.
        let replies = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let (r, s) = (replies.clone(), stop.clone());
        let counter = std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                r.fetch_add(1, Ordering::Release);
                std::thread::sleep(Duration::from_millis(1));
            }
        });
        let (_tx, rx) = one_shot();
        let start = now_ns();
        assert_eq!(
            runner.run_step(|| rx, &replies, 200_000_000, 1_000_000_000),
            Err(StepStalled::TooLong { s: 1 })
        );
        assert!(now_ns() - start >= 1_000_000_000);
        stop.store(true, Ordering::Relaxed);
        counter.join().unwrap();
        let (tx, rx) = one_shot();
        tx.send(4).unwrap();
        assert_eq!(runner.run_step(|| rx, &replies, 1, 1), Ok(4));
    }

    #[test]
    fn two_futures_share_a_deadline_and_keep_what_finished() {
        let runner = BlockOn::new().unwrap();
        let (tx, a) = one_shot();
        let (_never, b) = one_shot();
        tx.send(1).unwrap();
        let start = now_ns();
        assert_eq!(
            runner.run_both_until(a, Some(b), start + 3_000_000),
            (Some(1), None),
            "the first is kept though the second never came"
        );
        let (tx, a) = one_shot();
        let (ty, b) = one_shot();
        tx.send(1).unwrap();
        ty.send(2).unwrap();
        assert_eq!(runner.run_both_until(a, Some(b), 0), (Some(1), Some(2)));
        let (tx, a) = one_shot();
        tx.send(5).unwrap();
        assert_eq!(
            runner.run_both_until(a, None::<OneShot>, 0),
            (Some(5), None)
        );
    }

    /// A one-shot value with a waker, enough to test the runner without a bus.
    fn one_shot() -> (OneShotTx, OneShot) {
        let shared = Arc::new(std::sync::Mutex::new((None, None::<Waker>)));
        (OneShotTx(shared.clone()), OneShot(shared))
    }

    type Slot = Arc<std::sync::Mutex<(Option<u32>, Option<Waker>)>>;
    struct OneShotTx(Slot);
    struct OneShot(Slot);

    impl OneShotTx {
        fn send(self, v: u32) -> Result<(), ()> {
            let mut s = self.0.lock().map_err(|_| ())?;
            s.0 = Some(v);
            if let Some(w) = s.1.take() {
                w.wake();
            }
            Ok(())
        }
    }

    impl Future for OneShot {
        type Output = u32;
        fn poll(self: std::pin::Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<u32> {
            let mut s = self.0.lock().unwrap();
            match s.0.take() {
                Some(v) => Poll::Ready(v),
                None => {
                    s.1 = Some(cx.waker().clone());
                    Poll::Pending
                }
            }
        }
    }
}
