//! Service data objects (CiA 301 §7.2.4): confirmed access to any object of a node's
//! dictionary — expedited (up to 4 bytes in one exchange), segmented (7 bytes per
//! confirmed exchange) and block (sub-blocks of up to 127 unconfirmed segments, one
//! acknowledgement each, CRC over the whole).
//!
//! [`packet`] is the typed view over an SDO frame's bytes, [`command`] the commands parsed
//! from it, [`abort`] the abort codes, [`crc`] the block CRC,
//! [`dictionary`] what the server serves; [`SdoClient`] and [`SdoServer`] are the protocol
//! machines. Both are sans-I/O: feed them each received frame with the time
//! ([`SdoClient::receive`], [`SdoServer::receive`]), call `poll` with the time for
//! timeouts, and send every frame `transmit` returns until it returns None. They store the
//! data in a buffer the caller gives at construction (any `AsRef<[u8]> + AsMut<[u8]>`:
//! an array, a boxed slice made before the cycle starts), so nothing allocates after.

pub mod abort;
mod block;
pub mod client;
pub mod command;
pub mod crc;
pub mod dictionary;
pub mod packet;
pub mod server;
mod timing;

pub use abort::AbortCode;
pub use client::{DownloadMode, SdoClient, SdoClientError, UploadMode};
pub use command::{BlockSegment, ClientCommand, Initiate, Multiplexer, Segment, ServerCommand};
pub use dictionary::{Access, EntryInfo, ObjectDictionary, ObjectSize};
pub use packet::SdoPacket;
pub use server::SdoServer;

use thiserror::Error;

/// Which end of an SDO connection.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    /// The client (the master, here).
    Client,
    /// The server (the node).
    Server,
}

/// How a transfer ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Outcome {
    /// A download completed: the client got the server's confirmation; the server wrote
    /// the value to its dictionary.
    Downloaded {
        /// The object.
        mux: Multiplexer,
        /// Bytes written.
        len: usize,
    },
    /// An upload completed: the data is the first `len` bytes of the machine's buffer.
    Uploaded {
        /// The object.
        mux: Multiplexer,
        /// Bytes read.
        len: usize,
    },
    /// The transfer was aborted: by the peer (an abort frame arrived) or by this side
    /// (a protocol violation, a refused access, a timeout; the abort frame was queued).
    Aborted {
        /// The object.
        mux: Multiplexer,
        /// Why.
        code: AbortCode,
        /// Who aborted.
        by: Side,
    },
}

/// Protocol timing and block parameters, for either side.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SdoConfig {
    /// How long to wait for the peer's next frame before aborting with 0x05040000
    /// (CiA 301 leaves it to the application; 1 s is common).
    pub timeout_ns: u64,
    /// Segments per sub-block this side asks for when it receives a block (1..=127).
    pub block_size: u8,
    /// Whether this side supports the block CRC (CiA 301 §7.2.4.3.16; used only if both do).
    pub crc: bool,
    /// When receiving a sub-block: how long after the last segment to acknowledge what
    /// arrived in order, if the sub-block's last segment does not come (it was lost).
    /// Without it a lost last segment ends in a timeout (CiA 301 has no early
    /// acknowledgement); with it, in a retransmission. Off by default: segments are not
    /// told apart by sub-block, so segments of the old sub-block that were only late (a
    /// stalled sender) are taken as the new one's and the transfer fails (wrong CRC or an
    /// overrun). Only for links that lose frames but never delay them.
    pub sub_block_timeout_ns: Option<u64>,
    /// Client, block upload: protocol switch threshold sent to the server (0: none); the
    /// server may answer a smaller object with a normal upload (§7.2.4.3.13).
    pub pst: u8,
    /// Client, segmented and block download: whether to indicate the size.
    pub indicate_size: bool,
    /// Server: whether it serves block transfers (CiA 301 makes them optional; a server
    /// without them refuses a block request with 0x05040001, the command specifier it
    /// does not know).
    pub block: bool,
}

impl Default for SdoConfig {
    fn default() -> Self {
        Self {
            timeout_ns: 1_000_000_000,
            block_size: command::MAX_BLOCK_SIZE,
            crc: true,
            sub_block_timeout_ns: None,
            pst: 0,
            indicate_size: true,
            block: true,
        }
    }
}

/// A configuration the machines cannot run with.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum SdoConfigError {
    /// Block size outside 1..=127.
    #[error("SDO block size {0} is outside 1..=127 (CiA 301 §7.2.4.3.9)")]
    BlockSize(u8),
    /// A zero timeout.
    #[error("SDO timeout of 0 ns: every transfer would time out at once")]
    Timeout,
}

impl SdoConfig {
    /// Checks the values.
    pub fn validate(&self) -> Result<(), SdoConfigError> {
        if self.block_size == 0 || self.block_size > command::MAX_BLOCK_SIZE {
            return Err(SdoConfigError::BlockSize(self.block_size));
        }
        if self.timeout_ns == 0 {
            return Err(SdoConfigError::Timeout);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
