//! CiA-402 drive layer, bus-agnostic: object indices, the controlword/statusword state
//! machine shared by the master and the simulated drives, and modes of operation.
//!
//! Written so far (issue 3, first part): [`cia402`] objects, statusword decoding,
//! controlword commands, the one state-machine table, modes of operation. Not yet: PDO
//! layouts, scaling to counts on the wire, touch probe, homing-method table.
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
