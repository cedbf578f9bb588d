//! Controller-side homing (SPEC §4, issue 13 §2): switch inputs and touch-probe latches
//! reaching the axis, Jetter MoveHome (seed 000 §6.3) and Beckhoff MC_StepAbsoluteSwitch
//! (seed 003), both run by one sequencer.
//!
//! | module | what |
//! |---|---|
//! | `inputs` | limit and reference switches, touch-probe latches |
//! | `sequence` | the sequencer: searches with goals, reversal, distance limits, finish |
//! | `move_home` | Jetter MoveHome: parameters, switch configurations, modes → a plan |
//! | `step_switch` | Beckhoff MC_StepAbsoluteSwitch: Direction × SwitchMode → a plan |
//! | `error` | why a run failed |

pub mod error;
pub mod inputs;
pub mod move_home;
pub mod sequence;
pub mod step_switch;

pub use error::HomingError;
pub use inputs::{Latch, LimitSide, ProbeLatches, SwitchInputs};
pub use move_home::{HomingMode, MoveHome, MoveHomeCall, SwitchConfig};
pub use step_switch::{HomeDirection, StepAbsoluteSwitch, SwitchMode};

/// Progress of the last homing run (Jetter MoveHome status, seed 000 §6.3.2.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HomingStatus {
    /// IsReferenceRunStarted: a run has started.
    pub started: bool,
    /// IsSwitchFound: the coarse phase found the switch (or zero pulse).
    pub switch_found: bool,
    /// IsReferenceFound: the reference edge or zero pulse is latched.
    pub reference_found: bool,
    /// IsReferenceSet: the position is set (end of a run, or SetReference).
    pub reference_set: bool,
}
