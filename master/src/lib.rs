//! gantry, the motion master: the CLI's commands, the demo, trace and plot output.
//!
//! The buses, the real-time runtime and the configuration file come in later issues; today
//! the master runs the motion kernel on simulated axes.
#![deny(missing_docs)]

pub mod axis_fault;
pub mod cli;
pub mod config;
pub mod demo;
pub mod drive_axis;
pub mod drive_records;
pub mod error_chain;
pub mod ethercat;
pub mod pcap;
pub mod plot;
pub mod runtime;
pub mod service;
pub mod status_table;
pub mod trace;
