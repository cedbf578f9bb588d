//! The EtherCAT frame: Ethernet II header with EtherType 0x88A4, then the 2-byte EtherCAT
//! header (ETG.1000.4 §5.3.1: bits 0–10 length of the datagrams, bit 11 reserved, bits
//! 12–15 type, 1 = DLPDU).
//!
//! Contract (smoltcp `wire` style): after [`Frame::new_checked`] succeeds, no accessor
//! panics; [`Frame::new_unchecked`] is for emitting into a buffer the caller sized.

use thiserror::Error;

/// EtherType of EtherCAT.
pub const ETHERTYPE: u16 = 0x88A4;
/// EtherCAT header type of a frame carrying datagrams (DLPDU).
pub const TYPE_DLPDU: u8 = 1;
/// Length of the Ethernet II header.
pub const ETHERNET_HEADER_LEN: usize = 14;
/// Length of the EtherCAT header.
pub const ECAT_HEADER_LEN: usize = 2;

mod field {
    use core::ops::Range;
    pub const DST: Range<usize> = 0..6;
    pub const SRC: Range<usize> = 6..12;
    pub const ETHERTYPE: Range<usize> = 12..14;
    pub const ECAT_HEADER: Range<usize> = 14..16;
    pub const PAYLOAD: usize = 16;
}

/// What is wrong with a frame.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum FrameError {
    /// Shorter than the Ethernet and EtherCAT headers.
    #[error("frame of {len} bytes is shorter than the {need}-byte headers")]
    TooShort {
        /// Bytes present.
        len: usize,
        /// Bytes needed.
        need: usize,
    },
    /// Not EtherType 0x88A4.
    #[error("EtherType {ethertype:#06x} is not EtherCAT (0x88a4)")]
    NotEthercat {
        /// The EtherType found.
        ethertype: u16,
    },
    /// The EtherCAT header's length runs past the end of the frame.
    #[error("EtherCAT header says {declared} bytes of datagrams, the frame holds {present}")]
    LengthMismatch {
        /// Length in the header.
        declared: usize,
        /// Bytes after the header.
        present: usize,
    },
    /// A type other than DLPDU.
    #[error("EtherCAT header type {kind} is not 1 (DLPDU)")]
    UnsupportedType {
        /// The type found.
        kind: u8,
    },
}

