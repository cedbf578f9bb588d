//! Acyclic object access (SDO) while the cycle runs: what the application asks of a
//! drive's object dictionary and what comes back, in bus-neutral terms (index, sub-index,
//! bytes, a CiA 301 abort code). A bus carries a transfer beside the process data, a
//! bounded step per exchange under the cycle's deadline
//! ([`super::bus::CycleBus::start_sdo`]); on EtherCAT that is CoE through the slave's
//! mailbox, on CANopen the SDO channel.
//!
//! The application's side ([`SdoRequest`], [`SdoData`], [`SdoResult`]) owns its bytes
//! as it likes. The cycle thread's side never allocates nor frees: a transfer's bytes
//! travel in an [`SdoBuffer`] the application allocated (once, at start: the
//! [`super::controller::Controller`] keeps them), of a fixed capacity — the largest
//! object a transfer carries, [`SDO_MAX_BYTES`] unless configured — which the cycle
//! thread fills or reads in place and hands back with the outcome ([`SdoEnded`]). The
//! rest ([`SdoTransfer`], [`SdoError`]) is `Copy`.

use std::fmt;

use gantry_drives::canopen::sdo::abort::AbortCode;
use thiserror::Error;

/// The largest object a transfer carries unless `[bus] sdo_max_bytes` says otherwise
/// (bytes): a 64 KiB recorder or parameter file.
pub const SDO_MAX_BYTES: usize = 64 * 1024;

/// The least `[bus] sdo_max_bytes` may be: every string and numeric object fits.
pub const SDO_MIN_BYTES: usize = 256;

/// The most `[bus] sdo_max_bytes` may be (16 MiB): a firmware image is for FoE or a
/// file transfer, not for an object read beside the cycle.
pub const SDO_LIMIT_BYTES: usize = 16 << 20;

/// How long a drive may stay silent while it owes an answer, by default (ns). CiA 301
/// leaves the SDO timeout to the application; masters use 1 to 3 s per service. A large
/// object takes many services, each given this time: a transfer that makes progress is
/// never cut short.
pub const SDO_TIMEOUT_NS: u64 = 2_000_000_000;

/// An object's bytes on the application's side.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct SdoData(Vec<u8>);

impl SdoData {
    /// No bytes.
    pub const EMPTY: Self = Self(Vec::new());

    /// A copy of `bytes`.
    pub fn new(bytes: &[u8]) -> Self {
        Self(bytes.to_vec())
    }

    /// The bytes.
    pub fn as_slice(&self) -> &[u8] {
        &self.0
    }

    /// The bytes, owned.
    pub fn into_vec(self) -> Vec<u8> {
        self.0
    }

    /// Number of bytes.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// No bytes.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl From<Vec<u8>> for SdoData {
    fn from(bytes: Vec<u8>) -> Self {
        Self(bytes)
    }
}

impl fmt::Debug for SdoData {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const SHOWN: usize = 64;
        match self.0.get(..SHOWN) {
            Some(head) if self.0.len() > SHOWN => {
                write!(f, "SdoData({} bytes: {head:02X?}…)", self.0.len())
            }
            _ => write!(f, "SdoData({:02X?})", self.0),
        }
    }
}

/// A transfer's bytes on their way to and from the cycle thread: `len` bytes at the start
/// of a block of fixed capacity, allocated by the application. The cycle thread fills
/// it (an upload) or sends from it (a download) in place; it never grows, allocates or
/// frees it, and hands it back with the outcome ([`SdoEnded`]).
pub struct SdoBuffer {
    bytes: Box<[u8]>,
    len: usize,
}

impl SdoBuffer {
    /// An empty buffer for objects of up to `capacity` bytes (allocates: not on the
    /// cycle thread).
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            bytes: vec![0; capacity].into_boxed_slice(),
            len: 0,
        }
    }

    /// The most bytes it holds.
    pub fn capacity(&self) -> usize {
        self.bytes.len()
    }

    /// The bytes it holds.
    pub fn as_slice(&self) -> &[u8] {
        self.bytes.get(..self.len).unwrap_or_default()
    }

    /// Number of bytes it holds.
    pub fn len(&self) -> usize {
        self.len
    }

    /// It holds no bytes.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Holds a copy of `bytes` instead; false (unchanged) if they do not fit.
    pub fn fill(&mut self, bytes: &[u8]) -> bool {
        match self.bytes.get_mut(..bytes.len()) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                self.len = bytes.len();
                true
            }
            None => false,
        }
    }

    /// Appends `more`; false (nothing appended) when the total would pass the capacity.
    pub fn extend(&mut self, more: &[u8]) -> bool {
        let at = self.len;
        match self.bytes.get_mut(at..at + more.len()) {
            Some(dst) => {
                dst.copy_from_slice(more);
                self.len += more.len();
                true
            }
            None => false,
        }
    }

    /// Holds no bytes (the capacity stays).
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// The whole block, for a protocol machine that sends from it in place.
    pub fn storage(&self) -> &[u8] {
        &self.bytes
    }

    /// The whole block, for a protocol machine that writes an upload in place; then
    /// [`SdoBuffer::set_len`].
    pub fn storage_mut(&mut self) -> &mut [u8] {
        &mut self.bytes
    }

    /// Holds the first `len` bytes of the block; false (unchanged) past the capacity.
    pub fn set_len(&mut self, len: usize) -> bool {
        let fits = len <= self.bytes.len();
        if fits {
            self.len = len;
        }
        fits
    }
}

