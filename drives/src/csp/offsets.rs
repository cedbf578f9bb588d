//! Where the objects CSP uses sit in one drive's process data: a [`PdoMap`] that has
//! the four objects CSP cannot do without.

use thiserror::Error;

use crate::cia402::image::PdoMap;
use crate::cia402::objects::{self, ObjectId};
use crate::cia402::pdo::PdoLayout;

/// A layout that CSP cannot run on.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
#[error("the PDO layout lacks {object:#06x} {name}, which CSP needs")]
pub struct LayoutError {
    /// The missing object.
    pub object: u16,
    /// Its name.
    pub name: &'static str,
}

/// The process-data map of a drive that CSP can run on: controlword and target position
/// in the outputs, statusword and position actual value in the inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CspOffsets {
    map: PdoMap,
    /// Bytes of the outputs.
    pub output_bytes: usize,
    /// Bytes of the inputs.
    pub input_bytes: usize,
}

impl CspOffsets {
    /// The offsets in `layout`; the four objects CSP cannot do without must be there.
    pub fn of(layout: &PdoLayout) -> Result<Self, LayoutError> {
        let map = PdoMap::of(layout);
        let missing = |o: ObjectId| LayoutError {
            object: o.index,
            name: o.name,
        };
        for o in [objects::CONTROLWORD, objects::TARGET_POSITION] {
            map.output_offset(o).ok_or(missing(o))?;
        }
        for o in [objects::STATUSWORD, objects::POSITION_ACTUAL_VALUE] {
            map.input_offset(o).ok_or(missing(o))?;
        }
        Ok(Self {
            map,
            output_bytes: map.output_bytes,
            input_bytes: map.input_bytes,
        })
    }

    /// The power-up mapping of a CSP drive.
    pub fn minimal() -> Self {
        let map = PdoMap::of(&PdoLayout::csp_minimal());
        Self {
            map,
            output_bytes: map.output_bytes,
            input_bytes: map.input_bytes,
        }
    }

    /// The map, for views of the drive's process data.
    pub fn map(&self) -> &PdoMap {
        &self.map
    }
}
