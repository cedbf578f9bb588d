//! The simulated slave network: emulated EtherCAT slave controllers, CANopen nodes and
//! plant models (servo drive, encoder module, switch cams).
//!
//! Not written yet (issue 3). This crate is an empty skeleton so the workspace has its
//! final shape; nothing here works.
#![deny(missing_docs)]
