//! The SDO server (CiA 301 §7.2.4.2–.3, server side): a node serves its object dictionary
//! to one client, expedited, segmented and block, checking access rights and sizes before
//! it moves a byte.
//!
//! Sans-I/O like the client: feed it each received frame with the time and the dictionary
//! ([`SdoServer::receive`]), call [`SdoServer::poll`] for timeouts, and send every frame
//! [`SdoServer::transmit`] returns. A download is written to the dictionary only when it
//! is complete and checked (size, CRC), so an aborted transfer changes nothing.

use super::abort::AbortCode;
use super::block::{check_block_size, AckResult, BlockReceiver, BlockSender};
use super::command::{
    ClientCommand, Initiate, Multiplexer, Segment, ServerCommand, EXPEDITED_DATA, SEGMENT_DATA,
};
use super::dictionary::{EntryInfo, ObjectDictionary, ObjectSize};
use super::timing::{Timing, Transfer};
use super::{Outcome, SdoConfig, SdoConfigError, Side};
use crate::canopen::cob_id::{CobId, NodeId};
use crate::canopen::frame::CanFrame;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    DownloadSegment {
        mux: Multiplexer,
        info: EntryInfo,
        size: Option<u32>,
        received: usize,
        toggle: bool,
    },
    UploadSegment {
        mux: Multiplexer,
        len: usize,
        sent: usize,
        toggle: bool,
    },
    BlockDownload {
        mux: Multiplexer,
        info: EntryInfo,
        size: Option<u32>,
        crc: bool,
        receiver: BlockReceiver,
    },
    BlockUploadStart {
        mux: Multiplexer,
        len: usize,
        crc: bool,
        block_size: u8,
    },
    BlockUpload {
        mux: Multiplexer,
        len: usize,
        crc: bool,
        sender: BlockSender,
    },
    BlockUploadEnd {
        mux: Multiplexer,
        len: usize,
    },
}

impl Transfer for State {
    fn mux(&self) -> Option<Multiplexer> {
        match *self {
            Self::Idle => None,
            Self::DownloadSegment { mux, .. }
            | Self::UploadSegment { mux, .. }
            | Self::BlockDownload { mux, .. }
            | Self::BlockUploadStart { mux, .. }
            | Self::BlockUpload { mux, .. }
            | Self::BlockUploadEnd { mux, .. } => Some(mux),
        }
    }
    fn sending(&mut self) -> Option<&mut BlockSender> {
        match self {
            Self::BlockUpload { sender, .. } => Some(sender),
            _ => None,
        }
    }

    fn receiving(&mut self) -> Option<&mut BlockReceiver> {
        match self {
            Self::BlockDownload { receiver, .. } => Some(receiver),
            _ => None,
        }
    }

    fn end(&mut self) {
        *self = Self::Idle;
    }
}

/// An SDO server of one node, on the default SDO COB-IDs (requests on 0x600 + node,
/// responses on 0x580 + node).
#[derive(Debug)]
pub struct SdoServer<B> {
    node: NodeId,
    config: SdoConfig,
    buf: B,
    state: State,
    timing: Timing,
}

impl<B: AsRef<[u8]> + AsMut<[u8]>> SdoServer<B> {
    /// A server for `node`; `buf` holds a segmented or block transfer (its length is the
    /// largest object served that way; larger ones are refused with 0x05040005).
    pub fn new(node: NodeId, config: SdoConfig, buf: B) -> Result<Self, SdoConfigError> {
        config.validate()?;
        let timing = Timing::new(Side::Server, &config);
        Ok(Self {
            node,
            config,
            buf,
            state: State::Idle,
            timing,
        })
    }

    /// The node served.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// Whether no transfer is in progress.
    pub fn is_idle(&self) -> bool {
        matches!(self.state, State::Idle)
    }

    /// The next frame to send, if any. Call until None after every `receive` and `poll`.
    /// One answer is held at a time (a block sub-block is generated segment by segment from
    /// the buffer): a frame not taken before the next `receive` may be replaced by the
    /// next answer, e.g. by an abort, which supersedes it anyway.
    pub fn transmit(&mut self) -> Option<CanFrame> {
        let id = CobId::SdoTx(self.node).id();
        self.timing
            .transmit(&mut self.state, id, self.buf.as_ref(), None)
    }

    /// Checks the timeouts (see [`SdoConfig`]): the client's silence past `timeout_ns`
    /// aborts with 0x05040000; silence mid-sub-block of a block download acknowledges what
    /// arrived in order.
    pub fn poll(&mut self, now_ns: u64) -> Option<Outcome> {
        self.timing.poll(&mut self.state, now_ns)
    }

