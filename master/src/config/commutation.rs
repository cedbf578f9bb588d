//! `[axis.commutation]`: where the axis' drive exposes what `gantry commission AXIS
//! commutation` needs. CiA 402 has no commutation objects, so each maker has its own
//! (see its manual): the open-loop current-vector mode, the offset setting, the motor's
//! pole pairs, the vector's current and angle. Left out, they are gantry-sim's.
//!
//! ```toml
//! [axis.commutation]
//! mode = -3                                    # 0x6060 value of the open-loop current mode
//! offset = { index = 0x3010, type = "u16" }    # sub defaults to 0; type to the default's
//! offset_units = 65536                         # per electrical revolution ("counts": counts)
//! pole_pairs = 4                               # or an object: { index = 0x3011, type = "u8" }
//! current = { index = 0x3012 }                 # per mille of the rated current
//! angle = { index = 0x3013 }
//! angle_units = 3600                           # per electrical revolution
//! current_per_mille = 300                      # the vector's current while measuring
//! ```

use gantry_drives::cia402::objects::{DataType, ObjectId};
use gantry_drives::commutation::objects::MIN_ANGLE_UNITS;
use gantry_drives::commutation::{CommutationObjects, OffsetUnits, PolePairs};
use serde::Deserialize;

/// `[axis.commutation]`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CommutationSection {
    /// The open-loop current-vector mode (a negative 0x6060 value).
    #[serde(default)]
    pub mode: Option<i8>,
    /// The commutation offset setting.
    #[serde(default)]
    pub offset: Option<ObjectKey>,
    /// Its units to an electrical revolution, or `"counts"`.
    #[serde(default)]
    pub offset_units: Option<Units>,
    /// The motor's pole pairs: a number, or the object that holds them.
    #[serde(default)]
    pub pole_pairs: Option<PolePairsKey>,
    /// The vector's amplitude.
    #[serde(default)]
    pub current: Option<ObjectKey>,
    /// The vector's angle.
    #[serde(default)]
    pub angle: Option<ObjectKey>,
    /// Angle units to an electrical revolution.
    #[serde(default)]
    pub angle_units: Option<u32>,
    /// The vector's current while measuring (per mille of the rated current; default 300).
    #[serde(default)]
    pub current_per_mille: Option<u16>,
}

/// An object: `{ index = 0x3010, sub = 0, type = "i32" }`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ObjectKey {
    /// Index.
    pub index: u16,
    /// Sub-index (default 0).
    #[serde(default)]
    pub sub: u8,
    /// `"i8"`, `"u8"`, `"i16"`, `"u16"`, `"i32"` or `"u32"` (default: the default object's).
    #[serde(default, rename = "type")]
    pub kind: Option<TypeKey>,
}

/// An object's data type.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum TypeKey {
    /// INTEGER8.
    I8,
    /// UNSIGNED8.
    U8,
    /// INTEGER16.
    I16,
    /// UNSIGNED16.
    U16,
    /// INTEGER32.
    I32,
    /// UNSIGNED32.
    U32,
}

impl From<TypeKey> for DataType {
    fn from(t: TypeKey) -> Self {
        match t {
            TypeKey::I8 => DataType::I8,
            TypeKey::U8 => DataType::U8,
            TypeKey::I16 => DataType::I16,
            TypeKey::U16 => DataType::U16,
            TypeKey::I32 => DataType::I32,
            TypeKey::U32 => DataType::U32,
        }
    }
}

/// `offset_units`: a number per electrical revolution, or `"counts"`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(untagged)]
pub enum Units {
    /// Units per electrical revolution.
    PerElectricalRev(u32),
    /// `"counts"`.
    Named(UnitsName),
}

/// The named offset units.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum UnitsName {
    /// Encoder counts.
    Counts,
}

/// `pole_pairs`: a number, or an object.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(untagged)]
pub enum PolePairsKey {
    /// The motor's pole pairs.
    Fixed(u32),
    /// The object that holds them.
    Object(ObjectKey),
}

