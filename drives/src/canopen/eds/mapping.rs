//! Checks a PDO mapping against an EDS before it is written to a device (CiA 301
//! §7.4.7.1 and §7.5.2.37/38; CiA 306-1 §4.5, §4.6.3): every entry names an object the
//! EDS describes, mappable in that direction, with its data type's bit length; dummy
//! entries only where `[DummyUsage]` allows; no more entries than the mapping object has,
//! no more than 64 bits; no more PDOs than the device has. A device would refuse each of
//! these with an SDO abort in the middle of the configuration; the master refuses them
//! before the first write, naming the entry and the file.

use thiserror::Error;

use super::access::PdoDirection;
use super::Eds;

/// Most bits one PDO carries (a classical CAN frame's 8 bytes).
pub const MAX_PDO_BITS: u32 = 64;

/// A mapping entry's index, sub-index and bit length (the 32-bit value of 0x1600:n /
/// 0x1A00:n: index << 16 | sub << 8 | bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MappingEntry {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Length in bits.
    pub bits: u8,
}

impl MappingEntry {
    /// From the value written to a mapping object.
    pub const fn from_u32(v: u32) -> Self {
        Self {
            index: (v >> 16) as u16,
            sub: (v >> 8) as u8,
            bits: v as u8,
        }
    }

    /// The value written to a mapping object.
    pub const fn to_u32(self) -> u32 {
        ((self.index as u32) << 16) | ((self.sub as u32) << 8) | self.bits as u32
    }
}

impl From<crate::cia402::objects::ObjectId> for MappingEntry {
    /// The entry that maps a drive-layer object whole (the PDO layouts' objects).
    fn from(o: crate::cia402::objects::ObjectId) -> Self {
        Self::from_u32(crate::cia402::pdo::mapping_entry(&o))
    }
}

impl core::fmt::Display for MappingEntry {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "0x{:04X}:{:02X}", self.index, self.sub)
    }
}

/// A PDO mapping the EDS does not allow.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum MappingError {
    /// The object or sub-index is not in the EDS.
    #[error("{entry} is not in {file}")]
    NoObject {
        /// The entry.
        entry: MappingEntry,
        /// The EDS.
        file: String,
    },
    /// `PDOMapping=0`.
    #[error("{entry} is not PDO-mappable in {file}")]
    NotMappable {
        /// The entry.
        entry: MappingEntry,
        /// The EDS.
        file: String,
    },
    /// Mappable, but not this way (its access).
    #[error("{entry} is {access} in {file}: not mappable into an {direction}")]
    WrongDirection {
        /// The entry.
        entry: MappingEntry,
        /// Its access type.
        access: &'static str,
        /// The PDO's direction.
        direction: PdoDirection,
        /// The EDS.
        file: String,
    },
    /// The bit length is not the type's.
    #[error("{entry} maps {bits} bits, but it is a {data_type} of {want} bits in {file}")]
    Length {
        /// The entry.
        entry: MappingEntry,
        /// Bits mapped.
        bits: u8,
        /// Its type.
        data_type: &'static str,
        /// The type's bits (0: variable length, never mappable).
        want: u32,
        /// The EDS.
        file: String,
    },
    /// A dummy entry the device does not support (or in a TPDO).
    #[error("{entry}: {file} allows no dummy entry of type 0x{:04X} here ([DummyUsage]; RPDOs only)", .entry.index)]
    Dummy {
        /// The entry.
        entry: MappingEntry,
        /// The EDS.
        file: String,
    },
    /// `Granularity=0`: the device's mapping is fixed (CiA 306-1 §4.4).
    #[error("{entry}: {file} has Granularity=0: its PDO mapping cannot be changed")]
    FixedMapping {
        /// The entry.
        entry: MappingEntry,
        /// The EDS.
        file: String,
    },
    /// The device maps at a coarser granularity.
    #[error("{entry}: {bits} bits is not a multiple of the granularity {granularity} of {file}")]
    Granularity {
        /// The entry.
        entry: MappingEntry,
        /// Bits mapped.
        bits: u8,
        /// `Granularity=`.
        granularity: u8,
        /// The EDS.
        file: String,
    },
    /// More than 64 bits.
    #[error("{direction} {pdo} maps {bits} bits; a PDO carries at most 64")]
    TooLong {
        /// Direction.
        direction: PdoDirection,
        /// PDO number (1-based).
        pdo: u16,
        /// Bits.
        bits: u32,
    },
    /// More entries than the mapping object has sub-indices.
    #[error("{direction} {pdo} maps {count} objects; 0x{index:04X} in {file} has {max} entries")]
    TooMany {
        /// Direction.
        direction: PdoDirection,
        /// PDO number (1-based).
        pdo: u16,
        /// Entries given.
        count: usize,
        /// The mapping object.
        index: u16,
        /// Its entries.
        max: usize,
        /// The EDS.
        file: String,
    },
    /// The device has not this many PDOs.
    #[error("{direction} {pdo} does not exist: {file} has {max}")]
    NoPdo {
        /// Direction.
        direction: PdoDirection,
        /// PDO number (1-based).
        pdo: u16,
        /// PDOs the device has.
        max: u16,
        /// The EDS.
        file: String,
    },
}

