//! What a simulated servo is: its motor and load, its loop tuning, and the power-up values
//! of the CiA 402 objects that set its limits and stop reactions. The defaults are a 400 W
//! low-inertia AC servo (the class of Panasonic MSMF042, Yaskawa SGM7J-04: 1.27 N·m rated at
//! 3000 rpm, about 3x peak, ~0.26·10⁻⁴ kg·m² rotor) on a load of five times its inertia,
//! with a 17-bit absolute encoder, tuned as a commissioning engineer would leave it.

use thiserror::Error;

/// A servo's motor, load, tuning and object power-up values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoParams {
    /// Encoder counts per motor revolution (2¹⁷: a 17-bit encoder).
    pub counts_per_rev: u32,
    /// Rated (continuous) torque (N·m); 0x6076 Motor rated torque, and the unit of
    /// 0x6071/0x6072/0x6077 (per mille of it).
    pub rated_torque_nm: f64,
    /// Peak torque (N·m): the current limit of the power stage.
    pub peak_torque_nm: f64,
    /// Rotor inertia (kg·m²).
    pub rotor_inertia_kgm2: f64,
    /// Load inertia as a multiple of the rotor's (reflected to the motor shaft).
    pub load_inertia_ratio: f64,
    /// Coulomb (dry) friction torque (N·m): also the torque needed to break away.
    pub coulomb_friction_nm: f64,
    /// Viscous friction (N·m per rad/s).
    pub viscous_friction_nm_s: f64,
    /// Highest motor speed (rpm); the power-up value of 0x607F.
    pub max_speed_rpm: f64,
    /// Motor pole pairs (electrical revolutions per mechanical one).
    pub pole_pairs: u32,
    /// Where in the revolution the encoder's index pulse sits (counts).
    pub index_at: u32,
    /// Switch cams on the drive's own travel, read by its digital inputs (0x60FD).
    pub switches: super::probe::DriveSwitches,
    /// The motor's true commutation offset (counts), unknown to the master until it is
    /// commissioned.
    pub commutation_offset: i32,
    /// Rate of the drive's own control loops (Hz): the plant runs in steps of this size
    /// inside each application period.
    pub loop_rate_hz: f64,
    /// Bandwidth of the current (torque) loop (Hz).
    pub current_loop_hz: f64,
    /// Bandwidth of the velocity loop (Hz): the PI's proportional gain is J·2π·this, its
    /// integral time 4/(2π·this).
    pub velocity_loop_hz: f64,
    /// Position loop gain Kv (1/s): velocity command per count of following error.
    pub position_gain: f64,
    /// 0x6065 Following error window (counts); `u32::MAX` switches the check off.
    pub following_error_window: u32,
    /// 0x6066 Following error time out (ms).
    pub following_error_timeout_ms: u16,
    /// 0x6084 Profile deceleration (counts/s²): the "slow down ramp" of the option codes.
    pub profile_deceleration: u32,
    /// 0x6085 Quick stop deceleration (counts/s²).
    pub quick_stop_deceleration: u32,
    /// 0x605A Quick stop option code.
    pub quick_stop_option_code: i16,
    /// 0x605B Shutdown option code.
    pub shutdown_option_code: i16,
    /// 0x605C Disable operation option code.
    pub disable_operation_option_code: i16,
    /// 0x605E Fault reaction option code.
    pub fault_reaction_option_code: i16,
    /// Homing faults real drives are reported to have, to inject.
    pub homing_faults: super::homing::HomingFaults,
    /// Where its maker put the commutation objects and the open-loop current-vector mode
    /// (default 0x2100–0x2103, mode −1; `[slave.commutation]`).
    pub commutation_objects: gantry_drives::commutation::CommutationObjects,
}

