//! COB-IDs of the predefined connection set (CiA 301 §7.3.5, Tables 74–75): an 11-bit CAN
//! identifier is a 4-bit function code and a 7-bit node id, so a master that has not
//! configured anything still knows whose frame it reads and what it is.

use thiserror::Error;

/// Node id 0 addresses all nodes in an NMT command (CiA 301 §7.2.8.3.1).
pub const ALL_NODES: u8 = 0;
/// Smallest node id a device may have (CiA 301 predefined connection set: 7-bit node id, 0 is "all nodes" in NMT).
pub const MIN_NODE_ID: u8 = 1;
/// Largest node id a device may have (CiA 301 predefined connection set: 7-bit node id, 0 is "all nodes" in NMT).
pub const MAX_NODE_ID: u8 = 127;

/// NMT node control (CiA 301 Table 74).
pub const NMT_COB_ID: u16 = 0x000;
/// SYNC (CiA 301 Table 74; the default of object 0x1005).
pub const SYNC_COB_ID: u16 = 0x080;
/// TIME stamp (CiA 301 Table 74; the default of object 0x1012).
pub const TIME_COB_ID: u16 = 0x100;
/// EMCY base; the node's EMCY is `EMCY_BASE + node` (default of 0x1014).
pub const EMCY_BASE: u16 = 0x080;
/// TPDO1 base (default of 0x1800:01); TPDO2..4 add 0x100 each.
pub const TPDO1_BASE: u16 = 0x180;
/// RPDO1 base (default of 0x1400:01); RPDO2..4 add 0x100 each.
pub const RPDO1_BASE: u16 = 0x200;
/// SDO server → client base (default server SDO, 0x1200:02).
pub const SDO_TX_BASE: u16 = 0x580;
/// SDO client → server base (default server SDO, 0x1200:01).
pub const SDO_RX_BASE: u16 = 0x600;
/// NMT error control (heartbeat, boot-up, node guarding) base.
pub const NMT_ERROR_CONTROL_BASE: u16 = 0x700;

/// A bad node id or a COB-ID outside the predefined connection set.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum CobIdError {
    /// A node id outside 1..=127.
    #[error("node id {0} is outside 1..=127 (CiA 301: 7-bit node id, 0 reserved)")]
    NodeId(u8),
    /// A PDO number outside 1..=4 (the predefined set has four of each).
    #[error("PDO number {0} is outside 1..=4 (CiA 301 Table 75 predefines PDO 1 to 4)")]
    PdoNumber(u8),
    /// An identifier the predefined connection set does not assign.
    #[error("COB-ID 0x{0:03X} is not in the CiA 301 predefined connection set")]
    NotPredefined(u16),
}

/// A node id, 1..=127.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId(u8);

impl NodeId {
    /// A checked node id.
    pub const fn new(id: u8) -> Result<Self, CobIdError> {
        if id >= MIN_NODE_ID && id <= MAX_NODE_ID {
            Ok(Self(id))
        } else {
            Err(CobIdError::NodeId(id))
        }
    }

    /// The raw id.
    pub const fn get(self) -> u8 {
        self.0
    }
}

impl TryFrom<u8> for NodeId {
    type Error = CobIdError;
    fn try_from(id: u8) -> Result<Self, CobIdError> {
        Self::new(id)
    }
}

impl std::fmt::Display for NodeId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "node {}", self.0)
    }
}

/// The 4-bit function code, bits 10–7 of the COB-ID (CiA 301 Table 74–75).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum FunctionCode {
    /// 0b0000: NMT.
    Nmt = 0x0,
    /// 0b0001: SYNC (node 0) or EMCY (node 1..127).
    SyncEmcy = 0x1,
    /// 0b0010: TIME.
    Time = 0x2,
    /// 0b0011: TPDO1.
    Tpdo1 = 0x3,
    /// 0b0100: RPDO1.
    Rpdo1 = 0x4,
    /// 0b0101: TPDO2.
    Tpdo2 = 0x5,
    /// 0b0110: RPDO2.
    Rpdo2 = 0x6,
    /// 0b0111: TPDO3.
    Tpdo3 = 0x7,
    /// 0b1000: RPDO3.
    Rpdo3 = 0x8,
    /// 0b1001: TPDO4.
    Tpdo4 = 0x9,
    /// 0b1010: RPDO4.
    Rpdo4 = 0xA,
    /// 0b1011: SDO server → client.
    SdoTx = 0xB,
    /// 0b1100: SDO client → server.
    SdoRx = 0xC,
    /// 0b1101: not assigned.
    Unassigned13 = 0xD,
    /// 0b1110: NMT error control.
    NmtErrorControl = 0xE,
    /// 0b1111: not assigned (LSS uses 0x7E4/0x7E5 here, CiA 305).
    Unassigned15 = 0xF,
}

