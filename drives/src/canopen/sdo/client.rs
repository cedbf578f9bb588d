//! The SDO client (CiA 301 §7.2.4.2–.3, client side): the master reads (uploads) and writes
//! (downloads) one object of one node at a time, expedited, segmented or block.
//!
//! Sans-I/O: start a transfer with [`SdoClient::download`] or [`SdoClient::upload`], send
//! every frame [`SdoClient::transmit`] returns, feed every received frame to
//! [`SdoClient::receive`] and call [`SdoClient::poll`] with the time now and then; both
//! return the [`Outcome`] when the transfer ends. Any frame that breaks the protocol aborts
//! the transfer with the CiA 301 Table 22 code and queues the abort frame for the server.

use super::abort::AbortCode;
use super::block::{check_block_size, segments_for, AckResult, BlockReceiver, BlockSender};
use super::command::{
    ClientCommand, Initiate, Multiplexer, Segment, ServerCommand, EXPEDITED_DATA, SEGMENT_DATA,
};
use super::timing::{Timing, Transfer};
use super::{Outcome, SdoConfig, SdoConfigError, Side};
use crate::canopen::cob_id::{CobId, NodeId};
use crate::canopen::frame::CanFrame;
use thiserror::Error;

/// How to download.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DownloadMode {
    /// Expedited for 1..=4 bytes, segmented otherwise (what CiA 301 devices expect).
    Auto,
    /// Expedited (1..=4 bytes, size indicated).
    Expedited,
    /// Segmented, whatever the length.
    Segmented,
    /// Block.
    Block,
}

/// How to upload.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UploadMode {
    /// Initiate upload: the server answers expedited or segmented.
    Normal,
    /// Block upload (the server may switch to normal below the configured `pst`).
    Block,
}

/// Why a transfer cannot start.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum SdoClientError {
    /// A transfer is in progress.
    #[error("SDO client of {node}: transfer of {busy} in progress, cannot start {mux}")]
    Busy {
        /// The server.
        node: NodeId,
        /// The object being transferred.
        busy: Multiplexer,
        /// The object asked for.
        mux: Multiplexer,
    },
    /// The data does not fit the client's buffer (or the 32-bit size field).
    #[error("SDO download to {node} {mux}: {len} bytes, the client buffer holds {capacity}")]
    TooLarge {
        /// The server.
        node: NodeId,
        /// The object.
        mux: Multiplexer,
        /// Bytes to send.
        len: usize,
        /// Buffer size.
        capacity: usize,
    },
    /// Expedited download of a length other than 1..=4.
    #[error("SDO expedited download to {node} {mux}: {len} bytes, expedited carries 1 to 4")]
    ExpeditedLength {
        /// The server.
        node: NodeId,
        /// The object.
        mux: Multiplexer,
        /// Bytes to send.
        len: usize,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    DownloadInitiate {
        mux: Multiplexer,
        len: usize,
        segmented: bool,
    },
    /// A segment is in flight; `sent` bytes including it.
    DownloadSegment {
        mux: Multiplexer,
        len: usize,
        sent: usize,
        toggle: bool,
        last: bool,
    },
    BlockDownloadInitiate {
        mux: Multiplexer,
        len: usize,
    },
    BlockDownload {
        mux: Multiplexer,
        len: usize,
        crc: bool,
        sender: BlockSender,
    },
    BlockDownloadEnd {
        mux: Multiplexer,
        len: usize,
    },
    UploadInitiate {
        mux: Multiplexer,
        /// Started as block upload (a normal answer is a protocol switch).
        block: bool,
    },
    UploadSegment {
        mux: Multiplexer,
        size: Option<u32>,
        received: usize,
        toggle: bool,
    },
    BlockUpload {
        mux: Multiplexer,
        size: Option<u32>,
        crc: bool,
        receiver: BlockReceiver,
    },
}