impl Default for ServoParams {
    fn default() -> Self {
        let counts_per_rev = 1 << 17;
        let rev = f64::from(counts_per_rev);
        Self {
            counts_per_rev,
            rated_torque_nm: 1.27,
            peak_torque_nm: 3.8,
            rotor_inertia_kgm2: 0.26e-4,
            load_inertia_ratio: 5.0,
            // ~2.5 % and, at 3000 rpm, another ~2.5 % of rated torque.
            coulomb_friction_nm: 0.03,
            viscous_friction_nm_s: 1.0e-4,
            max_speed_rpm: 6000.0,
            pole_pairs: 5,
            index_at: 1000,
            switches: super::probe::DriveSwitches::default(),
            commutation_offset: 0,
            loop_rate_hz: 16_000.0,
            current_loop_hz: 2000.0,
            velocity_loop_hz: 200.0,
            // A fifth of the velocity loop's 2π·200 Hz (cascade rule: at most a quarter).
            position_gain: 2.0 * core::f64::consts::PI * 200.0 / 5.0,
            // A quarter turn for 10 ms: far above the few hundred counts a tuned axis lags
            // on an S-curve, far below what a wrong setpoint or a blocked axis produces.
            following_error_window: counts_per_rev / 4,
            following_error_timeout_ms: 10,
            // 500 and 1000 rev/s² (the load's peak is ~3900 rev/s² at peak torque).
            profile_deceleration: (500.0 * rev) as u32,
            quick_stop_deceleration: (1000.0 * rev) as u32,
            // CiA 402-2 defaults: quick stop ramp then Switch on disabled; shutdown lets
            // the motor coast; disable operation brakes on the slow down ramp; a fault
            // brakes on the quick stop ramp.
            quick_stop_option_code: 2,
            shutdown_option_code: 0,
            disable_operation_option_code: 1,
            fault_reaction_option_code: 2,
            homing_faults: super::homing::HomingFaults::default(),
            commutation_objects: Default::default(),
        }
    }
}

/// A parameter out of its range: which, and the range.
#[derive(Clone, Debug, Error, PartialEq)]
#[error("{name}: {reason}")]
pub struct ParamError {
    /// The parameter (the TOML key).
    pub name: &'static str,
    /// The range it must be in.
    pub reason: String,
}

impl ServoParams {
    /// Total inertia on the motor shaft (kg·m²).
    pub fn inertia(&self) -> f64 {
        self.rotor_inertia_kgm2 * (1.0 + self.load_inertia_ratio)
    }

    /// Highest motor speed (counts/s).
    pub fn max_speed_counts(&self) -> f64 {
        self.max_speed_rpm / 60.0 * f64::from(self.counts_per_rev)
    }

