//! The `gantry` subcommands.

pub mod profile;
pub mod scan;
