//! PDO layouts as data: which objects a drive exchanges every cycle, in which order. The
//! master writes a layout into the drive's mapping objects by SDO in PreOp (CiA 301 §7.5.2:
//! disable, write entries, set the count, assign), then finds every object's byte offset
//! in the process image from the same layout. Nothing here is vendor-specific.

use super::objects::{self, ObjectId};

/// First RxPDO mapping object (master → drive).
pub const RXPDO_MAPPING: u16 = 0x1600;
/// First TxPDO mapping object (drive → master).
pub const TXPDO_MAPPING: u16 = 0x1A00;
/// SyncManager 2 (outputs) PDO assignment.
pub const SM2_PDO_ASSIGNMENT: u16 = 0x1C12;
/// SyncManager 3 (inputs) PDO assignment.
pub const SM3_PDO_ASSIGNMENT: u16 = 0x1C13;

/// The objects of both directions.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoLayout {
    /// Outputs (RxPDO 0x1600), in order.
    pub outputs: Vec<ObjectId>,
    /// Inputs (TxPDO 0x1A00), in order.
    pub inputs: Vec<ObjectId>,
}

/// One SDO download of the mapping sequence.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SdoWrite {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Value (little-endian).
    pub value: Vec<u8>,
}

/// A mapping entry's 32-bit value: index << 16 | sub << 8 | bit length.
pub fn mapping_entry(o: &ObjectId) -> u32 {
    (u32::from(o.index) << 16) | (u32::from(o.sub) << 8) | (o.kind.size() as u32 * 8)
}

/// The object a mapping entry names, with its bit length.
pub fn parse_mapping_entry(entry: u32) -> (u16, u8, u8) {
    ((entry >> 16) as u16, (entry >> 8) as u8, entry as u8)
}

impl PdoLayout {
    /// Position mode with what a commissioning engineer wants to see: error code and
    /// velocity/torque actual values in the process data.
    pub fn csp() -> Self {
        Self {
            outputs: vec![
                objects::CONTROLWORD,
                objects::TARGET_POSITION,
                objects::MODES_OF_OPERATION,
            ],
            inputs: vec![
                objects::STATUSWORD,
                objects::POSITION_ACTUAL_VALUE,
                objects::VELOCITY_ACTUAL_VALUE,
                objects::TORQUE_ACTUAL_VALUE,
                objects::ERROR_CODE,
                objects::MODES_OF_OPERATION_DISPLAY,
            ],
        }
    }

    /// The smallest position layout: controlword + target / statusword + actual.
    pub fn csp_minimal() -> Self {
        Self {
            outputs: vec![objects::CONTROLWORD, objects::TARGET_POSITION],
            inputs: vec![objects::STATUSWORD, objects::POSITION_ACTUAL_VALUE],
        }
    }

    /// Bytes of the outputs.
    pub fn output_bytes(&self) -> usize {
        self.outputs.iter().map(|o| o.kind.size()).sum()
    }

    /// Bytes of the inputs.
    pub fn input_bytes(&self) -> usize {
        self.inputs.iter().map(|o| o.kind.size()).sum()
    }

    /// Byte offset of `index` in the outputs.
    pub fn output_offset(&self, index: u16) -> Option<usize> {
        offset(&self.outputs, index)
    }

    /// Byte offset of `index` in the inputs.
    pub fn input_offset(&self, index: u16) -> Option<usize> {
        offset(&self.inputs, index)
    }

    /// The SDO downloads that put this layout into a drive, in order: clear the
    /// assignment, clear and fill each mapping, set its count, assign it.
    pub fn sdo_writes(&self) -> Vec<SdoWrite> {
        let mut w = Vec::new();
        for (assign, mapping, objs) in [
            (SM2_PDO_ASSIGNMENT, RXPDO_MAPPING, &self.outputs),
            (SM3_PDO_ASSIGNMENT, TXPDO_MAPPING, &self.inputs),
        ] {
            let write = |index, sub, value: Vec<u8>| SdoWrite { index, sub, value };
            w.push(write(assign, 0, vec![0]));
            w.push(write(mapping, 0, vec![0]));
            for (i, o) in objs.iter().enumerate() {
                w.push(write(
                    mapping,
                    i as u8 + 1,
                    mapping_entry(o).to_le_bytes().to_vec(),
                ));
            }
            w.push(write(mapping, 0, vec![objs.len() as u8]));
            w.push(write(assign, 1, mapping.to_le_bytes().to_vec()));
            w.push(write(assign, 0, vec![1]));
        }
        w
    }
}

fn offset(objs: &[ObjectId], index: u16) -> Option<usize> {
    let mut at = 0;
    for o in objs {
        if o.index == index {
            return Some(at);
        }
        at += o.kind.size();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_sizes_and_the_mapping_sequence() {
        let l = PdoLayout::csp();
        assert_eq!(l.output_bytes(), 7);
        assert_eq!(l.input_bytes(), 15);
        assert_eq!(l.input_offset(0x6064), Some(2));
        assert_eq!(l.input_offset(0x603F), Some(12));
        assert_eq!(l.output_offset(0x6060), Some(6));
        assert_eq!(l.input_offset(0x60FF), None);
        assert_eq!(mapping_entry(&objects::TARGET_POSITION), 0x607A_0020);
        assert_eq!(parse_mapping_entry(0x6041_0010), (0x6041, 0, 16));
        let w = PdoLayout::csp_minimal().sdo_writes();
        let seq: Vec<(u16, u8, Vec<u8>)> =
            w.into_iter().map(|s| (s.index, s.sub, s.value)).collect();
        assert_eq!(
            seq[..6],
            [
                (0x1C12, 0, vec![0]),
                (0x1600, 0, vec![0]),
                (0x1600, 1, 0x6040_0010u32.to_le_bytes().to_vec()),
                (0x1600, 2, 0x607A_0020u32.to_le_bytes().to_vec()),
                (0x1600, 0, vec![2]),
                (0x1C12, 1, vec![0x00, 0x16]),
            ]
        );
        assert_eq!(seq[6], (0x1C12, 0, vec![1]));
        assert_eq!(seq.len(), 14);
    }
}
