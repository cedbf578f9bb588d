//! How frames reach the simulated chain from outside the process.

pub mod raw_socket;
