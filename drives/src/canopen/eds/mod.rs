//! Electronic data sheets and device configuration files (CiA 306-1): the model of what a
//! vendor ships with a CANopen device ([`Eds`]), a reader ([`read`], [`load`]), a writer
//! ([`write_eds`], [`write_dcf`]) and the queries a master needs — an object's type, size
//! and access for SDO ([`Eds::entry`]), whether it can be mapped into a PDO going one way
//! ([`Eds::pdo_mappable`]), how many PDOs the device has ([`Eds::max_pdos`]) and a check of
//! a whole PDO mapping ([`Eds::check_pdo`]: "0x6064:00 is not PDO-mappable in x.eds").
//!
//! Configuration-time code: it allocates, and never panics on any input (fuzzed by the
//! property test of `drives/tests/eds.rs`). The simulator writes its nodes' EDS through
//! this model and writer, so there is one EDS writer.

pub mod access;
pub mod data_type;
pub mod device;
pub mod error;
pub mod mapping;
pub mod object;
pub mod reader;
pub mod value;
pub mod writer;

use std::collections::BTreeMap;

use thiserror::Error;

pub use access::{AccessType, PdoDirection};
pub use data_type::DataType;
pub use device::{Commissioning, DeviceInfo, FileInfo, BAUD_RATES_KBIT};
pub use error::{EdsError, EdsErrorKind};
pub use mapping::{MappingEntry, MappingError, MAX_PDO_BITS};
pub use object::{Object, ObjectList, ObjectType, SubObject};
pub use reader::{load, read};
pub use value::{Value, ValueError};
pub use writer::{write_dcf, write_eds};

/// An EDS (or, with [`Eds::commissioning`] and parameter values, a DCF).
#[derive(Clone, Debug, PartialEq)]
pub struct Eds {
    /// The file's name, as errors and checks name it.
    pub file: String,
    /// `[FileInfo]`.
    pub file_info: FileInfo,
    /// `[DeviceInfo]`.
    pub device_info: DeviceInfo,
    /// `[DummyUsage]`: `dummy_usage[t]` for data type index `t` 1..=7 (index 0 unused).
    pub dummy_usage: [bool; 8],
    /// `[Comments]` lines.
    pub comments: Vec<String>,
    /// The objects by index.
    pub objects: BTreeMap<u16, Object>,
    /// A DCF's `[DeviceComissioning]`.
    pub commissioning: Option<Commissioning>,
}

/// A value that cannot go into a DCF.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum DcfError {
    /// No such entry.
    #[error("0x{index:04X}:{sub:02X} is not in {file}")]
    NoObject {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The EDS.
        file: String,
    },
    /// The entry cannot be written.
    #[error("0x{index:04X}:{sub:02X} is {access} in {file}: it cannot be configured")]
    NotWritable {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Its access.
        access: AccessType,
        /// The EDS.
        file: String,
    },
    /// Outside `LowLimit..=HighLimit`.
    #[error("0x{index:04X}:{sub:02X}: {value} is outside {low}..={high} in {file}")]
    OutsideLimits {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The value.
        value: i128,
        /// Low limit.
        low: i128,
        /// High limit.
        high: i128,
        /// The EDS.
        file: String,
    },
    /// The value does not fit the entry.
    #[error("0x{index:04X}:{sub:02X}: {source}")]
    Value {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        source: ValueError,
    },
}

impl Eds {
    /// An EDS named `file` with no objects (a writer fills it in).
    pub fn new(file: &str) -> Self {
        Self {
            file: file.to_string(),
            file_info: FileInfo {
                file_name: file.to_string(),
                eds_version: "4.0".to_string(),
                ..FileInfo::default()
            },
            device_info: DeviceInfo::default(),
            dummy_usage: [false; 8],
            comments: Vec::new(),
            objects: BTreeMap::new(),
            commissioning: None,
        }
    }

    /// The object at `index`.
    pub fn object(&self, index: u16) -> Option<&Object> {
        self.objects.get(&index)
    }

    /// The entry at `index`:`sub` (its data type, size and access).
    pub fn entry(&self, index: u16, sub: u8) -> Option<&SubObject> {
        self.objects.get(&index)?.subs.get(&sub)
    }

    /// Adds (or replaces) an object.
    pub fn insert(&mut self, object: Object) {
        self.objects.insert(object.index, object);
    }

    /// Whether `index`:`sub` may be mapped into a PDO going `direction`.
    pub fn pdo_mappable(&self, index: u16, sub: u8, direction: PdoDirection) -> bool {
        self.entry(index, sub)
            .is_some_and(|e| e.mappable_in(direction))
    }

    /// How many PDOs the device has going `direction` (`NrOfRXPDO` / `NrOfTXPDO`).
    pub fn max_pdos(&self, direction: PdoDirection) -> u16 {
        match direction {
            PdoDirection::Receive => self.device_info.nr_of_rx_pdo,
            PdoDirection::Transmit => self.device_info.nr_of_tx_pdo,
        }
    }

    /// Whether `[DummyUsage]` allows dummy entries of data type `index` (0x0001–0x0007).
    pub fn dummy_allowed(&self, index: u16) -> bool {
        self.dummy_usage
            .get(usize::from(index))
            .copied()
            .unwrap_or(false)
    }

    /// Records the value configured at `index`:`sub` (the DCF's `ParameterValue`): the
    /// entry must exist and be writable, and the value fit its type.
    pub fn set_parameter(&mut self, index: u16, sub: u8, value: Value) -> Result<(), DcfError> {
        let file = self.file.clone();
        let e = self
            .objects
            .get_mut(&index)
            .and_then(|o| o.subs.get_mut(&sub))
            .ok_or(DcfError::NoObject { index, sub, file })?;
        if !e.access.writable() {
            return Err(DcfError::NotWritable {
                index,
                sub,
                access: e.access,
                file: self.file.clone(),
            });
        }
        // The value on this node (a DCF is one node's: `$NODEID` resolves).
        let node = self.commissioning.as_ref().map_or(1, |c| c.node_id);
        value
            .to_le_bytes(e.data_type, node)
            .map_err(|source| DcfError::Value { index, sub, source })?;
        if !e.allows(&value, node) {
            let (low, high) = e.limits().unwrap_or((0, 0));
            return Err(DcfError::OutsideLimits {
                index,
                sub,
                value: value.integer_on(node).unwrap_or(0),
                low,
                high,
                file: self.file.clone(),
            });
        }
        e.parameter_value = Some(value);
        Ok(())
    }

    /// Records the bytes downloaded to `index`:`sub` (as an SDO carried them) as its
    /// configured value.
    pub fn set_parameter_bytes(
        &mut self,
        index: u16,
        sub: u8,
        bytes: &[u8],
    ) -> Result<(), DcfError> {
        let ty = self
            .entry(index, sub)
            .map(|e| e.data_type)
            .ok_or_else(|| DcfError::NoObject {
                index,
                sub,
                file: self.file.clone(),
            })?;
        let value = Value::from_le_bytes(bytes, ty).map_err(|source| DcfError::Value {
            index,
            sub,
            source,
        })?;
        self.set_parameter(index, sub, value)
    }

    /// Makes this a DCF of the device commissioned so (node id, bit rate, …).
    pub fn commission(&mut self, commissioning: Commissioning) {
        self.commissioning = Some(commissioning);
    }
}
