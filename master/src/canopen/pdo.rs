//! How an axis' process data layout goes into CAN PDOs: each direction's objects packed,
//! whole, into PDOs of at most 8 data bytes (CiA 301 §7.2.2: a PDO is one CAN frame),
//! first-fit by decreasing size so that a layout takes as few frames as it can (the CSP
//! layout's 15 input bytes: two TPDOs, not the three that packing in layout order gives).
//! The bus copies each mapped object between the PDO's data and the drive's bytes in
//! layout order, which is what the cycle decodes ([`gantry_drives::csp::CspOffsets`]).
//!
//! COB-IDs: PDOs 1–4 go on the drive's predefined identifiers (CiA 301 §7.3.5 Table 75:
//! 0x180/0x280/0x380/0x480 + node for TPDOs, 0x200/… + node for RPDOs). CiA 301 predefines
//! no identifier for PDO 5 and up: the master gives them one ([`CobIdPool`]) from the
//! predefined PDO identifiers of node ids no node of the bus has (nor gantry's own), from
//! the highest node id down, TPDOs from TPDO ranges and RPDOs from RPDO ranges — unique on
//! the bus as long as no device outside the configuration sits at those node ids (the
//! bring-up refuses one whose boot-up or heartbeat it hears).

use gantry_drives::canopen::cob_id::{CobId, NodeId};
use gantry_drives::canopen::frame::{frame_bits, MAX_DATA_LEN};
use gantry_drives::cia402::objects::ObjectId;
use gantry_drives::cia402::pdo::PdoLayout;
use thiserror::Error;

/// PDOs of one direction the predefined connection set gives a node (CiA 301 Table 75):
/// what gantry assumes a drive has when nothing says otherwise.
pub const PREDEFINED_PDOS: usize = 4;
/// Most PDOs of one direction gantry maps for one drive (CiA 301 numbers up to 512;
/// 64 × 8 bytes is far beyond any drive's process data, and a cycle keeps which TPDOs
/// came in one 64-bit word).
pub const MAX_PDOS: usize = 64;
/// Most mapping entries of one PDO (8 one-byte objects fill a frame).
pub const MAX_ENTRIES: usize = 8;

/// A layout that needs more PDOs than gantry maps for one drive ([`MAX_PDOS`]).
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
#[error(
    "the {direction} need {needed} PDOs of 8 bytes ({bytes} bytes); gantry maps at most {} \
     a direction",
    MAX_PDOS
)]
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

/// One PDO: its number, its COB-ID and what it maps, in order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoPlan {
    /// PDO number 1..=[`MAX_PDOS`] (RPDO n is 0x1400 + n − 1 / 0x1600 + n − 1, TPDO n
    /// 0x1800… / 0x1A00…).
    pub number: u8,
    /// Its 11-bit CAN identifier: the predefined one for PDOs 1–4 ([`DrivePlan::on_node`]),
    /// one a [`CobIdPool`] lent for 5 and up (0 until then).
    pub cob_id: u16,
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
    /// The PDOs of `layout`, without COB-IDs ([`DrivePlan::on_node`] gives them).
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

    /// The PDOs of `layout` for `node`: PDOs 1–4 on its predefined COB-IDs, 5 and up
    /// without (0: a [`CobIdPool`] lends them one).
    pub fn on_node(layout: &PdoLayout, node: NodeId) -> Result<Self, PlanError> {
        let mut plan = Self::of(layout)?;
        for p in &mut plan.rpdos {
            p.cob_id = CobId::rpdo(p.number, node).map_or(0, CobId::id);
        }
        for p in &mut plan.tpdos {
            p.cob_id = CobId::tpdo(p.number, node).map_or(0, CobId::id);
        }
        Ok(plan)
    }

    /// The PDOs still without a COB-ID (5 and up before a [`CobIdPool`] lent them one).
    pub fn unassigned(&self) -> impl Iterator<Item = &PdoPlan> {
        self.rpdos
            .iter()
            .chain(&self.tpdos)
            .filter(|p| p.cob_id == 0)
    }
}

/// Which way a PDO goes, for the [`CobIdPool`] and for messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Way {
    /// Receive PDO: gantry → drive.
    Rpdo,
    /// Transmit PDO: drive → gantry.
    Tpdo,
}

impl Way {
    /// "RPDO" or "TPDO".
    pub const fn name(self) -> &'static str {
        match self {
            Self::Rpdo => "RPDO",
            Self::Tpdo => "TPDO",
        }
    }
}

/// The pool ran dry: every node id the bus leaves free has lent its four PDO identifiers
/// of that direction.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
#[error(
    "no COB-ID left for {}{pdo}: the predefined {} identifiers of the {free} node ids no \
     node of the bus has are all lent",
    way.name(),
    way.name()
)]
pub struct CobIdsExhausted {
    /// Which way.
    pub way: Way,
    /// The PDO's number.
    pub pdo: u8,
    /// Node ids that could lend.
    pub free: usize,
}

/// COB-IDs for PDOs 5 and up (CiA 301 predefines none): the predefined PDO identifiers
/// of the node ids no node of the bus has, highest node id first, each lending its four
/// TPDO identifiers to TPDOs and its four RPDO identifiers to RPDOs (so a COB-ID still
/// reads as a PDO of its direction, and no two PDOs of the bus share one).
#[derive(Clone, Debug)]
pub struct CobIdPool {
    /// Node ids that may lend, highest first.
    free: Vec<NodeId>,
    /// Identifiers lent so far: RPDO, TPDO.
    lent: [usize; 2],
}

