//! NMT node control (CiA 301 §7.2.8.3.1): the master's commands that move nodes between
//! pre-operational, operational and stopped, or reset them. COB-ID 0x000, 2 data bytes:
//! the command specifier, then the node id (0 = every node).

use super::cob_id::{NodeId, ALL_NODES, MAX_NODE_ID, NMT_COB_ID};
use super::frame::CanFrame;
use thiserror::Error;

/// Command specifier: start remote node (→ operational).
pub const CS_START: u8 = 0x01;
/// Command specifier: stop remote node (→ stopped).
pub const CS_STOP: u8 = 0x02;
/// Command specifier: enter pre-operational.
pub const CS_ENTER_PRE_OPERATIONAL: u8 = 0x80;
/// Command specifier: reset node (application and communication parameters).
pub const CS_RESET_NODE: u8 = 0x81;
/// Command specifier: reset communication (communication parameters only).
pub const CS_RESET_COMMUNICATION: u8 = 0x82;
/// Data length of an NMT node-control frame.
pub const NMT_LEN: usize = 2;

/// Why a frame is not an NMT node-control command.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum NmtError {
    /// Not COB-ID 0x000.
    #[error("NMT command: COB-ID 0x{0:03X}, expected 0x000")]
    CobId(u16),
    /// A remote frame.
    #[error("NMT command: remote frame, CiA 301 §7.2.8.3.1 uses a data frame")]
    Remote,
    /// Not 2 data bytes.
    #[error("NMT command: {0} data bytes, expected 2 (command specifier, node id)")]
    Length(usize),
    /// An unknown command specifier (byte 0).
    #[error("NMT command: byte 0 command specifier 0x{0:02X} is not one of 0x01, 0x02, 0x80, 0x81, 0x82")]
    Command(u8),
    /// A node id over 127 (byte 1).
    #[error("NMT command: byte 1 node id {0} is over 127")]
    Node(u8),
}

/// An NMT node-control command (CiA 301 §7.2.8.2.1 NMT node control services).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtCommand {
    /// Start remote node.
    Start,
    /// Stop remote node.
    Stop,
    /// Enter pre-operational.
    EnterPreOperational,
    /// Reset node.
    ResetNode,
    /// Reset communication.
    ResetCommunication,
}

impl NmtCommand {
    /// The command specifier byte.
    pub const fn specifier(self) -> u8 {
        match self {
            Self::Start => CS_START,
            Self::Stop => CS_STOP,
            Self::EnterPreOperational => CS_ENTER_PRE_OPERATIONAL,
            Self::ResetNode => CS_RESET_NODE,
            Self::ResetCommunication => CS_RESET_COMMUNICATION,
        }
    }

    /// The command of a specifier byte.
    pub const fn from_specifier(cs: u8) -> Result<Self, NmtError> {
        Ok(match cs {
            CS_START => Self::Start,
            CS_STOP => Self::Stop,
            CS_ENTER_PRE_OPERATIONAL => Self::EnterPreOperational,
            CS_RESET_NODE => Self::ResetNode,
            CS_RESET_COMMUNICATION => Self::ResetCommunication,
            other => return Err(NmtError::Command(other)),
        })
    }
}

/// Whom an NMT command addresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtTarget {
    /// Node id 0: every node.
    All,
    /// One node.
    Node(NodeId),
}

impl NmtTarget {
    /// Whether a node with this id acts on the command.
    pub fn addresses(self, node: NodeId) -> bool {
        match self {
            Self::All => true,
            Self::Node(n) => n == node,
        }
    }
}

/// An NMT node-control frame, parsed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NmtFrame {
    /// The command.
    pub command: NmtCommand,
    /// Whom it addresses.
    pub target: NmtTarget,
}