impl Transfer for State {
    fn mux(&self) -> Option<Multiplexer> {
        match *self {
            Self::Idle => None,
            Self::DownloadInitiate { mux, .. }
            | Self::DownloadSegment { mux, .. }
            | Self::BlockDownloadInitiate { mux, .. }
            | Self::BlockDownload { mux, .. }
            | Self::BlockDownloadEnd { mux, .. }
            | Self::UploadInitiate { mux, .. }
            | Self::UploadSegment { mux, .. }
            | Self::BlockUpload { mux, .. } => Some(mux),
        }
    }
    fn sending(&mut self) -> Option<&mut BlockSender> {
        match self {
            Self::BlockDownload { sender, .. } => Some(sender),
            _ => None,
        }
    }

    fn receiving(&mut self) -> Option<&mut BlockReceiver> {
        match self {
            Self::BlockUpload { receiver, .. } => Some(receiver),
            _ => None,
        }
    }

    fn end(&mut self) {
        *self = Self::Idle;
    }
}

/// An SDO client for one server node, over the default SDO COB-IDs (0x600 + node
/// requests, 0x580 + node responses).
#[derive(Debug)]
pub struct SdoClient<B> {
    node: NodeId,
    config: SdoConfig,
    buf: B,
    state: State,
    timing: Timing,
    uploaded: usize,
}

impl<B: AsRef<[u8]> + AsMut<[u8]>> SdoClient<B> {
    /// A client for `node`; `buf` holds the data of a transfer (its length is the largest
    /// object the client can move).
    pub fn new(node: NodeId, config: SdoConfig, buf: B) -> Result<Self, SdoConfigError> {
        Self::with_buffer(node, config, buf).map_err(|(e, _)| e)
    }

    /// Like [`SdoClient::new`], but a configuration it cannot run with hands `buf` back
    /// with the reason (a buffer lent for one transfer goes back to its owner, whatever
    /// happens).
    pub fn with_buffer(
        node: NodeId,
        config: SdoConfig,
        buf: B,
    ) -> Result<Self, (SdoConfigError, B)> {
        if let Err(e) = config.validate() {
            return Err((e, buf));
        }
        let timing = Timing::new(Side::Client, &config);
        Ok(Self {
            node,
            config,
            buf,
            state: State::Idle,
            timing,
            uploaded: 0,
        })
    }

    /// The server node.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// Whether no transfer is in progress.
    pub fn is_idle(&self) -> bool {
        matches!(self.state, State::Idle)
    }

    /// The data of the last completed upload (empty once another transfer starts).
    pub fn data(&self) -> &[u8] {
        self.buf.as_ref().get(..self.uploaded).unwrap_or(&[])
    }

    /// The whole buffer, to put a download's data in before
    /// [`SdoClient::download_buffered`]. What an upload left there is gone.
    pub fn buffer_mut(&mut self) -> &mut [u8] {
        self.uploaded = 0;
        self.buf.as_mut()
    }

    /// The client's buffer back (a completed upload's data is its first
    /// [`SdoClient::data`]`().len()` bytes); a transfer in progress is dropped with the
    /// client, without an abort frame.
    pub fn into_buffer(self) -> B {
        self.buf
    }

    fn busy(&self, mux: Multiplexer) -> Result<(), SdoClientError> {
        match self.state.mux() {
            Some(busy) => Err(SdoClientError::Busy {
                node: self.node,
                busy,
                mux,
            }),
            None => Ok(()),
        }
    }

    /// Starts writing `data` to `mux` (copied into the client's buffer unless expedited).
    pub fn download(
        &mut self,
        mux: Multiplexer,
        data: &[u8],
        mode: DownloadMode,
        now_ns: u64,
    ) -> Result<(), SdoClientError> {
        self.busy(mux)?;
        let len = data.len();
        if !self.expedited(mode, len) {
            let capacity = self.buf.as_ref().len();
            let Some(dst) = self.buf.as_mut().get_mut(..len) else {
                return Err(SdoClientError::TooLarge {
                    node: self.node,
                    mux,
                    len,
                    capacity,
                });
            };
            dst.copy_from_slice(data);
        }
        let expedited = self.expedited(mode, len).then_some(data);
        self.start_download_of(mux, len, mode, expedited, now_ns)
    }

