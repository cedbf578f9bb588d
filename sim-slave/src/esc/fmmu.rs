//! FMMUs (ETG.1000.4 §6.6): map ranges of the logical address space onto physical memory,
//! which is how LRD/LWR/LRW reach process data. Byte-granular mappings are served; a
//! mapping that starts or ends inside a byte (bit-wise FMMUs) is not yet.

use super::command::Served;
use super::datagram::{Command, Datagram};
use super::memory::Memory;
use super::registers::FMMU0;

/// FMMUs of an ESC.
pub const COUNT: u16 = 8;
/// Bytes of one FMMU's registers.
pub const SIZE: u16 = 16;

/// One FMMU's configuration, read from its registers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fmmu {
    /// Logical start address.
    pub logical_start: u32,
    /// Length in bytes.
    pub length: u16,
    /// Physical start address.
    pub physical_start: u16,
    /// Maps for reading (inputs: physical → frame).
    pub read: bool,
    /// Maps for writing (outputs: frame → physical).
    pub write: bool,
    /// Enabled.
    pub active: bool,
}

impl Fmmu {
    /// FMMU `n` as configured in `mem`.
    pub fn read_from(mem: &Memory, n: u16) -> Self {
        let mut b = [0u8; SIZE as usize];
        if let Some(regs) = mem.raw(FMMU0 + n * SIZE, SIZE as usize) {
            b.copy_from_slice(regs);
        }
        Fmmu {
            logical_start: u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            length: u16::from_le_bytes([b[4], b[5]]),
            physical_start: u16::from_le_bytes([b[8], b[9]]),
            read: b[11] & 0x01 != 0,
            write: b[11] & 0x02 != 0,
            active: b[12] & 0x01 != 0,
        }
    }

    /// The overlap of this FMMU with logical `[addr, addr + len)`: (offset in the
    /// datagram, physical address, length).
    fn overlap(&self, addr: u32, len: usize) -> Option<(usize, u16, usize)> {
        let start = u64::from(self.logical_start.max(addr));
        let end = (u64::from(self.logical_start) + u64::from(self.length))
            .min(u64::from(addr) + len as u64);
        if start >= end {
            return None;
        }
        let in_frame = (start - u64::from(addr)) as usize;
        let phys = u64::from(self.physical_start) + (start - u64::from(self.logical_start));
        Some((in_frame, u16::try_from(phys).ok()?, (end - start) as usize))
    }
}

/// Whether a logical write of `[addr, addr + len)` reaches physical byte `phys` through an
/// active write FMMU (how a SyncManager learns that an LWR/LRW completed its buffer).
pub fn writes_byte(mem: &Memory, addr: u32, len: usize, phys: u16) -> bool {
    (0..COUNT).any(|n| {
        let f = Fmmu::read_from(mem, n);
        f.active
            && f.write
            && f.overlap(addr, len).is_some_and(|(_, start, count)| {
                u32::from(start) <= u32::from(phys)
                    && u32::from(phys) < u32::from(start) + count as u32
            })
    })
}

/// Whether a logical read of `[addr, addr + len)` reaches physical byte `phys` through an
/// active read FMMU (how a SyncManager learns that an LRD/LRW completed reading a buffer).
pub fn reads_byte(mem: &Memory, addr: u32, len: usize, phys: u16) -> bool {
    (0..COUNT).any(|n| {
        let f = Fmmu::read_from(mem, n);
        f.active
            && f.read
            && f.overlap(addr, len).is_some_and(|(_, start, count)| {
                u32::from(start) <= u32::from(phys)
                    && u32::from(phys) < u32::from(start) + count as u32
            })
    })
}

