//! gantry's EtherCAT master on ethercrab: the bus' bring-up (to SafeOp), its cyclic
//! exchange of the process data, its health and the recovery of slaves — one
//! implementation of [`crate::runtime::bus::CycleBus`], on a network interface or on a
//! link its caller plugs in ([`link::LinkFactory`]: the binary's in-process simulator).

pub mod bus;
pub mod coalesce;
pub mod coe_sdo;
pub mod doorbell;
pub mod frame;
pub mod health;
pub mod link;
pub mod mapping;
pub mod pump;
pub mod raw;
pub mod recovery;
pub mod transition;
