//! SDO frames (CiA 301 §7.2.4.3): the 8 data bytes of every client → server request and
//! server → client response, parsed into a typed representation and emitted back.
//!
//! Byte 0 holds the command specifier (ccs/scs, bits 7–5) and its flags; an initiate or
//! abort frame carries the multiplexer (index little-endian in bytes 1–2, sub-index in
//! byte 3) and a 4-byte field; a segment carries 7 data bytes. Block-transfer segments
//! carry no command specifier (byte 0 is `c` and the sequence number), so they are parsed
//! by [`BlockSegment::parse`] only where the protocol expects them.
//!
//! Parsing is total: any 8 bytes give a value or a [`SdoWireError`] naming the byte;
//! bits CiA 301 marks "x, not used, always 0" are ignored on receipt (as CiA 301 devices
//! do) and emitted as 0.

use super::abort::AbortCode;
use super::packet::{command_byte, SdoPacket};
use thiserror::Error;

/// Every SDO frame has 8 data bytes (CiA 301 §7.2.4.3: "DLC 8").
pub const SDO_LEN: usize = 8;
/// Data bytes in a segment (normal or block).
pub const SEGMENT_DATA: usize = 7;
/// Data bytes in an expedited transfer.
pub const EXPEDITED_DATA: usize = 4;
/// Largest block size (segments per sub-block), CiA 301 §7.2.4.3.9.
pub const MAX_BLOCK_SIZE: u8 = 127;

/// ccs: download segment request.
pub const CCS_DOWNLOAD_SEGMENT: u8 = 0;
/// ccs: initiate download request.
pub const CCS_INITIATE_DOWNLOAD: u8 = 1;
/// ccs: initiate upload request.
pub const CCS_INITIATE_UPLOAD: u8 = 2;
/// ccs: upload segment request.
pub const CCS_UPLOAD_SEGMENT: u8 = 3;
/// cs (either side): abort transfer.
pub const CS_ABORT: u8 = 4;
/// ccs: block upload (initiate, start, sub-block response, end response).
pub const CCS_BLOCK_UPLOAD: u8 = 5;
/// ccs: block download (initiate, end).
pub const CCS_BLOCK_DOWNLOAD: u8 = 6;
/// scs: upload segment response.
pub const SCS_UPLOAD_SEGMENT: u8 = 0;
/// scs: download segment response.
pub const SCS_DOWNLOAD_SEGMENT: u8 = 1;
/// scs: initiate upload response.
pub const SCS_INITIATE_UPLOAD: u8 = 2;
/// scs: initiate download response.
pub const SCS_INITIATE_DOWNLOAD: u8 = 3;
/// scs: block download (initiate response, sub-block response, end response).
pub const SCS_BLOCK_DOWNLOAD: u8 = 5;
/// scs: block upload (initiate response, end request).
pub const SCS_BLOCK_UPLOAD: u8 = 6;

/// Block sub-command (cs/ss, bits 1–0): initiate.
const SUB_INITIATE: u8 = 0;
/// Block sub-command: end.
const SUB_END: u8 = 1;
/// Block sub-command: sub-block response (acknowledge).
const SUB_ACK: u8 = 2;
/// Block upload sub-command: start upload.
const SUB_START: u8 = 3;

/// Why 8 bytes are not an SDO frame.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum SdoWireError {
    /// Not 8 data bytes.
    #[error("SDO frame has {0} data bytes, CiA 301 §7.2.4.3 requires 8")]
    Length(usize),
    /// A command specifier (or block sub-command) that the direction does not define.
    #[error("SDO {direction}: byte 0 = 0x{byte:02X}, command specifier {cs} is not defined (CiA 301 §7.2.4.3)")]
    CommandSpecifier {
        /// "request" (client → server) or "response" (server → client).
        direction: &'static str,
        /// Byte 0.
        byte: u8,
        /// Bits 7–5.
        cs: u8,
    },
    /// A block segment with sequence number 0 (valid ones are 1..=127).
    #[error("SDO block segment: byte 0 = 0x{0:02X}, sequence number 0 is not valid (1..=127)")]
    SequenceNumber(u8),
}

/// The object an SDO transfer addresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Multiplexer {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
}

impl Multiplexer {
    /// index:sub.
    pub const fn new(index: u16, sub: u8) -> Self {
        Self { index, sub }
    }
}