impl FunctionCode {
    /// The function code of an 11-bit identifier (bits above 10 ignored).
    pub const fn of(id: u16) -> Self {
        match (id >> 7) & 0xF {
            0x0 => Self::Nmt,
            0x1 => Self::SyncEmcy,
            0x2 => Self::Time,
            0x3 => Self::Tpdo1,
            0x4 => Self::Rpdo1,
            0x5 => Self::Tpdo2,
            0x6 => Self::Rpdo2,
            0x7 => Self::Tpdo3,
            0x8 => Self::Rpdo3,
            0x9 => Self::Tpdo4,
            0xA => Self::Rpdo4,
            0xB => Self::SdoTx,
            0xC => Self::SdoRx,
            0xD => Self::Unassigned13,
            0xE => Self::NmtErrorControl,
            _ => Self::Unassigned15,
        }
    }
}

/// What a COB-ID of the predefined connection set carries, and for which node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CobId {
    /// NMT node control, 0x000.
    Nmt,
    /// SYNC, 0x080.
    Sync,
    /// TIME, 0x100.
    Time,
    /// EMCY of a node, 0x080 + node.
    Emcy(NodeId),
    /// TPDO n (1..=4) of a node, 0x180 + 0x100·(n−1) + node.
    Tpdo(u8, NodeId),
    /// RPDO n (1..=4) of a node, 0x200 + 0x100·(n−1) + node.
    Rpdo(u8, NodeId),
    /// SDO server → client of a node, 0x580 + node.
    SdoTx(NodeId),
    /// SDO client → server of a node, 0x600 + node.
    SdoRx(NodeId),
    /// Heartbeat / boot-up / node guarding of a node, 0x700 + node.
    NmtErrorControl(NodeId),
}

impl CobId {
    /// TPDO `n` (1..=4) of `node`.
    pub const fn tpdo(n: u8, node: NodeId) -> Result<Self, CobIdError> {
        if n >= 1 && n <= 4 {
            Ok(Self::Tpdo(n, node))
        } else {
            Err(CobIdError::PdoNumber(n))
        }
    }

    /// RPDO `n` (1..=4) of `node`.
    pub const fn rpdo(n: u8, node: NodeId) -> Result<Self, CobIdError> {
        if n >= 1 && n <= 4 {
            Ok(Self::Rpdo(n, node))
        } else {
            Err(CobIdError::PdoNumber(n))
        }
    }

    /// Splits an 11-bit identifier into its function and node (CiA 301 Table 74–75).
    /// Refuses identifiers the set does not assign: node 0 with a per-node function, the
    /// unassigned function codes, anything past 11 bits, and node bits set on NMT/TIME.
    pub const fn classify(id: u16) -> Result<Self, CobIdError> {
        if id > 0x7FF {
            return Err(CobIdError::NotPredefined(id));
        }
        let node = (id & 0x7F) as u8;
        let fc = FunctionCode::of(id);
        if let FunctionCode::SyncEmcy = fc {
            if node == 0 {
                return Ok(Self::Sync);
            }
        }
        match fc {
            FunctionCode::Nmt if node == 0 => return Ok(Self::Nmt),
            FunctionCode::Time if node == 0 => return Ok(Self::Time),
            _ => {}
        }
        let node = match NodeId::new(node) {
            Ok(n) => n,
            Err(_) => return Err(CobIdError::NotPredefined(id)),
        };
        Ok(match fc {
            FunctionCode::SyncEmcy => Self::Emcy(node),
            FunctionCode::Tpdo1 => Self::Tpdo(1, node),
            FunctionCode::Rpdo1 => Self::Rpdo(1, node),
            FunctionCode::Tpdo2 => Self::Tpdo(2, node),
            FunctionCode::Rpdo2 => Self::Rpdo(2, node),
            FunctionCode::Tpdo3 => Self::Tpdo(3, node),
            FunctionCode::Rpdo3 => Self::Rpdo(3, node),
            FunctionCode::Tpdo4 => Self::Tpdo(4, node),
            FunctionCode::Rpdo4 => Self::Rpdo(4, node),
            FunctionCode::SdoTx => Self::SdoTx(node),
            FunctionCode::SdoRx => Self::SdoRx(node),
            FunctionCode::NmtErrorControl => Self::NmtErrorControl(node),
            FunctionCode::Nmt
            | FunctionCode::Time
            | FunctionCode::Unassigned13
            | FunctionCode::Unassigned15 => return Err(CobIdError::NotPredefined(id)),
        })
    }

