//! End-to-end tests of gantry: the master and the simulator together. The tests live in
//! `tests/tests/`; what they share lives here and in the master (`gantry::ethercat`).

pub mod netns;

pub use gantry::ethercat::embedded::EmbeddedBus;
