//! The frame pump: a thread that runs a [`FrameIo`] for code that drives ethercrab from an
//! ordinary thread with its own executor (lockstep tests, the demo's lockstep bus): it
//! sleeps until ethercrab queues a frame or a reply comes, and exchanges them. gantry's
//! cycle needs none: it exchanges its frames itself (`doorbell::BlockOn`).

use std::io;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Wake, Waker};
use std::thread::JoinHandle;

use super::doorbell::Doorbell;
use super::link::{FrameIo, LinkStats};

/// Name of the pump thread.
pub const PUMP_THREAD: &str = "ethercat-pump";

/// A running pump thread.
pub struct FramePump {
    stop: Arc<AtomicBool>,
    replies: Arc<AtomicU64>,
    doorbell: Arc<Doorbell>,
    thread: Option<JoinHandle<LinkStats>>,
}

impl FramePump {
    /// Starts the pump on `io`.
    pub fn start(mut io: FrameIo) -> io::Result<Self> {
        let doorbell = Doorbell::new()?;
        let stop = Arc::new(AtomicBool::new(false));
        let replies = io.replies();
        let (stop_io, bell) = (stop.clone(), doorbell.clone());
        let thread = std::thread::Builder::new()
            .name(PUMP_THREAD.into())
            .spawn(move || {
                let waker = Waker::from(bell.clone());
                while !stop_io.load(Ordering::Relaxed) {
                    // Registered anew before each look at the queue: a wake takes it.
                    io.wake_on_send(&waker);
                    if io.exchange() {
                        continue;
                    }
                    // Until ethercrab queues a frame, a reply arrives, or 1 ms passes.
                    bell.wait(io.readable(), Some(std::time::Duration::from_millis(1)));
                    io.idle();
                }
                io.finish()
            })?;
        Ok(Self {
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

    /// Stops the thread; returns what it counted.
    pub fn stop(mut self) -> LinkStats {
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
