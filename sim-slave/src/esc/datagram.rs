//! EtherCAT datagrams (ETG.1000.4 §5.4): 10-byte header, data, 2-byte working counter.
//!
//! ```text
//! 0      1      2        4        6                         8      10          10+n   12+n
//! | cmd  | idx  | ADP/ logical address  | len:11 r:3 C:1 M:1 | IRQ  | data (n) | WKC  |
//! ```
//!
//! Contract (smoltcp `wire` style): after [`Datagram::new_checked`] succeeds no accessor
//! panics, and [`Datagram::total_len`] is within the buffer. All fields little-endian.

use thiserror::Error;

mod field {
    use core::ops::Range;
    pub const CMD: usize = 0;
    pub const IDX: usize = 1;
    pub const ADP: Range<usize> = 2..4;
    pub const ADO: Range<usize> = 4..6;
    pub const LEN: Range<usize> = 6..8;
    pub const IRQ: Range<usize> = 8..10;
    pub const DATA: usize = 10;
}

/// Header length.
pub const HEADER_LEN: usize = 10;
/// Working counter length.
pub const WKC_LEN: usize = 2;
/// Largest data length the 11-bit field holds.
pub const MAX_DATA_LEN: usize = 0x7FF;

/// Datagram commands (ETG.1000.4 Table 4); decoding is total.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// 0: no operation.
    Nop,
    /// 1: auto-increment physical read.
    Aprd,
    /// 2: auto-increment physical write.
    Apwr,
    /// 3: auto-increment physical read/write.
    Aprw,
    /// 4: configured-address physical read.
    Fprd,
    /// 5: configured-address physical write.
    Fpwr,
    /// 6: configured-address physical read/write.
    Fprw,
    /// 7: broadcast read.
    Brd,
    /// 8: broadcast write.
    Bwr,
    /// 9: broadcast read/write.
    Brw,
    /// 10: logical read.
    Lrd,
    /// 11: logical write.
    Lwr,
    /// 12: logical read/write.
    Lrw,
    /// 13: auto-increment read, multiple write.
    Armw,
    /// 14: configured-address read, multiple write.
    Frmw,
    /// Anything else: slaves pass it on untouched.
    Unknown(u8),
}

impl From<u8> for Command {
    fn from(v: u8) -> Self {
        use Command::*;
        match v {
            0 => Nop,
            1 => Aprd,
            2 => Apwr,
            3 => Aprw,
            4 => Fprd,
            5 => Fpwr,
            6 => Fprw,
            7 => Brd,
            8 => Bwr,
            9 => Brw,
            10 => Lrd,
            11 => Lwr,
            12 => Lrw,
            13 => Armw,
            14 => Frmw,
            v => Unknown(v),
        }
    }
}

impl From<Command> for u8 {
    fn from(c: Command) -> u8 {
        use Command::*;
        match c {
            Nop => 0,
            Aprd => 1,
            Apwr => 2,
            Aprw => 3,
            Fprd => 4,
            Fpwr => 5,
            Fprw => 6,
            Brd => 7,
            Bwr => 8,
            Brw => 9,
            Lrd => 10,
            Lwr => 11,
            Lrw => 12,
            Armw => 13,
            Frmw => 14,
            Unknown(v) => v,
        }
    }
}

impl Command {
    /// Whether the address field is one 32-bit logical address (LRD/LWR/LRW).
    pub const fn is_logical(self) -> bool {
        matches!(self, Command::Lrd | Command::Lwr | Command::Lrw)
    }
}

/// What is wrong with a datagram.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum DatagramError {
    /// Fewer bytes than a header.
    #[error("datagram at offset {offset}: {len} bytes left, a header needs 10")]
    TruncatedHeader {
        /// Offset in the frame payload.
        offset: usize,
        /// Bytes left.
        len: usize,
    },
    /// The data and working counter run past the end.
    #[error("datagram at offset {offset}: length {data_len} needs {need} bytes, {len} left")]
    TruncatedData {
        /// Offset in the frame payload.
        offset: usize,
        /// Declared data length.
        data_len: usize,
        /// Bytes the datagram needs.
        need: usize,
        /// Bytes left.
        len: usize,
    },
    /// The "more" bit says another datagram follows but the frame ends.
    #[error("datagram at offset {offset} announces another datagram, but the frame ends")]
    MissingNext {
        /// Offset of the announcing datagram.
        offset: usize,
    },
}

/// A view of one datagram at the start of a buffer.
#[derive(Debug)]
pub struct Datagram<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Datagram<T> {
    /// Wraps without checks (for emitting into a buffer of [`Datagram::total_len`]).
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// Wraps a received buffer; `offset` is only for error messages.
    pub fn new_checked(buffer: T, offset: usize) -> Result<Self, DatagramError> {
        let d = Self::new_unchecked(buffer);
        let len = d.buffer.as_ref().len();
        if len < HEADER_LEN {
            return Err(DatagramError::TruncatedHeader { offset, len });
        }
        let need = d.total_len();
        if len < need {
            return Err(DatagramError::TruncatedData {
                offset,
                data_len: d.data_len(),
                need,
                len,
            });
        }
        Ok(d)
    }