    /// The 11-bit identifier. PDO numbers outside 1..=4 cannot be built (see [`CobId::tpdo`]);
    /// a hand-built one is clamped into 1..=4.
    pub const fn id(self) -> u16 {
        const fn pdo_offset(n: u8) -> u16 {
            let n = if n < 1 {
                1
            } else if n > 4 {
                4
            } else {
                n
            };
            0x100 * (n as u16 - 1)
        }
        match self {
            Self::Nmt => NMT_COB_ID,
            Self::Sync => SYNC_COB_ID,
            Self::Time => TIME_COB_ID,
            Self::Emcy(n) => EMCY_BASE + n.0 as u16,
            Self::Tpdo(k, n) => TPDO1_BASE + pdo_offset(k) + n.0 as u16,
            Self::Rpdo(k, n) => RPDO1_BASE + pdo_offset(k) + n.0 as u16,
            Self::SdoTx(n) => SDO_TX_BASE + n.0 as u16,
            Self::SdoRx(n) => SDO_RX_BASE + n.0 as u16,
            Self::NmtErrorControl(n) => NMT_ERROR_CONTROL_BASE + n.0 as u16,
        }
    }

    /// The node this COB-ID belongs to (none for NMT, SYNC, TIME).
    pub const fn node(self) -> Option<NodeId> {
        match self {
            Self::Nmt | Self::Sync | Self::Time => None,
            Self::Emcy(n)
            | Self::Tpdo(_, n)
            | Self::Rpdo(_, n)
            | Self::SdoTx(n)
            | Self::SdoRx(n)
            | Self::NmtErrorControl(n) => Some(n),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn n(id: u8) -> NodeId {
        NodeId::new(id).unwrap()
    }

    /// CiA 301 Table 74/75 rows, with node 5 for the per-node objects.
    static PREDEFINED: &[(u16, CobId)] = &[
        (0x000, CobId::Nmt),
        (0x080, CobId::Sync),
        (0x100, CobId::Time),
        (0x085, CobId::Emcy(NodeId(5))),
        (0x185, CobId::Tpdo(1, NodeId(5))),
        (0x205, CobId::Rpdo(1, NodeId(5))),
        (0x285, CobId::Tpdo(2, NodeId(5))),
        (0x305, CobId::Rpdo(2, NodeId(5))),
        (0x385, CobId::Tpdo(3, NodeId(5))),
        (0x405, CobId::Rpdo(3, NodeId(5))),
        (0x485, CobId::Tpdo(4, NodeId(5))),
        (0x505, CobId::Rpdo(4, NodeId(5))),
        (0x585, CobId::SdoTx(NodeId(5))),
        (0x605, CobId::SdoRx(NodeId(5))),
        (0x705, CobId::NmtErrorControl(NodeId(5))),
    ];

    #[test]
    fn predefined_connection_set_table_74_75() {
        for &(id, cob) in PREDEFINED {
            assert_eq!(CobId::classify(id), Ok(cob), "0x{id:03X}");
            assert_eq!(cob.id(), id);
        }
        assert_eq!(CobId::tpdo(4, n(127)).unwrap().id(), 0x4FF);
        assert_eq!(CobId::rpdo(1, n(1)).unwrap().id(), 0x201);
        assert_eq!(CobId::SdoRx(n(127)).id(), 0x67F);
    }

    #[test]
    fn node_ids_are_1_to_127() {
        assert_eq!(NodeId::new(0), Err(CobIdError::NodeId(0)));
        assert_eq!(NodeId::new(128), Err(CobIdError::NodeId(128)));
        assert_eq!(NodeId::new(1).unwrap().get(), 1);
        assert_eq!(NodeId::new(127).unwrap().get(), 127);
        assert!(NodeId::new(200).unwrap_err().to_string().contains("200"));
    }

    #[test]
    fn refuses_ids_outside_the_set() {
        for id in [
            0x001, 0x07F, 0x101, 0x180, 0x580, 0x600, 0x680, 0x6A0, 0x700, 0x7E5, 0x800,
        ] {
            assert_eq!(
                CobId::classify(id),
                Err(CobIdError::NotPredefined(id)),
                "0x{id:03X}"
            );
        }
        assert_eq!(CobId::tpdo(5, n(1)), Err(CobIdError::PdoNumber(5)));
        assert_eq!(CobId::rpdo(0, n(1)), Err(CobIdError::PdoNumber(0)));
    }

    #[test]
    fn function_code_is_bits_10_to_7() {
        assert_eq!(FunctionCode::of(0x585), FunctionCode::SdoTx);
        assert_eq!(FunctionCode::of(0x77F), FunctionCode::NmtErrorControl);
        assert_eq!(FunctionCode::of(0x080), FunctionCode::SyncEmcy);
    }

    proptest! {
        #[test]
        fn classify_round_trips(id in any::<u16>()) {
            if let Ok(c) = CobId::classify(id) {
                prop_assert_eq!(c.id(), id);
            }
        }
    }
}
