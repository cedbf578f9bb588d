//! The PLCopen axis state machine (PLCopen Motion Control Part 1, "State diagram").
//!
//! One table says which command each state accepts ([`accepts`]); the axis moves between
//! states only through [`AxisState::after`], so the whole diagram is in this file.

use super::command::{Command, PowerCommand};

/// PLCopen axis state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum AxisState {
    /// Power off.
    #[default]
    Disabled,
    /// Powered, not moving, no command running.
    Standstill,
    /// A homing run is in progress.
    Homing,
    /// A move with an end (PTP, halt) runs.
    DiscreteMotion,
    /// A move without an end (velocity, jog) runs.
    ContinuousMotion,
    /// Following a master (gearing, camming, group path).
    SynchronizedMotion,
    /// MC_Stop (or QuickStop) is active; the axis refuses motion until released.
    Stopping,
    /// An error stopped the axis; only Reset and power off are accepted.
    ErrorStop,
}

impl AxisState {
    /// Whether the drive is powered in this state.
    pub const fn is_enabled(self) -> bool {
        !matches!(self, AxisState::Disabled)
    }

    /// Name as PLCopen writes it.
    pub const fn name(self) -> &'static str {
        match self {
            AxisState::Disabled => "Disabled",
            AxisState::Standstill => "Standstill",
            AxisState::Homing => "Homing",
            AxisState::DiscreteMotion => "DiscreteMotion",
            AxisState::ContinuousMotion => "ContinuousMotion",
            AxisState::SynchronizedMotion => "SynchronizedMotion",
            AxisState::Stopping => "Stopping",
            AxisState::ErrorStop => "ErrorStop",
        }
    }

    /// The state an accepted command leads to (motion commands: the state while they run).
    /// `None`: the command does not change the state by itself.
    pub const fn after(self, cmd: &Command) -> Option<AxisState> {
        match cmd {
            Command::Power(PowerCommand::Enable) => match self {
                AxisState::Disabled => Some(AxisState::Standstill),
                _ => None,
            },
            Command::Power(PowerCommand::DisableForced) => Some(AxisState::Disabled),
            Command::Power(PowerCommand::Disable) => None,
            Command::Reset => None,
            Command::MovePtp(_) | Command::Halt { .. } => Some(AxisState::DiscreteMotion),
            Command::MoveVelocity(_) | Command::Jog(_) | Command::Reverse => {
                Some(AxisState::ContinuousMotion)
            }
            Command::Stop { .. } | Command::QuickStop => Some(AxisState::Stopping),
            Command::Change(..)
            | Command::Release
            | Command::SetPosition { .. }
            | Command::SetHomed(_) => None,
        }
    }
}

/// Whether `state` accepts `cmd` (PLCopen's diagram; unlisted pairs are refused).
///
/// Buffered moves are also accepted in the motion states (they wait); Stopping accepts only
/// power-off, quick stop and release; ErrorStop only Reset and power-off.
pub const fn accepts(state: AxisState, cmd: &Command) -> bool {
    use AxisState as S;
    match (state, cmd) {
        (_, Command::Power(PowerCommand::DisableForced)) => true,
        // Power off when off: nothing to do, as MC_Power with Enable = FALSE.
        (S::Disabled, Command::Power(PowerCommand::Enable | PowerCommand::Disable)) => true,
        (S::Disabled, Command::Reset) => true,
        (S::Disabled, Command::SetPosition { .. } | Command::SetHomed(_)) => true,
        (S::Disabled, _) => false,
        (S::ErrorStop, Command::Reset | Command::Power(PowerCommand::Disable)) => true,
        (S::ErrorStop, _) => false,
        (
            S::Stopping,
            Command::Release
            | Command::Power(PowerCommand::Disable)
            | Command::QuickStop
            | Command::Stop { .. },
        ) => true,
        (S::Stopping, _) => false,
        (_, Command::Power(PowerCommand::Enable)) => true,
        (_, Command::Reset) => true,
        (S::Standstill, Command::SetPosition { .. } | Command::SetHomed(_)) => true,
        (_, Command::SetPosition { .. }) => false,
        (_, Command::SetHomed(_)) => true,
        (S::Standstill, Command::Release) => true,
        (_, Command::Release) => false,
        (S::Standstill, Command::Change(..) | Command::Reverse) => false,
        (S::Homing | S::SynchronizedMotion, Command::Change(..) | Command::Reverse) => false,
        (
            S::Standstill
            | S::Homing
            | S::DiscreteMotion
            | S::ContinuousMotion
            | S::SynchronizedMotion,
            _,
        ) => true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::command::{HaltMode, MovePtp, PositioningMode};

    const ALL: [AxisState; 8] = [
        AxisState::Disabled,
        AxisState::Standstill,
        AxisState::Homing,
        AxisState::DiscreteMotion,
        AxisState::ContinuousMotion,
        AxisState::SynchronizedMotion,
        AxisState::Stopping,
        AxisState::ErrorStop,
    ];

    fn ptp() -> Command {
        Command::MovePtp(MovePtp::new(PositioningMode::RelActual, 1.0))
    }

    #[test]
    fn disabled_refuses_motion_but_takes_power_on() {
        assert!(!accepts(AxisState::Disabled, &ptp()));
        assert!(accepts(
            AxisState::Disabled,
            &Command::Power(PowerCommand::Enable)
        ));
    }

    #[test]
    fn error_stop_takes_only_reset_and_power_off() {
        for cmd in [
            ptp(),
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: None,
            },
            Command::Stop { deceleration: None },
            Command::Release,
        ] {
            assert!(!accepts(AxisState::ErrorStop, &cmd), "{cmd:?}");
        }
        assert!(accepts(AxisState::ErrorStop, &Command::Reset));
        assert!(accepts(
            AxisState::ErrorStop,
            &Command::Power(PowerCommand::Disable)
        ));
    }

    #[test]
    fn powering_off_an_axis_that_is_off_is_accepted() {
        assert!(accepts(
            AxisState::Disabled,
            &Command::Power(PowerCommand::Disable)
        ));
    }

    #[test]
    fn stopping_locks_out_motion_until_release() {
        assert!(!accepts(AxisState::Stopping, &ptp()));
        assert!(accepts(AxisState::Stopping, &Command::Release));
    }

    #[test]
    fn forced_disable_is_accepted_everywhere() {
        for s in ALL {
            assert!(accepts(s, &Command::Power(PowerCommand::DisableForced)));
            assert_eq!(
                s.after(&Command::Power(PowerCommand::DisableForced)),
                Some(AxisState::Disabled)
            );
        }
    }

    #[test]
    fn set_position_only_at_rest() {
        let cmd = Command::SetPosition {
            position: 0.0,
            relative: false,
        };
        for s in ALL {
            let expected = matches!(s, AxisState::Disabled | AxisState::Standstill);
            assert_eq!(accepts(s, &cmd), expected, "{s:?}");
        }
    }

    #[test]
    fn motion_commands_lead_to_motion_states() {
        assert_eq!(
            AxisState::Standstill.after(&ptp()),
            Some(AxisState::DiscreteMotion)
        );
        assert_eq!(
            AxisState::Standstill.after(&Command::Stop { deceleration: None }),
            Some(AxisState::Stopping)
        );
    }
}