    fn byte(&self, at: usize) -> u8 {
        self.buffer.as_ref().get(at).copied().unwrap_or(0)
    }

    fn u16_at(&self, at: usize) -> u16 {
        u16::from_le_bytes([self.byte(at), self.byte(at + 1)])
    }

    /// Command.
    pub fn command(&self) -> Command {
        Command::from(self.byte(field::CMD))
    }

    /// Index (the master's tag to match replies).
    pub fn index(&self) -> u8 {
        self.byte(field::IDX)
    }

    /// Position or configured address (ADP).
    pub fn adp(&self) -> u16 {
        self.u16_at(field::ADP.start)
    }

    /// Register offset (ADO).
    pub fn ado(&self) -> u16 {
        self.u16_at(field::ADO.start)
    }

    /// Logical address (LRD/LWR/LRW: ADP and ADO as one 32-bit value).
    pub fn logical_address(&self) -> u32 {
        u32::from(self.adp()) | (u32::from(self.ado()) << 16)
    }

    /// Data length (11 bits).
    pub fn data_len(&self) -> usize {
        (self.u16_at(field::LEN.start) & 0x07FF) as usize
    }

    /// Circulating frame bit.
    pub fn circulating(&self) -> bool {
        self.u16_at(field::LEN.start) & (1 << 14) != 0
    }

    /// Another datagram follows.
    pub fn more(&self) -> bool {
        self.u16_at(field::LEN.start) & (1 << 15) != 0
    }

    /// IRQ field.
    pub fn irq(&self) -> u16 {
        self.u16_at(field::IRQ.start)
    }

    /// Header + data + working counter.
    pub fn total_len(&self) -> usize {
        HEADER_LEN + self.data_len() + WKC_LEN
    }

    /// The data.
    pub fn data(&self) -> &[u8] {
        self.buffer
            .as_ref()
            .get(field::DATA..field::DATA + self.data_len())
            .unwrap_or(&[])
    }

