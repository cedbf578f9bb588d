//! How an axis' process data layout goes into CAN PDOs: each direction's objects packed,
//! whole, into at most four PDOs of at most 8 data bytes (CiA 301 §7.2.2: a PDO is one CAN
//! frame; the predefined connection set has four of each), first-fit by decreasing size
//! so that a layout takes as few frames as it can (the CSP layout's 15 input bytes: two
//! TPDOs, not the three that packing in layout order gives). The bus copies each mapped
//! object between the PDO's data and the drive's bytes in layout order, which is what
//! the cycle decodes ([`gantry_drives::csp::CspOffsets`]).

use gantry_drives::canopen::cob_id::{CobId, NodeId};
use gantry_drives::canopen::frame::{frame_bits, MAX_DATA_LEN};
use gantry_drives::cia402::objects::ObjectId;
use gantry_drives::cia402::pdo::PdoLayout;
use thiserror::Error;

/// PDOs of one direction a node has (CiA 301 predefined connection set).
pub const MAX_PDOS: usize = 4;
/// Most mapping entries of one PDO (8 one-byte objects fill a frame).
pub const MAX_ENTRIES: usize = 8;

/// A layout that does not fit a node's PDOs.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
#[error("the {direction} need {needed} PDOs of 8 bytes ({bytes} bytes), a CANopen node has 4")]
pub struct PlanError {
    /// "outputs" or "inputs".
    pub direction: &'static str,
    /// PDOs the objects need.
    pub needed: usize,
    /// Bytes of the objects.
    pub bytes: usize,
}

/// One mapped object: what it is and where it sits in the PDO and in the drive's bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mapped {
    /// The object.
    pub object: ObjectId,
    /// Byte offset in the PDO's data.
    pub in_pdo: usize,
    /// Byte offset in the drive's bytes (layout order).
    pub in_image: usize,
}

impl Mapped {
    /// Bytes of the object.
    pub fn size(&self) -> usize {
        self.object.kind.size()
    }
}

/// One PDO: its number (1..=4) and what it maps, in order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoPlan {
    /// PDO number 1..=4 (RPDO n is 0x1400 + n − 1 / 0x1600 + n − 1, TPDO n 0x1800… / 0x1A00…).
    pub number: u8,
    /// The mapped objects, in PDO order.
    pub entries: Vec<Mapped>,
    /// Data bytes.
    pub len: usize,
}

impl PdoPlan {
    /// The mapping entry values (CiA 301 §7.5.2.37: index << 16 | sub << 8 | bit length).
    pub fn mapping_values(&self) -> impl Iterator<Item = u32> + '_ {
        self.entries
            .iter()
            .map(|m| gantry_drives::cia402::pdo::mapping_entry(&m.object))
    }

    /// Bits the PDO's frame takes on the bus at worst (stuff bits included).
    pub fn frame_bits(&self) -> u64 {
        frame_bits(self.len)
    }
}

/// Both directions of one drive.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DrivePlan {
    /// RPDOs (master → drive): the outputs.
    pub rpdos: Vec<PdoPlan>,
    /// TPDOs (drive → master): the inputs.
    pub tpdos: Vec<PdoPlan>,
    /// Bytes of the outputs, layout order.
    pub output_bytes: usize,
    /// Bytes of the inputs, layout order.
    pub input_bytes: usize,
}

impl DrivePlan {
    /// The PDOs of `layout`.
    pub fn of(layout: &PdoLayout) -> Result<Self, PlanError> {
        Ok(Self {
            rpdos: pack(&layout.outputs, "outputs")?,
            tpdos: pack(&layout.inputs, "inputs")?,
            output_bytes: layout.output_bytes(),
            input_bytes: layout.input_bytes(),
        })
    }

    /// RPDOs and TPDOs.
    pub fn pdo_count(&self) -> usize {
        self.rpdos.len() + self.tpdos.len()
    }

    /// Bits every PDO of the drive takes per cycle at worst.
    pub fn bits_per_cycle(&self) -> u64 {
        self.rpdos
            .iter()
            .chain(&self.tpdos)
            .map(PdoPlan::frame_bits)
            .sum()
    }

    /// The COB-ID of TPDO `plan` of `node`, on the predefined connection set.
    pub fn tpdo_id(node: NodeId, plan: &PdoPlan) -> u16 {
        CobId::tpdo(plan.number, node).map_or(0, CobId::id)
    }