/// A view of an EtherCAT frame in a byte buffer.
#[derive(Debug)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// Wraps a buffer without checks (for emitting).
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// Wraps a received buffer, checking everything the accessors rely on.
    pub fn new_checked(buffer: T) -> Result<Self, FrameError> {
        let f = Self::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }

    /// Checks headers, EtherType, type and length.
    pub fn check_len(&self) -> Result<(), FrameError> {
        let b = self.buffer.as_ref();
        let need = ETHERNET_HEADER_LEN + ECAT_HEADER_LEN;
        if b.len() < need {
            return Err(FrameError::TooShort { len: b.len(), need });
        }
        let ethertype = self.ethertype();
        if ethertype != ETHERTYPE {
            return Err(FrameError::NotEthercat { ethertype });
        }
        if self.kind() != TYPE_DLPDU {
            return Err(FrameError::UnsupportedType { kind: self.kind() });
        }
        let present = b.len() - need;
        let declared = self.ecat_len();
        if declared > present {
            return Err(FrameError::LengthMismatch { declared, present });
        }
        Ok(())
    }

    fn u16_at(&self, at: usize, big_endian: bool) -> u16 {
        let b = self.buffer.as_ref();
        let (x, y) = (
            b.get(at).copied().unwrap_or(0),
            b.get(at + 1).copied().unwrap_or(0),
        );
        if big_endian {
            u16::from_be_bytes([x, y])
        } else {
            u16::from_le_bytes([x, y])
        }
    }

    /// Destination MAC address.
    pub fn dst(&self) -> [u8; 6] {
        let mut a = [0; 6];
        if let Some(s) = self.buffer.as_ref().get(field::DST) {
            a.copy_from_slice(s);
        }
        a
    }

    /// Source MAC address.
    pub fn src(&self) -> [u8; 6] {
        let mut a = [0; 6];
        if let Some(s) = self.buffer.as_ref().get(field::SRC) {
            a.copy_from_slice(s);
        }
        a
    }

    /// EtherType (big-endian on the wire).
    pub fn ethertype(&self) -> u16 {
        self.u16_at(field::ETHERTYPE.start, true)
    }

    /// Length of the datagrams (EtherCAT header bits 0–10, little-endian).
    pub fn ecat_len(&self) -> usize {
        (self.u16_at(field::ECAT_HEADER.start, false) & 0x07FF) as usize
    }

    /// EtherCAT header type (bits 12–15).
    pub fn kind(&self) -> u8 {
        (self.u16_at(field::ECAT_HEADER.start, false) >> 12) as u8
    }

    /// The datagrams (exactly `ecat_len` bytes).
    pub fn payload(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        let end = (field::PAYLOAD + self.ecat_len()).min(b.len());
        b.get(field::PAYLOAD..end).unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Sets the destination MAC address.
    pub fn set_dst(&mut self, a: [u8; 6]) {
        if let Some(s) = self.buffer.as_mut().get_mut(field::DST) {
            s.copy_from_slice(&a);
        }
    }

    /// Sets the source MAC address.
    pub fn set_src(&mut self, a: [u8; 6]) {
        if let Some(s) = self.buffer.as_mut().get_mut(field::SRC) {
            s.copy_from_slice(&a);
        }
    }

    /// Sets the EtherType.
    pub fn set_ethertype(&mut self, t: u16) {
        if let Some(s) = self.buffer.as_mut().get_mut(field::ETHERTYPE) {
            s.copy_from_slice(&t.to_be_bytes());
        }
    }

    /// Sets the EtherCAT header (length of the datagrams, type DLPDU).
    pub fn set_ecat_header(&mut self, len: usize) {
        let v = (len as u16 & 0x07FF) | (u16::from(TYPE_DLPDU) << 12);
        if let Some(s) = self.buffer.as_mut().get_mut(field::ECAT_HEADER) {
            s.copy_from_slice(&v.to_le_bytes());
        }
    }

    /// The datagrams, mutable.
    pub fn payload_mut(&mut self) -> &mut [u8] {
        let end = (field::PAYLOAD + self.ecat_len()).min(self.buffer.as_ref().len());
        self.buffer
            .as_mut()
            .get_mut(field::PAYLOAD..end)
            .unwrap_or(&mut [])
    }

    /// Marks the frame as passed by a slave: real ESCs set the locally-administered bit of
    /// the source address on the way back, which masters use to tell replies from their own
    /// frames.
    pub fn mark_forwarded(&mut self) {
        if let Some(b) = self.buffer.as_mut().get_mut(field::SRC.start) {
            *b |= 0x02;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A BRD of register 0x0000 (2 bytes), as a master sends it at the start of a scan:
    /// broadcast destination, master source 10:10:10:10:10:10.
    static BRD_FRAME: [u8; 30] = [
        0xff, 0xff, 0xff, 0xff, 0xff, 0xff, // dst
        0x10, 0x10, 0x10, 0x10, 0x10, 0x10, // src
        0x88, 0xa4, // EtherType
        0x0e, 0x10, // 14 bytes, type 1
        0x07, 0x01, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, // BRD idx 1 ado 0 len 2
        0x00, 0x00, // data
        0x00, 0x00, // WKC
    ];

    #[test]
    fn getters_read_the_fixture() {
        let f = Frame::new_checked(&BRD_FRAME[..]).unwrap();
        assert_eq!(f.dst(), [0xff; 6]);
        assert_eq!(f.src(), [0x10; 6]);
        assert_eq!(f.ethertype(), ETHERTYPE);
        assert_eq!(f.ecat_len(), 14);
        assert_eq!(f.kind(), TYPE_DLPDU);
        assert_eq!(f.payload().len(), 14);
    }

    #[test]
    fn setters_rebuild_the_fixture_in_a_poisoned_buffer() {
        let mut buf = [0xa5u8; 30];
        let mut f = Frame::new_unchecked(&mut buf[..]);
        f.set_dst([0xff; 6]);
        f.set_src([0x10; 6]);
        f.set_ethertype(ETHERTYPE);
        f.set_ecat_header(14);
        f.payload_mut().copy_from_slice(&BRD_FRAME[16..]);
        assert_eq!(buf, BRD_FRAME);
    }

    #[test]
    fn forwarded_frames_carry_the_local_bit() {
        let mut buf = BRD_FRAME;
        Frame::new_unchecked(&mut buf[..]).mark_forwarded();
        assert_eq!(buf[6], 0x12);
    }

    #[test]
    fn bad_frames_say_what_is_wrong() {
        assert_eq!(
            Frame::new_checked(&BRD_FRAME[..10]).unwrap_err(),
            FrameError::TooShort { len: 10, need: 16 }
        );
        let mut b = BRD_FRAME;
        b[12] = 0x08;
        b[13] = 0x00;
        assert_eq!(
            Frame::new_checked(&b[..]).unwrap_err(),
            FrameError::NotEthercat { ethertype: 0x0800 }
        );
        assert_eq!(
            Frame::new_checked(&BRD_FRAME[..20]).unwrap_err(),
            FrameError::LengthMismatch {
                declared: 14,
                present: 4
            }
        );
        let mut b = BRD_FRAME;
        b[15] = 0x40;
        assert_eq!(
            Frame::new_checked(&b[..]).unwrap_err(),
            FrameError::UnsupportedType { kind: 4 }
        );
    }
}