    /// Checks every value, naming the first that is out of range.
    pub fn check(&self) -> Result<(), ParamError> {
        let range = |name: &'static str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err(ParamError {
                    name,
                    reason: format!("{v} is not within {lo} to {hi}"),
                })
            }
        };
        range(
            "counts_per_rev",
            f64::from(self.counts_per_rev),
            16.0,
            f64::from(1u32 << 24),
        )?;
        range("rated_torque_nm", self.rated_torque_nm, 0.01, 1000.0)?;
        range(
            "peak_torque_nm",
            self.peak_torque_nm,
            self.rated_torque_nm,
            10.0 * self.rated_torque_nm,
        )?;
        range("rotor_inertia_kgm2", self.rotor_inertia_kgm2, 1e-7, 1.0)?;
        range("load_inertia_ratio", self.load_inertia_ratio, 0.0, 100.0)?;
        range(
            "coulomb_friction_nm",
            self.coulomb_friction_nm,
            0.0,
            self.rated_torque_nm,
        )?;
        range(
            "viscous_friction_nm_s",
            self.viscous_friction_nm_s,
            0.0,
            1.0,
        )?;
        range("max_speed_rpm", self.max_speed_rpm, 1.0, 100_000.0)?;
        range("pole_pairs", f64::from(self.pole_pairs), 1.0, 64.0)?;
        range(
            "index_at",
            f64::from(self.index_at),
            0.0,
            f64::from(self.counts_per_rev) - 1.0,
        )?;
        range("loop_rate_hz", self.loop_rate_hz, 1000.0, 64_000.0)?;
        range(
            "current_loop_hz",
            self.current_loop_hz,
            10.0,
            self.loop_rate_hz / 4.0,
        )?;
        // The velocity loop must be well inside the current loop and the loop rate.
        range(
            "velocity_loop_hz",
            self.velocity_loop_hz,
            1.0,
            (self.current_loop_hz / 2.0).min(self.loop_rate_hz / 20.0),
        )?;
        // The position loop inside the velocity loop (cascade rule: a factor of 4).
        range(
            "position_gain",
            self.position_gain,
            0.0,
            2.0 * core::f64::consts::PI * self.velocity_loop_hz / 4.0,
        )?;
        range(
            "following_error_timeout_ms",
            f64::from(self.following_error_timeout_ms),
            0.0,
            60_000.0,
        )?;
        range(
            "profile_deceleration",
            f64::from(self.profile_deceleration),
            1.0,
            f64::from(u32::MAX),
        )?;
        range(
            "quick_stop_deceleration",
            f64::from(self.quick_stop_deceleration),
            1.0,
            f64::from(u32::MAX),
        )?;
        let code =
            |name: &'static str, v: i16, hi: i16| range(name, f64::from(v), 0.0, f64::from(hi));
        code("quick_stop_option_code", self.quick_stop_option_code, 8)?;
        code("shutdown_option_code", self.shutdown_option_code, 1)?;
        code(
            "disable_operation_option_code",
            self.disable_operation_option_code,
            1,
        )?;
        code(
            "fault_reaction_option_code",
            self.fault_reaction_option_code,
            4,
        )?;
        self.check_commutation_objects()
    }

    /// The commutation objects: in the manufacturer's range (CiA 301 §7.4.1), each at an
    /// index of its own, the mode a manufacturer's (negative), the angle's units between a
    /// degree and 16 bits.
    fn check_commutation_objects(&self) -> Result<(), ParamError> {
        use gantry_drives::commutation::{OffsetUnits, PolePairs};
        let c = &self.commutation_objects;
        let bad = |name: &'static str, reason: String| Err(ParamError { name, reason });
        let mut indices = vec![
            ("commutation.offset", c.offset.index),
            ("commutation.current", c.current.index),
            ("commutation.angle", c.angle.index),
        ];
        if let PolePairs::Object(o) = c.pole_pairs {
            indices.push(("commutation.pole_pairs", o.index));
        }
        for (i, &(name, index)) in indices.iter().enumerate() {
            if !(0x2000..=0x5FFF).contains(&index) {
                return bad(
                    name,
                    format!("{index:#06x} is not a manufacturer-specific index (0x2000 to 0x5fff)"),
                );
            }
            if let Some((other, _)) = indices.iter().take(i).find(|(_, x)| *x == index) {
                return bad(name, format!("{index:#06x} is {other}'s index too"));
            }
        }
        if c.mode >= 0 {
            return bad(
                "commutation.mode",
                format!("{} is not a manufacturer's mode (negative)", c.mode),
            );
        }
        if !(360..=65536).contains(&c.angle_units) {
            return bad(
                "commutation.angle_units",
                format!("{} is not within 360 to 65536", c.angle_units),
            );
        }
        if let OffsetUnits::PerElectricalRev(n) = c.offset_units {
            if !(360..=65536).contains(&n) {
                return bad(
                    "commutation.offset_units",
                    format!("{n} is not within 360 to 65536 (or 0: counts)"),
                );
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_400_w_servo_is_consistent() {
        let p = ServoParams::default();
        p.check().unwrap();
        // 400 W at 3000 rpm is 1.27 N·m.
        let watts = p.rated_torque_nm * 3000.0 / 60.0 * 2.0 * core::f64::consts::PI;
        assert!((watts - 400.0).abs() < 2.0, "{watts} W");
        let bad = ServoParams {
            position_gain: 2000.0,
            ..p
        };
        assert_eq!(bad.check().unwrap_err().name, "position_gain");
        let bad = ServoParams {
            quick_stop_option_code: 9,
            ..p
        };
        assert_eq!(
            bad.check().unwrap_err().to_string(),
            "quick_stop_option_code: 9 is not within 0 to 8"
        );
    }

    #[test]
    fn commutation_objects_of_another_maker_are_checked() {
        use gantry_drives::cia402::objects::ObjectId;
        use gantry_drives::commutation::{CommutationObjects, OffsetUnits};
        let p = ServoParams::default();
        let d = CommutationObjects::default();
        let with = |c: CommutationObjects| ServoParams {
            commutation_objects: c,
            ..p
        };
        let at = |o: ObjectId, index: u16| ObjectId { index, ..o };
        let other = CommutationObjects {
            mode: -3,
            offset: at(d.offset, 0x3010),
            offset_units: OffsetUnits::PerElectricalRev(3600),
            current: at(d.current, 0x3012),
            angle: at(d.angle, 0x3013),
            angle_units: 3600,
            ..d
        };
        with(other).check().unwrap();
        let cases = [
            (
                CommutationObjects { mode: 8, ..other },
                "commutation.mode: 8 is not a manufacturer's mode (negative)",
            ),
            (
                CommutationObjects {
                    angle: at(d.angle, 0x3012),
                    ..other
                },
                "commutation.angle: 0x3012 is commutation.current's index too",
            ),
            (
                CommutationObjects {
                    offset: at(d.offset, 0x6000),
                    ..other
                },
                "commutation.offset: 0x6000 is not a manufacturer-specific index (0x2000 to 0x5fff)",
            ),
            (
                CommutationObjects {
                    angle_units: 100,
                    ..other
                },
                "commutation.angle_units: 100 is not within 360 to 65536",
            ),
        ];
        for (c, want) in cases {
            assert_eq!(with(c).check().unwrap_err().to_string(), want);
        }
    }
}
