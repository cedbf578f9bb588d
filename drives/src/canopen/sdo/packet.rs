//! A typed view over the 8 data bytes of an SDO frame (CiA 301 §7.2.4.3): getters and
//! setters for every field any command specifier uses, at the offsets of the spec's
//! figures. Which fields mean something depends on the command specifier and, for block
//! segments, on the protocol state: [`super::command`] parses the view into a typed
//! command.
//!
//! Contract (smoltcp `wire` style): [`SdoPacket::new_checked`] refuses any buffer that is
//! not exactly 8 bytes; after it, no getter or setter panics. [`SdoPacket::new_unchecked`]
//! is for 8-byte buffers the caller built (emitting); on a shorter buffer getters read 0
//! and setters write nothing, still without panicking.

use super::command::{SdoWireError, SDO_LEN};

/// Field offsets.
mod field {
    use std::ops::Range;
    /// Command byte: command specifier (bits 7–5) and its flags, or `c` + seqno.
    pub const COMMAND: usize = 0;
    /// Index, little-endian.
    pub const INDEX: Range<usize> = 1..3;
    /// Sub-index.
    pub const SUB_INDEX: usize = 3;
    /// Expedited data, size, or abort code.
    pub const DATA: Range<usize> = 4..8;
    /// Segment data (normal and block segments).
    pub const SEGMENT: Range<usize> = 1..8;
    /// Block sub-block response: last sequence number received in order.
    pub const ACKSEQ: usize = 1;
    /// Block sub-block response: next block size.
    pub const ACK_BLKSIZE: usize = 2;
    /// Block end: CRC, little-endian.
    pub const CRC: Range<usize> = 1..3;
    /// Block initiate (download response, upload request): block size.
    pub const INIT_BLKSIZE: usize = 4;
    /// Block upload request: protocol switch threshold.
    pub const PST: usize = 5;
}

/// Command byte bits.
mod bits {
    /// Bits 7–5: ccs/scs.
    pub const CS_SHIFT: u8 = 5;
    /// Bit 4: toggle.
    pub const TOGGLE: u8 = 0x10;
    /// Bits 3–1 of a segment: bytes without data.
    pub const SEGMENT_N_SHIFT: u8 = 1;
    /// Bits 3–2 of an expedited initiate: bytes without data.
    pub const EXPEDITED_N_SHIFT: u8 = 2;
    /// Bits 4–2 of a block end: bytes of the last segment without data.
    pub const END_N_SHIFT: u8 = 2;
    /// Bit 2 of a block initiate: CRC supported (`cc`/`sc`).
    pub const CRC_SUPPORT: u8 = 0x04;
    /// Bit 1 of an initiate: expedited (`e`); of a block initiate: size indicated (`s`).
    pub const BIT1: u8 = 0x02;
    /// Bit 0: size indicated (`s`, initiate), last segment (`c`, segment), block end.
    pub const BIT0: u8 = 0x01;
    /// Bits 1–0 of a block command: sub-command (cs/ss).
    pub const BLOCK_SUB: u8 = 0x03;
    /// Bit 7 of a block segment: last segment (`c`).
    pub const BLOCK_LAST: u8 = 0x80;
    /// Bits 6–0 of a block segment: sequence number.
    pub const SEQNO: u8 = 0x7F;
}

/// A view over an SDO frame's data bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoPacket<T> {
    buffer: T,
}

impl<T: AsRef<[u8]>> SdoPacket<T> {
    /// Wraps a buffer without checking it (for emitting into an 8-byte buffer).
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// Wraps received bytes: refuses anything but 8 bytes (CiA 301: SDO frames have DLC 8).
    pub fn new_checked(buffer: T) -> Result<Self, SdoWireError> {
        let len = buffer.as_ref().len();
        if len != SDO_LEN {
            return Err(SdoWireError::Length(len));
        }
        Ok(Self { buffer })
    }