impl std::fmt::Display for Multiplexer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "0x{:04X}:{:02X}", self.index, self.sub)
    }
}

/// What an initiate download request or initiate upload response carries in bytes 4–7.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Initiate {
    /// e = 1: the data itself. `len` is 1..=4 when s = 1 (n = 4 − len), None when the size
    /// is not indicated (s = 0: all 4 bytes, meaning left to the object's type).
    Expedited {
        /// Bytes 4–7.
        data: [u8; EXPEDITED_DATA],
        /// Number of valid bytes, if indicated.
        len: Option<u8>,
    },
    /// e = 0: segments follow; bytes 4–7 are the size when s = 1.
    Segmented {
        /// Total size in bytes, if indicated.
        size: Option<u32>,
    },
}

impl Initiate {
    /// An expedited payload of 1..=4 bytes with size indicated; None otherwise.
    pub fn expedited(bytes: &[u8]) -> Option<Self> {
        if bytes.is_empty() || bytes.len() > EXPEDITED_DATA {
            return None;
        }
        let mut data = [0u8; EXPEDITED_DATA];
        for (d, s) in data.iter_mut().zip(bytes) {
            *d = *s;
        }
        Some(Self::Expedited {
            data,
            len: Some(bytes.len() as u8),
        })
    }

    fn parse<T: AsRef<[u8]>>(p: &SdoPacket<T>) -> Self {
        let field = p.data();
        if p.expedited() {
            let len = p.size_indicated().then_some(4 - p.expedited_unused());
            let mut data = field;
            // Bytes past the indicated size carry no data: keep them zero.
            for (i, d) in data.iter_mut().enumerate() {
                if i >= len.unwrap_or(4) as usize {
                    *d = 0;
                }
            }
            Self::Expedited { data, len }
        } else {
            Self::Segmented {
                size: p.size_indicated().then_some(p.size()),
            }
        }
    }

    /// Byte 0 flags (n, e, s) and bytes 4–7.
    fn emit(&self) -> (u8, [u8; 4]) {
        match *self {
            Self::Expedited { data, len: None } => (command_byte::initiate(0, true, false), data),
            Self::Expedited {
                data,
                len: Some(len),
            } => {
                let len = len.clamp(1, 4);
                let mut out = [0u8; 4];
                for (o, d) in out.iter_mut().zip(data).take(len as usize) {
                    *o = d;
                }
                (command_byte::initiate(4 - len, true, true), out)
            }
            Self::Segmented { size: None } => (command_byte::initiate(0, false, false), [0; 4]),
            Self::Segmented { size: Some(s) } => {
                (command_byte::initiate(0, false, true), s.to_le_bytes())
            }
        }
    }
}

/// A segment of a normal (segmented) transfer: toggle bit, 1..=7 data bytes, last flag.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Segment {
    /// Bit 4: alternates 0, 1, 0, … starting at 0 (CiA 301 §7.2.4.3.3).
    pub toggle: bool,
    /// Bit 0 `c`: no more segments.
    pub last: bool,
    /// Bytes 1–7.
    pub data: [u8; SEGMENT_DATA],
    /// Valid bytes, 7 − n (0..=7).
    pub len: u8,
}

impl Segment {
    /// A segment of up to 7 bytes (more are cut).
    pub fn new(toggle: bool, last: bool, bytes: &[u8]) -> Self {
        let mut data = [0u8; SEGMENT_DATA];
        let mut len = 0u8;
        for (d, s) in data.iter_mut().zip(bytes) {
            *d = *s;
            len += 1;
        }
        Self {
            toggle,
            last,
            data,
            len,
        }
    }

    /// The valid data bytes.
    pub fn bytes(&self) -> &[u8] {
        self.data.get(..self.len as usize).unwrap_or(&self.data)
    }

    fn parse<T: AsRef<[u8]>>(p: &SdoPacket<T>) -> Self {
        let len = 7 - p.segment_unused();
        let mut data = p.segment_data();
        // Bytes past 7 − n carry no data: keep them zero.
        for (i, d) in data.iter_mut().enumerate() {
            if i >= len as usize {
                *d = 0;
            }
        }
        Self {
            toggle: p.toggle(),
            last: p.segment_last(),
            data,
            len,
        }
    }

