//! Objects and their sub-objects as an EDS describes them (CiA 306-1 §4.6): object type
//! (CiA 301 Table 42), data type, access, PDO mapping, default value and limits.

use std::collections::BTreeMap;

use super::access::{AccessType, PdoDirection};
use super::data_type::DataType;
use super::value::Value;

/// `ObjectType=` (CiA 301 §7.4.3 Table 42).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectType {
    /// NULL (0x0).
    Null,
    /// DOMAIN (0x2): a large variable amount of data.
    Domain,
    /// DEFTYPE (0x5): a type definition.
    DefType,
    /// DEFSTRUCT (0x6): a record type definition.
    DefStruct,
    /// VAR (0x7): a single value at sub-index 0.
    Var,
    /// ARRAY (0x8): sub 0 the number of entries, subs 1.. of one data type.
    Array,
    /// RECORD (0x9): sub 0 the highest sub-index, subs of any types.
    Record,
}

impl ObjectType {
    /// The code.
    pub const fn code(self) -> u8 {
        match self {
            Self::Null => 0x0,
            Self::Domain => 0x2,
            Self::DefType => 0x5,
            Self::DefStruct => 0x6,
            Self::Var => 0x7,
            Self::Array => 0x8,
            Self::Record => 0x9,
        }
    }

    /// The object type with this code.
    pub const fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0x0 => Self::Null,
            0x2 => Self::Domain,
            0x5 => Self::DefType,
            0x6 => Self::DefStruct,
            0x7 => Self::Var,
            0x8 => Self::Array,
            0x9 => Self::Record,
            _ => return None,
        })
    }

    /// Whether the object is one value at sub 0 described in its own section.
    pub const fn is_single(self) -> bool {
        matches!(self, Self::Var | Self::Domain | Self::DefType | Self::Null)
    }
}

/// Which list of the EDS names an object (CiA 306-1 §4.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectList {
    /// `[MandatoryObjects]`.
    Mandatory,
    /// `[OptionalObjects]`.
    Optional,
    /// `[ManufacturerObjects]`.
    Manufacturer,
}

impl ObjectList {
    /// The section's name.
    pub const fn section(self) -> &'static str {
        match self {
            Self::Mandatory => "MandatoryObjects",
            Self::Optional => "OptionalObjects",
            Self::Manufacturer => "ManufacturerObjects",
        }
    }

    /// The list an object at `index` belongs in: 0x1000, 0x1001, 0x1018 are mandatory
    /// (CiA 301 §7.4.5), 0x2000–0x5FFF manufacturer-specific, the rest optional.
    pub const fn for_index(index: u16) -> Self {
        match index {
            0x1000 | 0x1001 | 0x1018 => Self::Mandatory,
            0x2000..=0x5FFF => Self::Manufacturer,
            _ => Self::Optional,
        }
    }
}

/// One entry (a VAR object's value, or one sub-index of an ARRAY or RECORD).
#[derive(Clone, Debug, PartialEq)]
pub struct SubObject {
    /// `ParameterName=`.
    pub name: String,
    /// `ObjectType=` of the entry (VAR, or DOMAIN).
    pub object_type: ObjectType,
    /// `DataType=`.
    pub data_type: DataType,
    /// `AccessType=`.
    pub access: AccessType,
    /// `PDOMapping=1`.
    pub pdo_mapping: bool,
    /// `DefaultValue=` (None: not given).
    pub default_value: Option<Value>,
    /// `LowLimit=`.
    pub low_limit: Option<Value>,
    /// `HighLimit=`.
    pub high_limit: Option<Value>,
    /// `ParameterValue=` (a DCF: the value configured).
    pub parameter_value: Option<Value>,
}

impl SubObject {
    /// A VAR entry with no value, limits or mapping.
    pub fn new(name: &str, data_type: DataType, access: AccessType) -> Self {
        Self {
            name: name.to_string(),
            object_type: ObjectType::Var,
            data_type,
            access,
            pdo_mapping: false,
            default_value: None,
            low_limit: None,
            high_limit: None,
            parameter_value: None,
        }
    }

    /// With `PDOMapping=1`.
    pub fn mappable(mut self) -> Self {
        self.pdo_mapping = true;
        self
    }

    /// With this default value.
    pub fn with_default(mut self, value: Value) -> Self {
        self.default_value = Some(value);
        self
    }

    /// Size in bits (None: variable).
    pub fn bits(&self) -> Option<u32> {
        self.data_type.bits()
    }

    /// The integer range its values may take: `LowLimit..=HighLimit` where given, the
    /// data type's range otherwise (`None`: no integer type).
    pub fn limits(&self) -> Option<(i128, i128)> {
        let (lo, hi) = self.data_type.integer_range()?;
        let int = |v: &Option<Value>| match v {
            Some(Value::Integer(i)) => Some(*i),
            _ => None,
        };
        Some((
            int(&self.low_limit).unwrap_or(lo),
            int(&self.high_limit).unwrap_or(hi),
        ))
    }

    /// Whether `value` (on node `node`, for `$NODEID`) is within [`SubObject::limits`];
    /// true for values that are no integers.
    pub fn allows(&self, value: &Value, node: u8) -> bool {
        match (self.limits(), value.integer_on(node)) {
            (Some((lo, hi)), Some(v)) => (lo..=hi).contains(&v),
            _ => true,
        }
    }

    /// Whether it may be mapped into a PDO going `direction` (`PDOMapping=1` and an
    /// access that allows that direction).
    pub fn mappable_in(&self, direction: PdoDirection) -> bool {
        self.pdo_mapping && self.access.mappable_in(direction)
    }
}

/// One object at an index.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    /// Index.
    pub index: u16,
    /// `ParameterName=`.
    pub name: String,
    /// `ObjectType=`.
    pub object_type: ObjectType,
    /// Its entries by sub-index (a VAR: one at 0).
    pub subs: BTreeMap<u8, SubObject>,
    /// The list that names it.
    pub list: ObjectList,
}

impl Object {
    /// A VAR object.
    pub fn var(index: u16, entry: SubObject) -> Self {
        Self {
            index,
            name: entry.name.clone(),
            object_type: ObjectType::Var,
            subs: BTreeMap::from([(0, entry)]),
            list: ObjectList::for_index(index),
        }
    }

    /// An ARRAY or RECORD with these entries (sub 0 included).
    pub fn compound(
        index: u16,
        name: &str,
        object_type: ObjectType,
        subs: impl IntoIterator<Item = (u8, SubObject)>,
    ) -> Self {
        Self {
            index,
            name: name.to_string(),
            object_type,
            subs: subs.into_iter().collect(),
            list: ObjectList::for_index(index),
        }
    }

    /// The entry at `sub`.
    pub fn sub(&self, sub: u8) -> Option<&SubObject> {
        self.subs.get(&sub)
    }
}