    /// The buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
    }

    fn bytes<const N: usize>(&self, start: usize) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some(src) = self.buffer.as_ref().get(start..start + N) {
            out.copy_from_slice(src);
        }
        out
    }

    /// Byte 0.
    pub fn command(&self) -> u8 {
        self.byte(field::COMMAND)
    }

    /// Command specifier (ccs or scs), bits 7–5.
    pub fn command_specifier(&self) -> u8 {
        self.command() >> bits::CS_SHIFT
    }

    /// Toggle bit `t` (segments and segment requests/responses).
    pub fn toggle(&self) -> bool {
        self.command() & bits::TOGGLE != 0
    }

    /// Segment: `n`, bytes of bytes 1–7 that carry no data.
    pub fn segment_unused(&self) -> u8 {
        (self.command() >> bits::SEGMENT_N_SHIFT) & 0x07
    }

    /// Segment: `c`, no more segments.
    pub fn segment_last(&self) -> bool {
        self.command() & bits::BIT0 != 0
    }

    /// Initiate: `n`, bytes of bytes 4–7 without data (valid if expedited and size set).
    pub fn expedited_unused(&self) -> u8 {
        (self.command() >> bits::EXPEDITED_N_SHIFT) & 0x03
    }

    /// Initiate: `e`, expedited transfer.
    pub fn expedited(&self) -> bool {
        self.command() & bits::BIT1 != 0
    }

    /// Initiate: `s`, size indicated.
    pub fn size_indicated(&self) -> bool {
        self.command() & bits::BIT0 != 0
    }

    /// Block initiate: `cc`/`sc`, CRC supported.
    pub fn crc_supported(&self) -> bool {
        self.command() & bits::CRC_SUPPORT != 0
    }

    /// Block initiate: `s`, size indicated (bit 1).
    pub fn block_size_indicated(&self) -> bool {
        self.command() & bits::BIT1 != 0
    }

    /// Block command: sub-command `cs`/`ss`, bits 1–0.
    pub fn block_subcommand(&self) -> u8 {
        self.command() & bits::BLOCK_SUB
    }

    /// Block end: `n`, bytes of the last segment without data, bits 4–2.
    pub fn end_unused(&self) -> u8 {
        (self.command() >> bits::END_N_SHIFT) & 0x07
    }

    /// Block segment: `c`, last segment of the transfer.
    pub fn block_last(&self) -> bool {
        self.command() & bits::BLOCK_LAST != 0
    }

    /// Block segment: sequence number.
    pub fn seqno(&self) -> u8 {
        self.command() & bits::SEQNO
    }

    /// Object index.
    pub fn index(&self) -> u16 {
        u16::from_le_bytes(self.bytes(field::INDEX.start))
    }

    /// Sub-index.
    pub fn sub_index(&self) -> u8 {
        self.byte(field::SUB_INDEX)
    }

    /// Bytes 4–7: expedited data.
    pub fn data(&self) -> [u8; 4] {
        self.bytes(field::DATA.start)
    }

    /// Bytes 4–7 as a little-endian number: size, or abort code.
    pub fn size(&self) -> u32 {
        u32::from_le_bytes(self.data())
    }

    /// Bytes 1–7: segment data.
    pub fn segment_data(&self) -> [u8; 7] {
        self.bytes(field::SEGMENT.start)
    }

    /// Sub-block response: `ackseq`.
    pub fn ackseq(&self) -> u8 {
        self.byte(field::ACKSEQ)
    }

    /// Sub-block response: `blksize` for the next sub-block.
    pub fn ack_block_size(&self) -> u8 {
        self.byte(field::ACK_BLKSIZE)
    }

    /// Block end: CRC.
    pub fn crc(&self) -> u16 {
        u16::from_le_bytes(self.bytes(field::CRC.start))
    }

    /// Block download initiate response / block upload initiate request: `blksize`.
    pub fn init_block_size(&self) -> u8 {
        self.byte(field::INIT_BLKSIZE)
    }

    /// Block upload initiate request: `pst`.
    pub fn pst(&self) -> u8 {
        self.byte(field::PST)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> SdoPacket<T> {
    fn set_byte(&mut self, i: usize, v: u8) {
        if let Some(b) = self.buffer.as_mut().get_mut(i) {
            *b = v;
        }
    }

    fn set_bytes(&mut self, start: usize, v: &[u8]) {
        if let Some(dst) = self.buffer.as_mut().get_mut(start..start + v.len()) {
            dst.copy_from_slice(v);
        }
    }

    /// Sets byte 0.
    pub fn set_command(&mut self, v: u8) {
        self.set_byte(field::COMMAND, v);
    }

    /// Sets the index.
    pub fn set_index(&mut self, v: u16) {
        self.set_bytes(field::INDEX.start, &v.to_le_bytes());
    }

    /// Sets the sub-index.
    pub fn set_sub_index(&mut self, v: u8) {
        self.set_byte(field::SUB_INDEX, v);
    }

    /// Sets bytes 4–7.
    pub fn set_data(&mut self, v: [u8; 4]) {
        self.set_bytes(field::DATA.start, &v);
    }

    /// Sets bytes 1–7.
    pub fn set_segment_data(&mut self, v: [u8; 7]) {
        self.set_bytes(field::SEGMENT.start, &v);
    }

    /// Sets `ackseq` and the next block size of a sub-block response.
    pub fn set_ack(&mut self, ackseq: u8, block_size: u8) {
        self.set_byte(field::ACKSEQ, ackseq);
        self.set_byte(field::ACK_BLKSIZE, block_size);
    }

    /// Sets the CRC of a block end.
    pub fn set_crc(&mut self, v: u16) {
        self.set_bytes(field::CRC.start, &v.to_le_bytes());
    }

    /// Sets the block size of a block initiate.
    pub fn set_init_block_size(&mut self, v: u8) {
        self.set_byte(field::INIT_BLKSIZE, v);
    }

    /// Sets the protocol switch threshold of a block upload initiate.
    pub fn set_pst(&mut self, v: u8) {
        self.set_byte(field::PST, v);
    }
}

/// Command byte builders (bits as CiA 301 §7.2.4.3 lays them out).
pub(crate) mod command_byte {
    use super::bits;

    /// cs in bits 7–5.
    pub const fn cs(cs: u8) -> u8 {
        (cs & 0x07) << bits::CS_SHIFT
    }

    /// Toggle bit.
    pub const fn toggle(t: bool) -> u8 {
        if t {
            bits::TOGGLE
        } else {
            0
        }
    }

    /// A segment's `n` (0..=7) and `c`.
    pub const fn segment(n: u8, last: bool) -> u8 {
        ((n & 0x07) << bits::SEGMENT_N_SHIFT) | last as u8
    }

    /// An initiate's `n` (0..=3), `e` and `s`.
    pub const fn initiate(n: u8, expedited: bool, size: bool) -> u8 {
        ((n & 0x03) << bits::EXPEDITED_N_SHIFT) | ((expedited as u8) << 1) | size as u8
    }

    /// A block initiate's `cc`/`sc`, `s` and sub-command.
    pub const fn block_initiate(crc: bool, size: bool, sub: u8) -> u8 {
        ((crc as u8) << 2) | ((size as u8) << 1) | (sub & bits::BLOCK_SUB)
    }

    /// A block end's `n` (0..=7) and sub-command.
    pub const fn block_end(n: u8, sub: u8) -> u8 {
        ((n & 0x07) << bits::END_N_SHIFT) | (sub & bits::BLOCK_SUB)
    }

    /// A block segment's `c` and sequence number.
    pub const fn block_segment(last: bool, seqno: u8) -> u8 {
        ((last as u8) << 7) | (seqno & bits::SEQNO)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CiA 301 §7.2.4.3.3, initiate download, expedited, 2 bytes (n = 2, e = 1, s = 1) to
    /// 0x6040:00, value 0x000F.
    static EXPEDITED: [u8; 8] = [0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00, 0x00, 0x00];
    /// §7.2.4.3.10: block download end, n = 3, CRC 0x31C3.
    static BLOCK_END: [u8; 8] = [0xCD, 0xC3, 0x31, 0, 0, 0, 0, 0];

    #[test]
    fn getters_read_the_fixture() {
        let p = SdoPacket::new_checked(&EXPEDITED[..]).unwrap();
        assert_eq!(p.command_specifier(), 1);
        assert!(p.expedited() && p.size_indicated());
        assert_eq!(p.expedited_unused(), 2);
        assert_eq!((p.index(), p.sub_index()), (0x6040, 0));
        assert_eq!(p.data(), [0x0F, 0, 0, 0]);
        let p = SdoPacket::new_checked(&BLOCK_END[..]).unwrap();
        assert_eq!((p.command_specifier(), p.block_subcommand()), (6, 1));
        assert_eq!((p.end_unused(), p.crc()), (3, 0x31C3));
    }

    #[test]
    fn setters_rebuild_the_fixture_over_a5() {
        let mut buf = [0xA5u8; 8];
        let mut p = SdoPacket::new_unchecked(&mut buf[..]);
        p.set_command(command_byte::cs(1) | command_byte::initiate(2, true, true));
        p.set_index(0x6040);
        p.set_sub_index(0);
        p.set_data([0x0F, 0, 0, 0]);
        assert_eq!(buf, EXPEDITED);
        let mut buf = [0xA5u8; 8];
        let mut p = SdoPacket::new_unchecked(&mut buf[..]);
        p.set_command(command_byte::cs(6) | command_byte::block_end(3, 1));
        p.set_crc(0x31C3);
        p.set_index(0x31C3); // bytes 1-2 again: index and CRC share them
        p.set_sub_index(0);
        p.set_data([0; 4]);
        assert_eq!(buf, BLOCK_END);
    }

    #[test]
    fn new_checked_refuses_other_lengths() {
        assert_eq!(
            SdoPacket::new_checked(&[0u8; 7][..]),
            Err(SdoWireError::Length(7))
        );
        assert_eq!(
            SdoPacket::new_checked(&[0u8; 9][..]),
            Err(SdoWireError::Length(9))
        );
        // Unchecked on a short buffer: zeros, no panic.
        let p = SdoPacket::new_unchecked(&[0x43u8][..]);
        assert_eq!((p.command(), p.index(), p.size()), (0x43, 0, 0));
        let mut short = [0u8; 2];
        SdoPacket::new_unchecked(&mut short[..]).set_data([1; 4]);
        assert_eq!(short, [0, 0]);
    }
}
