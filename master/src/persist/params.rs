//! What gantry keeps of an axis between runs (seed 000 §5.2.6.2, the axis' parameter
//! file; SPEC §4, §5): the commutation offset measured by commissioning, the homing
//! parameters of the last homing call, the dynamics of the last point-to-point move, and
//! for an axis with an absolute encoder the offset between its position and its drive's.
//! Each part is optional: a part never saved is absent, and the axis then starts with
//! the configured defaults for it.
//!
//! The body of the file ([`super::envelope`]) is this structure as TOML; unknown keys
//! are refused (a file of a later gantry is not half-read). Format 1 has no
//! step-to-absolute-switch parameters and no homing method; a file that holds either is
//! written as format 2 ([`AxisParams::format`]), so that a gantry that reads only format 1
//! names the file's format instead of an unknown key, and a file without them stays
//! format 1, byte for byte.

use gantry_kernel::axis::command::MoveDirection;
use gantry_kernel::axis::Dynamics;
use gantry_kernel::homing::{
    HomeDirection, HomingMode, MoveHome, StepAbsoluteSwitch, SwitchConfig, SwitchMode,
};
use serde::{Deserialize, Serialize};

use crate::config::AxisSection;
use crate::service::protocol::{
    HomeMethod, HomeMode, HomeParams, HomeSwitches, JogDirection, StepDirection, StepSwitchMode,
    StepSwitchParams,
};

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
    /// The homing run a `home` call without a method repeats, when it is not MoveHome
    /// (absent: MoveHome). Format 2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home_method: Option<HomeMethod>,
    /// Homing parameters of the last homing call, every one of them (what the call left
    /// out completed by the ones before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home: Option<HomeParams>,
    /// Step-to-absolute-switch parameters of the last such homing call, every one of
    /// them. Format 2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub step_switch: Option<StepSwitchParams>,
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
            && self.home_method.is_none()
            && self.home.is_none()
            && self.step_switch.is_none()
            && self.ptp.is_none()
            && self.position.is_none()
    }

    /// The file format these parameters need: 2 when they hold what format 1 has not
    /// (step-to-absolute-switch parameters, a homing method), else 1.
    pub fn format(&self) -> u32 {
        if self.home_method.is_some() || self.step_switch.is_some() {
            2
        } else {
            1
        }
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

impl From<HomeDirection> for StepDirection {
    fn from(d: HomeDirection) -> Self {
        match d {
            HomeDirection::Positive => Self::Positive,
            HomeDirection::Negative => Self::Negative,
            HomeDirection::SwitchPositive => Self::SwitchPositive,
            HomeDirection::SwitchNegative => Self::SwitchNegative,
        }
    }
}

impl From<StepDirection> for HomeDirection {
    fn from(d: StepDirection) -> Self {
        match d {
            StepDirection::Positive => Self::Positive,
            StepDirection::Negative => Self::Negative,
            StepDirection::SwitchPositive => Self::SwitchPositive,
            StepDirection::SwitchNegative => Self::SwitchNegative,
        }
    }
}

impl From<SwitchMode> for StepSwitchMode {
    fn from(m: SwitchMode) -> Self {
        match m {
            SwitchMode::On => Self::On,
            SwitchMode::Off => Self::Off,
            SwitchMode::RisingEdge => Self::RisingEdge,
            SwitchMode::FallingEdge => Self::FallingEdge,
            SwitchMode::RisingEdgeInverse => Self::RisingEdgeInverse,
            SwitchMode::FallingEdgeInverse => Self::FallingEdgeInverse,
            SwitchMode::EdgeSwitchPositive => Self::EdgeSwitchPositive,
            SwitchMode::EdgeSwitchNegative => Self::EdgeSwitchNegative,
        }
    }
}

impl From<StepSwitchMode> for SwitchMode {
    fn from(m: StepSwitchMode) -> Self {
        match m {
            StepSwitchMode::On => Self::On,
            StepSwitchMode::Off => Self::Off,
            StepSwitchMode::RisingEdge => Self::RisingEdge,
            StepSwitchMode::FallingEdge => Self::FallingEdge,
            StepSwitchMode::RisingEdgeInverse => Self::RisingEdgeInverse,
            StepSwitchMode::FallingEdgeInverse => Self::FallingEdgeInverse,
            StepSwitchMode::EdgeSwitchPositive => Self::EdgeSwitchPositive,
            StepSwitchMode::EdgeSwitchNegative => Self::EdgeSwitchNegative,
        }
    }
}

impl From<StepAbsoluteSwitch> for StepSwitchParams {
    fn from(p: StepAbsoluteSwitch) -> Self {
        Self {
            direction: Some(p.direction.into()),
            switch_mode: Some(p.switch_mode.into()),
            velocity: Some(p.velocity),
            acceleration: Some(p.acceleration),
            deceleration: Some(p.deceleration),
            jerk: Some(p.jerk),
            set_position: Some(p.position),
            distance_limit: Some(p.distance_limit),
        }
    }
}

/// A step-to-absolute-switch parameter that has no default and was neither given nor
/// saved: its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NotGiven(pub &'static str);

impl StepSwitchParams {
    /// The run these parameters ask for: each one given, else `saved`'s, else its default
    /// (the axis' default acceleration, deceleration and jerk from `defaults`, a set
    /// position of 0, no distance limit); direction, switch mode and velocity have none.
    pub fn merged(
        &self,
        saved: Option<&StepAbsoluteSwitch>,
        defaults: &Dynamics,
    ) -> Result<StepAbsoluteSwitch, NotGiven> {
        let saved = saved
            .map(|s| StepSwitchParams::from(*s))
            .unwrap_or_default();
        let pick = |given: Option<f64>, saved: Option<f64>, default: f64| {
            given.or(saved).unwrap_or(default)
        };
        Ok(StepAbsoluteSwitch {
            direction: self
                .direction
                .or(saved.direction)
                .ok_or(NotGiven("direction"))?
                .into(),
            switch_mode: self
                .switch_mode
                .or(saved.switch_mode)
                .ok_or(NotGiven("switch mode"))?
                .into(),
            velocity: self
                .velocity
                .or(saved.velocity)
                .ok_or(NotGiven("velocity"))?,
            acceleration: pick(self.acceleration, saved.acceleration, defaults.acceleration),
            deceleration: pick(self.deceleration, saved.deceleration, defaults.deceleration),
            jerk: pick(self.jerk, saved.jerk, defaults.jerk),
            position: pick(self.set_position, saved.set_position, 0.0),
            distance_limit: pick(self.distance_limit, saved.distance_limit, f64::INFINITY),
        })
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

    fn step(direction: HomeDirection, switch_mode: SwitchMode) -> StepAbsoluteSwitch {
        StepAbsoluteSwitch {
            direction,
            switch_mode,
            position: -12.5,
            velocity: 20.0,
            acceleration: 300.0,
            deceleration: 40.0,
            jerk: 6000.0,
            distance_limit: f64::INFINITY,
        }
    }

    #[test]
    fn saved_step_switch_parameters_give_back_the_same_run_in_every_direction_and_mode() {
        let defaults =
            gantry_kernel::axis::AxisConfig::new("x", gantry_kernel::axis::AxisKind::Virtual)
                .defaults;
        for direction in HomeDirection::ALL {
            for mode in SwitchMode::ALL {
                let run = step(direction, mode);
                let saved = AxisParams {
                    step_switch: Some(StepSwitchParams::from(run)),
                    home_method: Some(HomeMethod::StepToSwitch),
                    ..AxisParams::new("x")
                };
                let text = toml::to_string(&saved).unwrap();
                let back: AxisParams = toml::from_str(&text).unwrap();
                assert_eq!(back, saved, "{text}");
                assert_eq!(back.format(), 2);
                // Unlimited distance survives TOML as `inf`.
                assert!(text.contains("distance_limit = inf"), "{text}");
                let merged = back.step_switch.unwrap().merged(None, &defaults).unwrap();
                assert_eq!(merged, run);
            }
        }
    }

    #[test]
    fn a_step_switch_call_takes_what_it_gives_then_the_saved_then_the_defaults() {
        let defaults =
            gantry_kernel::axis::AxisConfig::new("x", gantry_kernel::axis::AxisKind::Virtual)
                .defaults;
        let first = StepSwitchParams {
            direction: Some(StepDirection::SwitchNegative),
            switch_mode: Some(StepSwitchMode::RisingEdgeInverse),
            velocity: Some(7.0),
            ..StepSwitchParams::default()
        };
        // Nothing saved: the axis' default dynamics, position 0, no distance limit.
        let run = first.merged(None, &defaults).unwrap();
        assert_eq!(
            run,
            StepAbsoluteSwitch {
                direction: HomeDirection::SwitchNegative,
                switch_mode: SwitchMode::RisingEdgeInverse,
                position: 0.0,
                velocity: 7.0,
                acceleration: defaults.acceleration,
                deceleration: defaults.deceleration,
                jerk: defaults.jerk,
                distance_limit: f64::INFINITY,
            }
        );
        // A later call: what it gives, the saved run for the rest.
        let saved = step(HomeDirection::Positive, SwitchMode::FallingEdge);
        let later = StepSwitchParams {
            deceleration: Some(1000.0),
            set_position: Some(3.0),
            ..StepSwitchParams::default()
        };
        let run = later.merged(Some(&saved), &defaults).unwrap();
        assert_eq!(
            run,
            StepAbsoluteSwitch {
                deceleration: 1000.0,
                position: 3.0,
                ..saved
            }
        );
        // Nothing saved and no direction, switch mode or velocity: refused by name.
        for (call, missing) in [
            (StepSwitchParams::default(), "direction"),
            (
                StepSwitchParams {
                    switch_mode: None,
                    ..first
                },
                "switch mode",
            ),
            (
                StepSwitchParams {
                    velocity: None,
                    ..first
                },
                "velocity",
            ),
        ] {
            assert_eq!(call.merged(None, &defaults), Err(NotGiven(missing)));
            assert!(call.merged(Some(&saved), &defaults).is_ok());
        }
    }

    #[test]
    fn a_file_needs_format_2_only_for_step_switch_homing() {
        let mut p = AxisParams::new("x");
        p.home = Some(HomeParams::from(MoveHome::defaults(1.0, 1.0, 1.0)));
        p.commutation_offset = Some(3);
        assert_eq!(p.format(), 1);
        p.home_method = Some(HomeMethod::MoveHome);
        assert_eq!(p.format(), 2);
        p.home_method = None;
        p.step_switch = Some(StepSwitchParams::default());
        assert_eq!(p.format(), 2);
        assert!(!AxisParams {
            step_switch: Some(StepSwitchParams::default()),
            ..AxisParams::new("x")
        }
        .is_empty());
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