    fn fail(&mut self, mux: Multiplexer, code: AbortCode) -> Outcome {
        self.timing.fail(&mut self.state, mux, code)
    }

    fn finish(&mut self) {
        self.timing.finish(&mut self.state);
    }

    /// Takes a received frame; frames not on this node's request COB-ID are ignored.
    /// A frame that is not a valid request in the current state (wrong length, unknown
    /// command specifier, a segment while idle, a new initiate mid-transfer) is answered
    /// with an abort.
    pub fn receive<D: ObjectDictionary + ?Sized>(
        &mut self,
        frame: &CanFrame,
        now_ns: u64,
        od: &mut D,
    ) -> Option<Outcome> {
        if frame.id() != CobId::SdoRx(self.node).id() || frame.is_remote() {
            return None;
        }
        let data = frame.data();
        let current = self.state.mux();
        let buf = self.buf.as_mut();
        if let Some(taken) = self
            .timing
            .block_segment(&mut self.state, data, buf, now_ns)
        {
            return taken;
        }
        let cmd = match ClientCommand::parse(data) {
            Ok(c) => c,
            Err(_) => {
                let mux = current.unwrap_or(Multiplexer::new(0, 0));
                return Some(self.fail(mux, AbortCode::INVALID_COMMAND_SPECIFIER));
            }
        };
        if let ClientCommand::Abort { code, .. } = cmd {
            // An abort needs no answer; while idle there is nothing to abort.
            let mux = current?;
            self.finish();
            return Some(Outcome::Aborted {
                mux,
                code,
                by: Side::Client,
            });
        }
        let result = match current {
            None => self.initiate(cmd, now_ns, od),
            Some(mux) => self.step(mux, cmd, now_ns, od),
        };
        match result {
            Ok(outcome) => outcome,
            Err((mux, code)) => Some(self.fail(mux, code)),
        }
    }

    /// Checks that a download of `size` bytes (if indicated) may start.
    fn check_download<D: ObjectDictionary + ?Sized>(
        &self,
        mux: Multiplexer,
        size: Option<u32>,
        od: &D,
    ) -> Result<EntryInfo, AbortCode> {
        let info = od.entry(mux)?;
        if !info.access.writable() {
            return Err(AbortCode::READ_ONLY);
        }
        if let Some(size) = size {
            info.size.check(size as usize)?;
            if size as usize > self.buf.as_ref().len() {
                return Err(AbortCode::OUT_OF_MEMORY);
            }
        }
        Ok(info)
    }