    /// Starts writing the first `len` bytes of the client's buffer to `mux`: the data was
    /// put there beforehand ([`SdoClient::buffer_mut`]), so nothing is copied — a buffer
    /// lent for the transfer is sent from where it is.
    pub fn download_buffered(
        &mut self,
        mux: Multiplexer,
        len: usize,
        mode: DownloadMode,
        now_ns: u64,
    ) -> Result<(), SdoClientError> {
        self.busy(mux)?;
        let capacity = self.buf.as_ref().len();
        if len > capacity {
            return Err(SdoClientError::TooLarge {
                node: self.node,
                mux,
                len,
                capacity,
            });
        }
        if self.expedited(mode, len) {
            // An expedited request carries its bytes itself (1 to 4 of them).
            let mut small = [0u8; EXPEDITED_DATA];
            let n = len.min(EXPEDITED_DATA);
            if let (Some(dst), Some(src)) = (small.get_mut(..n), self.buf.as_ref().get(..n)) {
                dst.copy_from_slice(src);
            }
            let data = small.get(..len).unwrap_or(&[]);
            return self.start_download_of(mux, len, mode, Some(data), now_ns);
        }
        self.start_download_of(mux, len, mode, None, now_ns)
    }

    /// Whether a download of `len` bytes in `mode` goes expedited.
    fn expedited(&self, mode: DownloadMode, len: usize) -> bool {
        match mode {
            DownloadMode::Auto => (1..=EXPEDITED_DATA).contains(&len),
            DownloadMode::Expedited => true,
            DownloadMode::Segmented | DownloadMode::Block => false,
        }
    }

    /// Starts the download of `len` bytes: `expedited` carries them in the request, else
    /// they are the buffer's first `len`.
    fn start_download_of(
        &mut self,
        mux: Multiplexer,
        len: usize,
        mode: DownloadMode,
        expedited: Option<&[u8]>,
        now_ns: u64,
    ) -> Result<(), SdoClientError> {
        // The buffer holds the download: the last upload is gone.
        self.uploaded = 0;
        if u32::try_from(len).is_err() {
            return Err(SdoClientError::TooLarge {
                node: self.node,
                mux,
                len,
                capacity: self.buf.as_ref().len(),
            });
        }
        let size = self.config.indicate_size.then_some(len as u32);
        let request = if let Some(data) = expedited {
            let Some(payload) = Initiate::expedited(data) else {
                return Err(SdoClientError::ExpeditedLength {
                    node: self.node,
                    mux,
                    len,
                });
            };
            self.state = State::DownloadInitiate {
                mux,
                len,
                segmented: false,
            };
            ClientCommand::InitiateDownload { mux, payload }
        } else if mode == DownloadMode::Block {
            self.state = State::BlockDownloadInitiate { mux, len };
            ClientCommand::BlockDownloadInitiate {
                mux,
                crc: self.config.crc,
                size,
            }
        } else {
            self.state = State::DownloadInitiate {
                mux,
                len,
                segmented: true,
            };
            ClientCommand::InitiateDownload {
                mux,
                payload: Initiate::Segmented { size },
            }
        };
        self.timing.send(request.emit(), now_ns);
        Ok(())
    }

    /// Starts reading `mux`.
    pub fn upload(
        &mut self,
        mux: Multiplexer,
        mode: UploadMode,
        now_ns: u64,
    ) -> Result<(), SdoClientError> {
        self.busy(mux)?;
        self.uploaded = 0;
        let request = match mode {
            UploadMode::Normal => ClientCommand::InitiateUpload { mux },
            UploadMode::Block => ClientCommand::BlockUploadInitiate {
                mux,
                crc: self.config.crc,
                block_size: self.config.block_size,
                pst: self.config.pst,
            },
        };
        self.state = State::UploadInitiate {
            mux,
            block: mode == UploadMode::Block,
        };
        self.timing.send(request.emit(), now_ns);
        Ok(())
    }

