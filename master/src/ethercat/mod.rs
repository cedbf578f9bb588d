//! gantry's EtherCAT master on ethercrab: the bus' bring-up (to SafeOp), its cyclic
//! exchange of the process data, its health and the recovery of slaves — one
//! implementation of [`crate::runtime::bus::CycleBus`], on a network interface or on the
//! in-process simulator's chain.

pub mod bus;
pub mod coalesce;
pub mod doorbell;
pub mod embedded;
pub mod frame;
pub mod health;
pub mod link;
pub mod mapping;
pub mod pump;
pub mod raw;
pub mod recovery;
pub mod transition;
