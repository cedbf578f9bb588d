//! A classical CAN data or remote frame with an 11-bit identifier (CAN base frame format,
//! the only one the CiA 301 predefined connection set uses) and 0–8 data bytes.

use thiserror::Error;

/// Largest 11-bit identifier (ISO 11898-1 base format).
pub const MAX_STANDARD_ID: u16 = 0x7FF;
/// Largest data length of a classical CAN frame.
pub const MAX_DATA_LEN: usize = 8;

/// Worst-case bits a classical base-format data frame with `len` data bytes occupies on
/// the bus (ISO 11898-1): 47 fixed bits (the 3-bit inter-frame space included) and 8 per
/// byte, plus one stuff bit per 4 of the 34 + 8·len stuffable bits. 135 bits for 8 data
/// bytes: 1 Mbit/s carries about 7 such frames per millisecond.
pub const fn frame_bits(len: usize) -> u64 {
    let stuffable = 34 + 8 * len as u64;
    47 + 8 * len as u64 + (stuffable - 1) / 4
}

/// Why bytes do not make a CAN frame.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum FrameError {
    /// The identifier does not fit 11 bits.
    #[error("CAN identifier 0x{id:X} does not fit 11 bits (largest 0x7FF)")]
    IdOutOfRange {
        /// The identifier given.
        id: u32,
    },
    /// More than 8 data bytes.
    #[error("CAN frame 0x{id:03X}: {len} data bytes, a classical CAN frame carries at most 8")]
    TooLong {
        /// The identifier.
        id: u16,
        /// The length given.
        len: usize,
    },
}

/// A CAN frame: identifier, RTR flag, data length code 0–8 and the data bytes.
///
/// The invariants (id ≤ 0x7FF, len ≤ 8) hold for every value, since the fields are only
/// set through the checked constructors; bytes past `len` are always zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: u16,
    rtr: bool,
    len: u8,
    data: [u8; MAX_DATA_LEN],
}

impl CanFrame {
    /// A data frame; refuses an identifier over 11 bits or more than 8 bytes.
    pub fn new(id: u32, data: &[u8]) -> Result<Self, FrameError> {
        let id = check_id(id)?;
        if data.len() > MAX_DATA_LEN {
            return Err(FrameError::TooLong {
                id,
                len: data.len(),
            });
        }
        let mut bytes = [0u8; MAX_DATA_LEN];
        for (dst, src) in bytes.iter_mut().zip(data) {
            *dst = *src;
        }
        Ok(Self {
            id,
            rtr: false,
            len: data.len() as u8,
            data: bytes,
        })
    }

    /// A remote (RTR) frame asking for `dlc` bytes (CiA 301 §7.2.8.3.2.1 node guarding
    /// uses RTR; CiA recommends against RTR otherwise).
    pub fn new_remote(id: u32, dlc: usize) -> Result<Self, FrameError> {
        let id = check_id(id)?;
        if dlc > MAX_DATA_LEN {
            return Err(FrameError::TooLong { id, len: dlc });
        }
        Ok(Self {
            id,
            rtr: true,
            len: dlc as u8,
            data: [0; MAX_DATA_LEN],
        })
    }

    /// An 8-byte data frame from an identifier already known to fit 11 bits (masked).
    pub(crate) const fn from_parts(id: u16, data: [u8; MAX_DATA_LEN]) -> Self {
        Self {
            id: id & MAX_STANDARD_ID,
            rtr: false,
            len: MAX_DATA_LEN as u8,
            data,
        }
    }

    /// A data frame of `len` (clamped to 8) bytes from an identifier already known to fit.
    pub(crate) fn from_parts_len(id: u16, data: [u8; MAX_DATA_LEN], len: u8) -> Self {
        let len = len.min(MAX_DATA_LEN as u8);
        let mut frame = Self::from_parts(id, [0; MAX_DATA_LEN]);
        frame.len = len;
        for (dst, src) in frame.data.iter_mut().zip(data).take(len as usize) {
            *dst = src;
        }
        frame
    }

    /// The 11-bit identifier (the COB-ID).
    pub const fn id(&self) -> u16 {
        self.id
    }

    /// Whether this is a remote (RTR) frame.
    pub const fn is_remote(&self) -> bool {
        self.rtr
    }

    /// The data length code (0–8).
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    /// Whether the frame has no data bytes.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The data bytes (`len()` of them; empty for a remote frame's payload).
    pub fn data(&self) -> &[u8] {
        if self.rtr {
            return &[];
        }
        self.data.get(..self.len as usize).unwrap_or(&[])
    }

    /// All 8 data bytes, zero past `len()`.
    pub const fn raw(&self) -> &[u8; MAX_DATA_LEN] {
        &self.data
    }
}

fn check_id(id: u32) -> Result<u16, FrameError> {
    if id > MAX_STANDARD_ID as u32 {
        return Err(FrameError::IdOutOfRange { id });
    }
    Ok(id as u16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_bits_of_cia_figures() {
        // 8 data bytes: 111 bits + 24 stuff bits = 135 (the figure).
        assert_eq!(frame_bits(8), 135);
        // SYNC without data: 47 + 8 stuff bits.
        assert_eq!(frame_bits(0), 55);
    }
    use proptest::prelude::*;

    #[test]
    fn data_frame_keeps_id_and_bytes() {
        let f = CanFrame::new(0x601, &[0x40, 0x00, 0x10, 0x00]).unwrap();
        assert_eq!(f.id(), 0x601);
        assert_eq!(f.len(), 4);
        assert!(!f.is_remote());
        assert_eq!(f.data(), &[0x40, 0x00, 0x10, 0x00]);
        assert_eq!(f.raw(), &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
    }

    #[test]
    fn refuses_id_over_11_bits_and_more_than_8_bytes() {
        assert_eq!(
            CanFrame::new(0x800, &[]),
            Err(FrameError::IdOutOfRange { id: 0x800 })
        );
        assert_eq!(
            CanFrame::new(0x100, &[0; 9]),
            Err(FrameError::TooLong { id: 0x100, len: 9 })
        );
        assert_eq!(
            CanFrame::new_remote(0x701, 9),
            Err(FrameError::TooLong { id: 0x701, len: 9 })
        );
        let e = CanFrame::new(0x1234, &[]).unwrap_err().to_string();
        assert!(e.contains("0x1234"), "{e}");
    }

    #[test]
    fn remote_frame_has_dlc_but_no_data() {
        let f = CanFrame::new_remote(0x705, 1).unwrap();
        assert!(f.is_remote());
        assert_eq!(f.len(), 1);
        assert!(f.data().is_empty());
    }

    proptest! {
        #[test]
        fn any_input_is_a_frame_or_an_error(id in 0u32..0x1000, data in proptest::collection::vec(any::<u8>(), 0..12)) {
            match CanFrame::new(id, &data) {
                Ok(f) => {
                    prop_assert!(id <= 0x7FF && data.len() <= 8);
                    prop_assert_eq!(f.data(), &data[..]);
                }
                Err(_) => prop_assert!(id > 0x7FF || data.len() > 8),
            }
        }
    }
}
