//! End-to-end tests of gantry: the master and the simulator together. The tests live in
//! `tests/tests/`; what they share lives in the master (`gantry::ethercat::embedded`).

pub use gantry::ethercat::embedded::EmbeddedBus;
