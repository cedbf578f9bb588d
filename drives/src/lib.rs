//! CiA-402 drive layer, bus-agnostic, shared by the master and the simulated drives:
//! [`cia402`] objects, the controlword/statusword state machine, modes of operation, PDO
//! layouts and the typed process-data view ([`cia402::image`]); user units ⇄ drive
//! counts ([`scaling`]); and the master's side of a drive in cyclic synchronous position
//! mode ([`csp`]); the commutation offset measurement ([`commutation`]). It depends on no
//! other gantry crate. Not yet: homing-method table.
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
pub mod cia402;
pub mod commutation;
pub mod csp;
pub mod scaling;