    /// Reads a readable object into the buffer; its length.
    fn read_object<D: ObjectDictionary + ?Sized>(
        &mut self,
        mux: Multiplexer,
        od: &mut D,
    ) -> Result<usize, AbortCode> {
        let info = od.entry(mux)?;
        if !info.access.readable() {
            return Err(AbortCode::WRITE_ONLY);
        }
        let len = od.read(mux, self.buf.as_mut())?;
        if len > self.buf.as_ref().len() || u32::try_from(len).is_err() {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        Ok(len)
    }

    /// Answers an upload of `len` bytes already in the buffer the normal way.
    fn normal_upload(&mut self, mux: Multiplexer, len: usize, now_ns: u64) -> Option<Outcome> {
        let buf = self.buf.as_ref().get(..len).unwrap_or(&[]);
        if let Some(payload) = Initiate::expedited(buf) {
            self.timing
                .queue(ServerCommand::InitiateUpload { mux, payload }.emit());
            return Some(Outcome::Uploaded { mux, len });
        }
        let payload = Initiate::Segmented {
            size: Some(len as u32),
        };
        self.state = State::UploadSegment {
            mux,
            len,
            sent: 0,
            toggle: false,
        };
        self.timing.send(
            ServerCommand::InitiateUpload { mux, payload }.emit(),
            now_ns,
        );
        None
    }

    fn initiate<D: ObjectDictionary + ?Sized>(
        &mut self,
        cmd: ClientCommand,
        now_ns: u64,
        od: &mut D,
    ) -> Result<Option<Outcome>, (Multiplexer, AbortCode)> {
        use ClientCommand as C;
        match cmd {
            C::BlockDownloadInitiate { mux, .. } | C::BlockUploadInitiate { mux, .. }
                if !self.config.block =>
            {
                Err((mux, AbortCode::INVALID_COMMAND_SPECIFIER))
            }
            C::InitiateDownload {
                mux,
                payload: Initiate::Expedited { data, len },
            } => {
                let info = self.check_download(mux, None, od).map_err(|c| (mux, c))?;
                // Size not indicated: the object's own size says how many bytes count.
                let len = match (len, info.size) {
                    (Some(l), _) => l as usize,
                    (None, ObjectSize::Fixed(n)) if n <= EXPEDITED_DATA => n,
                    (None, _) => EXPEDITED_DATA,
                };
                let bytes = data.get(..len).unwrap_or(&data);
                info.size.check(bytes.len()).map_err(|c| (mux, c))?;
                od.write(mux, bytes).map_err(|c| (mux, c))?;
                self.timing
                    .queue(ServerCommand::InitiateDownload { mux }.emit());
                Ok(Some(Outcome::Downloaded {
                    mux,
                    len: bytes.len(),
                }))
            }
            C::InitiateDownload {
                mux,
                payload: Initiate::Segmented { size },
            } => {
                let info = self.check_download(mux, size, od).map_err(|c| (mux, c))?;
                self.state = State::DownloadSegment {
                    mux,
                    info,
                    size,
                    received: 0,
                    toggle: false,
                };
                self.timing
                    .send(ServerCommand::InitiateDownload { mux }.emit(), now_ns);
                Ok(None)
            }
            C::InitiateUpload { mux } => {
                let len = self.read_object(mux, od).map_err(|c| (mux, c))?;
                Ok(self.normal_upload(mux, len, now_ns))
            }
            C::BlockDownloadInitiate { mux, crc, size } => {
                let info = self.check_download(mux, size, od).map_err(|c| (mux, c))?;
                let block_size = self.config.block_size;
                self.state = State::BlockDownload {
                    mux,
                    info,
                    size,
                    crc: crc && self.config.crc,
                    receiver: BlockReceiver::new(block_size),
                };
                let answer = ServerCommand::BlockDownloadInitiate {
                    mux,
                    crc: self.config.crc,
                    block_size,
                };
                self.timing.send(answer.emit(), now_ns);
                Ok(None)
            }
            C::BlockUploadInitiate {
                mux,
                crc,
                block_size,
                pst,
            } => {
                let block_size = check_block_size(block_size).map_err(|c| (mux, c))?;
                let len = self.read_object(mux, od).map_err(|c| (mux, c))?;
                if pst > 0 && len <= pst as usize {
                    // Protocol switch (CiA 301 §7.2.4.3.13): small objects go the normal way.
                    return Ok(self.normal_upload(mux, len, now_ns));
                }
                let crc = crc && self.config.crc;
                self.state = State::BlockUploadStart {
                    mux,
                    len,
                    crc,
                    block_size,
                };
                let answer = ServerCommand::BlockUploadInitiate {
                    mux,
                    crc: self.config.crc,
                    size: Some(len as u32),
                };
                self.timing.send(answer.emit(), now_ns);
                Ok(None)
            }
            C::DownloadSegment(_)
            | C::UploadSegment { .. }
            | C::BlockDownloadEnd { .. }
            | C::BlockUploadStart
            | C::BlockUploadAck { .. }
            | C::BlockUploadEnd
            | C::Abort { .. } => {
                Err((Multiplexer::new(0, 0), AbortCode::INVALID_COMMAND_SPECIFIER))
            }
        }
    }

    fn step<D: ObjectDictionary + ?Sized>(
        &mut self,
        mux: Multiplexer,
        cmd: ClientCommand,
        now_ns: u64,
        od: &mut D,
    ) -> Result<Option<Outcome>, (Multiplexer, AbortCode)> {
        use ClientCommand as C;
        let fail = |code| Err((mux, code));
        match (self.state, cmd) {
            (
                State::DownloadSegment {
                    info,
                    size,
                    received,
                    toggle,
                    ..
                },
                C::DownloadSegment(seg),
            ) => {
                if seg.toggle != toggle {
                    return fail(AbortCode::TOGGLE_BIT_NOT_ALTERNATED);
                }
                let bytes = seg.bytes();
                let end = received + bytes.len();
                let Some(dst) = self.buf.as_mut().get_mut(received..end) else {
                    return fail(AbortCode::OUT_OF_MEMORY);
                };
                dst.copy_from_slice(bytes);
                if let Some(size) = size {
                    if end > size as usize {
                        return fail(AbortCode::LENGTH_TOO_HIGH);
                    }
                    if seg.last && end < size as usize {
                        return fail(AbortCode::LENGTH_TOO_LOW);
                    }
                }
                if let ObjectSize::Variable { max } = info.size {
                    if end > max {
                        return fail(AbortCode::LENGTH_TOO_HIGH);
                    }
                }
                if seg.last {
                    let data = self.buf.as_ref().get(..end).unwrap_or(&[]);
                    info.size.check(end).map_err(|c| (mux, c))?;
                    od.write(mux, data).map_err(|c| (mux, c))?;
                    self.finish();
                    self.timing
                        .queue(ServerCommand::DownloadSegment { toggle }.emit());
                    return Ok(Some(Outcome::Downloaded { mux, len: end }));
                }
                self.state = State::DownloadSegment {
                    mux,
                    info,
                    size,
                    received: end,
                    toggle: !toggle,
                };
                self.timing
                    .send(ServerCommand::DownloadSegment { toggle }.emit(), now_ns);
                Ok(None)
            }
            (
                State::UploadSegment {
                    len, sent, toggle, ..
                },
                C::UploadSegment { toggle: t },
            ) => {
                if t != toggle {
                    return fail(AbortCode::TOGGLE_BIT_NOT_ALTERNATED);
                }
                let end = (sent + SEGMENT_DATA).min(len);
                let bytes = self.buf.as_ref().get(sent..end).unwrap_or(&[]);
                let last = end >= len;
                let seg = Segment::new(toggle, last, bytes);
                if last {
                    self.finish();
                    self.timing.queue(ServerCommand::UploadSegment(seg).emit());
                    return Ok(Some(Outcome::Uploaded { mux, len }));
                }
                self.state = State::UploadSegment {
                    mux,
                    len,
                    sent: end,
                    toggle: !toggle,
                };
                self.timing
                    .send(ServerCommand::UploadSegment(seg).emit(), now_ns);
                Ok(None)
            }
            (
                State::BlockDownload {
                    info,
                    size,
                    crc: use_crc,
                    receiver,
                    ..
                },
                C::BlockDownloadEnd { unused, crc },
            ) if receiver.is_done() => {
                let Some(len) = receiver.length(unused) else {
                    return fail(AbortCode::INVALID_COMMAND_SPECIFIER);
                };
                let Some(data) = self.buf.as_ref().get(..len) else {
                    return fail(AbortCode::OUT_OF_MEMORY);
                };
                if let Some(size) = size {
                    if len > size as usize {
                        return fail(AbortCode::LENGTH_TOO_HIGH);
                    }
                    if len < size as usize {
                        return fail(AbortCode::LENGTH_TOO_LOW);
                    }
                }
                if use_crc && receiver.crc(data, len) != crc {
                    return fail(AbortCode::CRC_ERROR);
                }
                info.size.check(len).map_err(|c| (mux, c))?;
                od.write(mux, data).map_err(|c| (mux, c))?;
                self.finish();
                self.timing.queue(ServerCommand::BlockDownloadEnd.emit());
                Ok(Some(Outcome::Downloaded { mux, len }))
            }
            (
                State::BlockUploadStart {
                    len,
                    crc,
                    block_size,
                    ..
                },
                C::BlockUploadStart,
            ) => {
                self.state = State::BlockUpload {
                    mux,
                    len,
                    crc,
                    sender: BlockSender::new(len, block_size),
                };
                self.timing.arm(now_ns);
                Ok(None)
            }
            (
                State::BlockUpload {
                    len,
                    crc,
                    mut sender,
                    ..
                },
                C::BlockUploadAck { ackseq, block_size },
            ) => match sender.on_ack(ackseq, block_size, self.buf.as_ref()) {
                Err(code) => fail(code),
                Ok(AckResult::More) => {
                    self.state = State::BlockUpload {
                        mux,
                        len,
                        crc,
                        sender,
                    };
                    self.timing.arm(now_ns);
                    Ok(None)
                }
                Ok(AckResult::Done) => {
                    let crc = if crc { sender.crc() } else { 0 };
                    let unused = sender.unused_in_last();
                    self.state = State::BlockUploadEnd { mux, len };
                    self.timing
                        .send(ServerCommand::BlockUploadEnd { unused, crc }.emit(), now_ns);
                    Ok(None)
                }
            },
            (State::BlockUploadEnd { len, .. }, C::BlockUploadEnd) => {
                self.finish();
                Ok(Some(Outcome::Uploaded { mux, len }))
            }
            _ => fail(AbortCode::INVALID_COMMAND_SPECIFIER),
        }
    }
}
