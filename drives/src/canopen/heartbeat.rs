//! Heartbeat and boot-up (CiA 301 §7.2.8.3.2): a node sends its NMT state on 0x700 + node
//! id, one byte, every producer heartbeat time (0x1017); the boot-up message is the same
//! frame with state 0, sent once on entering pre-operational after initialisation. The
//! consumer learns from it that the node is alive and in which state.

use super::cob_id::{CobId, NodeId};
use super::frame::CanFrame;
use thiserror::Error;

/// Boot-up (CiA 301 §7.2.8.3.2, heartbeat protocol).
pub const STATE_BOOT_UP: u8 = 0x00;
/// Stopped.
pub const STATE_STOPPED: u8 = 0x04;
/// Operational.
pub const STATE_OPERATIONAL: u8 = 0x05;
/// Pre-operational.
pub const STATE_PRE_OPERATIONAL: u8 = 0x7F;
/// Bit 7: the node-guarding toggle bit (reserved, 0, in a heartbeat).
pub const TOGGLE_BIT: u8 = 0x80;

/// Why a frame is not a heartbeat.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum HeartbeatError {
    /// Not 0x701..=0x77F.
    #[error("heartbeat: COB-ID 0x{0:03X} is not 0x700 + node id 1..127")]
    CobId(u16),
    /// A remote frame: a node-guarding request, not a heartbeat.
    #[error("heartbeat: remote frame on 0x{0:03X} is a node-guarding request, not a heartbeat")]
    Remote(u16),
    /// Not 1 data byte.
    #[error("heartbeat: 0x{id:03X} has {len} data bytes, expected 1 (CiA 301 §7.2.8.3.2.2)")]
    Length {
        /// The COB-ID.
        id: u16,
        /// The data length.
        len: usize,
    },
    /// An unknown state (bits 6–0).
    #[error("heartbeat: 0x{id:03X} byte 0 state 0x{state:02X} is not 0x00, 0x04, 0x05 or 0x7F (CiA 301 §7.2.8.3.2, heartbeat protocol)")]
    State {
        /// The COB-ID.
        id: u16,
        /// The state bits.
        state: u8,
    },
}

/// The NMT state a node reports (CiA 301 §7.2.8.3.2, heartbeat protocol).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtState {
    /// Boot-up: the node has just initialised (then it is pre-operational).
    BootUp,
    /// Stopped.
    Stopped,
    /// Operational.
    Operational,
    /// Pre-operational.
    PreOperational,
}

impl NmtState {
    /// The state byte.
    pub const fn code(self) -> u8 {
        match self {
            Self::BootUp => STATE_BOOT_UP,
            Self::Stopped => STATE_STOPPED,
            Self::Operational => STATE_OPERATIONAL,
            Self::PreOperational => STATE_PRE_OPERATIONAL,
        }
    }

    /// The state of a byte's bits 6–0, if it is one.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code & !TOGGLE_BIT {
            STATE_BOOT_UP => Some(Self::BootUp),
            STATE_STOPPED => Some(Self::Stopped),
            STATE_OPERATIONAL => Some(Self::Operational),
            STATE_PRE_OPERATIONAL => Some(Self::PreOperational),
            _ => None,
        }
    }
}

/// A heartbeat, boot-up or node-guarding response.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Heartbeat {
    /// The producing node.
    pub node: NodeId,
    /// Its state.
    pub state: NmtState,
    /// Bit 7: the toggle of a node-guarding response; false in a heartbeat.
    pub toggle: bool,
}

impl Heartbeat {
    /// A heartbeat (toggle bit 0).
    pub const fn new(node: NodeId, state: NmtState) -> Self {
        Self {
            node,
            state,
            toggle: false,
        }
    }

    /// Whether this is the boot-up message.
    pub const fn is_boot_up(&self) -> bool {
        matches!(self.state, NmtState::BootUp)
    }

    /// Parses a received frame.
    pub fn parse(frame: &CanFrame) -> Result<Self, HeartbeatError> {
        let id = frame.id();
        let Ok(CobId::NmtErrorControl(node)) = CobId::classify(id) else {
            return Err(HeartbeatError::CobId(id));
        };
        if frame.is_remote() {
            return Err(HeartbeatError::Remote(id));
        }
        let &[byte] = frame.data() else {
            return Err(HeartbeatError::Length {
                id,
                len: frame.len(),
            });
        };
        let Some(state) = NmtState::from_code(byte) else {
            return Err(HeartbeatError::State {
                id,
                state: byte & !TOGGLE_BIT,
            });
        };
        Ok(Self {
            node,
            state,
            toggle: byte & TOGGLE_BIT != 0,
        })
    }

    /// The frame to send.
    pub fn emit(&self) -> CanFrame {
        let mut data = [0u8; 8];
        data[0] = self.state.code() | if self.toggle { TOGGLE_BIT } else { 0 };
        CanFrame::from_parts_len(CobId::NmtErrorControl(self.node).id(), data, 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// CiA 301 §7.2.8.3.2: 0x700 + node, one byte with the NMT state.
    static FIXTURES: &[(u32, u8, NmtState)] = &[
        (0x705, 0x00, NmtState::BootUp),
        (0x705, 0x04, NmtState::Stopped),
        (0x77F, 0x05, NmtState::Operational),
        (0x701, 0x7F, NmtState::PreOperational),
    ];

    #[test]
    fn fixtures_parse_and_emit() {
        for &(id, byte, state) in FIXTURES {
            let frame = CanFrame::new(id, &[byte]).unwrap();
            let hb = Heartbeat::parse(&frame).unwrap();
            assert_eq!(hb.node.get() as u32, id - 0x700);
            assert_eq!(hb.state, state);
            assert!(!hb.toggle);
            assert_eq!(hb.is_boot_up(), byte == 0);
            assert_eq!(hb.emit(), frame);
        }
    }

    #[test]
    fn node_guarding_toggle_is_bit_7() {
        let frame = CanFrame::new(0x70A, &[0x85]).unwrap();
        let hb = Heartbeat::parse(&frame).unwrap();
        assert!(hb.toggle);
        assert_eq!(hb.state, NmtState::Operational);
        assert_eq!(hb.emit(), frame);
    }

    #[test]
    fn refuses_bad_frames_naming_the_field() {
        let p = |id, d: &[u8]| Heartbeat::parse(&CanFrame::new(id, d).unwrap());
        assert_eq!(p(0x700, &[0]), Err(HeartbeatError::CobId(0x700)));
        assert_eq!(p(0x605, &[0]), Err(HeartbeatError::CobId(0x605)));
        assert_eq!(
            p(0x705, &[]),
            Err(HeartbeatError::Length { id: 0x705, len: 0 })
        );
        assert_eq!(
            p(0x705, &[5, 0]),
            Err(HeartbeatError::Length { id: 0x705, len: 2 })
        );
        assert_eq!(
            p(0x705, &[0x06]),
            Err(HeartbeatError::State {
                id: 0x705,
                state: 6
            })
        );
        assert_eq!(
            Heartbeat::parse(&CanFrame::new_remote(0x705, 1).unwrap()),
            Err(HeartbeatError::Remote(0x705))
        );
    }

    proptest! {
        #[test]
        fn any_frame_parses_or_errs_and_round_trips(id in 0u32..0x800, data in proptest::collection::vec(any::<u8>(), 0..=8)) {
            let frame = CanFrame::new(id, &data).unwrap();
            if let Ok(p) = Heartbeat::parse(&frame) {
                prop_assert_eq!(p.emit(), frame);
            }
        }
    }
}
