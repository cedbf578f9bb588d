//! The emulated EtherCAT slave controller (ESC): a register file and its rules.
//! So far: wire formats, the register table, memory with access rights, and the
//! physical-addressing commands with their working-counter rules.

pub mod al;
pub mod command;
pub mod datagram;
pub mod dc;
pub mod fmmu;
pub mod frame;
pub mod memory;
pub mod registers;
pub mod sii;
pub mod watchdog;