impl CobIdPool {
    /// The pool of a bus whose nodes (and gantry) have the ids `used`.
    pub fn new(used: &[u8]) -> Self {
        let free = (1..=gantry_drives::canopen::cob_id::MAX_NODE_ID)
            .rev()
            .filter(|n| !used.contains(n))
            .filter_map(|n| NodeId::new(n).ok())
            .collect();
        Self { free, lent: [0; 2] }
    }

    /// The next identifier of `way`.
    fn take(&mut self, way: Way) -> Option<u16> {
        let k = match way {
            Way::Rpdo => &mut self.lent[0],
            Way::Tpdo => &mut self.lent[1],
        };
        let lender = *self.free.get(*k / PREDEFINED_PDOS)?;
        let n = (*k % PREDEFINED_PDOS) as u8 + 1;
        *k += 1;
        let cob = match way {
            Way::Rpdo => CobId::rpdo(n, lender),
            Way::Tpdo => CobId::tpdo(n, lender),
        };
        cob.ok().map(CobId::id)
    }

    /// Gives every PDO of `plan` without a COB-ID (5 and up) the next free one.
    pub fn lend(&mut self, plan: &mut DrivePlan) -> Result<(), CobIdsExhausted> {
        for (way, pdos) in [(Way::Rpdo, &mut plan.rpdos), (Way::Tpdo, &mut plan.tpdos)] {
            for p in pdos.iter_mut().filter(|p| p.cob_id == 0) {
                p.cob_id = self.take(way).ok_or(CobIdsExhausted {
                    way,
                    pdo: p.number,
                    free: self.free.len(),
                })?;
            }
        }
        Ok(())
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
                    cob_id: 0,
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
        let node = NodeId::new(3).unwrap();
        let p = DrivePlan::on_node(&PdoLayout::csp_minimal(), node).unwrap();
        assert_eq!((p.rpdos.len(), p.tpdos.len()), (1, 1));
        assert_eq!((p.rpdos[0].len, p.tpdos[0].len), (6, 6));
        assert_eq!(p.bits_per_cycle(), 2 * 115);
        assert_eq!(p.tpdos[0].cob_id, 0x183);
        assert_eq!(p.rpdos[0].cob_id, 0x203);
    }

    #[test]
    fn a_layout_beyond_four_pdos_takes_more_and_beyond_64_is_refused() {
        let five = PdoLayout {
            outputs: vec![objects::CONTROLWORD],
            inputs: vec![objects::POSITION_ACTUAL_VALUE; 9],
        };
        let node = NodeId::new(3).unwrap();
        let p = DrivePlan::on_node(&five, node).unwrap();
        assert_eq!(p.tpdos.len(), 5);
        let ids: Vec<u16> = p.tpdos.iter().map(|t| t.cob_id).collect();
        assert_eq!(
            ids,
            [0x183, 0x283, 0x383, 0x483, 0],
            "TPDO5 has no predefined id"
        );
        assert_eq!(p.unassigned().count(), 1);
        let many = PdoLayout {
            outputs: vec![objects::CONTROLWORD],
            inputs: vec![objects::POSITION_ACTUAL_VALUE; 130],
        };
        let e = DrivePlan::of(&many).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the inputs need 65 PDOs of 8 bytes (520 bytes); gantry maps at most 64 a direction"
        );
    }

    #[test]
    fn pdos_beyond_four_borrow_the_identifiers_of_free_node_ids() {
        let layout = |rx: usize, tx: usize| PdoLayout {
            outputs: vec![objects::TARGET_POSITION; 2 * rx],
            inputs: vec![objects::POSITION_ACTUAL_VALUE; 2 * tx],
        };
        // Nodes 1, 2 and 126 on the bus, gantry is 127: 125 lends first.
        let mut pool = CobIdPool::new(&[1, 2, 126, 127]);
        let mut a = DrivePlan::on_node(&layout(5, 6), NodeId::new(1).unwrap()).unwrap();
        let mut b = DrivePlan::on_node(&layout(1, 8), NodeId::new(2).unwrap()).unwrap();
        pool.lend(&mut a).unwrap();
        pool.lend(&mut b).unwrap();
        let ids = |p: &[PdoPlan]| p.iter().map(|x| x.cob_id).collect::<Vec<_>>();
        assert_eq!(ids(&a.rpdos), [0x201, 0x301, 0x401, 0x501, 0x27D]);
        assert_eq!(ids(&a.tpdos), [0x181, 0x281, 0x381, 0x481, 0x1FD, 0x2FD]);
        assert_eq!(ids(&b.rpdos), [0x202]);
        // TPDO5–8 of node 2: the rest of 125's TPDO identifiers, then 124's.
        assert_eq!(
            ids(&b.tpdos),
            [0x182, 0x282, 0x382, 0x482, 0x3FD, 0x4FD, 0x1FC, 0x2FC]
        );
        // Every identifier once, each a PDO of its direction.
        let mut all: Vec<u16> = [&a, &b]
            .iter()
            .flat_map(|p| p.rpdos.iter().chain(&p.tpdos).map(|x| x.cob_id))
            .collect();
        let n = all.len();
        all.sort_unstable();
        all.dedup();
        assert_eq!(all.len(), n);
        for t in a.tpdos.iter().chain(&b.tpdos) {
            assert!(matches!(CobId::classify(t.cob_id), Ok(CobId::Tpdo(..))));
        }
        // A bus that leaves one node id free lends four TPDO identifiers.
        let used: Vec<u8> = (1..=126).collect();
        let mut tight = CobIdPool::new(&used);
        let mut c = DrivePlan::on_node(&layout(1, 9), NodeId::new(1).unwrap()).unwrap();
        assert_eq!(
            tight.lend(&mut c).unwrap_err().to_string(),
            "no COB-ID left for TPDO9: the predefined TPDO identifiers of the 1 node ids no \
             node of the bus has are all lent"
        );
    }
}
