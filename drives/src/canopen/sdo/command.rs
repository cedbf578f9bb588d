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

    fn parse(b0: u8, field: [u8; 4]) -> Self {
        let e = b0 & 0x02 != 0;
        let s = b0 & 0x01 != 0;
        if e {
            let n = (b0 >> 2) & 0x03;
            let len = s.then_some(4 - n);
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
                size: s.then_some(u32::from_le_bytes(field)),
            }
        }
    }

    /// Byte 0 flags (n, e, s) and bytes 4–7.
    fn emit(&self) -> (u8, [u8; 4]) {
        match *self {
            Self::Expedited { data, len: None } => (0x02, data),
            Self::Expedited {
                data,
                len: Some(len),
            } => {
                let len = len.clamp(1, 4);
                let mut out = [0u8; 4];
                for (i, (o, d)) in out.iter_mut().zip(data).enumerate() {
                    if i < len as usize {
                        *o = d;
                    }
                }
                (((4 - len) << 2) | 0x03, out)
            }
            Self::Segmented { size: None } => (0x00, [0; 4]),
            Self::Segmented { size: Some(s) } => (0x01, s.to_le_bytes()),
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

    fn parse(b0: u8, rest: [u8; 7]) -> Self {
        let n = (b0 >> 1) & 0x07;
        let len = 7 - n;
        let mut data = rest;
        // Bytes past 7 − n carry no data: keep them zero.
        for (i, d) in data.iter_mut().enumerate() {
            if i >= len as usize {
                *d = 0;
            }
        }
        Self {
            toggle: b0 & 0x10 != 0,
            last: b0 & 0x01 != 0,
            data,
            len,
        }
    }

    fn emit(&self, cs: u8) -> [u8; SDO_LEN] {
        let len = self.len.min(7);
        let n = 7 - len;
        let mut out = [0u8; SDO_LEN];
        out[0] = (cs << 5) | ((self.toggle as u8) << 4) | (n << 1) | self.last as u8;
        for (i, (o, d)) in out.iter_mut().skip(1).zip(self.data).enumerate() {
            if i < len as usize {
                *o = d;
            }
        }
        out
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

fn mux_of(b: &[u8; SDO_LEN]) -> Multiplexer {
    Multiplexer {
        index: u16::from_le_bytes([b[1], b[2]]),
        sub: b[3],
    }
}

fn field_of(b: &[u8; SDO_LEN]) -> [u8; 4] {
    [b[4], b[5], b[6], b[7]]
}

fn rest_of(b: &[u8; SDO_LEN]) -> [u8; 7] {
    [b[1], b[2], b[3], b[4], b[5], b[6], b[7]]
}

fn with_mux(b0: u8, mux: Multiplexer, field: [u8; 4]) -> [u8; SDO_LEN] {
    let [i0, i1] = mux.index.to_le_bytes();
    let [f0, f1, f2, f3] = field;
    [b0, i0, i1, mux.sub, f0, f1, f2, f3]
}

fn eight(data: &[u8]) -> Result<&[u8; SDO_LEN], SdoWireError> {
    data.try_into()
        .map_err(|_| SdoWireError::Length(data.len()))
}

impl ClientCommand {
    /// Parses the 8 data bytes of a client → server frame.
    pub fn parse(data: &[u8]) -> Result<Self, SdoWireError> {
        let b = eight(data)?;
        let b0 = b[0];
        let sub = b0 & 0x03;
        let bad = || SdoWireError::CommandSpecifier {
            direction: "request",
            byte: b0,
            cs: b0 >> 5,
        };
        Ok(match b0 >> 5 {
            CCS_DOWNLOAD_SEGMENT => Self::DownloadSegment(Segment::parse(b0, rest_of(b))),
            CCS_INITIATE_DOWNLOAD => Self::InitiateDownload {
                mux: mux_of(b),
                payload: Initiate::parse(b0, field_of(b)),
            },
            CCS_INITIATE_UPLOAD => Self::InitiateUpload { mux: mux_of(b) },
            CCS_UPLOAD_SEGMENT => Self::UploadSegment {
                toggle: b0 & 0x10 != 0,
            },
            CS_ABORT => Self::Abort {
                mux: mux_of(b),
                code: AbortCode(u32::from_le_bytes(field_of(b))),
            },
            CCS_BLOCK_UPLOAD => match sub {
                SUB_INITIATE => Self::BlockUploadInitiate {
                    mux: mux_of(b),
                    crc: b0 & 0x04 != 0,
                    block_size: b[4],
                    pst: b[5],
                },
                SUB_START => Self::BlockUploadStart,
                SUB_ACK => Self::BlockUploadAck {
                    ackseq: b[1],
                    block_size: b[2],
                },
                _ => Self::BlockUploadEnd,
            },
            CCS_BLOCK_DOWNLOAD => {
                if b0 & 0x01 == SUB_INITIATE {
                    Self::BlockDownloadInitiate {
                        mux: mux_of(b),
                        crc: b0 & 0x04 != 0,
                        size: (b0 & 0x02 != 0).then_some(u32::from_le_bytes(field_of(b))),
                    }
                } else {
                    Self::BlockDownloadEnd {
                        unused: (b0 >> 2) & 0x07,
                        crc: u16::from_le_bytes([b[1], b[2]]),
                    }
                }
            }
            _ => return Err(bad()),
        })
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; SDO_LEN] {
        match *self {
            Self::InitiateDownload { mux, payload } => {
                let (flags, field) = payload.emit();
                with_mux((CCS_INITIATE_DOWNLOAD << 5) | flags, mux, field)
            }
            Self::DownloadSegment(s) => s.emit(CCS_DOWNLOAD_SEGMENT),
            Self::InitiateUpload { mux } => with_mux(CCS_INITIATE_UPLOAD << 5, mux, [0; 4]),
            Self::UploadSegment { toggle } => [
                (CCS_UPLOAD_SEGMENT << 5) | ((toggle as u8) << 4),
                0,
                0,
                0,
                0,
                0,
                0,
                0,
            ],
            Self::Abort { mux, code } => with_mux(CS_ABORT << 5, mux, code.0.to_le_bytes()),
            Self::BlockDownloadInitiate { mux, crc, size } => {
                let b0 = (CCS_BLOCK_DOWNLOAD << 5)
                    | ((crc as u8) << 2)
                    | ((size.is_some() as u8) << 1)
                    | SUB_INITIATE;
                with_mux(b0, mux, size.unwrap_or(0).to_le_bytes())
            }
            Self::BlockDownloadEnd { unused, crc } => {
                let [c0, c1] = crc.to_le_bytes();
                let b0 = (CCS_BLOCK_DOWNLOAD << 5) | ((unused & 0x07) << 2) | SUB_END;
                [b0, c0, c1, 0, 0, 0, 0, 0]
            }
            Self::BlockUploadInitiate {
                mux,
                crc,
                block_size,
                pst,
            } => with_mux(
                (CCS_BLOCK_UPLOAD << 5) | ((crc as u8) << 2) | SUB_INITIATE,
                mux,
                [block_size, pst, 0, 0],
            ),
            Self::BlockUploadStart => [(CCS_BLOCK_UPLOAD << 5) | SUB_START, 0, 0, 0, 0, 0, 0, 0],
            Self::BlockUploadAck { ackseq, block_size } => [
                (CCS_BLOCK_UPLOAD << 5) | SUB_ACK,
                ackseq,
                block_size,
                0,
                0,
                0,
                0,
                0,
            ],
            Self::BlockUploadEnd => [(CCS_BLOCK_UPLOAD << 5) | SUB_END, 0, 0, 0, 0, 0, 0, 0],
        }
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
        let b = eight(data)?;
        let b0 = b[0];
        let bad = || SdoWireError::CommandSpecifier {
            direction: "response",
            byte: b0,
            cs: b0 >> 5,
        };
        Ok(match b0 >> 5 {
            SCS_UPLOAD_SEGMENT => Self::UploadSegment(Segment::parse(b0, rest_of(b))),
            SCS_DOWNLOAD_SEGMENT => Self::DownloadSegment {
                toggle: b0 & 0x10 != 0,
            },
            SCS_INITIATE_UPLOAD => Self::InitiateUpload {
                mux: mux_of(b),
                payload: Initiate::parse(b0, field_of(b)),
            },
            SCS_INITIATE_DOWNLOAD => Self::InitiateDownload { mux: mux_of(b) },
            CS_ABORT => Self::Abort {
                mux: mux_of(b),
                code: AbortCode(u32::from_le_bytes(field_of(b))),
            },
            SCS_BLOCK_DOWNLOAD => match b0 & 0x03 {
                SUB_INITIATE => Self::BlockDownloadInitiate {
                    mux: mux_of(b),
                    crc: b0 & 0x04 != 0,
                    block_size: b[4],
                },
                SUB_END => Self::BlockDownloadEnd,
                SUB_ACK => Self::BlockDownloadAck {
                    ackseq: b[1],
                    block_size: b[2],
                },
                _ => return Err(bad()),
            },
            SCS_BLOCK_UPLOAD => {
                if b0 & 0x01 == SUB_INITIATE {
                    Self::BlockUploadInitiate {
                        mux: mux_of(b),
                        crc: b0 & 0x04 != 0,
                        size: (b0 & 0x02 != 0).then_some(u32::from_le_bytes(field_of(b))),
                    }
                } else {
                    Self::BlockUploadEnd {
                        unused: (b0 >> 2) & 0x07,
                        crc: u16::from_le_bytes([b[1], b[2]]),
                    }
                }
            }
            _ => return Err(bad()),
        })
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; SDO_LEN] {
        match *self {
            Self::InitiateDownload { mux } => with_mux(SCS_INITIATE_DOWNLOAD << 5, mux, [0; 4]),
            Self::DownloadSegment { toggle } => [
                (SCS_DOWNLOAD_SEGMENT << 5) | ((toggle as u8) << 4),
                0,
                0,
                0,
                0,
                0,
                0,
                0,
            ],
            Self::InitiateUpload { mux, payload } => {
                let (flags, field) = payload.emit();
                with_mux((SCS_INITIATE_UPLOAD << 5) | flags, mux, field)
            }
            Self::UploadSegment(s) => s.emit(SCS_UPLOAD_SEGMENT),
            Self::Abort { mux, code } => with_mux(CS_ABORT << 5, mux, code.0.to_le_bytes()),
            Self::BlockDownloadInitiate {
                mux,
                crc,
                block_size,
            } => with_mux(
                (SCS_BLOCK_DOWNLOAD << 5) | ((crc as u8) << 2) | SUB_INITIATE,
                mux,
                [block_size, 0, 0, 0],
            ),
            Self::BlockDownloadAck { ackseq, block_size } => [
                (SCS_BLOCK_DOWNLOAD << 5) | SUB_ACK,
                ackseq,
                block_size,
                0,
                0,
                0,
                0,
                0,
            ],
            Self::BlockDownloadEnd => [(SCS_BLOCK_DOWNLOAD << 5) | SUB_END, 0, 0, 0, 0, 0, 0, 0],
            Self::BlockUploadInitiate { mux, crc, size } => with_mux(
                (SCS_BLOCK_UPLOAD << 5)
                    | ((crc as u8) << 2)
                    | ((size.is_some() as u8) << 1)
                    | SUB_INITIATE,
                mux,
                size.unwrap_or(0).to_le_bytes(),
            ),
            Self::BlockUploadEnd { unused, crc } => {
                let [c0, c1] = crc.to_le_bytes();
                [
                    (SCS_BLOCK_UPLOAD << 5) | ((unused & 0x07) << 2) | SUB_END,
                    c0,
                    c1,
                    0,
                    0,
                    0,
                    0,
                    0,
                ]
            }
        }
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
pub const ABORT_BYTE0: u8 = CS_ABORT << 5;

impl BlockSegment {
    /// Parses a block segment. Sequence number 0 is refused (0x80 is an abort frame).
    pub fn parse(data: &[u8]) -> Result<Self, SdoWireError> {
        let b = eight(data)?;
        let seqno = b[0] & 0x7F;
        if seqno == 0 {
            return Err(SdoWireError::SequenceNumber(b[0]));
        }
        Ok(Self {
            seqno,
            last: b[0] & 0x80 != 0,
            data: rest_of(b),
        })
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; SDO_LEN] {
        let [d0, d1, d2, d3, d4, d5, d6] = self.data;
        [
            ((self.last as u8) << 7) | (self.seqno & 0x7F),
            d0,
            d1,
            d2,
            d3,
            d4,
            d5,
            d6,
        ]
    }
}

#[cfg(test)]
mod tests;
