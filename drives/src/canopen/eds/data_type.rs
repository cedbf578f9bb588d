//! The static data types of CiA 301 §7.4.7.1 (Table 44) an EDS names by number in
//! `DataType=` (CiA 306-1 §4.6.3), with their size on the wire.

/// A CiA 301 static data type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DataType {
    /// BOOLEAN (0x0001), 1 bit.
    Boolean,
    /// INTEGER8 (0x0002).
    Integer8,
    /// INTEGER16 (0x0003).
    Integer16,
    /// INTEGER32 (0x0004).
    Integer32,
    /// UNSIGNED8 (0x0005).
    Unsigned8,
    /// UNSIGNED16 (0x0006).
    Unsigned16,
    /// UNSIGNED32 (0x0007).
    Unsigned32,
    /// REAL32 (0x0008), IEEE 754 single.
    Real32,
    /// VISIBLE_STRING (0x0009), variable length.
    VisibleString,
    /// OCTET_STRING (0x000A), variable length.
    OctetString,
    /// UNICODE_STRING (0x000B), variable length.
    UnicodeString,
    /// TIME_OF_DAY (0x000C), 48 bits.
    TimeOfDay,
    /// TIME_DIFFERENCE (0x000D), 48 bits.
    TimeDifference,
    /// DOMAIN (0x000F), any length.
    Domain,
    /// INTEGER24 (0x0010).
    Integer24,
    /// REAL64 (0x0011), IEEE 754 double.
    Real64,
    /// INTEGER40 (0x0012).
    Integer40,
    /// INTEGER48 (0x0013).
    Integer48,
    /// INTEGER56 (0x0014).
    Integer56,
    /// INTEGER64 (0x0015).
    Integer64,
    /// UNSIGNED24 (0x0016).
    Unsigned24,
    /// UNSIGNED40 (0x0018).
    Unsigned40,
    /// UNSIGNED48 (0x0019).
    Unsigned48,
    /// UNSIGNED56 (0x001A).
    Unsigned56,
    /// UNSIGNED64 (0x001B).
    Unsigned64,
}

/// Every type, in code order.
pub const ALL: [DataType; 25] = [
    DataType::Boolean,
    DataType::Integer8,
    DataType::Integer16,
    DataType::Integer32,
    DataType::Unsigned8,
    DataType::Unsigned16,
    DataType::Unsigned32,
    DataType::Real32,
    DataType::VisibleString,
    DataType::OctetString,
    DataType::UnicodeString,
    DataType::TimeOfDay,
    DataType::TimeDifference,
    DataType::Domain,
    DataType::Integer24,
    DataType::Real64,
    DataType::Integer40,
    DataType::Integer48,
    DataType::Integer56,
    DataType::Integer64,
    DataType::Unsigned24,
    DataType::Unsigned40,
    DataType::Unsigned48,
    DataType::Unsigned56,
    DataType::Unsigned64,
];

impl DataType {
    /// The data type index (CiA 301 Table 44).
    pub const fn code(self) -> u16 {
        match self {
            Self::Boolean => 0x0001,
            Self::Integer8 => 0x0002,
            Self::Integer16 => 0x0003,
            Self::Integer32 => 0x0004,
            Self::Unsigned8 => 0x0005,
            Self::Unsigned16 => 0x0006,
            Self::Unsigned32 => 0x0007,
            Self::Real32 => 0x0008,
            Self::VisibleString => 0x0009,
            Self::OctetString => 0x000A,
            Self::UnicodeString => 0x000B,
            Self::TimeOfDay => 0x000C,
            Self::TimeDifference => 0x000D,
            Self::Domain => 0x000F,
            Self::Integer24 => 0x0010,
            Self::Real64 => 0x0011,
            Self::Integer40 => 0x0012,
            Self::Integer48 => 0x0013,
            Self::Integer56 => 0x0014,
            Self::Integer64 => 0x0015,
            Self::Unsigned24 => 0x0016,
            Self::Unsigned40 => 0x0018,
            Self::Unsigned48 => 0x0019,
            Self::Unsigned56 => 0x001A,
            Self::Unsigned64 => 0x001B,
        }
    }

    /// The type with this index; `None` for 0x000E and 0x0017 (reserved), the complex
    /// types from 0x0020 on (PDO parameter records, identity: no type of a sub-object)
    /// and anything else.
    pub fn from_code(code: u16) -> Option<Self> {
        ALL.iter().copied().find(|t| t.code() == code)
    }