    /// Aborts the transfer in progress with `code` (queues the abort frame).
    pub fn abort(&mut self, code: AbortCode) -> Option<Outcome> {
        let mux = self.state.mux()?;
        Some(self.fail(mux, code))
    }

    /// The next frame to send, if any. Call until None after every `download`, `upload`,
    /// `receive`, `poll` and `abort`.
    /// One answer is held at a time (a block sub-block is generated segment by segment from
    /// the buffer): a frame not taken before the next `receive` may be replaced by the
    /// next answer, e.g. by an abort, which supersedes it anyway.
    pub fn transmit(&mut self) -> Option<CanFrame> {
        let id = CobId::SdoRx(self.node).id();
        self.timing
            .transmit(&mut self.state, id, self.buf.as_ref(), None)
    }

    /// How many frames the server sends in answer to the next frame
    /// [`SdoClient::transmit`] returns: none to an abort, to the last frame of a transfer
    /// or to a block download's segment but the sub-block's last (its acknowledgement);
    /// a sub-block to a block upload's start or acknowledgement (what remains of the
    /// object, when the server gave its size; the end frame after the last); one to any
    /// other request. For a caller that budgets the bus.
    pub fn answers_to_next(&self) -> u8 {
        use ClientCommand as C;
        if let Some(bytes) = self.timing.pending() {
            let sub_block = |block_size: u8| match self.state {
                State::BlockUpload { receiver, .. } if receiver.is_done() => 1,
                State::BlockUpload {
                    receiver,
                    size: Some(size),
                    ..
                } => {
                    let left = segments_for(size as usize).saturating_sub(receiver.segments());
                    block_size.min(u8::try_from(left).unwrap_or(u8::MAX))
                }
                _ => block_size,
            };
            return match ClientCommand::parse(bytes) {
                Ok(C::Abort { .. } | C::BlockUploadEnd) => 0,
                Ok(C::BlockUploadStart) => sub_block(self.config.block_size),
                Ok(C::BlockUploadAck { block_size, .. }) => sub_block(block_size),
                _ => 1,
            };
        }
        match self.state {
            State::BlockDownload { sender, .. } => u8::from(sender.next_ends_sub_block()),
            _ => 0,
        }
    }

    /// [`SdoClient::transmit`] for a caller that paces a block download's segments (a few
    /// per cycle, so that the bus keeps room for the process data): the server's silence
    /// is timed from the segment sent last at `now_ns`, not from the sub-block's start.
    pub fn transmit_at(&mut self, now_ns: u64) -> Option<CanFrame> {
        let id = CobId::SdoRx(self.node).id();
        self.timing
            .transmit(&mut self.state, id, self.buf.as_ref(), Some(now_ns))
    }

    /// Checks the timeouts: the server's silence past `timeout_ns` aborts with 0x05040000;
    /// in a block upload, silence mid-sub-block past `sub_block_timeout_ns` acknowledges
    /// what arrived so the server sends the rest again.
    pub fn poll(&mut self, now_ns: u64) -> Option<Outcome> {
        self.timing.poll(&mut self.state, now_ns)
    }

    fn fail(&mut self, mux: Multiplexer, code: AbortCode) -> Outcome {
        self.timing.fail(&mut self.state, mux, code)
    }

    fn finish(&mut self) {
        self.timing.finish(&mut self.state);
    }

    /// Takes a received frame; frames not on this server's response COB-ID are ignored,
    /// and so is anything while idle (a late answer to an aborted transfer).
    pub fn receive(&mut self, frame: &CanFrame, now_ns: u64) -> Option<Outcome> {
        if frame.id() != CobId::SdoTx(self.node).id() || frame.is_remote() {
            return None;
        }
        let mux = self.state.mux()?;
        let data = frame.data();
        let buf = self.buf.as_mut();
        if let Some(taken) = self
            .timing
            .block_segment(&mut self.state, data, buf, now_ns)
        {
            return taken;
        }
        let cmd = match ServerCommand::parse(data) {
            Ok(c) => c,
            Err(_) => return Some(self.fail(mux, AbortCode::INVALID_COMMAND_SPECIFIER)),
        };
        if let ServerCommand::Abort { code, .. } = cmd {
            self.finish();
            return Some(Outcome::Aborted {
                mux,
                code,
                by: Side::Server,
            });
        }
        match self.step(mux, cmd, now_ns) {
            Ok(outcome) => outcome,
            Err(code) => Some(self.fail(mux, code)),
        }
    }

