//! gantry's CANopen bus (CiA 301 / CiA 402 over CAN): the second [`CycleBus`] beside
//! EtherCAT. The bring-up ([`bring_up`]) resets the nodes' communication, waits for their
//! boot-up, checks each is a CiA 402 drive, maps its PDOs by SDO in pre-operational and
//! starts it; the cycle ([`bus::CanopenBus`]) sends each drive's RPDOs then the SYNC from
//! the cycle thread and reads the TPDOs the drives answer with until the deadline, and
//! watches the nodes: EMCY, heartbeat, boot-up. [`load`] refuses a configuration whose
//! frames do not fit the bit rate, [`eds`] one that the drives' EDS say they would
//! refuse; [`pdo`] packs an axis' layout into PDOs. The bus
//! talks through a [`link::CanLink`] (SocketCAN, or an in-memory bus in lockstep tests).
//!
//! Drive positions: axis `i` of the configuration is on bus position `i`, the node its
//! `node` key names (one node per axis), so the cycle ([`crate::runtime::cycle::Cycle`])
//! addresses CANopen drives exactly as it addresses EtherCAT slaves. The digital-input
//! modules (CiA 401) the axes' switches read ([`io_module`]) come after the drives, on
//! positions `axes..`, in the order the configuration first names them.
//!
//! [`CycleBus`]: crate::runtime::bus::CycleBus

pub mod bring_up;
pub mod bus;
pub mod eds;
pub mod io_module;
pub mod link;
pub mod load;
pub mod pdo;
pub mod socket;

pub use bus::CanopenBus;
pub use link::{CanLink, Received};
pub use socket::SocketLink;
