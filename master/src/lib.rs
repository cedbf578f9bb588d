//! gantry, the motion master as a library: the configuration, the real-time engine and
//! its [`runtime::controller::Controller`], the buses (EtherCAT on a network interface, or
//! on any [`ethercat::link::Link`] a caller plugs in; CANopen on a SocketCAN interface or
//! any [`canopen::CanLink`]; [`bus::AnyBus`], the one a configuration names; the
//! [`simulated`] axes' bus, with no hardware), the service and the trace.
//!
//! The `gantry` binary (package `gantry-cli`) adds the command line, the demo, the plot,
//! the status table and the in-process simulator's links; this library knows nothing of
//! the simulator.
#![deny(missing_docs)]

pub mod axis_fault;
pub mod bus;
pub mod cam;
pub mod canopen;
pub mod commission;
pub mod config;
pub mod drive_axis;
pub mod error_chain;
pub mod ethercat;
pub mod pcap;
pub mod persist;
pub mod runtime;
pub mod service;
pub mod simulated;
pub mod trace;
