//! ethercrab driven in one thread, no pump thread: poll the master's future, pass every
//! frame it queued through the simulated chain, hand the replies back, poll again. Used
//! where thread hand-offs would blur a measurement (the benchmarks).

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};

use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::Op;
use ethercrab::{DefaultLock, MainDevice, PduRx, PduTx, SubDeviceGroup};
use gantry_sim::chain::SlaveChain;

/// Rewrites a reply frame in place.
pub type Mangler = Box<dyn FnMut(&mut Vec<u8>)>;

/// A master's PDU queues joined to a chain in the calling thread.
pub struct Lockstep {
    tx: PduTx<'static>,
    rx: PduRx<'static>,
    /// The chain.
    pub chain: SlaveChain,
    frame: Vec<u8>,
    /// The last frame sent, as sent (before the chain processed it).
    pub last_sent: Vec<u8>,
    /// Applied to every reply before the master sees it (to garble frames in tests).
    pub mangle: Option<Mangler>,
}

impl Lockstep {
    /// Joins ethercrab's queues to `chain`.
    pub fn new(tx: PduTx<'static>, rx: PduRx<'static>, chain: SlaveChain) -> Self {
        Self {
            tx,
            rx,
            chain,
            frame: Vec::with_capacity(1600),
            last_sent: Vec::with_capacity(1600),
            mangle: None,
        }
    }

    /// Passes every queued frame through the chain and hands the replies back.
    pub fn pump(&mut self) {
        while let Some(frame) = self.tx.next_sendable_frame() {
            let (buf, sent) = (&mut self.frame, &mut self.last_sent);
            let ok = frame.send_blocking(|bytes| {
                buf.clear();
                buf.extend_from_slice(bytes);
                sent.clear();
                sent.extend_from_slice(bytes);
                Ok(bytes.len())
            });
            if ok.is_ok() && self.chain.process(&mut self.frame).is_ok() {
                if let Some(mangle) = self.mangle.as_mut() {
                    mangle(&mut self.frame);
                }
                let _ = self.rx.receive_frame(&self.frame);
            }
        }
    }

    /// Runs `fut` to completion, pumping frames between polls.
    pub fn block_on<F: Future>(&mut self, fut: F) -> F::Output {
        let mut fut = pin!(fut);
        let mut cx = Context::from_waker(Waker::noop());
        loop {
            if let Poll::Ready(out) = fut.as_mut().poll(&mut cx) {
                return out;
            }
            self.pump();
        }
    }

    /// Discovers the chain and takes it to Op the way gantry's cycle does (SafeOp, then Op
    /// with the process data running: drives reach Op only with valid outputs): a group of
    /// at most `N` slaves and `PDI` bytes of process image.
    pub fn group_in_op<const N: usize, const PDI: usize>(
        &mut self,
        md: &MainDevice<'_>,
    ) -> Result<SubDeviceGroup<N, PDI, DefaultLock, Op>, ethercrab::error::Error> {
        let group = self.block_on(md.init_single_group::<N, PDI>(ethercat_now))?;
        self.block_on(async {
            gantry::ethercat::transition::into_op(
                group.into_safe_op(md).await?,
                md,
                gantry::ethercat::transition::OP_TIMEOUT,
            )
            .await
        })
    }
}
