//! The CRC of SDO block transfer (CiA 301 §7.2.4.3.16): CRC-16-CCITT, polynomial
//! x^16 + x^12 + x^5 + 1 (0x1021), initial value 0, no reflection, no final XOR (the
//! "XMODEM" variant), over the data bytes only. Table-driven so a 64 KiB block costs one
//! lookup per byte; the table is built at compile time.

/// The generator polynomial.
pub const POLY: u16 = 0x1021;
/// The initial value the spec gives.
pub const INIT: u16 = 0x0000;

// Indexing in const evaluation: an out-of-range index fails the build, never a run.
#[allow(clippy::indexing_slicing)]
const TABLE: [u16; 256] = {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ POLY
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
};

/// A running CRC, fed segment by segment as a block transfer proceeds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crc16(u16);

impl Crc16 {
    /// A CRC at the initial value.
    pub const fn new() -> Self {
        Self(INIT)
    }

    /// Feeds bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            let idx = ((self.0 >> 8) as u8 ^ b) as usize;
            // idx is a u8: always in the 256-entry table.
            self.0 = (self.0 << 8) ^ TABLE.get(idx).copied().unwrap_or(0);
        }
    }

    /// The CRC so far.
    pub const fn value(&self) -> u16 {
        self.0
    }

    /// The CRC of a whole buffer.
    pub fn of(bytes: &[u8]) -> u16 {
        let mut c = Self::new();
        c.update(bytes);
        c.value()
    }
}

impl Default for Crc16 {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Bit-by-bit reference, straight from the polynomial.
    fn reference(bytes: &[u8]) -> u16 {
        let mut crc = INIT;
        for &b in bytes {
            crc ^= (b as u16) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ POLY
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    #[test]
    fn check_value_of_123456789_is_0x31c3() {
        // The catalogue check value of CRC-16/XMODEM (poly 0x1021, init 0).
        assert_eq!(Crc16::of(b"123456789"), 0x31C3);
        assert_eq!(Crc16::of(&[]), 0);
    }

    proptest! {
        #[test]
        fn table_matches_bitwise_and_is_incremental(data in proptest::collection::vec(any::<u8>(), 0..300), split in 0usize..300) {
            let split = split.min(data.len());
            let mut c = Crc16::new();
            c.update(&data[..split]);
            c.update(&data[split..]);
            prop_assert_eq!(c.value(), reference(&data));
        }
    }
}
