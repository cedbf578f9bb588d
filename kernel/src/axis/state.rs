//! The PLCopen axis state machine (PLCopen Motion Control Part 1, "State diagram").
//!
//! Two tables say all of it: [`accepts`] which command each state takes, and
//! [`AxisState::on`] where each [`Event`] leads. The axis changes its state only by
//! applying an event through [`AxisState::on`] (`Axis::enter`), so the whole diagram is in
//! this file; a transition the table does not list is refused, not taken.

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

    /// The state `event` leads to from this one; `None`: the diagram has no such
    /// transition (the caller keeps the state and flags it).
    ///
    /// Only Reset leaves ErrorStop (PLCopen: "ErrorStop → Reset → Standstill or
    /// Disabled"): powering off, braking and a move ending keep the axis there.
    pub const fn on(self, event: Event) -> Option<AxisState> {
        use AxisState as S;
        match (self, event) {
            (S::ErrorStop, Event::Reset { powered: true }) => Some(S::Standstill),
            (S::ErrorStop, Event::Reset { powered: false }) => Some(S::Disabled),
            (_, Event::Reset { .. }) => None,
            (_, Event::Error) => Some(S::ErrorStop),
            (S::ErrorStop, Event::PoweredOff | Event::StopStarted | Event::MotionDone) => {
                Some(S::ErrorStop)
            }
            (S::ErrorStop, _) => None,
            (_, Event::PoweredOff) => Some(S::Disabled),
            (S::Disabled, Event::PoweredOn) => Some(S::Standstill),
            (S::Disabled, _) => None,
            // Power on while on: MC_Power is level-triggered, nothing changes.
            (S::Stopping, Event::PoweredOn) => None,
            (s, Event::PoweredOn) => Some(s),
            (_, Event::StopStarted) => Some(S::Stopping),
            (S::Stopping, Event::Released) => Some(S::Standstill),
            (_, Event::Released) => None,
            (S::Stopping, _) => None,
            (_, Event::DiscreteMotionStarted) => Some(S::DiscreteMotion),
            (_, Event::ContinuousMotionStarted) => Some(S::ContinuousMotion),
            (S::Homing, Event::SynchronizedMotionStarted) => None,
            (_, Event::SynchronizedMotionStarted) => Some(S::SynchronizedMotion),
            (S::DiscreteMotion | S::Homing | S::SynchronizedMotion, Event::MotionDone) => {
                Some(S::Standstill)
            }
            (S::Standstill, Event::HomingStarted) => Some(S::Homing),
            (_, Event::HomingStarted) => None,
            (_, Event::MotionDone) => None,
        }
    }
}