    fn emit_into<T: AsRef<[u8]> + AsMut<[u8]>>(&self, cs: u8, p: &mut SdoPacket<T>) {
        let len = self.len.min(7);
        p.set_command(
            command_byte::cs(cs)
                | command_byte::toggle(self.toggle)
                | command_byte::segment(7 - len, self.last),
        );
        let mut data = [0u8; SEGMENT_DATA];
        for (o, d) in data.iter_mut().zip(self.data).take(len as usize) {
            *o = d;
        }
        p.set_segment_data(data);
    }
}

/// A client → server SDO frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ClientCommand {
    /// ccs = 1: initiate download (§7.2.4.3.3).
    InitiateDownload {
        /// Object.
        mux: Multiplexer,
        /// Expedited data or segmented size.
        payload: Initiate,
    },
    /// ccs = 0: download segment (§7.2.4.3.4).
    DownloadSegment(Segment),
    /// ccs = 2: initiate upload (§7.2.4.3.6).
    InitiateUpload {
        /// Object.
        mux: Multiplexer,
    },
    /// ccs = 3: upload segment (§7.2.4.3.7).
    UploadSegment {
        /// Bit 4.
        toggle: bool,
    },
    /// ccs = 4: abort transfer (§7.2.4.3.17).
    Abort {
        /// Object.
        mux: Multiplexer,
        /// Reason.
        code: AbortCode,
    },
    /// ccs = 6, cs = 0: initiate block download (§7.2.4.3.9).
    BlockDownloadInitiate {
        /// Object.
        mux: Multiplexer,
        /// Bit 2 `cc`: the client supports CRC.
        crc: bool,
        /// Bytes 4–7 when bit 1 `s` is set.
        size: Option<u32>,
    },
    /// ccs = 6, cs = 1: end block download (§7.2.4.3.11).
    BlockDownloadEnd {
        /// Bits 4–2 `n`: bytes of the last segment that carry no data.
        unused: u8,
        /// Bytes 1–2: CRC of the whole data (0 when CRC is not used).
        crc: u16,
    },
    /// ccs = 5, cs = 0: initiate block upload (§7.2.4.3.13).
    BlockUploadInitiate {
        /// Object.
        mux: Multiplexer,
        /// Bit 2 `cc`: the client supports CRC.
        crc: bool,
        /// Byte 4: segments per sub-block, 1..=127.
        block_size: u8,
        /// Byte 5: protocol switch threshold (0: no switch).
        pst: u8,
    },
    /// ccs = 5, cs = 3: start upload (§7.2.4.3.13).
    BlockUploadStart,
    /// ccs = 5, cs = 2: sub-block response (§7.2.4.3.14).
    BlockUploadAck {
        /// Byte 1: last segment received in sequence (0: none).
        ackseq: u8,
        /// Byte 2: segments in the next sub-block.
        block_size: u8,
    },
    /// ccs = 5, cs = 1: end block upload response (§7.2.4.3.15).
    BlockUploadEnd,
}

fn mux_of<T: AsRef<[u8]>>(p: &SdoPacket<T>) -> Multiplexer {
    Multiplexer {
        index: p.index(),
        sub: p.sub_index(),
    }
}

/// Writes a frame with a multiplexer: byte 0, index, sub-index, bytes 4–7.
fn emit_with_mux<T: AsRef<[u8]> + AsMut<[u8]>>(
    p: &mut SdoPacket<T>,
    b0: u8,
    mux: Multiplexer,
    field: [u8; 4],
) {
    p.set_command(b0);
    p.set_index(mux.index);
    p.set_sub_index(mux.sub);
    p.set_data(field);
}

/// Writes a frame of byte 0 and zeros.
fn emit_bare<T: AsRef<[u8]> + AsMut<[u8]>>(p: &mut SdoPacket<T>, b0: u8) {
    p.set_command(b0);
    p.set_segment_data([0; SEGMENT_DATA]);
}

/// Writes a block sub-block response.
fn emit_ack<T: AsRef<[u8]> + AsMut<[u8]>>(p: &mut SdoPacket<T>, b0: u8, ackseq: u8, bs: u8) {
    emit_bare(p, b0);
    p.set_ack(ackseq, bs);
}

/// Writes a block end frame.
fn emit_end<T: AsRef<[u8]> + AsMut<[u8]>>(p: &mut SdoPacket<T>, cs: u8, unused: u8, crc: u16) {
    emit_bare(
        p,
        command_byte::cs(cs) | command_byte::block_end(unused, SUB_END),
    );
    p.set_crc(crc);
}