    /// Working counter.
    pub fn wkc(&self) -> u16 {
        self.u16_at(field::DATA + self.data_len())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Datagram<T> {
    fn set_u16(&mut self, at: usize, v: u16) {
        if let Some(s) = self.buffer.as_mut().get_mut(at..at + 2) {
            s.copy_from_slice(&v.to_le_bytes());
        }
    }

    /// Sets the command.
    pub fn set_command(&mut self, c: Command) {
        if let Some(b) = self.buffer.as_mut().get_mut(field::CMD) {
            *b = c.into();
        }
    }

    /// Sets the index.
    pub fn set_index(&mut self, i: u8) {
        if let Some(b) = self.buffer.as_mut().get_mut(field::IDX) {
            *b = i;
        }
    }

    /// Sets ADP (auto-increment slaves bump it on the way).
    pub fn set_adp(&mut self, v: u16) {
        self.set_u16(field::ADP.start, v);
    }

    /// Sets ADO.
    pub fn set_ado(&mut self, v: u16) {
        self.set_u16(field::ADO.start, v);
    }

    /// Sets the length field (data length, circulating and more bits).
    pub fn set_len(&mut self, data_len: usize, circulating: bool, more: bool) {
        let v = (data_len.min(MAX_DATA_LEN) as u16)
            | if circulating { 1 << 14 } else { 0 }
            | if more { 1 << 15 } else { 0 };
        self.set_u16(field::LEN.start, v);
    }

    /// Sets the IRQ field.
    pub fn set_irq(&mut self, v: u16) {
        self.set_u16(field::IRQ.start, v);
    }

    /// The data, mutable.
    pub fn data_mut(&mut self) -> &mut [u8] {
        let n = self.data_len();
        self.buffer
            .as_mut()
            .get_mut(field::DATA..field::DATA + n)
            .unwrap_or(&mut [])
    }

    /// Sets the working counter.
    pub fn set_wkc(&mut self, v: u16) {
        let at = field::DATA + self.data_len();
        self.set_u16(at, v);
    }
}

/// Checks every datagram of a frame payload without touching it; returns how many there
/// are. Lets a slave refuse a frame that is malformed half-way before serving any of it.
pub fn validate(payload: &[u8]) -> Result<usize, DatagramError> {
    let mut offset = 0;
    let mut n = 0;
    loop {
        let rest = payload.get(offset..).unwrap_or(&[]);
        let d = Datagram::new_checked(rest, offset)?;
        n += 1;
        let len = d.total_len();
        offset += len;
        if !d.more() {
            return Ok(n);
        }
        if offset >= payload.len() {
            return Err(DatagramError::MissingNext {
                offset: offset - len,
            });
        }
    }
}

/// Walks the datagrams of a frame payload, handing each to `f` mutably (a slave reads
/// and writes them in place). Stops at the first malformed one; returns how many it
/// handled.
pub fn for_each_mut(
    payload: &mut [u8],
    mut f: impl FnMut(Datagram<&mut [u8]>),
) -> Result<usize, DatagramError> {
    let mut offset = 0;
    let mut n = 0;
    loop {
        let rest = payload.get_mut(offset..).unwrap_or(&mut []);
        let (len, more) = {
            let d = Datagram::new_checked(&*rest, offset)?;
            (d.total_len(), d.more())
        };
        let (this, _) = rest.split_at_mut(len.min(rest.len()));
        f(Datagram::new_unchecked(this));
        n += 1;
        offset += len;
        if !more {
            return Ok(n);
        }
        if offset >= payload.len() {
            return Err(DatagramError::MissingNext {
                offset: offset - len,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Two datagrams: an FPRD of AL status (0x0130, 2 bytes) at station 0x1001 with more
    /// set, then an LRW of 4 bytes at logical 0x00010000 — the shape of a cyclic frame.
    static TWO: [u8; 30] = [
        0x04, 0x05, 0x01, 0x10, 0x30, 0x01, 0x02, 0x80, 0x00, 0x00, 0x08, 0x00, 0x01, 0x00, 0x0c,
        0x06, 0x00, 0x00, 0x01, 0x00, 0x04, 0x00, 0x00, 0x00, 0x11, 0x22, 0x33, 0x44, 0x03, 0x00,
    ];

    #[test]
    fn getters_read_the_fixture() {
        let d = Datagram::new_checked(&TWO[..], 0).unwrap();
        assert_eq!(d.command(), Command::Fprd);
        assert_eq!(d.index(), 5);
        assert_eq!(d.adp(), 0x1001);
        assert_eq!(d.ado(), 0x0130);
        assert_eq!(d.data_len(), 2);
        assert!(d.more() && !d.circulating());
        assert_eq!(d.data(), &[0x08, 0x00]);
        assert_eq!(d.wkc(), 1);
        let d2 = Datagram::new_checked(&TWO[14..], 14).unwrap();
        assert_eq!(d2.command(), Command::Lrw);
        assert_eq!(d2.logical_address(), 0x0001_0000);
        assert_eq!(d2.data(), &[0x11, 0x22, 0x33, 0x44]);
        assert_eq!(d2.wkc(), 3);
        assert!(!d2.more());
    }

    #[test]
    fn setters_rebuild_the_fixture_in_a_poisoned_buffer() {
        let mut buf = [0xa5u8; 30];
        {
            let mut d = Datagram::new_unchecked(&mut buf[..14]);
            d.set_command(Command::Fprd);
            d.set_index(5);
            d.set_adp(0x1001);
            d.set_ado(0x0130);
            d.set_len(2, false, true);
            d.set_irq(0);
            d.data_mut().copy_from_slice(&[0x08, 0x00]);
            d.set_wkc(1);
        }
        {
            let mut d = Datagram::new_unchecked(&mut buf[14..]);
            d.set_command(Command::Lrw);
            d.set_index(6);
            d.set_adp(0x0000);
            d.set_ado(0x0001);
            d.set_len(4, false, false);
            d.set_irq(0);
            d.data_mut().copy_from_slice(&[0x11, 0x22, 0x33, 0x44]);
            d.set_wkc(3);
        }
        assert_eq!(buf, TWO);
    }

    #[test]
    fn walking_visits_every_datagram_and_can_write() {
        let mut buf = TWO;
        let mut seen = Vec::new();
        let n = for_each_mut(&mut buf, |mut d| {
            seen.push(d.command());
            let w = d.wkc();
            d.set_wkc(w + 1);
        })
        .unwrap();
        assert_eq!(n, 2);
        assert_eq!(validate(&TWO), Ok(2));
        assert_eq!(seen, vec![Command::Fprd, Command::Lrw]);
        assert_eq!(buf[12], 2);
        assert_eq!(buf[28], 4);
    }

    #[test]
    fn malformed_datagrams_say_where_and_what() {
        assert_eq!(
            Datagram::new_checked(&TWO[..5], 0).unwrap_err(),
            DatagramError::TruncatedHeader { offset: 0, len: 5 }
        );
        assert_eq!(
            Datagram::new_checked(&TWO[..12], 0).unwrap_err(),
            DatagramError::TruncatedData {
                offset: 0,
                data_len: 2,
                need: 14,
                len: 12
            }
        );
        let mut first_only = [0u8; 14];
        first_only.copy_from_slice(&TWO[..14]);
        assert_eq!(
            for_each_mut(&mut first_only, |_| {}).unwrap_err(),
            DatagramError::MissingNext { offset: 0 }
        );
    }

    #[test]
    fn commands_decode_totally() {
        for v in 0..=u8::MAX {
            assert_eq!(u8::from(Command::from(v)), v);
        }
        assert!(Command::Lrw.is_logical() && !Command::Fprd.is_logical());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, rng_seed: proptest::test_runner::RngSeed::Fixed(3), failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn arbitrary_bytes_never_panic(mut bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let _ = for_each_mut(&mut bytes, |mut d| {
                let _ = (d.command(), d.adp(), d.ado(), d.data().len(), d.wkc(), d.irq());
                d.set_wkc(d.wkc().wrapping_add(1));
                d.data_mut().fill(0);
            });
            let _ = crate::esc::frame::Frame::new_checked(&bytes[..]).map(|f| f.payload().len());
        }
    }
}
