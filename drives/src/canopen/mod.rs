//! CANopen (CiA 301 v4.2) communication layer, sans-I/O: typed views over CAN frames and
//! the SDO protocol machines, shared by the master (SDO client) and the simulated nodes
//! (SDO server, object dictionary).
//!
//! Nothing here touches a socket or reads a clock: every machine takes the received
//! [`CanFrame`] and the time in nanoseconds and hands back the frames to send, so the same
//! code runs on SocketCAN, on an in-memory bus and in lockstep tests. No function here
//! allocates or panics, whatever the input (fuzzed by the property tests of each module).
//!
//! Written so far (issue 12 §2, first part): frames and the predefined connection set
//! ([`frame`], [`cob_id`]), NMT node control ([`nmt`]), heartbeat / boot-up ([`heartbeat`]),
//! SYNC ([`sync`]), EMCY ([`emcy`]), SDO wire formats, abort codes, client and server
//! ([`sdo`]). Not yet: the NMT master, PDO configuration, the SYNC producer, the EMCY and
//! heartbeat consumers.
//!
//! EDS/DCF ([`eds`], CiA 306-1) is configuration-time code beside them: it reads and
//! writes files and allocates; nothing on the cycle path calls it.

pub mod cob_id;
pub mod eds;
pub mod emcy;
pub mod frame;
pub mod heartbeat;
pub mod nmt;
pub mod sdo;
pub mod sync;

pub use cob_id::{CobId, FunctionCode, NodeId};
pub use frame::CanFrame;
