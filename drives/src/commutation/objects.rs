//! Where a drive exposes what the commutation measurement needs. CiA 402 has no objects
//! for commutation: every maker puts the offset, the motor's pole pairs and an open-loop
//! current vector at indices of its own (CiA 301 §7.4.1 gives 0x2000–0x5FFF to the
//! manufacturer), in units of its own, and the open-loop mode at a negative 0x6060 value
//! of its own. [`CommutationObjects`] names them; its default is gantry-sim's servo
//! (0x2100–0x2103, mode −1). The measurement itself works in encoder counts and
//! electrical angle; only the wire values are converted here.

use crate::cia402::mode::OPEN_LOOP_CURRENT_VECTOR;
use crate::cia402::objects::{self, ObjectId};

/// The units of the drive's commutation offset setting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OffsetUnits {
    /// Encoder counts (0 ≤ offset < counts of an electrical revolution): gantry-sim's.
    Counts,
    /// This many units to an electrical revolution (3600: tenths of a degree; 65536).
    PerElectricalRev(u32),
}

/// The motor's pole pairs: read from the drive, or given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PolePairs {
    /// An object of the drive that holds them.
    Object(ObjectId),
    /// The motor's data sheet value (a drive that does not expose them).
    Fixed(u32),
}

/// A drive's commutation objects and open-loop mode (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommutationObjects {
    /// The open-loop current-vector mode (a 0x6060 value; the makers' are negative).
    pub mode: i8,
    /// The commutation offset setting the drive commutates with (read-write).
    pub offset: ObjectId,
    /// Its units.
    pub offset_units: OffsetUnits,
    /// The motor's pole pairs.
    pub pole_pairs: PolePairs,
    /// The vector's amplitude in the open-loop mode, per mille of the rated current.
    pub current: ObjectId,
    /// The vector's electrical angle in the open-loop mode.
    pub angle: ObjectId,
    /// Angle units to an electrical revolution (at least 360).
    pub angle_units: u32,
}

impl Default for CommutationObjects {
    /// gantry-sim's servo: 0x2100 offset in counts, 0x2101 pole pairs, 0x2102 current,
    /// 0x2103 angle (65536 to an electrical revolution), mode −1.
    fn default() -> Self {
        Self {
            mode: OPEN_LOOP_CURRENT_VECTOR,
            offset: objects::COMMUTATION_OFFSET,
            offset_units: OffsetUnits::Counts,
            pole_pairs: PolePairs::Object(objects::MOTOR_POLE_PAIRS),
            current: objects::COMMUTATION_CURRENT,
            angle: objects::COMMUTATION_ANGLE,
            angle_units: 65536,
        }
    }
}

/// Fewest angle units to an electrical revolution: coarser, the vector would step by
/// more than a degree and the measurement could not promise ±1° electrical.
pub const MIN_ANGLE_UNITS: u32 = 360;

impl CommutationObjects {
    /// The offset as the drive's object holds it, for `counts` (0 ≤ counts < `e`, the
    /// counts of an electrical revolution).
    pub fn offset_to_drive(&self, counts: i64, e: f64) -> i64 {
        match self.offset_units {
            OffsetUnits::Counts => counts,
            OffsetUnits::PerElectricalRev(n) => {
                let v = (counts as f64 / e * f64::from(n)).round() as i64;
                v.rem_euclid(i64::from(n.max(1)))
            }
        }
    }

    /// The offset in counts (0 ≤ result < `e`) for the drive's value `v`.
    pub fn offset_to_counts(&self, v: i64, e: f64) -> i64 {
        match self.offset_units {
            OffsetUnits::Counts => v,
            OffsetUnits::PerElectricalRev(n) => {
                let c = (v as f64 / f64::from(n.max(1)) * e).round() as i64;
                if e >= 1.0 {
                    c.rem_euclid(e.round() as i64)
                } else {
                    c
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_convert_both_ways_within_half_a_unit() {
        let o = CommutationObjects {
            offset_units: OffsetUnits::PerElectricalRev(3600),
            ..Default::default()
        };
        // 2^17 counts, 5 pole pairs: 26214.4 counts to an electrical revolution.
        let e = 131_072.0 / 5.0;
        for counts in [0i64, 1, 7, 13_107, 17_000, 26_213] {
            let v = o.offset_to_drive(counts, e);
            assert!((0..3600).contains(&v), "{counts} -> {v}");
            let back = o.offset_to_counts(v, e);
            // Half a tenth of a degree: 3.6 counts.
            let d = (back - counts).rem_euclid(26_214);
            let d = d.min(26_214 - d);
            assert!(d <= 4, "{counts} -> {v} -> {back}");
        }
        // Counts pass through unchanged.
        let c = CommutationObjects::default();
        assert_eq!(c.offset_to_drive(17_000, e), 17_000);
        assert_eq!(c.offset_to_counts(17_000, e), 17_000);
    }
}
