//! An ESC's memory: registers below 0x1000 (with the access rights of
//! [`super::registers::TABLE`]) and process RAM above. The EtherCAT side goes through
//! [`Memory::ecat_read`]/[`Memory::ecat_write`]; the device application (PDI side) may
//! write read-only registers such as AL status.

use std::sync::OnceLock;

use super::registers::{self, Access, PROCESS_RAM};

/// Bytes of process RAM (8 KiB, like an ET1100).
pub const RAM_BYTES: usize = 8 * 1024;

const UNMAPPED: u8 = 0;
const READ_ONLY: u8 = 1;
const READ_WRITE: u8 = 2;

/// Access of every register byte below process RAM, from the register table: looked up
/// per byte on every access, so it is a flat map rather than a search of the table.
fn access_map() -> &'static [u8] {
    static MAP: OnceLock<Box<[u8]>> = OnceLock::new();
    MAP.get_or_init(|| {
        let mut map = vec![UNMAPPED; PROCESS_RAM as usize].into_boxed_slice();
        for r in &registers::TABLE {
            let at = r.address as usize;
            let access = if r.access == Access::ReadWrite {
                READ_WRITE
            } else {
                READ_ONLY
            };
            if let Some(bytes) = map.get_mut(at..at + r.width as usize) {
                bytes.fill(access);
            }
        }
        for (a, m) in map.iter_mut().enumerate() {
            if registers::sm_byte_read_only(a as u16) {
                *m = READ_ONLY;
            }
        }
        map
    })
}

/// Registers plus process RAM.
#[derive(Clone, Debug)]
pub struct Memory {
    bytes: Box<[u8]>,
    /// Whether the DC registers (0x0900–0x09AF) exist: an ESC without DC leaves them
    /// unmapped, so accesses there are not counted (a master latching receive times with a
    /// broadcast expects only DC slaves in the working counter).
    dc: bool,
}

impl Default for Memory {
    fn default() -> Self {
        Self::new()
    }
}

impl Memory {
    /// Memory with every register at its reset value.
    pub fn new() -> Self {
        let mut bytes = vec![0u8; PROCESS_RAM as usize + RAM_BYTES].into_boxed_slice();
        for r in &registers::TABLE {
            let reset = r.reset.to_le_bytes();
            let n = (r.width as usize).min(8);
            let at = r.address as usize;
            if let (Some(dst), Some(src)) = (bytes.get_mut(at..at + n), reset.get(..n)) {
                dst.copy_from_slice(src);
            }
        }
        Self { bytes, dc: true }
    }

    /// Memory of an ESC without distributed clocks: the DC block is unmapped (and zero).
    pub fn without_dc() -> Self {
        let mut m = Self {
            dc: false,
            ..Self::new()
        };
        for (a, b) in m.bytes.iter_mut().enumerate() {
            if u16::try_from(a).is_ok_and(registers::is_dc) {
                *b = 0;
            }
        }
        m
    }

    /// Whether register byte `a` exists in this ESC (the DC block only with DC).
    fn has(&self, a: usize) -> bool {
        self.dc || !u16::try_from(a).is_ok_and(registers::is_dc)
    }

    /// Whether at least one byte of `[address, address + len)` is a register or RAM. An
    /// ESC counts a datagram when at least one of its bytes was read or written (ESC
    /// datasheet section I, "Working Counter"): a read spanning reserved addresses
    /// (SOEM reads AL status, the reserved 0x0132 and AL status code in one go) counts.
    fn mapped(&self, address: u16, len: usize) -> bool {
        let (start, end) = (address as usize, address as usize + len);
        let ram = PROCESS_RAM as usize..PROCESS_RAM as usize + RAM_BYTES;
        if start < ram.end && end > ram.start {
            return true;
        }
        let map = access_map();
        (start..end).any(|a| map.get(a).is_some_and(|&m| m != UNMAPPED) && self.has(a))
    }

    /// EtherCAT read into `out` (OR-ed in when `or`); false when nothing there is mapped.
    /// Reserved addresses read as zero (section II: "read data from reserved addresses
    /// has to be ignored"); addresses past the RAM leave the frame as it was.
    pub fn ecat_read(&self, address: u16, out: &mut [u8], or: bool) -> bool {
        if !self.mapped(address, out.len()) {
            return false;
        }
        let at = address as usize;
        if let Some(src) = self.bytes.get(at..at + out.len()) {
            // Reserved register bytes are never written, so they hold zero.
            if or {
                for (o, s) in out.iter_mut().zip(src) {
                    *o |= *s;
                }
            } else {
                out.copy_from_slice(src);
            }
        } else {
            // The datagram runs past the end of the RAM: only the bytes inside.
            let inside = self.bytes.len().saturating_sub(at);
            if let (Some(src), Some(dst)) = (self.bytes.get(at..), out.get_mut(..inside)) {
                for (o, s) in dst.iter_mut().zip(src) {
                    *o = if or { *o | *s } else { *s };
                }
            }
        }
        true
    }

    /// EtherCAT write; bytes of read-only registers keep their value. False when nothing
    /// there is mapped.
    pub fn ecat_write(&mut self, address: u16, data: &[u8]) -> bool {
        if !self.mapped(address, data.len()) {
            return false;
        }
        let at = address as usize;
        if at >= PROCESS_RAM as usize {
            // Process RAM: all writable; a datagram running past its end writes the
            // bytes inside.
            let n = data.len().min(self.bytes.len().saturating_sub(at));
            if let (Some(dst), Some(src)) = (self.bytes.get_mut(at..at + n), data.get(..n)) {
                dst.copy_from_slice(src);
            }
            return true;
        }
        let map = access_map();
        for (i, b) in data.iter().enumerate() {
            let a = at + i;
            let writable =
                a >= PROCESS_RAM as usize || (map.get(a) == Some(&READ_WRITE) && self.has(a));
            if writable {
                if let Some(dst) = self.bytes.get_mut(a) {
                    *dst = *b;
                }
            }
        }
        true
    }

