//! Mechanics (SPEC §1; seed 000 §3): linear or rotary, normal or modulo, allowed
//! direction, software limits. Positions are in user units here; units ⇄ drive counts
//! (scaling, modulo counts, the drive's wrapping counter) belong to the drive layer,
//! `gantry_drives::scaling`, which the kernel does not use.
//!
//! NOTE for whoever extends this module: `Mechanics`, `Modulo` (with `period()`, `wrap`,
//! `delta_positive`, `delta_negative`, `delta_shortest`, `follow`), `Direction` and
//! `MechanicsError` are used by `axis/`; keep these names and signatures.

mod direction;
mod error;
mod modulo;

pub use direction::Direction;
pub use error::MechanicsError;
pub use modulo::Modulo;

/// Linear or rotary motion (only changes how values are labelled; both can be modulo).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MotionKind {
    /// Straight-line motion (mm, m).
    #[default]
    Linear,
    /// Rotation (°, rev).
    Rotary,
}

/// Mechanics of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mechanics {
    /// Linear or rotary.
    pub kind: MotionKind,
    /// Modulo period, if the axis is modulo.
    pub modulo: Option<Modulo>,
    /// Allowed direction.
    pub direction: Direction,
    /// Software limits `(min, max)` (units), active once the axis is homed; ignored on
    /// modulo axes (a modulo position has no end).
    pub software_limits: Option<(f64, f64)>,
}

impl Mechanics {
    /// Checks the mechanics for consistency: a finite period > 0, finite software limits
    /// with `min < max`. A one-way direction on a normal axis is allowed (a conveyor
    /// belt's absolute position may just grow).
    pub fn validate(&self) -> Result<(), MechanicsError> {
        if let Some(m) = self.modulo {
            Modulo::try_new(m.period())?;
        }
        if let Some((min, max)) = self.software_limits {
            if !(min.is_finite() && max.is_finite()) {
                return Err(MechanicsError::LimitNotFinite { min, max });
            }
            if min >= max {
                return Err(MechanicsError::LimitsNotOrdered { min, max });
            }
        }
        Ok(())
    }

    /// Checks a target position (units, axis frame): finite, and inside the software
    /// limits on a normal axis that has them. The caller decides whether the limits are
    /// active yet (they are once the axis is homed).
    pub fn check_target(&self, p: f64) -> Result<(), MechanicsError> {
        if !p.is_finite() {
            return Err(MechanicsError::NotFinite {
                name: "target",
                value: p,
            });
        }
        if let (None, Some((min, max))) = (self.modulo, self.software_limits) {
            if p < min {
                return Err(MechanicsError::BelowSoftwareLimit { value: p, min });
            }
            if p > max {
                return Err(MechanicsError::AboveSoftwareLimit { value: p, max });
            }
        }
        Ok(())
    }

    /// Checks that a move by `delta` (units, signed) goes an allowed way.
    pub fn check_direction(&self, delta: f64) -> Result<(), MechanicsError> {
        if self.direction.allows(delta) {
            Ok(())
        } else {
            Err(MechanicsError::DirectionNotAllowed {
                delta,
                allowed: self.direction,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mechanics_validation_names_the_problem() {
        let mut m = Mechanics {
            software_limits: Some((5.0, -5.0)),
            ..Mechanics::default()
        };
        assert_eq!(
            m.validate(),
            Err(MechanicsError::LimitsNotOrdered {
                min: 5.0,
                max: -5.0
            })
        );
        m.software_limits = Some((f64::NEG_INFINITY, 5.0));
        assert_eq!(
            m.validate(),
            Err(MechanicsError::LimitNotFinite {
                min: f64::NEG_INFINITY,
                max: 5.0
            })
        );
        m.software_limits = Some((-5.0, 5.0));
        m.direction = Direction::PositiveOnly;
        assert_eq!(m.validate(), Ok(()), "one-way normal axes are allowed");
    }

    #[test]
    fn targets_are_checked_against_the_software_limits() {
        let m = Mechanics {
            software_limits: Some((-10.0, 100.0)),
            ..Mechanics::default()
        };
        assert_eq!(m.check_target(50.0), Ok(()));
        assert_eq!(m.check_target(100.0), Ok(()));
        assert_eq!(
            m.check_target(-10.5),
            Err(MechanicsError::BelowSoftwareLimit {
                value: -10.5,
                min: -10.0
            })
        );
        assert_eq!(
            m.check_target(100.5),
            Err(MechanicsError::AboveSoftwareLimit {
                value: 100.5,
                max: 100.0
            })
        );
        assert!(matches!(
            m.check_target(f64::NAN),
            Err(MechanicsError::NotFinite { name: "target", .. })
        ));
        // Modulo axes have no software limits.
        let r = Mechanics {
            modulo: Modulo::new(360.0),
            ..m
        };
        assert_eq!(r.check_target(500.0), Ok(()));
        let msg = m.check_target(100.5).unwrap_err().to_string();
        assert!(msg.contains("100.5") && msg.contains("max 100"), "{msg}");
    }

    #[test]
    fn directions_are_checked() {
        let mut m = Mechanics {
            direction: Direction::PositiveOnly,
            ..Mechanics::default()
        };
        assert_eq!(m.check_direction(1.0), Ok(()));
        assert_eq!(m.check_direction(0.0), Ok(()));
        assert_eq!(
            m.check_direction(-1.0),
            Err(MechanicsError::DirectionNotAllowed {
                delta: -1.0,
                allowed: Direction::PositiveOnly
            })
        );
        m.direction = Direction::NegativeOnly;
        assert!(m.check_direction(1.0).is_err() && m.check_direction(-1.0).is_ok());
        assert!(m.check_direction(f64::NAN).is_err());
        m.direction = Direction::Both;
        assert!(m.check_direction(1.0).is_ok() && m.check_direction(-1.0).is_ok());
        let msg = MechanicsError::DirectionNotAllowed {
            delta: -3.0,
            allowed: Direction::PositiveOnly,
        }
        .to_string();
        assert!(msg.contains("-3") && msg.contains("positive only"), "{msg}");
    }
}