fn to_bytes(emit: impl FnOnce(&mut SdoPacket<&mut [u8]>)) -> [u8; SDO_LEN] {
    let mut out = [0u8; SDO_LEN];
    emit(&mut SdoPacket::new_unchecked(&mut out[..]));
    out
}

impl ClientCommand {
    /// Parses the 8 data bytes of a client → server frame.
    pub fn parse(data: &[u8]) -> Result<Self, SdoWireError> {
        let p = SdoPacket::new_checked(data)?;
        Ok(match p.command_specifier() {
            CCS_DOWNLOAD_SEGMENT => Self::DownloadSegment(Segment::parse(&p)),
            CCS_INITIATE_DOWNLOAD => Self::InitiateDownload {
                mux: mux_of(&p),
                payload: Initiate::parse(&p),
            },
            CCS_INITIATE_UPLOAD => Self::InitiateUpload { mux: mux_of(&p) },
            CCS_UPLOAD_SEGMENT => Self::UploadSegment { toggle: p.toggle() },
            CS_ABORT => Self::Abort {
                mux: mux_of(&p),
                code: AbortCode(p.size()),
            },
            CCS_BLOCK_UPLOAD => match p.block_subcommand() {
                SUB_INITIATE => Self::BlockUploadInitiate {
                    mux: mux_of(&p),
                    crc: p.crc_supported(),
                    block_size: p.init_block_size(),
                    pst: p.pst(),
                },
                SUB_START => Self::BlockUploadStart,
                SUB_ACK => Self::BlockUploadAck {
                    ackseq: p.ackseq(),
                    block_size: p.ack_block_size(),
                },
                _ => Self::BlockUploadEnd,
            },
            // Bit 0 alone tells initiate (0) from end (1): bit 1 is `s` of an initiate.
            CCS_BLOCK_DOWNLOAD if p.block_subcommand() & SUB_END == SUB_INITIATE => {
                Self::BlockDownloadInitiate {
                    mux: mux_of(&p),
                    crc: p.crc_supported(),
                    size: p.block_size_indicated().then_some(p.size()),
                }
            }
            CCS_BLOCK_DOWNLOAD => Self::BlockDownloadEnd {
                unused: p.end_unused(),
                crc: p.crc(),
            },
            cs => {
                return Err(SdoWireError::CommandSpecifier {
                    direction: "request",
                    byte: p.command(),
                    cs,
                })
            }
        })
    }

    /// Writes the frame into a view over 8 bytes (every byte written; reserved ones 0).
    pub fn emit_into<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut SdoPacket<T>) {
        use command_byte as b;
        match *self {
            Self::InitiateDownload { mux, payload } => {
                let (flags, field) = payload.emit();
                emit_with_mux(p, b::cs(CCS_INITIATE_DOWNLOAD) | flags, mux, field);
            }
            Self::DownloadSegment(s) => s.emit_into(CCS_DOWNLOAD_SEGMENT, p),
            Self::InitiateUpload { mux } => {
                emit_with_mux(p, b::cs(CCS_INITIATE_UPLOAD), mux, [0; 4]);
            }
            Self::UploadSegment { toggle } => {
                emit_bare(p, b::cs(CCS_UPLOAD_SEGMENT) | b::toggle(toggle));
            }
            Self::Abort { mux, code } => {
                emit_with_mux(p, b::cs(CS_ABORT), mux, code.0.to_le_bytes());
            }
            Self::BlockDownloadInitiate { mux, crc, size } => {
                let b0 = b::cs(CCS_BLOCK_DOWNLOAD)
                    | b::block_initiate(crc, size.is_some(), SUB_INITIATE);
                emit_with_mux(p, b0, mux, size.unwrap_or(0).to_le_bytes());
            }
            Self::BlockDownloadEnd { unused, crc } => {
                emit_end(p, CCS_BLOCK_DOWNLOAD, unused, crc);
            }
            Self::BlockUploadInitiate {
                mux,
                crc,
                block_size,
                pst,
            } => {
                let b0 = b::cs(CCS_BLOCK_UPLOAD) | b::block_initiate(crc, false, SUB_INITIATE);
                emit_with_mux(p, b0, mux, [0; 4]);
                p.set_init_block_size(block_size);
                p.set_pst(pst);
            }
            Self::BlockUploadStart => emit_bare(p, b::cs(CCS_BLOCK_UPLOAD) | SUB_START),
            Self::BlockUploadAck { ackseq, block_size } => {
                emit_ack(p, b::cs(CCS_BLOCK_UPLOAD) | SUB_ACK, ackseq, block_size);
            }
            Self::BlockUploadEnd => emit_bare(p, b::cs(CCS_BLOCK_UPLOAD) | SUB_END),
        }
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; SDO_LEN] {
        to_bytes(|p| self.emit_into(p))
    }
}

