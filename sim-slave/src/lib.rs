//! The simulated slave network: emulated EtherCAT slave controllers, CANopen nodes and
//! plant models (servo drive, encoder module, switch cams).
//!
//! Written so far (issue 3, first part): the EtherCAT wire formats the emulated slave
//! controllers parse ([`esc::frame`], [`esc::datagram`]). Not yet: the register file, SII,
//! SyncManagers/FMMUs, AL state machine, DC, mailbox/CoE, devices, transports.
#![deny(missing_docs)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::indexing_slicing,
        clippy::panic
    )
)]

pub mod catalog;
pub mod chain;
pub mod coe;
pub mod config;
pub mod esc;
pub mod fault;
pub mod plant;
pub mod slave;
pub mod transport;
