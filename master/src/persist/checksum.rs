//! CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, as zlib and PNG compute it) over a
//! parameter file's bytes: it finds every truncation and every burst of altered bytes up
//! to 32 bits long, and any other change with probability 1 − 2⁻³². It is a check against
//! accidents (a torn write, a damaged sector, a hand edit), not a signature.

/// The CRC-32 of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            // Bitwise: the files are a few hundred bytes, a table would be bigger than them.
            let mask = (crc & 1).wrapping_neg();
            crc = (crc >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_matches_the_standard_check_value() {
        // The check value of CRC-32/ISO-HDLC ("123456789"), as every catalogue lists it.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
        // zlib.crc32(b"gantry") in Python.
        assert_eq!(crc32(b"gantry"), 0xBCB0_52EC);
    }
}