/// A server → client SDO frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ServerCommand {
    /// scs = 3: initiate download response.
    InitiateDownload {
        /// Object.
        mux: Multiplexer,
    },
    /// scs = 1: download segment response.
    DownloadSegment {
        /// Bit 4: the toggle of the segment it confirms.
        toggle: bool,
    },
    /// scs = 2: initiate upload response.
    InitiateUpload {
        /// Object.
        mux: Multiplexer,
        /// Expedited data or segmented size.
        payload: Initiate,
    },
    /// scs = 0: upload segment response.
    UploadSegment(Segment),
    /// scs = 4: abort transfer.
    Abort {
        /// Object.
        mux: Multiplexer,
        /// Reason.
        code: AbortCode,
    },
    /// scs = 5, ss = 0: initiate block download response.
    BlockDownloadInitiate {
        /// Object.
        mux: Multiplexer,
        /// Bit 2 `sc`: the server supports CRC.
        crc: bool,
        /// Byte 4: segments per sub-block, 1..=127.
        block_size: u8,
    },
    /// scs = 5, ss = 2: block download sub-block response.
    BlockDownloadAck {
        /// Byte 1: last segment received in sequence (0: none).
        ackseq: u8,
        /// Byte 2: segments in the next sub-block.
        block_size: u8,
    },
    /// scs = 5, ss = 1: end block download response.
    BlockDownloadEnd,
    /// scs = 6, ss = 0: initiate block upload response.
    BlockUploadInitiate {
        /// Object.
        mux: Multiplexer,
        /// Bit 2 `sc`: the server supports CRC.
        crc: bool,
        /// Bytes 4–7 when bit 1 `s` is set.
        size: Option<u32>,
    },
    /// scs = 6, ss = 1: end block upload request.
    BlockUploadEnd {
        /// Bits 4–2 `n`: bytes of the last segment that carry no data.
        unused: u8,
        /// Bytes 1–2: CRC (0 when CRC is not used).
        crc: u16,
    },
}

impl ServerCommand {
    /// Parses the 8 data bytes of a server → client frame.
    pub fn parse(data: &[u8]) -> Result<Self, SdoWireError> {
        let p = SdoPacket::new_checked(data)?;
        let bad = |cs| SdoWireError::CommandSpecifier {
            direction: "response",
            byte: p.command(),
            cs,
        };
        Ok(match p.command_specifier() {
            SCS_UPLOAD_SEGMENT => Self::UploadSegment(Segment::parse(&p)),
            SCS_DOWNLOAD_SEGMENT => Self::DownloadSegment { toggle: p.toggle() },
            SCS_INITIATE_UPLOAD => Self::InitiateUpload {
                mux: mux_of(&p),
                payload: Initiate::parse(&p),
            },
            SCS_INITIATE_DOWNLOAD => Self::InitiateDownload { mux: mux_of(&p) },
            CS_ABORT => Self::Abort {
                mux: mux_of(&p),
                code: AbortCode(p.size()),
            },
            SCS_BLOCK_DOWNLOAD => match p.block_subcommand() {
                SUB_INITIATE => Self::BlockDownloadInitiate {
                    mux: mux_of(&p),
                    crc: p.crc_supported(),
                    block_size: p.init_block_size(),
                },
                SUB_END => Self::BlockDownloadEnd,
                SUB_ACK => Self::BlockDownloadAck {
                    ackseq: p.ackseq(),
                    block_size: p.ack_block_size(),
                },
                _ => return Err(bad(SCS_BLOCK_DOWNLOAD)),
            },
            // Bit 0 alone tells initiate (0) from end (1): bit 1 is `s` of an initiate.
            SCS_BLOCK_UPLOAD if p.block_subcommand() & SUB_END == SUB_INITIATE => {
                Self::BlockUploadInitiate {
                    mux: mux_of(&p),
                    crc: p.crc_supported(),
                    size: p.block_size_indicated().then_some(p.size()),
                }
            }
            SCS_BLOCK_UPLOAD => Self::BlockUploadEnd {
                unused: p.end_unused(),
                crc: p.crc(),
            },
            cs => return Err(bad(cs)),
        })
    }

