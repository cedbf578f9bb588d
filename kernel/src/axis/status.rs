//! What an axis reports every cycle: slope state, status bits and the values a user
//! watches (Jetter `Mechanism.Slope`, Logix MotionStatus bits).

use super::command::CommandError;
use super::state::AxisState;
use crate::profile::KinematicState;

/// Slope (ramp) state of the set values (seed 000 §6.4.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SlopeState {
    /// Set velocity and acceleration are zero.
    #[default]
    Stopped,
    /// |set velocity| rising.
    Accelerating,
    /// Constant set velocity.
    ConstantSpeed,
    /// |set velocity| falling.
    Decelerating,
}

impl SlopeState {
    /// Classifies a set-value state. `eps_v`/`eps_a` are what counts as zero.
    pub fn of(s: &KinematicState, eps_v: f64, eps_a: f64) -> Self {
        let moving = s.v.abs() > eps_v;
        let accel = s.a.abs() > eps_a;
        match (moving, accel) {
            (false, false) => SlopeState::Stopped,
            (true, false) => SlopeState::ConstantSpeed,
            (false, true) => SlopeState::Accelerating,
            (true, true) if s.a * s.v > 0.0 => SlopeState::Accelerating,
            (true, true) => SlopeState::Decelerating,
        }
    }

    /// Name as Jetter writes it.
    pub const fn name(self) -> &'static str {
        match self {
            SlopeState::Stopped => "Stopped",
            SlopeState::Accelerating => "Accelerating",
            SlopeState::ConstantSpeed => "ConstantSpeed",
            SlopeState::Decelerating => "Decelerating",
        }
    }
}

/// Axis status bits (SPEC §3; Logix MotionStatus).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct StatusBits {
    /// |set velocity| rising.
    pub accelerating: bool,
    /// |set velocity| falling.
    pub decelerating: bool,
    /// Set velocity is not zero.
    pub moving: bool,
    /// A jog runs.
    pub jogging: bool,
    /// A master-driven jog follows its master now (Logix JogLockStatus): set when the
    /// lock direction is satisfied, cleared while the master moves the other way.
    pub jog_locked: bool,
    /// Gearing to a master (GearIn, GearInPos).
    pub gearing: bool,
    /// Camming to a master (CamIn).
    pub camming: bool,
    /// The axis' group is enabled (Omron Status.Coordinated): it belongs to that group
    /// and no other may take it; while the group moves, its path drives the axis.
    pub coordinated: bool,
    /// The follower is on its relation's law: caught up (PLCopen InGear / InSync).
    pub in_sync: bool,
    /// A cam began another period or passed the end of its table this cycle (PLCopen
    /// EndOfProfile, a pulse).
    pub end_of_profile: bool,
    /// The master asked more of this follower than its own limits allow (speed,
    /// acceleration or direction) this cycle: with the reaction "warning" the axis goes on
    /// and says so here; with "errorstop" (the default) it is in ErrorStop.
    pub sync_limit_exceeded: bool,
    /// A homing run is in progress.
    pub homing: bool,
    /// Stop or QuickStop is active.
    pub stopping: bool,
    /// The position is referenced.
    pub homed: bool,
    /// The actual position is within the target window of the last PTP target (TwinCAT's
    /// InPositionArea). With target position monitoring a PTP is Done once this has held
    /// for the dwell time after the set value reached the target.
    pub in_target_window: bool,
    /// |set velocity| exceeds the configured maximum speed (e.g. a superimposed jog).
    pub max_speed_exceeded: bool,
    /// The axis is in ErrorStop.
    pub error: bool,
}

