//! CiA-402 drive layer: object indices, the controlword/statusword state machine shared by
//! master and simulator, modes of operation, PDO layouts and scaling.
//!
//! Not written yet (issue 3). This crate is an empty skeleton so the workspace has its
//! final shape; nothing here works.
#![deny(missing_docs)]