impl Eds {
    /// Checks one mapping entry for `direction`.
    pub fn check_entry(
        &self,
        direction: PdoDirection,
        entry: MappingEntry,
    ) -> Result<(), MappingError> {
        let file = || self.file.clone();
        let granularity = self.device_info.granularity;
        if granularity == 0 {
            return Err(MappingError::FixedMapping {
                entry,
                file: file(),
            });
        }
        if entry.bits % granularity != 0 {
            return Err(MappingError::Granularity {
                entry,
                bits: entry.bits,
                granularity,
                file: file(),
            });
        }
        // Dummy entries: the index of a data type (CiA 301 §7.4.7.1), sub 0, if
        // [DummyUsage] allows that type; in RPDOs only (they let a device skip received
        // bytes meant for another; a TPDO has nothing to fill them with).
        if (0x0001..=0x0007).contains(&entry.index) {
            if entry.sub != 0
                || !self.dummy_allowed(entry.index)
                || direction != PdoDirection::Receive
            {
                return Err(MappingError::Dummy {
                    entry,
                    file: file(),
                });
            }
            let want = super::DataType::from_code(entry.index).and_then(|t| t.bits());
            if want != Some(u32::from(entry.bits)) {
                return Err(MappingError::Length {
                    entry,
                    bits: entry.bits,
                    data_type: super::DataType::from_code(entry.index).map_or("?", |t| t.name()),
                    want: want.unwrap_or(0),
                    file: file(),
                });
            }
            return Ok(());
        }
        let e = self
            .entry(entry.index, entry.sub)
            .ok_or_else(|| MappingError::NoObject {
                entry,
                file: file(),
            })?;
        if !e.pdo_mapping {
            return Err(MappingError::NotMappable {
                entry,
                file: file(),
            });
        }
        if !e.access.mappable_in(direction) {
            return Err(MappingError::WrongDirection {
                entry,
                access: e.access.as_str(),
                direction,
                file: file(),
            });
        }
        if e.bits() != Some(u32::from(entry.bits)) {
            return Err(MappingError::Length {
                entry,
                bits: entry.bits,
                data_type: e.data_type.name(),
                want: e.bits().unwrap_or(0),
                file: file(),
            });
        }
        Ok(())
    }

    /// Checks the mapping of PDO `pdo` (1-based, as CiA 301 counts: RPDO1 is
    /// 0x1400/0x1600) going `direction`: the PDO exists, its mapping object has room
    /// for the entries, each entry is allowed, and they fit 64 bits.
    pub fn check_pdo(
        &self,
        direction: PdoDirection,
        pdo: u16,
        entries: &[MappingEntry],
    ) -> Result<(), MappingError> {
        let max = self.max_pdos(direction);
        if pdo == 0 || pdo > max {
            return Err(MappingError::NoPdo {
                direction,
                pdo,
                max,
                file: self.file.clone(),
            });
        }
        let base: u16 = match direction {
            PdoDirection::Receive => 0x1600,
            PdoDirection::Transmit => 0x1A00,
        };
        // CiA 301 numbers at most 512 PDOs each way (a model built by hand may claim more).
        let Some(index) = base.checked_add(pdo - 1).filter(|_| pdo <= 512) else {
            return Err(MappingError::NoPdo {
                direction,
                pdo,
                max,
                file: self.file.clone(),
            });
        };
        // The mapping object's entries: its sub-indices above 0.
        let room = self
            .object(index)
            .map_or(0, |o| o.subs.keys().filter(|&&s| s > 0).count());
        if entries.len() > room {
            return Err(MappingError::TooMany {
                direction,
                pdo,
                count: entries.len(),
                index,
                max: room,
                file: self.file.clone(),
            });
        }
        for &e in entries {
            self.check_entry(direction, e)?;
        }
        let bits: u32 = entries.iter().map(|e| u32::from(e.bits)).sum();
        if bits > MAX_PDO_BITS {
            return Err(MappingError::TooLong {
                direction,
                pdo,
                bits,
            });
        }
        Ok(())
    }
}