/// Everything an axis reports after a cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisStatus {
    /// PLCopen state.
    pub state: AxisState,
    /// Slope state of the set values.
    pub slope: SlopeState,
    /// Set values; `p` is wrapped into the period on modulo axes.
    pub set: KinematicState,
    /// Actual position, on the same side of the modulo wrap as `set.p`.
    pub actual_position: f64,
    /// Actual velocity.
    pub actual_velocity: f64,
    /// Whole modulo periods of the set position (0 on normal axes).
    pub turns: i64,
    /// Status bits.
    pub bits: StatusBits,
    /// Target of the last PTP move (wrapped on modulo axes), if any.
    pub target: Option<f64>,
    /// Why the axis is in ErrorStop.
    pub error: Option<AxisFault>,
    /// Progress of the last homing run (Jetter MoveHome status bits).
    pub homing: crate::homing::HomingStatus,
    /// The switches as the axis saw them this cycle.
    pub switches: crate::homing::SwitchInputs,
    /// The master this axis follows (gear or cam), if any.
    pub master: Option<usize>,
    /// Axis position minus drive position (units): what SetPosition and homing set. An
    /// absolute-encoder axis is where it was homed again at the next start when this is
    /// restored (SPEC §1), so the service saves it.
    pub position_offset: f64,
}

/// Why an axis went to ErrorStop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AxisFault {
    /// The running command failed (e.g. planning failed).
    Command(CommandError),
    /// The drive reported a fault (CiA-402 error code 0x603F).
    Drive {
        /// Error code.
        code: u16,
    },
    /// The following error exceeded its window.
    FollowingError {
        /// |set − actual| (units).
        error: f64,
        /// The window (units).
        window: f64,
    },
    /// Target position monitoring: a positioning move's actual position did not settle in
    /// its target window within the timeout.
    TargetNotReached {
        /// The target (units).
        target: f64,
        /// The actual position at the timeout (units).
        actual: f64,
        /// The target window (units).
        window: f64,
        /// The timeout (s).
        timeout_s: f64,
    },
    /// The set position reached a software limit during a continuous move.
    SoftwareLimit {
        /// The limit that was reached (units).
        limit: f64,
    },
    /// The axis moved into an active hardware limit switch (stopped with its quick-stop
    /// deceleration; after Reset it may only move away from the switch).
    LimitSwitch {
        /// Which one.
        side: crate::homing::LimitSide,
    },
    /// An external axis' encoder input failed (module unreachable, its error bit, its
    /// values frozen): the master layer's code says which.
    Encoder {
        /// Error code (CiA 301 emergency class: 0x7300 sensor, 0x8100 communication…).
        code: u16,
    },
    /// The master this axis followed became unavailable (its encoder or drive failed).
    MasterLost {
        /// The master's index.
        master: usize,
    },
    /// The master asked more than this follower's limits allow.
    SyncLimit(SyncLimit),
}

/// What a master asked of a follower beyond its limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SyncLimit {
    /// "speed", "acceleration", "deceleration" or "direction".
    pub quantity: &'static str,
    /// What the relation asked (units/s, units/s²; for direction the velocity).
    pub value: f64,
    /// The axis' limit (for direction 0).
    pub max: f64,
}

impl core::fmt::Display for SyncLimit {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if self.quantity == "direction" {
            write!(
                f,
                "the master drove the follower at {} against its allowed direction",
                self.value
            )
        } else {
            write!(
                f,
                "the master asked {} {} of the follower, above its maximum {}",
                self.quantity, self.value, self.max
            )
        }
    }
}

impl core::fmt::Display for AxisFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            AxisFault::Command(e) => write!(f, "{e}"),
            AxisFault::Drive { code } => write!(f, "drive fault, error code 0x{code:04X}"),
            AxisFault::FollowingError { error, window } => {
                write!(f, "following error {error} exceeds window {window}")
            }
            AxisFault::SoftwareLimit { limit } => {
                write!(f, "software limit {limit} reached")
            }
            AxisFault::TargetNotReached { .. } => write!(f, "{}", self.summary()),
            AxisFault::LimitSwitch { side } => write!(f, "{side}"),
            AxisFault::Encoder { .. } | AxisFault::MasterLost { .. } | AxisFault::SyncLimit(_) => {
                write!(f, "{}", self.summary())
            }
        }
    }
}

