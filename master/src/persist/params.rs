//! What gantry keeps of an axis between runs (seed 000 §5.2.6.2, the axis' parameter
//! file; SPEC §4, §5): the commutation offset measured by commissioning, the homing
//! parameters of the last homing call, the dynamics of the last point-to-point move, and
//! for an axis with an absolute encoder the offset between its position and its drive's.
//! Each part is optional: a part never saved is absent, and the axis then starts with
//! the configured defaults for it.
//!
//! The body of the file ([`super::envelope`]) is this structure as TOML; unknown keys
//! are refused (a file of a later gantry is not half-read).

use gantry_kernel::axis::command::MoveDirection;
use gantry_kernel::homing::{HomingMode, MoveHome, SwitchConfig};
use serde::{Deserialize, Serialize};

use crate::config::AxisSection;
use crate::service::protocol::{HomeMode, HomeParams, HomeSwitches, JogDirection};

/// Everything saved of one axis.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisParams {
    /// The axis' name (checked at load: a file copied under another axis' name is refused).
    pub axis: String,
    /// Commutation offset of the axis' motor, in the drive's own units, as the drive takes
    /// it (opaque here: commissioning measures it, writes it to the drive and saves it; at
    /// start it is written back).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub commutation_offset: Option<i32>,
    /// Homing parameters of the last homing call, every one of them (what the call left
    /// out completed by the ones before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home: Option<HomeParams>,
    /// Dynamics of the last point-to-point move (those ever given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ptp: Option<PtpParams>,
    /// Axis position minus drive position of an absolute-encoder axis, saved whenever it
    /// is homed, with the scaling it was taken under.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<PositionOffset>,
}

impl AxisParams {
    /// Nothing saved yet for `axis`.
    pub fn new(axis: &str) -> Self {
        Self {
            axis: axis.to_string(),
            ..Self::default()
        }
    }

    /// Whether nothing but the name is saved.
    pub fn is_empty(&self) -> bool {
        self.commutation_offset.is_none()
            && self.home.is_none()
            && self.ptp.is_none()
            && self.position.is_none()
    }
}

/// The dynamics of the last point-to-point move; left-out ones were never given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PtpParams {
    /// Speed (units/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
    /// Acceleration (units/s²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceleration: Option<f64>,
    /// Deceleration (units/s²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deceleration: Option<f64>,
    /// Jerk (units/s³).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jerk: Option<f64>,
}

impl PtpParams {
    /// `self` with what `newer` gives put in.
    pub fn overlaid(self, newer: PtpParams) -> PtpParams {
        PtpParams {
            speed: newer.speed.or(self.speed),
            acceleration: newer.acceleration.or(self.acceleration),
            deceleration: newer.deceleration.or(self.deceleration),
            jerk: newer.jerk.or(self.jerk),
        }
    }
}

/// The position offset of an absolute-encoder axis: its position is the drive's position
/// plus `offset`. Valid only under the scaling it was taken with; any change of the
/// scaling (a new gear, another encoder resolution) makes it meaningless.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositionOffset {
    /// Axis position minus drive position (units).
    pub offset: f64,
    /// The scaling it was taken under.
    pub scaling: ScalingStamp,
}

/// The scaling of an axis as it was when a position offset was saved.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScalingStamp {
    /// Encoder counts per motor revolution.
    pub counts_per_motor_rev: u32,
    /// Gear: motor revolutions …
    pub motor_revs: u32,
    /// … per load revolutions.
    pub load_revs: u32,
    /// Units per load revolution.
    pub units_per_load_rev: f64,
    /// Inverted.
    pub invert: bool,
    /// Modulo period (units), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub modulo: Option<f64>,
}

impl ScalingStamp {
    /// The scaling axis `a` is configured with.
    pub fn of(a: &AxisSection) -> Self {
        Self {
            counts_per_motor_rev: a.scaling.counts_per_motor_rev,
            motor_revs: a.scaling.motor_revs,
            load_revs: a.scaling.load_revs,
            units_per_load_rev: a.scaling.units_per_load_rev,
            invert: a.scaling.invert,
            modulo: a.modulo,
        }
    }
}

impl From<MoveHome> for HomeParams {
    fn from(p: MoveHome) -> Self {
        Self {
            direction: Some(match p.direction {
                MoveDirection::Positive => JogDirection::Positive,
                MoveDirection::Negative => JogDirection::Negative,
            }),
            switches: Some(match p.switch_config {
                SwitchConfig::NoSwitch => HomeSwitches::None,
                SwitchConfig::RefAndLimitSwitch => HomeSwitches::RefAndLimit,
                SwitchConfig::RefSwitch => HomeSwitches::Ref,
                SwitchConfig::LimitSwitch => HomeSwitches::Limit,
            }),
            mode: Some(match p.mode {
                HomingMode::SwitchingEdge1Phase => HomeMode::Edge,
                HomingMode::SwitchingEdge2Phase => HomeMode::Edge2,
                HomingMode::ZeroPulse1Phase => HomeMode::ZeroPulse,
                HomingMode::ZeroPulse2Phase => HomeMode::ZeroPulse2,
            }),
            speed_switch: Some(p.speed_switch_search),
            max_distance_switch: Some(p.max_distance_switch_search),
            speed_reference: Some(p.speed_reference_search),
            max_distance_reference: Some(p.max_distance_reference_search),
            acceleration: Some(p.acceleration),
            jerk: Some(p.jerk),
            reference_offset: Some(p.reference_offset),
            normal_position: Some(p.normal_position),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_kernel::homing::MoveHomeCall;

    #[test]
    fn saved_homing_parameters_give_back_the_same_run() {
        let mut p = MoveHome::defaults(100.0, 1000.0, 10_000.0);
        p.direction = MoveDirection::Negative;
        p.switch_config = SwitchConfig::LimitSwitch;
        p.mode = HomingMode::ZeroPulse2Phase;
        p.reference_offset = -2.5;
        p.max_distance_reference_search = 12.0;
        let saved = HomeParams::from(p);
        let text = toml::to_string(&saved).unwrap();
        let back: HomeParams = toml::from_str(&text).unwrap();
        assert_eq!(back, saved, "{text}");
        // Unlimited distances (the defaults) survive TOML as `inf`.
        assert!(text.contains("max_distance_switch = inf"), "{text}");
        let other = MoveHome::defaults(1.0, 1.0, 1.0);
        assert_eq!(MoveHomeCall::from(back).merged(&other), p);
    }

    #[test]
    fn later_ptp_dynamics_win_and_left_out_ones_stay() {
        let old = PtpParams {
            speed: Some(10.0),
            jerk: Some(100.0),
            ..PtpParams::default()
        };
        let new = PtpParams {
            speed: Some(20.0),
            acceleration: Some(5.0),
            ..PtpParams::default()
        };
        assert_eq!(
            old.overlaid(new),
            PtpParams {
                speed: Some(20.0),
                acceleration: Some(5.0),
                deceleration: None,
                jerk: Some(100.0)
            }
        );
    }
}
