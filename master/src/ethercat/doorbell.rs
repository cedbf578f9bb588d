//! A doorbell: an eventfd that a waker rings and one thread sleeps on. The pump sleeps on
//! one until ethercrab queues a frame; the cycle thread on another until its frame's reply
//! is in. A parker (what `futures_lite::block_on` uses) waits on a mutex and condition
//! variable; the doorbell takes no lock, so the only thing the real-time cycle waits for is
//! the bus, and a test can prove it never enters a futex.

use std::future::Future;
use std::io;
use std::os::fd::{AsFd, BorrowedFd};
use std::pin::pin;
use std::sync::Arc;
use std::task::{Context, Poll, Wake, Waker};
use std::time::Duration;

use nix::poll::{ppoll, PollFd, PollFlags};
use nix::sys::eventfd::{EfdFlags, EventFd};
use nix::sys::time::TimeSpec;

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
/// Made once before the cycle starts: running a future allocates nothing.
#[derive(Debug)]
pub struct BlockOn {
    bell: Arc<Doorbell>,
    waker: Waker,
}

impl BlockOn {
    /// A runner with its own doorbell.
    pub fn new() -> io::Result<Self> {
        let bell = Doorbell::new()?;
        Ok(Self {
            waker: Waker::from(bell.clone()),
            bell,
        })
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
            self.bell.wait(None, None);
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
            let left = deadline_ns.checked_sub(now_ns()).filter(|&ns| ns > 0)?;
            self.bell.wait(None, Some(Duration::from_nanos(left)));
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
