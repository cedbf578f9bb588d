//! The `gantry` binary's own code: its subcommands (the control-socket client, `profile`,
//! `rt-check`, `scan`, `dcf`), the demo, the plot and the status table, and the in-process
//! simulator — the links to a [`gantry_sim`] chain that the binary (`gantry demo`,
//! `[bus] simulator`) and the tests plug into the library's bus ([`simulator`]). The
//! library (`gantry`) knows nothing of the simulator.
#![deny(missing_docs)]

pub mod cam;
pub mod can_simulator;
pub mod client;
pub mod dcf;
pub mod demo;
pub mod drive_records;
pub mod embedded;
pub mod plot;
pub mod profile;
pub mod rt_check;
pub mod scan;
pub mod sdo;
pub mod simulator;
pub mod status_table;
pub mod sync_jitter;
