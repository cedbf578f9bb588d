//! The emulated EtherCAT slave controller (ESC): a register file and its rules.
//! Wire formats, the register table, memory with access rights, the addressing commands
//! with their working-counter rules, FMMUs, SyncManagers, the SII EEPROM, distributed
//! clocks, the process-data watchdog and the AL state machine.

pub mod al;
pub mod command;
pub mod datagram;
pub mod dc;
pub mod fmmu;
pub mod frame;
pub mod memory;
pub mod registers;
pub mod sii;
pub mod sync_manager;
pub mod watchdog;