    /// Size on the wire in bits; `None` for the variable-length types (strings, DOMAIN).
    pub const fn bits(self) -> Option<u32> {
        match self {
            Self::Boolean => Some(1),
            Self::Integer8 | Self::Unsigned8 => Some(8),
            Self::Integer16 | Self::Unsigned16 => Some(16),
            Self::Integer24 | Self::Unsigned24 => Some(24),
            Self::Integer32 | Self::Unsigned32 | Self::Real32 => Some(32),
            Self::Integer40 | Self::Unsigned40 => Some(40),
            Self::Integer48 | Self::Unsigned48 | Self::TimeOfDay | Self::TimeDifference => Some(48),
            Self::Integer56 | Self::Unsigned56 => Some(56),
            Self::Integer64 | Self::Unsigned64 | Self::Real64 => Some(64),
            Self::VisibleString | Self::OctetString | Self::UnicodeString | Self::Domain => None,
        }
    }

    /// Size on the wire in bytes (BOOLEAN takes one byte in an SDO); `None` when variable.
    pub const fn bytes(self) -> Option<usize> {
        match self.bits() {
            Some(b) => Some(b.div_ceil(8) as usize),
            None => None,
        }
    }

    /// The name CiA 301 gives it.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Boolean => "BOOLEAN",
            Self::Integer8 => "INTEGER8",
            Self::Integer16 => "INTEGER16",
            Self::Integer32 => "INTEGER32",
            Self::Unsigned8 => "UNSIGNED8",
            Self::Unsigned16 => "UNSIGNED16",
            Self::Unsigned32 => "UNSIGNED32",
            Self::Real32 => "REAL32",
            Self::VisibleString => "VISIBLE_STRING",
            Self::OctetString => "OCTET_STRING",
            Self::UnicodeString => "UNICODE_STRING",
            Self::TimeOfDay => "TIME_OF_DAY",
            Self::TimeDifference => "TIME_DIFFERENCE",
            Self::Domain => "DOMAIN",
            Self::Integer24 => "INTEGER24",
            Self::Real64 => "REAL64",
            Self::Integer40 => "INTEGER40",
            Self::Integer48 => "INTEGER48",
            Self::Integer56 => "INTEGER56",
            Self::Integer64 => "INTEGER64",
            Self::Unsigned24 => "UNSIGNED24",
            Self::Unsigned40 => "UNSIGNED40",
            Self::Unsigned48 => "UNSIGNED48",
            Self::Unsigned56 => "UNSIGNED56",
            Self::Unsigned64 => "UNSIGNED64",
        }
    }

    /// The type of a CiA 301 name (any case), e.g. for a command line's `--type`.
    pub fn from_name(name: &str) -> Option<Self> {
        ALL.iter()
            .copied()
            .find(|t| t.name().eq_ignore_ascii_case(name.trim()))
    }

    /// Whether its values are integers (BOOLEAN included: 0 or 1).
    pub const fn is_integer(self) -> bool {
        self.integer_range().is_some()
    }

    /// Whether it is a signed integer.
    pub const fn is_signed(self) -> bool {
        matches!(
            self,
            Self::Integer8
                | Self::Integer16
                | Self::Integer24
                | Self::Integer32
                | Self::Integer40
                | Self::Integer48
                | Self::Integer56
                | Self::Integer64
        )
    }

    /// The smallest and largest value of an integer type; `None` for the others.
    pub const fn integer_range(self) -> Option<(i128, i128)> {
        let bits = match self {
            Self::Boolean => return Some((0, 1)),
            Self::Real32
            | Self::Real64
            | Self::VisibleString
            | Self::OctetString
            | Self::UnicodeString
            | Self::TimeOfDay
            | Self::TimeDifference
            | Self::Domain => return None,
            t => match t.bits() {
                Some(b) => b,
                None => return None,
            },
        };
        if self.is_signed() {
            Some((-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1))
        } else {
            Some((0, (1i128 << bits) - 1))
        }
    }
}

impl core::fmt::Display for DataType {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_reserved_codes_are_no_type() {
        for t in ALL {
            assert_eq!(DataType::from_code(t.code()), Some(t));
            assert_eq!(DataType::from_name(&t.name().to_lowercase()), Some(t));
        }
        for code in [0x0000, 0x000E, 0x0017, 0x0020, 0x0021, 0x0023, 0x0099] {
            assert_eq!(DataType::from_code(code), None, "{code:#06x}");
        }
    }

    #[test]
    fn sizes_and_ranges_of_table_44() {
        assert_eq!(DataType::Boolean.bits(), Some(1));
        assert_eq!(DataType::Boolean.bytes(), Some(1));
        assert_eq!(DataType::Unsigned24.bits(), Some(24));
        assert_eq!(DataType::TimeOfDay.bytes(), Some(6));
        assert_eq!(DataType::VisibleString.bits(), None);
        assert_eq!(DataType::Integer8.integer_range(), Some((-128, 127)));
        assert_eq!(
            DataType::Unsigned64.integer_range(),
            Some((0, u64::MAX as i128))
        );
        assert_eq!(
            DataType::Integer64.integer_range(),
            Some((i64::MIN as i128, i64::MAX as i128))
        );
        assert_eq!(DataType::Real32.integer_range(), None);
    }
}