    /// One protocol step; Err is the abort code to send.
    fn step(
        &mut self,
        mux: Multiplexer,
        cmd: ServerCommand,
        now_ns: u64,
    ) -> Result<Option<Outcome>, AbortCode> {
        use ServerCommand as S;
        let check_mux = |m: Multiplexer| {
            if m == mux {
                Ok(())
            } else {
                Err(AbortCode::PARAMETER_INCOMPATIBILITY)
            }
        };
        match (self.state, cmd) {
            (State::DownloadInitiate { len, segmented, .. }, S::InitiateDownload { mux: m }) => {
                check_mux(m)?;
                if !segmented {
                    self.finish();
                    return Ok(Some(Outcome::Downloaded { mux, len }));
                }
                self.send_download_segment(mux, len, 0, false, now_ns);
                Ok(None)
            }
            (
                State::DownloadSegment {
                    len,
                    sent,
                    toggle,
                    last,
                    ..
                },
                S::DownloadSegment { toggle: t },
            ) => {
                if t != toggle {
                    return Err(AbortCode::TOGGLE_BIT_NOT_ALTERNATED);
                }
                if last {
                    self.finish();
                    return Ok(Some(Outcome::Downloaded { mux, len }));
                }
                self.send_download_segment(mux, len, sent, !toggle, now_ns);
                Ok(None)
            }
            (
                State::BlockDownloadInitiate { len, .. },
                S::BlockDownloadInitiate {
                    mux: m,
                    crc,
                    block_size,
                },
            ) => {
                check_mux(m)?;
                let block_size = check_block_size(block_size)?;
                self.state = State::BlockDownload {
                    mux,
                    len,
                    crc: crc && self.config.crc,
                    sender: BlockSender::new(len, block_size),
                };
                self.timing.arm(now_ns);
                Ok(None)
            }
            (
                State::BlockDownload {
                    len,
                    crc,
                    mut sender,
                    ..
                },
                S::BlockDownloadAck { ackseq, block_size },
            ) => {
                let result = sender.on_ack(ackseq, block_size, self.buf.as_ref())?;
                match result {
                    AckResult::More => {
                        self.state = State::BlockDownload {
                            mux,
                            len,
                            crc,
                            sender,
                        };
                        self.timing.arm(now_ns);
                    }
                    AckResult::Done => {
                        let crc = if crc { sender.crc() } else { 0 };
                        let unused = sender.unused_in_last();
                        self.state = State::BlockDownloadEnd { mux, len };
                        self.timing.send(
                            ClientCommand::BlockDownloadEnd { unused, crc }.emit(),
                            now_ns,
                        );
                    }
                }
                Ok(None)
            }
            (State::BlockDownloadEnd { len, .. }, S::BlockDownloadEnd) => {
                self.finish();
                Ok(Some(Outcome::Downloaded { mux, len }))
            }
            (State::UploadInitiate { block, .. }, S::InitiateUpload { mux: m, payload }) => {
                check_mux(m)?;
                if block && self.config.pst == 0 {
                    // The server may switch protocol only if the client offered it.
                    return Err(AbortCode::INVALID_COMMAND_SPECIFIER);
                }
                match payload {
                    Initiate::Expedited { data, len } => {
                        let len = len.unwrap_or(EXPEDITED_DATA as u8) as usize;
                        let src = data.get(..len).unwrap_or(&[]);
                        let dst = self
                            .buf
                            .as_mut()
                            .get_mut(..len)
                            .ok_or(AbortCode::OUT_OF_MEMORY)?;
                        dst.copy_from_slice(src);
                        self.uploaded = len;
                        self.finish();
                        Ok(Some(Outcome::Uploaded { mux, len }))
                    }
                    Initiate::Segmented { size } => {
                        self.check_capacity(size)?;
                        self.state = State::UploadSegment {
                            mux,
                            size,
                            received: 0,
                            toggle: false,
                        };
                        self.timing.send(
                            ClientCommand::UploadSegment { toggle: false }.emit(),
                            now_ns,
                        );
                        Ok(None)
                    }
                }
            }
            (
                State::UploadSegment {
                    size,
                    received,
                    toggle,
                    ..
                },
                S::UploadSegment(seg),
            ) => {
                if seg.toggle != toggle {
                    return Err(AbortCode::TOGGLE_BIT_NOT_ALTERNATED);
                }
                let bytes = seg.bytes();
                let end = received + bytes.len();
                let dst = self
                    .buf
                    .as_mut()
                    .get_mut(received..end)
                    .ok_or(AbortCode::OUT_OF_MEMORY)?;
                dst.copy_from_slice(bytes);
                if let Some(size) = size {
                    if end > size as usize {
                        return Err(AbortCode::LENGTH_TOO_HIGH);
                    }
                    if seg.last && end < size as usize {
                        return Err(AbortCode::LENGTH_TOO_LOW);
                    }
                }
                if seg.last {
                    self.uploaded = end;
                    self.finish();
                    return Ok(Some(Outcome::Uploaded { mux, len: end }));
                }
                self.state = State::UploadSegment {
                    mux,
                    size,
                    received: end,
                    toggle: !toggle,
                };
                self.timing.send(
                    ClientCommand::UploadSegment { toggle: !toggle }.emit(),
                    now_ns,
                );
                Ok(None)
            }
            (
                State::UploadInitiate { block: true, .. },
                S::BlockUploadInitiate { mux: m, crc, size },
            ) => {
                check_mux(m)?;
                self.check_capacity(size)?;
                self.state = State::BlockUpload {
                    mux,
                    size,
                    crc: crc && self.config.crc,
                    receiver: BlockReceiver::new(self.config.block_size),
                };
                self.timing
                    .send(ClientCommand::BlockUploadStart.emit(), now_ns);
                Ok(None)
            }
            (
                State::BlockUpload {
                    size,
                    crc: use_crc,
                    receiver,
                    ..
                },
                S::BlockUploadEnd { unused, crc },
            ) if receiver.is_done() => {
                let len = receiver
                    .length(unused)
                    .ok_or(AbortCode::INVALID_COMMAND_SPECIFIER)?;
                let data = self
                    .buf
                    .as_ref()
                    .get(..len)
                    .ok_or(AbortCode::OUT_OF_MEMORY)?;
                if let Some(size) = size {
                    if len != size as usize {
                        return Err(AbortCode::LENGTH_MISMATCH);
                    }
                }
                if use_crc && receiver.crc(data, len) != crc {
                    return Err(AbortCode::CRC_ERROR);
                }
                self.uploaded = len;
                self.finish();
                self.timing.queue(ClientCommand::BlockUploadEnd.emit());
                Ok(Some(Outcome::Uploaded { mux, len }))
            }
            _ => Err(AbortCode::INVALID_COMMAND_SPECIFIER),
        }
    }

    fn check_capacity(&self, size: Option<u32>) -> Result<(), AbortCode> {
        match size {
            Some(s) if s as usize > self.buf.as_ref().len() => Err(AbortCode::OUT_OF_MEMORY),
            _ => Ok(()),
        }
    }

    fn send_download_segment(
        &mut self,
        mux: Multiplexer,
        len: usize,
        from: usize,
        toggle: bool,
        now_ns: u64,
    ) {
        let end = (from + SEGMENT_DATA).min(len);
        let bytes = self.buf.as_ref().get(from..end).unwrap_or(&[]);
        let last = end >= len;
        let seg = Segment::new(toggle, last, bytes);
        self.state = State::DownloadSegment {
            mux,
            len,
            sent: end,
            toggle,
            last,
        };
        self.timing
            .send(ClientCommand::DownloadSegment(seg).emit(), now_ns);
    }
}