impl CommutationSection {
    /// The drive's objects, checked: each at an index of its own, the offset's units and
    /// the angle's at least [`MIN_ANGLE_UNITS`], the mode negative, the pole pairs 1–64.
    /// Errors name the key (below `commutation.`) and why.
    pub fn objects(&self) -> Result<CommutationObjects, (String, String)> {
        let key = |k: &str| format!("commutation.{k}");
        let d = CommutationObjects::default();
        let object = |k: &'static str, given: Option<ObjectKey>, default: ObjectId| {
            let Some(o) = given else {
                return Ok(default);
            };
            if o.index < 0x1000 {
                return Err((
                    key(k),
                    format!("{:#06x} is not an object of a device's dictionary", o.index),
                ));
            }
            Ok(ObjectId {
                index: o.index,
                sub: o.sub,
                kind: o.kind.map_or(default.kind, DataType::from),
                name: default.name,
            })
        };
        let offset = object("offset", self.offset, d.offset)?;
        let current = object("current", self.current, d.current)?;
        let angle = object("angle", self.angle, d.angle)?;
        let pole_pairs = match (self.pole_pairs, d.pole_pairs) {
            (None, p) => p,
            (Some(PolePairsKey::Fixed(n)), _) if (1..=64).contains(&n) => PolePairs::Fixed(n),
            (Some(PolePairsKey::Fixed(n)), _) => {
                return Err((key("pole_pairs"), format!("{n} is not within 1 to 64")))
            }
            (Some(PolePairsKey::Object(o)), PolePairs::Object(default)) => {
                PolePairs::Object(object("pole_pairs", Some(o), default)?)
            }
            (Some(PolePairsKey::Object(o)), PolePairs::Fixed(_)) => PolePairs::Object(object(
                "pole_pairs",
                Some(o),
                gantry_drives::cia402::objects::MOTOR_POLE_PAIRS,
            )?),
        };
        // (key, object, whether the file gives it): a clash is named by the key written.
        let mut objects = vec![
            ("offset", offset, self.offset.is_some()),
            ("current", current, self.current.is_some()),
            ("angle", angle, self.angle.is_some()),
        ];
        if let PolePairs::Object(o) = pole_pairs {
            objects.push(("pole_pairs", o, self.pole_pairs.is_some()));
        }
        for (i, &(k, o, given)) in objects.iter().enumerate() {
            let clash = objects
                .iter()
                .take(i)
                .find(|(_, x, _)| (x.index, x.sub) == (o.index, o.sub));
            if let Some(&(other, _, other_given)) = clash {
                let (k, other) = if given || !other_given {
                    (k, other)
                } else {
                    (other, k)
                };
                return Err((
                    key(k),
                    format!("{:#06x}:{} is {other}'s object too", o.index, o.sub),
                ));
            }
        }
        let mode = self.mode.unwrap_or(d.mode);
        if mode >= 0 {
            return Err((
                key("mode"),
                format!(
                    "{mode} is a CiA 402 mode; the open-loop current mode is a maker's (negative)"
                ),
            ));
        }
        let units = |k: &str, n: u32| {
            if n < MIN_ANGLE_UNITS {
                Err((
                    key(k),
                    format!("{n} per electrical revolution is coarser than a degree (at least {MIN_ANGLE_UNITS})"),
                ))
            } else {
                Ok(n)
            }
        };
        let offset_units = match self.offset_units {
            None | Some(Units::Named(UnitsName::Counts)) => OffsetUnits::Counts,
            Some(Units::PerElectricalRev(n)) => {
                OffsetUnits::PerElectricalRev(units("offset_units", n)?)
            }
        };
        let angle_units = units("angle_units", self.angle_units.unwrap_or(d.angle_units))?;
        let max_angle = match angle.kind {
            DataType::I8 | DataType::U8 => 1 << 8,
            DataType::I16 | DataType::U16 => 1 << 16,
            DataType::I32 | DataType::U32 => u64::from(u32::MAX) + 1,
        };
        if u64::from(angle_units) > max_angle {
            return Err((
                key("angle_units"),
                format!(
                    "{angle_units} does not fit the angle's object ({:?})",
                    angle.kind
                ),
            ));
        }
        if let Some(c) = self.current_per_mille {
            if !(1..=1000).contains(&c) {
                return Err((
                    key("current_per_mille"),
                    format!("{c} is not within 1 to 1000 (per mille of the rated current)"),
                ));
            }
        }
        Ok(CommutationObjects {
            mode,
            offset,
            offset_units,
            pole_pairs,
            current,
            angle,
            angle_units,
        })
    }
}
