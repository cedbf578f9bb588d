//! CiA 402 (IEC 61800-7-201) device profile for drives and motion control.

pub mod controlword;
pub mod error_code;
pub mod homing;
pub mod image;
pub mod mode;
pub mod objects;
pub mod pdo;
pub mod procedure;
pub mod state;
pub mod statusword;

pub use controlword::{Command, Controlword};
pub use mode::ModeOfOperation;
pub use state::{next_command, DeviceStateMachine, State, Target};
pub use statusword::Statusword;