    /// Writes the frame into a view over 8 bytes (every byte written; reserved ones 0).
    pub fn emit_into<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut SdoPacket<T>) {
        use command_byte as b;
        match *self {
            Self::InitiateDownload { mux } => {
                emit_with_mux(p, b::cs(SCS_INITIATE_DOWNLOAD), mux, [0; 4]);
            }
            Self::DownloadSegment { toggle } => {
                emit_bare(p, b::cs(SCS_DOWNLOAD_SEGMENT) | b::toggle(toggle));
            }
            Self::InitiateUpload { mux, payload } => {
                let (flags, field) = payload.emit();
                emit_with_mux(p, b::cs(SCS_INITIATE_UPLOAD) | flags, mux, field);
            }
            Self::UploadSegment(s) => s.emit_into(SCS_UPLOAD_SEGMENT, p),
            Self::Abort { mux, code } => {
                emit_with_mux(p, b::cs(CS_ABORT), mux, code.0.to_le_bytes());
            }
            Self::BlockDownloadInitiate {
                mux,
                crc,
                block_size,
            } => {
                let b0 = b::cs(SCS_BLOCK_DOWNLOAD) | b::block_initiate(crc, false, SUB_INITIATE);
                emit_with_mux(p, b0, mux, [0; 4]);
                p.set_init_block_size(block_size);
            }
            Self::BlockDownloadAck { ackseq, block_size } => {
                emit_ack(p, b::cs(SCS_BLOCK_DOWNLOAD) | SUB_ACK, ackseq, block_size);
            }
            Self::BlockDownloadEnd => emit_bare(p, b::cs(SCS_BLOCK_DOWNLOAD) | SUB_END),
            Self::BlockUploadInitiate { mux, crc, size } => {
                let b0 =
                    b::cs(SCS_BLOCK_UPLOAD) | b::block_initiate(crc, size.is_some(), SUB_INITIATE);
                emit_with_mux(p, b0, mux, size.unwrap_or(0).to_le_bytes());
            }
            Self::BlockUploadEnd { unused, crc } => {
                emit_end(p, SCS_BLOCK_UPLOAD, unused, crc);
            }
        }
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; SDO_LEN] {
        to_bytes(|p| self.emit_into(p))
    }
}

/// A segment of a block sub-block (CiA 301 §7.2.4.3.10/.14): byte 0 is `c` (bit 7, last
/// segment of the transfer) and the sequence number 1..=127; bytes 1–7 are data (the
/// number of valid bytes in the last one comes with the end frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BlockSegment {
    /// Sequence number in the sub-block, 1..=127.
    pub seqno: u8,
    /// No more segments follow.
    pub last: bool,
    /// Bytes 1–7.
    pub data: [u8; SEGMENT_DATA],
}

/// Byte 0 of an abort frame: inside a sub-block it cannot be a segment (seqno 0), so a
/// receiver tells an abort from a segment by it.
pub const ABORT_BYTE0: u8 = command_byte::cs(CS_ABORT);

impl BlockSegment {
    /// Parses a block segment. Sequence number 0 is refused (0x80 is an abort frame).
    pub fn parse(data: &[u8]) -> Result<Self, SdoWireError> {
        let p = SdoPacket::new_checked(data)?;
        if p.seqno() == 0 {
            return Err(SdoWireError::SequenceNumber(p.command()));
        }
        Ok(Self {
            seqno: p.seqno(),
            last: p.block_last(),
            data: p.segment_data(),
        })
    }

    /// Writes the segment into a view over 8 bytes.
    pub fn emit_into<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut SdoPacket<T>) {
        p.set_command(command_byte::block_segment(self.last, self.seqno));
        p.set_segment_data(self.data);
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; SDO_LEN] {
        to_bytes(|p| self.emit_into(p))
    }
}

#[cfg(test)]
mod tests;
