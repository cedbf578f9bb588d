//! Acyclic object access (SDO) while the cycle runs: what the application asks of a
//! drive's object dictionary and what comes back, in bus-neutral terms (index, sub-index,
//! bytes, a CiA 301 abort code). A bus carries a transfer beside the process data, one
//! step per exchange under the cycle's deadline ([`super::bus::CycleBus::start_sdo`]);
//! on EtherCAT that is CoE through the slave's mailbox, on CANopen the SDO channel.
//!
//! Everything here is `Copy` and fixed-size: a transfer crosses the cycle thread without
//! allocating, so its data is capped at [`SDO_MAX_DATA`] bytes — enough for any numeric
//! object and for the strings a commissioning engineer reads (device name, versions);
//! larger objects (firmware, files) are for FoE or block transfer outside the cycle.

use std::fmt;

use gantry_drives::canopen::sdo::abort::AbortCode;
use thiserror::Error;

/// Most data bytes one transfer carries either way.
pub const SDO_MAX_DATA: usize = 256;

/// How long a drive may take for a whole transfer, by default (ns). CiA 301 leaves it to
/// the application; masters use 1 to 3 s per service, and a segmented transfer of
/// [`SDO_MAX_DATA`] bytes takes a few services.
pub const SDO_TIMEOUT_NS: u64 = 2_000_000_000;

/// Up to [`SDO_MAX_DATA`] bytes, inline.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct SdoData {
    len: u16,
    bytes: [u8; SDO_MAX_DATA],
}

impl SdoData {
    /// No bytes.
    pub const EMPTY: Self = Self {
        len: 0,
        bytes: [0; SDO_MAX_DATA],
    };

    /// A copy of `bytes`; `None` when longer than [`SDO_MAX_DATA`].
    pub fn new(bytes: &[u8]) -> Option<Self> {
        let mut d = Self::EMPTY;
        d.bytes.get_mut(..bytes.len())?.copy_from_slice(bytes);
        d.len = bytes.len() as u16;
        Some(d)
    }

    /// The bytes.
    pub fn as_slice(&self) -> &[u8] {
        self.bytes.get(..usize::from(self.len)).unwrap_or_default()
    }

    /// Appends `more`; false (nothing appended) when the total would pass
    /// [`SDO_MAX_DATA`].
    pub fn extend(&mut self, more: &[u8]) -> bool {
        let at = usize::from(self.len);
        match self.bytes.get_mut(at..at + more.len()) {
            Some(dst) => {
                dst.copy_from_slice(more);
                self.len += more.len() as u16;
                true
            }
            None => false,
        }
    }

    /// Number of bytes.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// No bytes.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl Default for SdoData {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl fmt::Debug for SdoData {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "SdoData({:02X?})", self.as_slice())
    }
}

/// Which way a transfer goes.
// The data is inline on purpose: boxing it would allocate in the cycle thread.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoKind {
    /// Read the object (the drive uploads it to the master).
    Upload,
    /// Write these bytes to the object (the master downloads them to the drive).
    Download(SdoData),
}

/// One transfer to one object of one drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoRequest {
    /// The drive, by its position on the bus (what an axis' `drive` says).
    pub drive: usize,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Upload or download.
    pub kind: SdoKind,
    /// How long the drive may take for the whole transfer (ns).
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
}

/// What a transfer ended with: the object's bytes for an upload, none for a download.
pub type SdoResult = Result<SdoData, SdoError>;

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
    /// The drive did not finish the transfer in time.
    #[error("drive {drive}: SDO 0x{index:04X}:{sub:02X}: no answer within {waited_ms} ms")]
    TimedOut {
        /// The drive.
        drive: usize,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// How long the master waited.
        waited_ms: u64,
    },
    /// The object is larger than one transfer in the cycle carries.
    #[error(
        "drive {drive}: SDO 0x{index:04X}:{sub:02X} holds {size} bytes, more than the \
         {SDO_MAX_DATA} a transfer beside the cycle carries"
    )]
    TooLarge {
        /// The drive.
        drive: usize,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The size the drive announced.
        size: u32,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_holds_up_to_its_cap_and_no_more() {
        let d = SdoData::new(&[1, 2, 3]).unwrap();
        assert_eq!(d.as_slice(), &[1, 2, 3]);
        assert!(SdoData::new(&[0; SDO_MAX_DATA]).is_some());
        assert!(SdoData::new(&[0; SDO_MAX_DATA + 1]).is_none());
        let mut d = SdoData::new(&[0; SDO_MAX_DATA - 2]).unwrap();
        assert!(d.extend(&[7, 8]));
        assert!(!d.extend(&[9]));
        assert_eq!(d.len(), SDO_MAX_DATA);
        assert_eq!(&d.as_slice()[SDO_MAX_DATA - 2..], &[7, 8]);
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