/// Serves a logical datagram (LRD/LWR/LRW) through the active FMMUs.
pub fn serve(mem: &mut Memory, d: &mut Datagram<&mut [u8]>) -> Served {
    let cmd = d.command();
    if !cmd.is_logical() {
        return Served::Passed;
    }
    let addr = d.logical_address();
    let len = d.data_len();
    let (mut did_read, mut did_write) = (false, false);
    for n in 0..COUNT {
        // Most FMMUs are off: look at the activate register before decoding the rest.
        let active = mem
            .raw(FMMU0 + n * SIZE + 12, 1)
            .is_some_and(|a| a.first().is_some_and(|b| b & 0x01 != 0));
        if !active {
            continue;
        }
        let f = Fmmu::read_from(mem, n);
        let Some((at, phys, count)) = f.overlap(addr, len) else {
            continue;
        };
        if f.write && matches!(cmd, Command::Lwr | Command::Lrw) {
            if let Some(src) = d.data().get(at..at + count) {
                did_write |= mem.ecat_write(phys, src);
            }
        }
        if f.read && matches!(cmd, Command::Lrd | Command::Lrw) {
            if let Some(dst) = d.data_mut().get_mut(at..at + count) {
                did_read |= mem.ecat_read(phys, dst, false);
            }
        }
    }
    // ETG.1000.4 §5.4.3 (Table 4, working counter): LRD and LWR add 1 when the slave read
    // or wrote at least one byte; LRW adds 1 for the read and 2 for the write (3 for both).
    let add = match cmd {
        Command::Lrw => u16::from(did_read) + 2 * u16::from(did_write),
        _ => u16::from(did_read || did_write),
    };
    if add > 0 {
        let w = d.wkc();
        d.set_wkc(w.wrapping_add(add));
    }
    match (did_read, did_write) {
        (true, true) => Served::ReadWritten,
        (true, false) => Served::Read,
        (false, true) => Served::Written,
        (false, false) => Served::Passed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::registers::PROCESS_RAM;

    fn configure(mem: &mut Memory, n: u16, logical: u32, len: u16, phys: u16, kind: u8) {
        let mut b = [0u8; 16];
        b[0..4].copy_from_slice(&logical.to_le_bytes());
        b[4..6].copy_from_slice(&len.to_le_bytes());
        b[7] = 7;
        b[8..10].copy_from_slice(&phys.to_le_bytes());
        b[11] = kind;
        b[12] = 1;
        assert!(mem.ecat_write(FMMU0 + n * SIZE, &b));
    }

    fn lrw(addr: u32, data: &[u8]) -> Vec<u8> {
        let mut buf = vec![0u8; 12 + data.len()];
        let mut d = Datagram::new_unchecked(&mut buf[..]);
        d.set_command(Command::Lrw);
        d.set_adp(addr as u16);
        d.set_ado((addr >> 16) as u16);
        d.set_len(data.len(), false, false);
        d.data_mut().copy_from_slice(data);
        buf
    }

    #[test]
    fn lrw_writes_outputs_reads_inputs_and_counts_three() {
        let mut mem = Memory::new();
        configure(&mut mem, 0, 0x0001_0000, 4, PROCESS_RAM, 2); // outputs
        configure(&mut mem, 1, 0x0001_0004, 2, PROCESS_RAM + 0x400, 1); // inputs
        mem.pdi_write(PROCESS_RAM + 0x400, &[0xAB, 0xCD]);
        let mut buf = lrw(0x0001_0000, &[1, 2, 3, 4, 0, 0]);
        let served = serve(&mut mem, &mut Datagram::new_unchecked(&mut buf[..]));
        assert_eq!(served, Served::ReadWritten);
        let d = Datagram::new_unchecked(&buf[..]);
        assert_eq!(d.wkc(), 3);
        assert_eq!(d.data(), &[1, 2, 3, 4, 0xAB, 0xCD]);
        let mut out = [0u8; 4];
        mem.ecat_read(PROCESS_RAM, &mut out, false);
        assert_eq!(out, [1, 2, 3, 4]);
    }

    fn logical(cmd: Command, addr: u32, data: &[u8]) -> Vec<u8> {
        let mut buf = lrw(addr, data);
        Datagram::new_unchecked(&mut buf[..]).set_command(cmd);
        buf
    }

    #[test]
    fn lwr_counts_one_per_slave_written() {
        // Two slaves, each with 4 output bytes at consecutive logical addresses.
        let mut slaves = [Memory::new(), Memory::new()];
        configure(&mut slaves[0], 0, 0x0001_0000, 4, PROCESS_RAM, 2);
        configure(&mut slaves[1], 0, 0x0001_0004, 4, PROCESS_RAM, 2);
        let mut buf = logical(Command::Lwr, 0x0001_0000, &[1, 2, 3, 4, 5, 6, 7, 8]);
        for m in &mut slaves {
            assert_eq!(
                serve(m, &mut Datagram::new_unchecked(&mut buf[..])),
                Served::Written
            );
        }
        let d = Datagram::new_unchecked(&buf[..]);
        assert_eq!(d.wkc(), 2, "LWR: one per slave written, not two");
        // Byte level: the WKC field is the last two bytes of the datagram.
        assert_eq!(&buf[buf.len() - 2..], &[2, 0]);
        let mut out = [0u8; 4];
        slaves[1].ecat_read(PROCESS_RAM, &mut out, false);
        assert_eq!(out, [5, 6, 7, 8]);
    }

    #[test]
    fn lrd_counts_one_and_lrw_three_per_slave() {
        let mut mem = Memory::new();
        configure(&mut mem, 0, 0x100, 2, PROCESS_RAM, 2);
        configure(&mut mem, 1, 0x102, 2, PROCESS_RAM + 0x400, 1);
        let mut buf = logical(Command::Lrd, 0x100, &[0; 4]);
        serve(&mut mem, &mut Datagram::new_unchecked(&mut buf[..]));
        assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 1);
        let mut buf = logical(Command::Lwr, 0x100, &[0; 4]);
        serve(&mut mem, &mut Datagram::new_unchecked(&mut buf[..]));
        assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 1);
        let mut buf = logical(Command::Lrw, 0x100, &[0; 4]);
        serve(&mut mem, &mut Datagram::new_unchecked(&mut buf[..]));
        assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 3);
    }

    #[test]
    fn partial_overlaps_and_misses() {
        let mut mem = Memory::new();
        configure(&mut mem, 0, 100, 4, PROCESS_RAM, 1);
        mem.pdi_write(PROCESS_RAM, &[9, 8, 7, 6]);
        // Datagram covers logical 102..106: bytes 2 and 3 of the FMMU.
        let mut buf = lrw(102, &[0, 0, 0, 0]);
        serve(&mut mem, &mut Datagram::new_unchecked(&mut buf[..]));
        let d = Datagram::new_unchecked(&buf[..]);
        assert_eq!(d.data(), &[7, 6, 0, 0]);
        assert_eq!(d.wkc(), 1);
        let mut buf = lrw(200, &[0, 0]);
        assert_eq!(
            serve(&mut mem, &mut Datagram::new_unchecked(&mut buf[..])),
            Served::Passed
        );
    }
}
