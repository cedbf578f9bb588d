//! The simulated slave network: emulated EtherCAT slave controllers, CANopen nodes and
//! plant models (servo drive, encoder module, switch cams).
//!
//! Written so far: the EtherCAT wire formats ([`esc::frame`], [`esc::datagram`]), the
//! register file, SII, FMMUs, AL state machine, distributed clocks ([`esc::dc`]), the CoE
//! mailbox and the servo plant; `README.md` lists what is not yet there.
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

pub mod canopen;
pub mod catalog;
pub mod chain;
pub mod coe;
pub mod config;
pub mod esc;
pub mod fault;
pub mod plant;
pub mod realtime;
pub mod slave;
