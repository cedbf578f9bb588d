//! The wire both ends of gantry's EtherCAT share: an `AF_PACKET` raw socket bound to one
//! network interface for the EtherCAT EtherType. The master sends its frames on it
//! (`gantry`'s `RawLink`, `gantry scan`), the simulator listens on it (`gantry-sim
//! --interface`, one end of a veth pair); neither depends on the other for it.
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

pub mod can_socket;
pub mod raw_socket;