    /// PDI-side write (the device application): any mapped byte.
    pub fn pdi_write(&mut self, address: u16, data: &[u8]) {
        let at = address as usize;
        if let Some(dst) = self.bytes.get_mut(at..at + data.len()) {
            dst.copy_from_slice(data);
        }
    }

    /// PDI-side read of `len` bytes (the ESC's own logic reading its registers).
    pub fn raw(&self, address: u16, len: usize) -> Option<&[u8]> {
        self.bytes.get(address as usize..address as usize + len)
    }

    /// Reads a little-endian u16.
    pub fn read_u16(&self, address: u16) -> u16 {
        let mut b = [0; 2];
        let at = address as usize;
        if let Some(s) = self.bytes.get(at..at + 2) {
            b.copy_from_slice(s);
        }
        u16::from_le_bytes(b)
    }

    /// Reads a little-endian u64.
    pub fn read_u64(&self, address: u16) -> u64 {
        let mut b = [0; 8];
        let at = address as usize;
        if let Some(s) = self.bytes.get(at..at + 8) {
            b.copy_from_slice(s);
        }
        u64::from_le_bytes(b)
    }

    /// Reads a little-endian u32.
    pub fn read_u32(&self, address: u16) -> u32 {
        let mut b = [0; 4];
        let at = address as usize;
        if let Some(s) = self.bytes.get(at..at + 4) {
            b.copy_from_slice(s);
        }
        u32::from_le_bytes(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::registers::{AL_STATUS, AL_STATUS_CODE, FEATURES, STATION_ADDRESS, TYPE};

    #[test]
    fn reset_values_and_access_rights() {
        let mut m = Memory::new();
        let mut b = [0u8; 1];
        assert!(m.ecat_read(TYPE, &mut b, false));
        assert_eq!(b[0], 0x11);
        assert_eq!(m.read_u16(FEATURES), 0x010C);
        assert!(m.ecat_write(STATION_ADDRESS, &[1, 2]));
        assert_eq!(m.read_u16(STATION_ADDRESS), 0x0201);
        assert!(m.ecat_write(AL_STATUS, &[8, 0]));
        assert_eq!(m.read_u16(AL_STATUS), 1, "read-only from the EtherCAT side");
        m.pdi_write(AL_STATUS, &[2, 0]);
        assert_eq!(m.read_u16(AL_STATUS), 2, "the device application sets it");
        // SyncManager 1: the master configures start, length, control and activate; the
        // status (mailbox full) and PDI control bytes belong to the ESC.
        m.pdi_write(0x080D, &[0x08]);
        assert!(m.ecat_write(0x0808, &[0x80, 0x10, 0x80, 0, 0x22, 0x00, 0x01, 0x02]));
        assert_eq!(
            m.raw(0x0808, 8),
            Some(&[0x80, 0x10, 0x80, 0, 0x22, 0x08, 0x01, 0][..])
        );
    }

    #[test]
    fn unmapped_addresses_are_not_accessed() {
        let mut m = Memory::new();
        let mut b = [0u8; 2];
        assert!(!m.ecat_read(0x0050, &mut b, false));
        assert!(!m.ecat_write(0x0050, &[1]));
        assert!(m.ecat_write(PROCESS_RAM, &[1, 2, 3]));
        assert!(!m.ecat_read(PROCESS_RAM + RAM_BYTES as u16, &mut b, false));
    }

    #[test]
    fn an_esc_without_dc_does_not_map_the_dc_block() {
        let mut m = Memory::without_dc();
        let mut b = [0u8; 4];
        assert!(!m.ecat_read(0x0900, &mut b, false));
        assert!(!m.ecat_write(0x0910, &[1, 2, 3, 4]));
        assert!(!m.ecat_read(0x09AE, &mut b[..2], false));
        assert!(m.ecat_read(0x083C, &mut b, false), "SyncManagers stay");
        let mut m = Memory::new();
        assert!(m.ecat_write(0x0900, &[1, 2, 3, 4]));
        assert_eq!(m.read_u32(0x0900), 0, "receive times are read-only");
    }

    #[test]
    fn accesses_spanning_reserved_addresses_count_and_read_zero_there() {
        let mut m = Memory::new();
        m.pdi_write(AL_STATUS, &[0x02, 0x00]);
        m.pdi_write(AL_STATUS_CODE, &[0x11, 0x00]);
        // AL status (2), reserved 0x0132..0x0134, AL status code (2): one 6-byte read.
        let mut b = [0xEEu8; 6];
        assert!(m.ecat_read(AL_STATUS, &mut b, false));
        assert_eq!(b, [0x02, 0x00, 0, 0, 0x11, 0x00]);
        // A write across the reserved bytes lands in the registers, not in between.
        assert!(m.ecat_write(0x0010, &[1, 2, 3, 4, 5, 6]));
        assert_eq!(m.read_u16(STATION_ADDRESS), 0x0201);
        let mut r = [0xEEu8; 6];
        assert!(m.ecat_read(0x0010, &mut r, false));
        assert_eq!(r, [1, 2, 3, 4, 0, 0], "0x0014.. is reserved");
        // The last RAM bytes and beyond: what is inside counts.
        let end = PROCESS_RAM + RAM_BYTES as u16;
        assert!(m.ecat_write(end - 2, &[7, 8, 9, 10]));
        let mut t = [0u8; 4];
        assert!(m.ecat_read(end - 2, &mut t, false));
        assert_eq!(t, [7, 8, 0, 0]);
    }
}
