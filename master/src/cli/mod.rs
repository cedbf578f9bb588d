//! The `gantry` subcommands.

pub mod client;
pub mod profile;
pub mod rt_check;
pub mod scan;
