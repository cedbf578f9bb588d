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

/// Entries the master puts into one mapping object before it starts the next (0x1601,
/// 0x1A01, …). CiA 301 / ETG.1000.6 leave the number of entries per PDO to the device (a
/// CoE drive's mapping objects commonly hold 8 to 10, the simulated one 10); 8 is the
/// conservative choice, so every layout of up to 8 objects a direction stays one PDO as
/// before and a larger one is split instead of refused. A drive that takes fewer refuses
/// the download with its abort (0x06040042), which names the object.
pub const ENTRIES_PER_PDO: usize = 8;

/// The objects of both directions.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoLayout {
    /// Outputs (RxPDO 0x1600, then 0x1601… past [`ENTRIES_PER_PDO`]), in order.
    pub outputs: Vec<ObjectId>,
    /// Inputs (TxPDO 0x1A00, then 0x1A01… past [`ENTRIES_PER_PDO`]), in order.
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

    /// The SDO downloads that put this layout into a drive, in order (ETG.1000.6
    /// §5.6.7.4, CiA 301 §7.5.2): clear the SyncManager's assignment; for each PDO of at
    /// most [`ENTRIES_PER_PDO`] entries (0x1600, 0x1601, … / 0x1A00, 0x1A01, …) clear its
    /// mapping, fill it, set its count and assign it; then set the assignment's count.
    /// The process image is the assigned PDOs one after the other, so the objects keep
    /// the offsets of the flat lists. A direction without objects still gets one empty
    /// PDO assigned, as before.
    pub fn sdo_writes(&self) -> Vec<SdoWrite> {
        let mut w = Vec::new();
        for (assign, first_mapping, objs) in [
            (SM2_PDO_ASSIGNMENT, RXPDO_MAPPING, &self.outputs),
            (SM3_PDO_ASSIGNMENT, TXPDO_MAPPING, &self.inputs),
        ] {
            let write = |index, sub, value: Vec<u8>| SdoWrite { index, sub, value };
            w.push(write(assign, 0, vec![0]));
            let pdos = objs.len().div_ceil(ENTRIES_PER_PDO).max(1);
            for pdo in 0..pdos {
                let mapping = first_mapping + pdo as u16;
                let chunk = objs
                    .get(pdo * ENTRIES_PER_PDO..)
                    .unwrap_or_default()
                    .iter()
                    .take(ENTRIES_PER_PDO);
                w.push(write(mapping, 0, vec![0]));
                let mut n = 0u8;
                for o in chunk {
                    n += 1;
                    w.push(write(mapping, n, mapping_entry(o).to_le_bytes().to_vec()));
                }
                w.push(write(mapping, 0, vec![n]));
                w.push(write(assign, pdo as u8 + 1, mapping.to_le_bytes().to_vec()));
            }
            w.push(write(assign, 0, vec![pdos as u8]));
        }
        w
    }

    /// The PDOs [`PdoLayout::sdo_writes`] assigns: (outputs, inputs).
    pub fn pdo_count(&self) -> (usize, usize) {
        let n = |objs: &Vec<ObjectId>| objs.len().div_ceil(ENTRIES_PER_PDO).max(1);
        (n(&self.outputs), n(&self.inputs))
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

    #[test]
    fn a_direction_past_eight_entries_takes_a_second_pdo() {
        let mut l = PdoLayout::csp();
        // csp with switches and both probe values: 11 inputs, 4 outputs.
        l.outputs.push(objects::TOUCH_PROBE_FUNCTION);
        l.inputs.extend([
            objects::DIGITAL_INPUTS,
            objects::TOUCH_PROBE_STATUS,
            objects::TOUCH_PROBE_POS1_POS_VALUE,
            objects::TOUCH_PROBE_POS1_NEG_VALUE,
            objects::TOUCH_PROBE_POS2_POS_VALUE,
        ]);
        assert_eq!(l.pdo_count(), (1, 2));
        let seq: Vec<(u16, u8, Vec<u8>)> = l
            .sdo_writes()
            .into_iter()
            .map(|s| (s.index, s.sub, s.value))
            .collect();
        let inputs = seq
            .iter()
            .position(|w| *w == (0x1C13, 0, vec![0]))
            .expect("inputs cleared");
        let tx = &seq[inputs..];
        // 0x1A00: clear, 8 entries, count 8, assigned as 1.
        assert_eq!(tx[1], (0x1A00, 0, vec![0]));
        assert_eq!(tx[2], (0x1A00, 1, 0x6041_0010u32.to_le_bytes().to_vec()));
        assert_eq!(tx[10], (0x1A00, 0, vec![8]));
        assert_eq!(tx[11], (0x1C13, 1, vec![0x00, 0x1A]));
        // 0x1A01: the last 3 (0x60BA, 0x60BB, 0x60BC), assigned as 2.
        assert_eq!(tx[12], (0x1A01, 0, vec![0]));
        assert_eq!(tx[13], (0x1A01, 1, 0x60BA_0020u32.to_le_bytes().to_vec()));
        assert_eq!(tx[15], (0x1A01, 3, 0x60BC_0020u32.to_le_bytes().to_vec()));
        assert_eq!(tx[16], (0x1A01, 0, vec![3]));
        assert_eq!(tx[17], (0x1C13, 2, vec![0x01, 0x1A]));
        assert_eq!(tx[18], (0x1C13, 0, vec![2]));
        assert_eq!(tx.len(), 19);
        // Offsets are those of the flat list.
        assert_eq!(l.input_offset(0x60BC), Some(l.input_bytes() - 4));
        // The outputs stay one PDO.
        assert!(seq.contains(&(0x1C12, 0, vec![1])));
        assert!(!seq.iter().any(|w| w.0 == 0x1601));
    }
}
