//! Emergency (EMCY, CiA 301 §7.2.7): a node reports an internal error once, when it
//! occurs (and error code 0x0000 when it is gone), on 0x080 + node id. 8 data bytes:
//! the error code (little-endian, the classes of CiA 301 §7.2.7.1; CiA 402 adds drive codes), the error
//! register (object 0x1001) and 5 manufacturer-specific bytes.

use super::cob_id::{CobId, NodeId};
use super::frame::CanFrame;
use thiserror::Error;

/// Error code 0x0000: error reset or no error (CiA 301 §7.2.7.1).
pub const ERROR_RESET: u16 = 0x0000;
/// Data length of an EMCY frame.
pub const EMCY_LEN: usize = 8;

/// Why a frame is not an EMCY.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum EmcyError {
    /// Not 0x081..=0x0FF.
    #[error("EMCY: COB-ID 0x{0:03X} is not 0x080 + node id 1..127")]
    CobId(u16),
    /// A remote frame.
    #[error("EMCY: remote frame on 0x{0:03X}, CiA 301 §7.2.7 uses a data frame")]
    Remote(u16),
    /// Not 8 data bytes.
    #[error("EMCY: 0x{id:03X} has {len} data bytes, expected 8 (CiA 301 §7.2.7.3.1)")]
    Length {
        /// The COB-ID.
        id: u16,
        /// The data length.
        len: usize,
    },
}

/// An emergency message.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Emergency {
    /// The producing node.
    pub node: NodeId,
    /// Emergency error code (bytes 0–1).
    pub error_code: u16,
    /// Error register, object 0x1001 (byte 2).
    pub error_register: u8,
    /// Manufacturer-specific error code (bytes 3–7).
    pub manufacturer: [u8; 5],
}

impl Emergency {
    /// Whether this is the "error reset / no error" message.
    pub const fn is_reset(&self) -> bool {
        self.error_code == ERROR_RESET
    }

    /// Parses a received frame.
    pub fn parse(frame: &CanFrame) -> Result<Self, EmcyError> {
        let id = frame.id();
        let Ok(CobId::Emcy(node)) = CobId::classify(id) else {
            return Err(EmcyError::CobId(id));
        };
        if frame.is_remote() {
            return Err(EmcyError::Remote(id));
        }
        let &[c0, c1, reg, m0, m1, m2, m3, m4] = frame.data() else {
            return Err(EmcyError::Length {
                id,
                len: frame.len(),
            });
        };
        Ok(Self {
            node,
            error_code: u16::from_le_bytes([c0, c1]),
            error_register: reg,
            manufacturer: [m0, m1, m2, m3, m4],
        })
    }

    /// The frame to send.
    pub fn emit(&self) -> CanFrame {
        let [c0, c1] = self.error_code.to_le_bytes();
        let [m0, m1, m2, m3, m4] = self.manufacturer;
        CanFrame::from_parts(
            CobId::Emcy(self.node).id(),
            [c0, c1, self.error_register, m0, m1, m2, m3, m4],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn fixture_heartbeat_error_of_node_1() {
        // CiA 301 §7.2.7.3.1 layout; 0x8130 "life guard or heartbeat error" (§7.2.7.1),
        // register 0x11 = generic error | communication error (object 0x1001 bits 0 and 4).
        static BYTES: [u8; 8] = [0x30, 0x81, 0x11, 0xDE, 0xAD, 0xBE, 0xEF, 0x01];
        let frame = CanFrame::new(0x081, &BYTES).unwrap();
        let e = Emergency::parse(&frame).unwrap();
        assert_eq!(e.node.get(), 1);
        assert_eq!(e.error_code, 0x8130);
        assert_eq!(e.error_register, 0x11);
        assert_eq!(e.manufacturer, [0xDE, 0xAD, 0xBE, 0xEF, 0x01]);
        assert!(!e.is_reset());
        assert_eq!(e.emit(), frame);
    }

    #[test]
    fn fixture_error_reset() {
        let frame = CanFrame::new(0x0FF, &[0; 8]).unwrap();
        let e = Emergency::parse(&frame).unwrap();
        assert_eq!(e.node.get(), 127);
        assert!(e.is_reset());
    }

    #[test]
    fn refuses_bad_frames_naming_the_field() {
        let p = |id, d: &[u8]| Emergency::parse(&CanFrame::new(id, d).unwrap());
        assert_eq!(p(0x080, &[0; 8]), Err(EmcyError::CobId(0x080)));
        assert_eq!(p(0x181, &[0; 8]), Err(EmcyError::CobId(0x181)));
        assert_eq!(
            p(0x081, &[0; 7]),
            Err(EmcyError::Length { id: 0x81, len: 7 })
        );
        assert_eq!(
            Emergency::parse(&CanFrame::new_remote(0x81, 8).unwrap()),
            Err(EmcyError::Remote(0x81))
        );
    }

    proptest! {
        #[test]
        fn any_frame_parses_or_errs_and_round_trips(id in 0u32..0x800, data in proptest::collection::vec(any::<u8>(), 0..=8)) {
            let frame = CanFrame::new(id, &data).unwrap();
            if let Ok(p) = Emergency::parse(&frame) {
                prop_assert_eq!(p.emit(), frame);
            }
        }
    }
}
