//! One drive's share of a cycle in cyclic synchronous position mode, the master's side:
//! decode its inputs into feedback in user units, and turn set values in user units into
//! its outputs — the controlword from the shared CiA-402 table, the target position in
//! counts. Plain data in and out ([`CspSetpoint`], [`CspFeedback`]): this crate knows no
//! kernel, the master joins the two.
//!
//! # Counts
//!
//! Inside gantry a drive position is a 64-bit count. A CSP drive counts in 32 bits and
//! wraps (0x607A/0x6064 are INTEGER32; with the position range limit 0x607B at its
//! default, CiA 402-2, a position past 2³¹−1 continues at −2³¹), so the target sent is the
//! low half of the 64-bit count and the 32-bit position actual value is extended by the
//! difference to the last one ([`CountExtender`](crate::scaling::CountExtender)): crossing
//! ±2³¹ is no event for either side. A modulo axis' set position comes as whole periods
//! and the position within ([`CspSetpoint::turns`]); [`ModuloCounts`](crate::scaling::ModuloCounts)
//! turns that into counts exactly however many periods it has turned, and the channel
//! keeps the number of periods between the set value's frame and the drive's counter,
//! taken where the drive stands when it is enabled. A set position whose count does not
//! fit 64 bits is sent nowhere: the drive keeps its last target and the axis faults
//! ([`COUNT_RANGE_FAULT`]).
//!
//! Where each object sits comes from the drive's PDO layout (mapped by SDO in PreOp); a
//! drive left with its power-up mapping exchanges the minimal CSP set: outputs `0x6040
//! controlword: u16, 0x607A target position: i32`; inputs `0x6041 statusword: u16, 0x6064
//! position actual value: i32`. The bytes are read and written through the process-data
//! view the simulated drive uses too ([`crate::cia402::image`]).

mod channel;
mod codec;
mod offsets;
pub mod probe;

pub use channel::{CountError, CspChannel, CspFeedback, CspLatches, CspSetpoint};
pub use codec::{encode_outputs, encode_procedure_outputs, encode_touch_probe, CspInputs};
pub use offsets::{CspOffsets, LayoutError};

use crate::cia402::ModeOfOperation;

/// Error code reported for a faulted drive whose 0x603F error code is not in the process
/// data (CiA 301 generic error 0xFF00 "device specific"); the real code needs an SDO read.
pub const FAULT_CODE_NOT_MAPPED: u16 = 0xFF00;

/// Error code an axis faults with when its set position has no 64-bit count (CiA 301
/// 0x6320 "parameter error": the axis' scaling and travel ask for more than a drive
/// position can hold). The drive keeps its last target.
pub const COUNT_RANGE_FAULT: u16 = 0x6320;

/// Modes of operation: cyclic synchronous position.
pub const MODE_CSP: i8 = ModeOfOperation::CyclicSyncPosition.raw();
