//! What the SDO client and server both keep beside their protocol state: the one frame
//! waiting to go, the peer's deadline (CiA 301 leaves the SDO timeout to the application;
//! past it the transfer aborts with 0x05040000) and, while a block is received, the
//! sub-block's silence deadline after which what arrived in order is acknowledged so the
//! sender repeats the rest (§7.2.4.3.10, .14). One piece for both sides: only the
//! COB-ID, the acknowledgement's command and who aborts differ.

use super::abort::AbortCode;
use super::block::{BlockReceiver, BlockSender};
use super::command::{
    BlockSegment, ClientCommand, Multiplexer, ServerCommand, ABORT_BYTE0, SDO_LEN,
};
use super::{Outcome, SdoConfig, Side};
use crate::canopen::frame::CanFrame;

/// What [`Timing`] needs of a side's protocol state.
pub(super) trait Transfer {
    /// The object of the transfer in progress; None while idle.
    fn mux(&self) -> Option<Multiplexer>;
    /// The block this side is sending, if it is.
    fn sending(&mut self) -> Option<&mut BlockSender>;
    /// The block this side is receiving, if it is.
    fn receiving(&mut self) -> Option<&mut BlockReceiver>;
    /// Back to idle.
    fn end(&mut self);
}

/// The frame to send and the deadlines of one side of an SDO connection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Timing {
    side: Side,
    timeout_ns: u64,
    sub_block_timeout_ns: Option<u64>,
    pending: Option<[u8; SDO_LEN]>,
    deadline: Option<u64>,
    silence_deadline: Option<u64>,
}

impl Timing {
    /// Nothing to send, no deadline, for `side` with `config`'s timeouts.
    pub(super) fn new(side: Side, config: &SdoConfig) -> Self {
        Self {
            side,
            timeout_ns: config.timeout_ns,
            sub_block_timeout_ns: config.sub_block_timeout_ns,
            pending: None,
            deadline: None,
            silence_deadline: None,
        }
    }

    /// The next frame on COB-ID `id`: the answer waiting, else the next segment of the
    /// block `state` is sending (from `buf`). With `now_ns`, a segment restarts the wait
    /// for the peer (it answers a sub-block only after its last segment).
    pub(super) fn transmit(
        &mut self,
        state: &mut impl Transfer,
        id: u16,
        buf: &[u8],
        now_ns: Option<u64>,
    ) -> Option<CanFrame> {
        if let Some(bytes) = self.pending.take() {
            return Some(CanFrame::from_parts(id, bytes));
        }
        let seg = state.sending()?.next_segment(buf)?;
        if let Some(now) = now_ns {
            self.arm(now);
        }
        Some(CanFrame::from_parts(id, seg.emit()))
    }

    /// The frame waiting to be taken.
    pub(super) fn pending(&self) -> Option<&[u8; SDO_LEN]> {
        self.pending.as_ref()
    }

    /// Queues `bytes` (replacing a frame not yet taken) and waits for the peer's answer.
    pub(super) fn send(&mut self, bytes: [u8; SDO_LEN], now_ns: u64) {
        self.pending = Some(bytes);
        self.arm(now_ns);
    }

    /// Queues `bytes` without a new deadline (the last frame of a transfer).
    pub(super) fn queue(&mut self, bytes: [u8; SDO_LEN]) {
        self.pending = Some(bytes);
    }

    /// Waits for the peer's next frame from `now_ns`.
    pub(super) fn arm(&mut self, now_ns: u64) {
        self.deadline = Some(now_ns.saturating_add(self.timeout_ns));
    }

    /// The transfer `state` ran ended: idle, no deadlines.
    pub(super) fn finish(&mut self, state: &mut impl Transfer) {
        state.end();
        self.deadline = None;
        self.silence_deadline = None;
    }

    /// Ends the transfer of `mux` that `state` ran with `code`, queuing the abort frame
    /// for the peer.
    pub(super) fn fail(
        &mut self,
        state: &mut impl Transfer,
        mux: Multiplexer,
        code: AbortCode,
    ) -> Outcome {
        self.pending = Some(match self.side {
            Side::Client => ClientCommand::Abort { mux, code }.emit(),
            Side::Server => ServerCommand::Abort { mux, code }.emit(),
        });
        self.finish(state);
        Outcome::Aborted {
            mux,
            code,
            by: self.side,
        }
    }

    /// This side's acknowledgement of a sub-block up to `ackseq`.
    fn block_ack(&self, ackseq: u8, block_size: u8) -> [u8; SDO_LEN] {
        match self.side {
            Side::Client => ClientCommand::BlockUploadAck { ackseq, block_size }.emit(),
            Side::Server => ServerCommand::BlockDownloadAck { ackseq, block_size }.emit(),
        }
    }

    /// Checks the deadlines of the transfer `state` runs at `now_ns`: a sub-block silent
    /// past its deadline is acknowledged as far as it arrived; past the peer's deadline
    /// the transfer aborts with 0x05040000.
    pub(super) fn poll(&mut self, state: &mut impl Transfer, now_ns: u64) -> Option<Outcome> {
        let mux = state.mux()?;
        if let (Some(t), Some(receiver)) = (self.silence_deadline, state.receiving()) {
            if now_ns >= t {
                self.silence_deadline = None;
                if let Some(ackseq) = receiver.on_silence() {
                    let ack = self.block_ack(ackseq, receiver.block_size());
                    self.send(ack, now_ns);
                }
            }
        }
        match self.deadline {
            Some(t) if now_ns >= t => Some(self.fail(state, mux, AbortCode::TIMED_OUT)),
            _ => None,
        }
    }

    /// While `state` receives a block: takes `data` as its next segment into `buf`
    /// (None: not a block segment — no block being received, it is complete, or an abort
    /// frame — for the caller to parse as a command). A complete sub-block is
    /// acknowledged; otherwise the next segment is waited for (and, past the sub-block
    /// timeout, none). A frame that is no segment aborts with 0x05040001.
    pub(super) fn block_segment(
        &mut self,
        state: &mut impl Transfer,
        data: &[u8],
        buf: &mut [u8],
        now_ns: u64,
    ) -> Option<Option<Outcome>> {
        let mux = state.mux()?;
        let receiver = state.receiving()?;
        if receiver.is_done() || data.first() == Some(&ABORT_BYTE0) {
            return None;
        }
        let taken = BlockSegment::parse(data)
            .map_err(|_| AbortCode::INVALID_COMMAND_SPECIFIER)
            .and_then(|seg| receiver.on_segment(&seg, buf));
        Some(match taken {
            Err(code) => Some(self.fail(state, mux, code)),
            Ok(Some(ackseq)) => {
                self.silence_deadline = None;
                let ack = self.block_ack(ackseq, receiver.block_size());
                self.send(ack, now_ns);
                None
            }
            Ok(None) => {
                self.silence_deadline = self.sub_block_timeout_ns.map(|t| now_ns.saturating_add(t));
                self.arm(now_ns);
                None
            }
        })
    }
}
