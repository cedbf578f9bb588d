//! The emulated EtherCAT slave controller (ESC). So far: its wire formats.

pub mod datagram;
pub mod frame;
