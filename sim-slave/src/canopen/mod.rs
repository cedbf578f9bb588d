//! CANopen nodes (CiA 301 slave side) for the simulator: a device of [`crate::plant`] —
//! the CiA 402 servo, the encoder module as a CiA 406 encoder, the switch-cam module as
//! CiA 401 digital inputs ([`device`]) — behind an NMT slave ([`nmt`]), SDO server on its
//! object dictionary ([`dictionary`]), PDOs with the CiA 301 configuration rules
//! ([`pdo`]), SYNC, EMCY and heartbeat, sans-I/O ([`node::CanNode`]); its EDS ([`eds`],
//! through the shared model and writer of `gantry_drives::canopen::eds`); and an
//! in-memory CAN bus that delivers frames to several nodes in lockstep ([`bus::CanBus`]);
//! the nodes of a chain description behind one CAN interface ([`network::CanNetwork`],
//! `gantry-sim --can`).
//! The wire formats and the SDO machines are `gantry_drives::canopen`, shared with the
//! master.

pub mod bus;
pub mod device;
pub mod dictionary;
pub mod eds;
pub mod network;
pub mod nmt;
pub mod node;
pub mod pdo;

pub use bus::CanBus;
pub use device::{CanDevice, CanDeviceConfig, DeviceKind};
pub use network::{CanNetwork, CanNetworkError};
pub use node::{CanNode, CanNodeConfig, CanNodeError, SlaveNodeError};