    /// The COB-ID of RPDO `plan` of `node`, on the predefined connection set.
    pub fn rpdo_id(node: NodeId, plan: &PdoPlan) -> u16 {
        CobId::rpdo(plan.number, node).map_or(0, CobId::id)
    }
}

/// First-fit decreasing: the largest objects first (equal sizes in layout order), each
/// into the first PDO with room for it and an entry left.
fn pack(objects: &[ObjectId], direction: &'static str) -> Result<Vec<PdoPlan>, PlanError> {
    let mut at = 0;
    let mut placed: Vec<(ObjectId, usize)> = objects
        .iter()
        .map(|o| {
            let here = at;
            at += o.kind.size();
            (*o, here)
        })
        .collect();
    let bytes = at;
    // Stable: equal sizes keep the layout's order.
    placed.sort_by_key(|(o, _)| std::cmp::Reverse(o.kind.size()));
    let mut pdos: Vec<PdoPlan> = Vec::new();
    for (object, in_image) in placed {
        let size = object.kind.size();
        let slot = pdos
            .iter_mut()
            .find(|p| p.len + size <= MAX_DATA_LEN && p.entries.len() < MAX_ENTRIES);
        let pdo = match slot {
            Some(p) => p,
            None => {
                pdos.push(PdoPlan {
                    number: pdos.len() as u8 + 1,
                    entries: Vec::new(),
                    len: 0,
                });
                let last = pdos.len() - 1;
                &mut pdos[last]
            }
        };
        pdo.entries.push(Mapped {
            object,
            in_pdo: pdo.len,
            in_image,
        });
        pdo.len += size;
    }
    if pdos.len() > MAX_PDOS {
        return Err(PlanError {
            direction,
            needed: pdos.len(),
            bytes,
        });
    }
    Ok(pdos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::cia402::objects;

    #[test]
    fn the_csp_layout_takes_one_rpdo_and_two_tpdos() {
        let p = DrivePlan::of(&PdoLayout::csp()).unwrap();
        assert_eq!(p.rpdos.len(), 1);
        assert_eq!(p.rpdos[0].len, 7);
        assert_eq!(p.tpdos.len(), 2, "{:?}", p.tpdos);
        // 4-byte objects first: position and velocity actual value fill TPDO1.
        let t1: Vec<u16> = p.tpdos[0].entries.iter().map(|m| m.object.index).collect();
        assert_eq!(t1, [0x6064, 0x606C]);
        let t2: Vec<u16> = p.tpdos[1].entries.iter().map(|m| m.object.index).collect();
        assert_eq!(t2, [0x6041, 0x6077, 0x603F, 0x6061]);
        assert_eq!((p.tpdos[0].len, p.tpdos[1].len), (8, 7));
        // Image offsets are the layout's: statusword 0, position 2, velocity 6…
        let sw = p.tpdos[1].entries[0];
        assert_eq!((sw.in_pdo, sw.in_image), (0, 0));
        let pos = p.tpdos[0].entries[0];
        assert_eq!((pos.in_pdo, pos.in_image), (0, 2));
        assert_eq!(p.tpdos[1].entries[3].in_image, 14);
        // RPDO: target (4) first, then controlword and mode.
        assert_eq!(
            p.rpdos[0].mapping_values().collect::<Vec<_>>(),
            [0x607A_0020, 0x6040_0010, 0x6060_0008]
        );
        assert_eq!(p.pdo_count(), 3);
        assert_eq!(p.bits_per_cycle(), 125 + 135 + 125);
    }

    #[test]
    fn the_minimal_layout_takes_one_pdo_each_way() {
        let p = DrivePlan::of(&PdoLayout::csp_minimal()).unwrap();
        assert_eq!((p.rpdos.len(), p.tpdos.len()), (1, 1));
        assert_eq!((p.rpdos[0].len, p.tpdos[0].len), (6, 6));
        assert_eq!(p.bits_per_cycle(), 2 * 115);
        let node = NodeId::new(3).unwrap();
        assert_eq!(DrivePlan::tpdo_id(node, &p.tpdos[0]), 0x183);
        assert_eq!(DrivePlan::rpdo_id(node, &p.rpdos[0]), 0x203);
    }

    #[test]
    fn a_layout_beyond_four_pdos_is_refused_with_the_figure() {
        let layout = PdoLayout {
            outputs: vec![objects::CONTROLWORD],
            inputs: vec![objects::POSITION_ACTUAL_VALUE; 9],
        };
        let e = DrivePlan::of(&layout).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the inputs need 5 PDOs of 8 bytes (36 bytes), a CANopen node has 4"
        );
    }
}