/// What makes an axis change its state (the arcs of PLCopen's diagram).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Event {
    /// The drive is on (a real axis: its drive reports Operation enabled).
    PoweredOn,
    /// Power is off (MC_Power off, forced, or at the end of a quick stop).
    PoweredOff,
    /// A homing run starts (MoveHome, StepAbsoluteSwitch); only from Standstill.
    HomingStarted,
    /// A move with an end starts (MovePtp, Halt).
    DiscreteMotionStarted,
    /// A move without an end starts (MoveVelocity, Jog, or a superimposed jog that still
    /// moves the axis after the move under it ended).
    ContinuousMotionStarted,
    /// The axis begins to follow a master (GearIn, GearInPos, CamIn).
    SynchronizedMotionStarted,
    /// Braking that locks the axis starts (MC_Stop, QuickStop, power off while moving).
    StopStarted,
    /// A move with an end is done and nothing waits behind it.
    MotionDone,
    /// MC_Stop's Execute fell after the axis stood still.
    Released,
    /// An error: a drive fault, a failed command, a software limit, a target not reached.
    Error,
    /// MC_Reset acknowledged the error; `powered` says whether the drive is still on.
    Reset {
        /// The drive is on: the axis goes to Standstill, else to Disabled.
        powered: bool,
    },
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
        (
            S::Disabled,
            Command::SetPosition { .. } | Command::SetHomed(_) | Command::SetReference(_),
        ) => true,
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
        (
            S::Standstill,
            Command::SetPosition { .. }
            | Command::SetHomed(_)
            | Command::SetReference(_)
            | Command::MoveHome(_)
            | Command::StepAbsoluteSwitch(_),
        ) => true,
        (_, Command::SetPosition { .. } | Command::SetReference(_)) => false,
        // PLCopen MC_Home: from Standstill only.
        (_, Command::MoveHome(_) | Command::StepAbsoluteSwitch(_)) => false,
        (_, Command::SetHomed(_)) => true,
        (S::Standstill, Command::Release) => true,
        (_, Command::Release) => false,
        (S::Standstill, Command::Change(..) | Command::Reverse) => false,
        // A homing run is not aborted by a master relation: stop it first.
        (
            S::Homing,
            Command::GearIn(_)
            | Command::GearInPos(_)
            | Command::CamIn(_)
            | Command::MasterJog(_)
            | Command::GearOut
            | Command::CamOut,
        ) => false,
        (S::SynchronizedMotion, Command::GearOut | Command::CamOut) => true,
        (_, Command::GearOut | Command::CamOut) => false,
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
    fn forced_disable_is_accepted_everywhere_and_only_reset_leaves_error_stop() {
        for s in ALL {
            assert!(accepts(s, &Command::Power(PowerCommand::DisableForced)));
            let expected = if s == AxisState::ErrorStop {
                AxisState::ErrorStop
            } else {
                AxisState::Disabled
            };
            assert_eq!(s.on(Event::PoweredOff), Some(expected), "{s:?}");
        }
        assert_eq!(
            AxisState::ErrorStop.on(Event::Reset { powered: false }),
            Some(AxisState::Disabled)
        );
        assert_eq!(
            AxisState::ErrorStop.on(Event::Reset { powered: true }),
            Some(AxisState::Standstill)
        );
        for e in [
            Event::PoweredOn,
            Event::DiscreteMotionStarted,
            Event::ContinuousMotionStarted,
            Event::Released,
        ] {
            assert_eq!(AxisState::ErrorStop.on(e), None, "{e:?}");
        }
    }

    #[test]
    fn every_state_goes_to_error_stop_on_an_error_and_reset_is_only_for_error_stop() {
        for s in ALL {
            assert_eq!(s.on(Event::Error), Some(AxisState::ErrorStop));
            if s != AxisState::ErrorStop {
                assert_eq!(s.on(Event::Reset { powered: true }), None, "{s:?}");
            }
        }
    }

    #[test]
    fn homing_starts_only_from_standstill_and_ends_there() {
        for s in ALL {
            let expected = (s == AxisState::Standstill).then_some(AxisState::Homing);
            assert_eq!(s.on(Event::HomingStarted), expected, "{s:?}");
            let cmd = Command::MoveHome(crate::homing::MoveHomeCall::default());
            assert_eq!(accepts(s, &cmd), s == AxisState::Standstill, "{s:?}");
        }
        assert_eq!(
            AxisState::Homing.on(Event::MotionDone),
            Some(AxisState::Standstill)
        );
        assert_eq!(
            AxisState::Homing.on(Event::Error),
            Some(AxisState::ErrorStop)
        );
        // A new move aborts the run (PLCopen: Homing -> DiscreteMotion on an aborting move).
        assert!(accepts(AxisState::Homing, &ptp()));
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
    fn motion_events_lead_to_motion_states_and_back() {
        let s = AxisState::Standstill;
        assert_eq!(
            s.on(Event::DiscreteMotionStarted),
            Some(AxisState::DiscreteMotion)
        );
        assert_eq!(
            AxisState::DiscreteMotion.on(Event::MotionDone),
            Some(AxisState::Standstill)
        );
        assert_eq!(s.on(Event::StopStarted), Some(AxisState::Stopping));
        assert_eq!(
            AxisState::Stopping.on(Event::DiscreteMotionStarted),
            None,
            "Stopping locks out motion until Release"
        );
        assert_eq!(
            AxisState::Stopping.on(Event::Released),
            Some(AxisState::Standstill)
        );
        assert_eq!(AxisState::Disabled.on(Event::DiscreteMotionStarted), None);
        assert_eq!(
            AxisState::Disabled.on(Event::PoweredOn),
            Some(AxisState::Standstill)
        );
    }
}