impl NmtFrame {
    /// Parses a received frame, refusing any other COB-ID, length or value.
    pub fn parse(frame: &CanFrame) -> Result<Self, NmtError> {
        if frame.id() != NMT_COB_ID {
            return Err(NmtError::CobId(frame.id()));
        }
        if frame.is_remote() {
            return Err(NmtError::Remote);
        }
        let &[cs, node] = frame.data() else {
            return Err(NmtError::Length(frame.len()));
        };
        let command = NmtCommand::from_specifier(cs)?;
        let target = if node == ALL_NODES {
            NmtTarget::All
        } else if node > MAX_NODE_ID {
            return Err(NmtError::Node(node));
        } else {
            match NodeId::new(node) {
                Ok(n) => NmtTarget::Node(n),
                Err(_) => return Err(NmtError::Node(node)),
            }
        };
        Ok(Self { command, target })
    }

    /// The frame to send.
    pub fn emit(&self) -> CanFrame {
        let node = match self.target {
            NmtTarget::All => ALL_NODES,
            NmtTarget::Node(n) => n.get(),
        };
        let mut data = [0u8; 8];
        data[0] = self.command.specifier();
        data[1] = node;
        CanFrame::from_parts_len(NMT_COB_ID, data, NMT_LEN as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// CiA 301 §7.2.8.3.1: COB-ID 0, byte 0 command specifier, byte 1 node id.
    static FIXTURES: &[([u8; 2], NmtCommand, u8)] = &[
        ([0x01, 0x00], NmtCommand::Start, 0),
        ([0x02, 0x05], NmtCommand::Stop, 5),
        ([0x80, 0x7F], NmtCommand::EnterPreOperational, 127),
        ([0x81, 0x01], NmtCommand::ResetNode, 1),
        ([0x82, 0x00], NmtCommand::ResetCommunication, 0),
    ];

    #[test]
    fn fixtures_parse_and_emit() {
        for (bytes, command, node) in FIXTURES {
            let target = if *node == 0 {
                NmtTarget::All
            } else {
                NmtTarget::Node(NodeId::new(*node).unwrap())
            };
            let frame = CanFrame::new(0, bytes).unwrap();
            let parsed = NmtFrame::parse(&frame).unwrap();
            assert_eq!(
                parsed,
                NmtFrame {
                    command: *command,
                    target
                }
            );
            assert_eq!(parsed.emit(), frame);
        }
    }

    #[test]
    fn node_zero_addresses_all() {
        let n3 = NodeId::new(3).unwrap();
        assert!(NmtTarget::All.addresses(n3));
        assert!(NmtTarget::Node(n3).addresses(n3));
        assert!(!NmtTarget::Node(NodeId::new(4).unwrap()).addresses(n3));
    }

    #[test]
    fn refuses_bad_frames_naming_the_field() {
        let f = |id, d: &[u8]| NmtFrame::parse(&CanFrame::new(id, d).unwrap());
        assert_eq!(f(0x001, &[1, 0]), Err(NmtError::CobId(1)));
        assert_eq!(f(0, &[1]), Err(NmtError::Length(1)));
        assert_eq!(f(0, &[1, 0, 0]), Err(NmtError::Length(3)));
        assert_eq!(f(0, &[0x03, 0]), Err(NmtError::Command(3)));
        assert_eq!(f(0, &[0x01, 0x80]), Err(NmtError::Node(0x80)));
        assert_eq!(
            NmtFrame::parse(&CanFrame::new_remote(0, 2).unwrap()),
            Err(NmtError::Remote)
        );
        assert!(f(0, &[0x03, 0]).unwrap_err().to_string().contains("byte 0"));
    }

    proptest! {
        #[test]
        fn any_frame_parses_or_errs_and_round_trips(id in 0u32..0x800, data in proptest::collection::vec(any::<u8>(), 0..=8)) {
            let frame = CanFrame::new(id, &data).unwrap();
            if let Ok(p) = NmtFrame::parse(&frame) {
                prop_assert_eq!(p.emit(), frame);
            }
        }
    }
}
