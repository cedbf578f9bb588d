//! The `gantry` subcommands.

pub mod client;
pub mod profile;
pub mod scan;
