//! What can end a homing run in error; each names what and where.

use super::inputs::LimitSide;

/// A homing run failed (the axis goes to ErrorStop; `gantry status` shows this).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum HomingError {
    /// A search travelled its maximum distance without finding what it looks for
    /// (seed 000 §6.3.2.1: MaxDistanceSwitchSearch / MaxDistanceReferenceSearch).
    #[error(
        "{command}: {distance} = {limit} exceeded ({travelled} travelled) without finding the {looking_for}"
    )]
    DistanceExceeded {
        /// Command name.
        command: &'static str,
        /// The parameter that limits the search (e.g. "MaxDistanceSwitchSearch").
        distance: &'static str,
        /// Its value (units).
        limit: f64,
        /// Distance travelled in the search (units).
        travelled: f64,
        /// What the search looked for ("reference switch", "index pulse", ...).
        looking_for: &'static str,
    },
    /// The search reversed at both limit switches without finding the switch.
    #[error("{command}: the {looking_for} was not found between the limit switches")]
    NotFoundBetweenLimits {
        /// Command name.
        command: &'static str,
        /// What the search looked for.
        looking_for: &'static str,
    },
    /// A limit switch the configuration does not use for homing was reached.
    #[error("{command}: {side} reached")]
    LimitSwitch {
        /// Command name.
        command: &'static str,
        /// Which one.
        side: LimitSide,
    },
}

impl HomingError {
    /// The command's name.
    pub const fn command(&self) -> &'static str {
        match self {
            Self::DistanceExceeded { command, .. }
            | Self::NotFoundBetweenLimits { command, .. }
            | Self::LimitSwitch { command, .. } => command,
        }
    }
}
