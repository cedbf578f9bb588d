//! The real-time side: the cycle thread (priority, affinity, locked memory), the engine
//! it runs each cycle, what crosses between it and the application, and the figures it
//! records.

pub mod bus;
pub mod cam;
pub mod clock;
pub mod controller;
pub mod cycle;
pub mod encoder_input;
pub mod engine;
pub mod histogram;
pub mod phase;
pub mod procedure;
pub mod protocol;
pub mod rt;
pub mod sdo;
pub mod stats;