impl fmt::Debug for SdoBuffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "SdoBuffer({} of {} bytes)", self.len, self.bytes.len())
    }
}

/// Which way a transfer goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoDirection {
    /// Read the object (the drive uploads it to the master).
    Upload,
    /// Write it (the master downloads the buffer's bytes to the drive).
    Download,
}

/// One transfer as the bus carries it (its bytes in the [`SdoBuffer`] beside it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoTransfer {
    /// The drive, by its position on the bus (what an axis' `drive` says).
    pub drive: usize,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Upload or download.
    pub direction: SdoDirection,
    /// How long the drive may stay silent while it owes an answer (ns).
    pub timeout_ns: u64,
}

impl SdoTransfer {
    /// Reads `index:sub` of drive `drive`, with the default timeout.
    pub const fn upload(drive: usize, index: u16, sub: u8) -> Self {
        Self {
            drive,
            index,
            sub,
            direction: SdoDirection::Upload,
            timeout_ns: SDO_TIMEOUT_NS,
        }
    }

    /// Writes the buffer to `index:sub` of drive `drive`, with the default timeout.
    pub const fn download(drive: usize, index: u16, sub: u8) -> Self {
        Self {
            drive,
            index,
            sub,
            direction: SdoDirection::Download,
            timeout_ns: SDO_TIMEOUT_NS,
        }
    }
}

/// How a transfer on the bus ended: `result`, and its buffer back — holding the object's
/// bytes after an upload, none after a download.
#[derive(Debug)]
pub struct SdoEnded {
    /// Done, or why not.
    pub result: Result<(), SdoError>,
    /// The buffer lent with the transfer.
    pub buffer: SdoBuffer,
}

impl SdoEnded {
    /// Ended at once with `error` (refused), the buffer given back untouched.
    pub fn refused(error: SdoError, buffer: SdoBuffer) -> Self {
        Self {
            result: Err(error),
            buffer,
        }
    }
}

/// Which way a request goes, with the bytes to write.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SdoKind {
    /// Read the object (the drive uploads it to the master).
    Upload,
    /// Write these bytes to the object (the master downloads them to the drive).
    Download(SdoData),
}

/// One transfer to one object of one drive, as the application asks for it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SdoRequest {
    /// The drive, by its position on the bus (what an axis' `drive` says).
    pub drive: usize,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Upload or download.
    pub kind: SdoKind,
    /// How long the drive may stay silent while it owes an answer (ns).
    pub timeout_ns: u64,
}

impl SdoRequest {
    /// Reads `index:sub` of drive `drive`, with the default timeout.
    pub fn upload(drive: usize, index: u16, sub: u8) -> Self {
        Self {
            drive,
            index,
            sub,
            kind: SdoKind::Upload,
            timeout_ns: SDO_TIMEOUT_NS,
        }
    }

    /// Writes `data` to `index:sub` of drive `drive`, with the default timeout.
    pub fn download(drive: usize, index: u16, sub: u8, data: SdoData) -> Self {
        Self {
            drive,
            index,
            sub,
            kind: SdoKind::Download(data),
            timeout_ns: SDO_TIMEOUT_NS,
        }
    }

    /// The transfer as the bus carries it.
    pub fn transfer(&self) -> SdoTransfer {
        SdoTransfer {
            drive: self.drive,
            index: self.index,
            sub: self.sub,
            direction: match self.kind {
                SdoKind::Upload => SdoDirection::Upload,
                SdoKind::Download(_) => SdoDirection::Download,
            },
            timeout_ns: self.timeout_ns,
        }
    }
}

/// What a transfer ended with: the object's bytes for an upload, none for a download.
pub type SdoResult = Result<SdoData, SdoError>;

/// An object's size in an error: the bytes the drive announced, if it did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ObjectBytes(pub Option<u32>);

impl fmt::Display for ObjectBytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(n) => write!(f, "{n} bytes"),
            None => f.write_str("a size it did not announce"),
        }
    }
}

