//! `[axis.drive_homing]`: homing done by the drive itself (CiA 402 homing mode), in the
//! axis' units; converted to the drive's counts for
//! [`gantry_drives::cia402::homing::DriveHomingParams`].
//!
//! ```toml
//! [axis.drive_homing]
//! method = 19            # CiA 402-2 homing method (1–35, 37; negative: the drive maker's)
//! speed_switch = 20.0    # units/s, 0x6099:01 speed during search for switch
//! speed_zero = 2.0       # units/s, 0x6099:02 speed during search for zero
//! acceleration = 200.0   # units/s², 0x609A
//! home_offset = 0.0      # units, 0x607C: the home position reads as minus this
//! timeout = 30.0         # s the drive may take to report homing attained
//! skip = false           # an absolute drive: no homing run, homed where it reports
//! ```

use gantry_drives::cia402::homing::DriveHomingParams;
use gantry_drives::scaling::Scaling;
use serde::Deserialize;

/// `[axis.drive_homing]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DriveHomingSection {
    /// 0x6098 homing method.
    pub method: i8,
    /// Speed during search for switch (units/s).
    pub speed_switch: f64,
    /// Speed during search for zero (units/s).
    pub speed_zero: f64,
    /// Homing acceleration (units/s²).
    pub acceleration: f64,
    /// Home offset (units): the home position reads as minus this afterwards (CiA 402-2
    /// 0x607C: the zero position is the home position plus the home offset).
    #[serde(default)]
    pub home_offset: f64,
    /// How long the drive may take to report homing attained (s).
    #[serde(default = "default_timeout")]
    pub timeout: f64,
    /// Skip the drive's homing run (a drive with an absolute encoder): the axis is homed
    /// on the position the drive reports.
    #[serde(default)]
    pub skip: bool,
}

/// Default of `timeout` (s).
pub const DEFAULT_TIMEOUT_S: f64 = 30.0;

fn default_timeout() -> f64 {
    DEFAULT_TIMEOUT_S
}

impl DriveHomingSection {
    /// The drive's parameters in counts, checked: speeds within (0, `max_speed`],
    /// acceleration > 0, timeout > 0, every value representable in its object. Errors
    /// name the key (below `drive_homing.`) and why.
    pub fn params(
        &self,
        scaling: &Scaling,
        max_speed: f64,
    ) -> Result<DriveHomingParams, (String, String)> {
        let key = |k: &str| format!("drive_homing.{k}");
        let positive = |k: &str, v: f64, max: f64| {
            if !(v.is_finite() && v > 0.0) {
                Err((key(k), format!("{v} must be a finite number > 0")))
            } else if v > max {
                Err((key(k), format!("{v} exceeds max.speed {max}")))
            } else {
                Ok(v)
            }
        };
        let delta = |v: f64| -> Option<i64> {
            Some(scaling.try_units_to_counts(v).ok()? - scaling.try_units_to_counts(0.0).ok()?)
        };
        let u32_counts = |k: &str, v: f64| {
            delta(v)
                .map(i64::abs)
                .and_then(|c| u32::try_from(c.max(1)).ok())
                .ok_or_else(|| {
                    (
                        key(k),
                        format!("{v} is beyond what the drive's 32 bits count"),
                    )
                })
        };
        let speed_switch = u32_counts(
            "speed_switch",
            positive("speed_switch", self.speed_switch, max_speed)?,
        )?;
        let speed_zero = u32_counts(
            "speed_zero",
            positive("speed_zero", self.speed_zero, max_speed)?,
        )?;
        let acceleration = u32_counts(
            "acceleration",
            positive("acceleration", self.acceleration, f64::INFINITY)?,
        )?;
        if !self.home_offset.is_finite() {
            return Err((key("home_offset"), "must be a finite number".into()));
        }
        let home_offset = delta(self.home_offset)
            .and_then(|c| i32::try_from(c).ok())
            .ok_or_else(|| {
                (
                    key("home_offset"),
                    format!(
                        "{} is beyond what the drive's 32 bits count",
                        self.home_offset
                    ),
                )
            })?;
        let timeout_s = positive("timeout", self.timeout, f64::INFINITY)?;
        Ok(DriveHomingParams {
            method: self.method,
            speed_switch,
            speed_zero,
            acceleration,
            home_offset,
            timeout_s,
            skip: self.skip,
        })
    }
}
