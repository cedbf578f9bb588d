//! The `gantry` subcommands.

pub mod profile;