/// Why a transfer failed. `Copy`: the cycle thread hands it on without allocating.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum SdoError {
    /// The bus has no acyclic object access (yet).
    #[error("this bus does not carry SDO transfers while the cycle runs")]
    NotSupported,
    /// Another transfer is running on the bus (one at a time).
    #[error("another SDO transfer is running; try again")]
    Busy,
    /// No drive at that position.
    #[error("no drive at bus position {drive}")]
    NoDrive {
        /// The position asked for.
        drive: usize,
    },
    /// The drive has no channel for SDO (EtherCAT: no CoE mailbox).
    #[error("drive {drive} has no SDO channel (EtherCAT: no CoE mailbox)")]
    NoChannel {
        /// The drive.
        drive: usize,
    },
    /// The drive aborted the transfer (or the master did, for the reason given).
    #[error("drive {drive}: SDO 0x{index:04X}:{sub:02X} aborted: {code}")]
    Aborted {
        /// The drive.
        drive: usize,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// CiA 301 Table 22 code; its `Display` has the text.
        code: AbortCode,
    },
    /// The drive did not answer in time.
    #[error("drive {drive}: SDO 0x{index:04X}:{sub:02X}: no answer within {waited_ms} ms")]
    TimedOut {
        /// The drive.
        drive: usize,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// How long the master waited for the drive's next frame.
        waited_ms: u64,
    },
    /// The object is larger than a transfer may carry: a download refused before it
    /// starts, an upload aborted at the drive (0x05040005 out of memory) once it says its
    /// size.
    #[error(
        "drive {drive}: SDO 0x{index:04X}:{sub:02X}: the object has {size}, more than the \
         {max} bytes a transfer carries here (`[bus] sdo_max_bytes`)"
    )]
    TooLarge {
        /// The drive.
        drive: usize,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Its size: the data to write, or what the drive announced.
        size: ObjectBytes,
        /// The most a transfer carries.
        max: usize,
    },
    /// The drive answered something the protocol does not allow there.
    #[error("drive {drive}: SDO 0x{index:04X}:{sub:02X}: {what}")]
    Protocol {
        /// The drive.
        drive: usize,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What was wrong.
        what: &'static str,
    },
}

impl SdoError {
    /// A transfer of `t` refused as larger than `max` bytes: it has `size`.
    pub fn too_large(t: &SdoTransfer, size: Option<u32>, max: usize) -> Self {
        Self::TooLarge {
            drive: t.drive,
            index: t.index,
            sub: t.sub,
            size: ObjectBytes(size),
            max,
        }
    }

    /// A protocol error of `t`.
    pub fn protocol(t: &SdoTransfer, what: &'static str) -> Self {
        Self::Protocol {
            drive: t.drive,
            index: t.index,
            sub: t.sub,
            what,
        }
    }

    /// `t` aborted with `code`.
    pub fn aborted(t: &SdoTransfer, code: AbortCode) -> Self {
        Self::Aborted {
            drive: t.drive,
            index: t.index,
            sub: t.sub,
            code,
        }
    }

    /// `t` found the drive silent for `waited_ns`.
    pub fn timed_out(t: &SdoTransfer, waited_ns: u64) -> Self {
        Self::TimedOut {
            drive: t.drive,
            index: t.index,
            sub: t.sub,
            waited_ms: waited_ns / 1_000_000,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_buffer_holds_up_to_its_capacity_and_no_more() {
        let mut b = SdoBuffer::with_capacity(8);
        assert!(b.fill(&[1, 2, 3]));
        assert_eq!(b.as_slice(), &[1, 2, 3]);
        assert!(!b.fill(&[0; 9]), "past the capacity");
        assert_eq!(b.as_slice(), &[1, 2, 3], "unchanged");
        assert!(b.extend(&[4, 5, 6, 7, 8]));
        assert!(!b.extend(&[9]));
        assert_eq!(b.len(), 8);
        assert!(!b.set_len(9));
        assert!(b.set_len(2));
        assert_eq!(b.as_slice(), &[1, 2]);
        b.clear();
        assert!(b.is_empty());
        assert_eq!(b.capacity(), 8);
    }

    #[test]
    fn too_large_names_the_size_and_the_setting() {
        let t = SdoTransfer::upload(0, 0x2F00, 0);
        assert_eq!(
            SdoError::too_large(&t, Some(70_000), 65_536).to_string(),
            "drive 0: SDO 0x2F00:00: the object has 70000 bytes, more than the 65536 bytes a \
             transfer carries here (`[bus] sdo_max_bytes`)"
        );
        assert!(SdoError::too_large(&t, None, 256)
            .to_string()
            .contains("the object has a size it did not announce, more than the 256 bytes"));
    }

    #[test]
    fn an_abort_says_its_code_and_the_cia_301_text() {
        let e = SdoError::Aborted {
            drive: 1,
            index: 0x2000,
            sub: 0,
            code: AbortCode(0x0602_0000),
        };
        assert_eq!(
            e.to_string(),
            "drive 1: SDO 0x2000:00 aborted: 0x06020000 Object does not exist in the object \
             dictionary."
        );
    }
}