impl AxisFault {
    /// The fault without the failed command's own error (a [`CommandError`] cannot hold
    /// another one): what a command refused in ErrorStop names.
    pub const fn summary(&self) -> FaultSummary {
        match *self {
            AxisFault::Command(e) => FaultSummary::Command {
                command: e.command(),
            },
            AxisFault::Drive { code } => FaultSummary::Drive { code },
            AxisFault::FollowingError { error, window } => {
                FaultSummary::FollowingError { error, window }
            }
            AxisFault::SoftwareLimit { limit } => FaultSummary::SoftwareLimit { limit },
            AxisFault::LimitSwitch { side } => FaultSummary::LimitSwitch { side },
            AxisFault::Encoder { code } => FaultSummary::Encoder { code },
            AxisFault::MasterLost { master } => FaultSummary::MasterLost { master },
            AxisFault::SyncLimit(l) => FaultSummary::SyncLimit(l),
            AxisFault::TargetNotReached {
                target,
                actual,
                window,
                timeout_s,
            } => FaultSummary::TargetNotReached {
                target,
                actual,
                window,
                timeout_s,
            },
        }
    }
}

/// Why an axis is in ErrorStop, as a command refused there reports it ([`AxisFault`] with
/// the failed command named instead of its error).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FaultSummary {
    /// A command failed while it ran (`gantry status` shows its error).
    Command {
        /// The command's name.
        command: &'static str,
    },
    /// The drive reported a fault.
    Drive {
        /// CiA-402 error code (0x603F).
        code: u16,
    },
    /// The following error exceeded its window.
    FollowingError {
        /// |set − actual| (units).
        error: f64,
        /// The window (units).
        window: f64,
    },
    /// The set position reached a software limit.
    SoftwareLimit {
        /// The limit (units).
        limit: f64,
    },
    /// A positioning move did not settle in its target window in time.
    TargetNotReached {
        /// The target (units).
        target: f64,
        /// The actual position at the timeout (units).
        actual: f64,
        /// The target window (units).
        window: f64,
        /// The timeout (s).
        timeout_s: f64,
    },
    /// A hardware limit switch stopped the axis.
    LimitSwitch {
        /// Which one.
        side: crate::homing::LimitSide,
    },
    /// The encoder input failed.
    Encoder {
        /// Error code.
        code: u16,
    },
    /// The master became unavailable.
    MasterLost {
        /// The master's index.
        master: usize,
    },
    /// The master asked more than the follower's limits allow.
    SyncLimit(SyncLimit),
    /// No error is recorded.
    Unknown,
}

impl core::fmt::Display for FaultSummary {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            FaultSummary::Command { command } => write!(f, "{command} failed"),
            FaultSummary::Drive { code } => write!(f, "drive fault, error code 0x{code:04X}"),
            FaultSummary::FollowingError { error, window } => {
                write!(f, "following error {error} exceeds window {window}")
            }
            FaultSummary::SoftwareLimit { limit } => write!(f, "software limit {limit} reached"),
            FaultSummary::TargetNotReached {
                target,
                actual,
                window,
                timeout_s,
            } => write!(
                f,
                "target {target} not reached: actual {actual} not settled within ±{window} \
                 {timeout_s} s after the set value reached it"
            ),
            FaultSummary::LimitSwitch { side } => write!(f, "{side}"),
            FaultSummary::Encoder { code } => {
                write!(f, "encoder input failed, error code 0x{code:04X}")
            }
            FaultSummary::MasterLost { master } => write!(
                f,
                "master axis {master} became unavailable (its encoder or drive failed)"
            ),
            FaultSummary::SyncLimit(l) => write!(f, "{l}"),
            FaultSummary::Unknown => write!(f, "no error recorded"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_state_follows_sign_of_a_times_v() {
        let s = |v, a| {
            SlopeState::of(
                &KinematicState {
                    p: 0.0,
                    v,
                    a,
                    j: 0.0,
                },
                1e-9,
                1e-9,
            )
        };
        assert_eq!(s(0.0, 0.0), SlopeState::Stopped);
        assert_eq!(s(0.0, 1.0), SlopeState::Accelerating);
        assert_eq!(s(1.0, 1.0), SlopeState::Accelerating);
        assert_eq!(s(-1.0, -1.0), SlopeState::Accelerating);
        assert_eq!(s(-1.0, 1.0), SlopeState::Decelerating);
        assert_eq!(s(2.0, 0.0), SlopeState::ConstantSpeed);
    }
}
