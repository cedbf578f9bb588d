//! End-to-end tests of gantry: the master and the simulator together. The tests live in
//! `tests/tests/`; this library holds what they share.
