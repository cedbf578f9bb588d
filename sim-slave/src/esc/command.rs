//! How one ESC serves a datagram passing through it (ETG.1000.4 §5.4, Table 4 and the
//! working-counter rules): addressing by position (auto-increment), by configured address
//! or alias, or broadcast; reads copy (or OR, for broadcasts) into the frame, writes copy
//! out of it; the working counter grows by 1 for a read, 2 for a write and 3 for a
//! read-write that did both. Logical commands (LRD/LWR/LRW) go through the FMMUs
//! ([`super::fmmu`]).

use super::datagram::{Command, Datagram};
use super::memory::Memory;
use super::registers::{DL_CONTROL, STATION_ADDRESS, STATION_ALIAS};

/// What the slave did with a datagram (for traces and tests).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Served {
    /// Not addressed to this slave (or a command it does not serve).
    Passed,
    /// Read from this slave.
    Read,
    /// Written to this slave.
    Written,
    /// Read and written.
    ReadWritten,
}

/// Whether the station alias is enabled (DL control bit 24).
fn alias_enabled(mem: &Memory) -> bool {
    mem.read_u32(DL_CONTROL) & (1 << 24) != 0
}

/// What a datagram asks of this slave once its address is decoded: the addressing rules
/// apart from the access itself, so that a slave can pass a datagram that is not for it
/// without looking further (in a cyclic frame most datagrams are for another slave).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Not for this slave (or a command it does not serve).
    None,
    /// Read into the frame; OR-ed in for broadcasts.
    Read {
        /// OR the read into the frame's data instead of replacing it.
        or: bool,
    },
    /// Write the frame's data.
    Write,
    /// Read the old contents into the frame and write the frame's data.
    ReadWrite,
    /// BRW: read OR-ed in, then write the frame's original data.
    BroadcastReadWrite,
    /// LRD/LWR/LRW: through the FMMUs.
    Logical,
}

/// Decodes `d`'s address for this slave. Auto-increment and broadcast commands have
/// their position incremented here, as every slave does on the way, addressed or not.
#[inline]
pub fn address(mem: &Memory, d: &mut Datagram<&mut [u8]>) -> Access {
    let cmd = d.command();
    let adp = d.adp();
    match cmd {
        Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => {
            // Auto-increment: the slave that sees position 0 is addressed; every slave
            // increments the position on the way.
            d.set_adp(adp.wrapping_add(1));
            match (cmd, adp == 0) {
                (Command::Aprd | Command::Armw, true) => Access::Read { or: false },
                (Command::Apwr, true) => Access::Write,
                (_, true) => Access::ReadWrite,
                (Command::Armw, false) => Access::Write,
                (_, false) => Access::None,
            }
        }
        Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => {
            let me = adp == mem.read_u16(STATION_ADDRESS)
                || (alias_enabled(mem) && adp == mem.read_u16(STATION_ALIAS));
            match (cmd, me) {
                (Command::Fprd | Command::Frmw, true) => Access::Read { or: false },
                (Command::Fpwr, true) => Access::Write,
                (Command::Fprw, true) => Access::ReadWrite,
                (Command::Frmw, false) => Access::Write,
                _ => Access::None,
            }
        }
        // Broadcasts: every slave increments the position field too (ETG.1000.4 §5.4.1.2,
        // Table 4: "ADP ... incremented by each slave"), so a master can count the slaves
        // from the returned ADP as well as from the working counter.
        Command::Brd => {
            d.set_adp(adp.wrapping_add(1));
            Access::Read { or: true }
        }
        Command::Bwr => {
            d.set_adp(adp.wrapping_add(1));
            Access::Write
        }
        Command::Brw => {
            d.set_adp(adp.wrapping_add(1));
            Access::BroadcastReadWrite
        }
        Command::Lrd | Command::Lwr | Command::Lrw => Access::Logical,
        Command::Nop | Command::Unknown(_) => Access::None,
    }
}

/// Performs `access` (from [`address`]) on `d` with this slave's memory.
pub fn apply(mem: &mut Memory, d: &mut Datagram<&mut [u8]>, access: Access) -> Served {
    let ado = d.ado();
    match access {
        Access::None => Served::Passed,
        Access::Read { or } => read(mem, d, ado, or),
        Access::Write => write(mem, d, ado),
        Access::ReadWrite => read_write(mem, d, ado),
        Access::BroadcastReadWrite => {
            // Broadcast read-write: OR the read into the frame, write the frame's data.
            let data_in: [u8; 2048] = copy_prefix(d.data());
            let n = d.data().len();
            let r = read(mem, d, ado, true);
            let _ = mem.ecat_write(ado, data_in.get(..n.min(2048)).unwrap_or(&[]));
            if r == Served::Read {
                bump(d, 2);
                Served::ReadWritten
            } else {
                r
            }
        }
        Access::Logical => super::fmmu::serve(mem, d),
    }
}

/// Serves `d` with this slave's memory.
pub fn serve(mem: &mut Memory, d: &mut Datagram<&mut [u8]>) -> Served {
    let access = address(mem, d);
    apply(mem, d, access)
}

fn copy_prefix(data: &[u8]) -> [u8; 2048] {
    let mut out = [0; 2048];
    let n = data.len().min(2048);
    if let (Some(o), Some(i)) = (out.get_mut(..n), data.get(..n)) {
        o.copy_from_slice(i);
    }
    out
}

fn bump(d: &mut Datagram<&mut [u8]>, by: u16) {
    let w = d.wkc();
    d.set_wkc(w.wrapping_add(by));
}

fn read(mem: &Memory, d: &mut Datagram<&mut [u8]>, ado: u16, or: bool) -> Served {
    if mem.ecat_read(ado, d.data_mut(), or) {
        bump(d, 1);
        Served::Read
    } else {
        Served::Passed
    }
}

fn write(mem: &mut Memory, d: &mut Datagram<&mut [u8]>, ado: u16) -> Served {
    if mem.ecat_write(ado, d.data()) {
        bump(d, 1);
        Served::Written
    } else {
        Served::Passed
    }
}

fn read_write(mem: &mut Memory, d: &mut Datagram<&mut [u8]>, ado: u16) -> Served {
    // Read first into a copy, then write the frame's original data, then hand back the
    // read: the frame leaves with the old contents (ETG.1000.4: "read and write").
    let data_in: [u8; 2048] = copy_prefix(d.data());
    let n = d.data().len().min(2048);
    let ok_read = mem.ecat_read(ado, d.data_mut(), false);
    let ok_write = mem.ecat_write(ado, data_in.get(..n).unwrap_or(&[]));
    match (ok_read, ok_write) {
        (true, true) => {
            bump(d, 3);
            Served::ReadWritten
        }
        (true, false) => {
            bump(d, 1);
            Served::Read
        }
        (false, true) => {
            bump(d, 2);
            Served::Written
        }
        (false, false) => Served::Passed,
    }
}

#[cfg(test)]
mod tests {
    use super::super::registers::{AL_STATUS, TYPE};
    use super::*;

    /// Builds a datagram buffer: header, `data`, WKC 0.
    fn dg(cmd: Command, adp: u16, ado: u16, data: &[u8]) -> Vec<u8> {
        let mut buf = vec![0u8; 12 + data.len()];
        let mut d = Datagram::new_unchecked(&mut buf[..]);
        d.set_command(cmd);
        d.set_adp(adp);
        d.set_ado(ado);
        d.set_len(data.len(), false, false);
        d.data_mut().copy_from_slice(data);
        buf
    }

    fn chain(n: usize) -> Vec<Memory> {
        (0..n)
            .map(|i| {
                let mut m = Memory::new();
                m.pdi_write(STATION_ADDRESS, &(0x1000 + i as u16).to_le_bytes());
                m
            })
            .collect()
    }

    fn pass(chain: &mut [Memory], buf: &mut [u8]) -> Vec<Served> {
        chain
            .iter_mut()
            .map(|m| serve(m, &mut Datagram::new_unchecked(&mut buf[..])))
            .collect()
    }

    #[test]
    fn brd_counts_every_slave_and_ors_the_data() {
        let mut c = chain(3);
        let mut buf = dg(Command::Brd, 0, TYPE, &[0, 0]);
        pass(&mut c, &mut buf);
        let d = Datagram::new_unchecked(&buf[..]);
        assert_eq!(d.wkc(), 3);
        assert_eq!(d.data(), &[0x11, 0x00]);
    }

    #[test]
    fn broadcasts_increment_the_position_in_every_slave() {
        for cmd in [Command::Brd, Command::Bwr, Command::Brw] {
            let mut c = chain(3);
            let mut buf = dg(cmd, 0, 0x0F80, &[0, 0]);
            pass(&mut c, &mut buf);
            // Byte level: ADP is bytes 2..4 of the datagram header.
            assert_eq!(&buf[2..4], &[3, 0], "{cmd:?}: three slaves passed");
            // Unmapped address: nothing counted, the position still moved.
            assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 0, "{cmd:?}");
        }
        let mut c = chain(2);
        let mut buf = dg(Command::Brd, 0xFFFF, TYPE, &[0]);
        pass(&mut c, &mut buf);
        assert_eq!(Datagram::new_unchecked(&buf[..]).adp(), 1, "wraps");
    }

    #[test]
    fn aprd_reads_the_slave_at_position_zero_and_increments_adp() {
        let mut c = chain(3);
        // Position 1 is addressed as ADP = -1 (0xFFFF) by masters.
        let mut buf = dg(Command::Aprd, 0xFFFF, STATION_ADDRESS, &[0, 0]);
        let served = pass(&mut c, &mut buf);
        assert_eq!(served, vec![Served::Passed, Served::Read, Served::Passed]);
        let d = Datagram::new_unchecked(&buf[..]);
        assert_eq!(d.data(), &0x1001u16.to_le_bytes());
        assert_eq!(d.wkc(), 1);
        assert_eq!(d.adp(), 2);
    }

    #[test]
    fn fpwr_writes_only_the_addressed_station_and_counts_one() {
        let mut c = chain(3);
        let mut buf = dg(Command::Fpwr, 0x1002, STATION_ALIAS, &[0x34, 0x12]);
        pass(&mut c, &mut buf);
        assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 1);
        assert_eq!(c[2].read_u16(STATION_ALIAS), 0x1234);
        assert_eq!(c[1].read_u16(STATION_ALIAS), 0);
    }

    #[test]
    fn fprw_counts_three_and_returns_the_old_value() {
        let mut c = chain(2);
        c[1].pdi_write(STATION_ALIAS, &[0x22, 0x11]);
        let mut buf = dg(Command::Fprw, 0x1001, STATION_ALIAS, &[0x44, 0x33]);
        pass(&mut c, &mut buf);
        let d = Datagram::new_unchecked(&buf[..]);
        assert_eq!(d.wkc(), 3);
        assert_eq!(d.data(), &[0x22, 0x11]);
        assert_eq!(c[1].read_u16(STATION_ALIAS), 0x3344);
    }

    #[test]
    fn frmw_reads_at_the_addressed_slave_and_writes_the_others() {
        let mut c = chain(3);
        c[0].pdi_write(STATION_ALIAS, &[0x78, 0x56]);
        let mut buf = dg(Command::Frmw, 0x1000, STATION_ALIAS, &[0, 0]);
        pass(&mut c, &mut buf);
        assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 3);
        assert_eq!(c[2].read_u16(STATION_ALIAS), 0x5678);
    }

    #[test]
    fn alias_addresses_only_when_enabled() {
        let mut c = chain(1);
        c[0].pdi_write(STATION_ALIAS, &0x0042u16.to_le_bytes());
        let mut buf = dg(Command::Fprd, 0x0042, TYPE, &[0]);
        pass(&mut c, &mut buf);
        assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 0);
        c[0].pdi_write(DL_CONTROL, &(1u32 << 24 | 1).to_le_bytes());
        let mut buf = dg(Command::Fprd, 0x0042, TYPE, &[0]);
        pass(&mut c, &mut buf);
        assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 1);
    }

    #[test]
    fn writes_to_read_only_registers_change_nothing() {
        let mut c = chain(1);
        let mut buf = dg(Command::Bwr, 0, AL_STATUS, &[0x08, 0x00]);
        pass(&mut c, &mut buf);
        assert_eq!(c[0].read_u16(AL_STATUS), 0x0001);
        // The access still counts: the ESC accepted the datagram (the register is there).
        assert_eq!(Datagram::new_unchecked(&buf[..]).wkc(), 1);
    }

    #[test]
    fn logical_commands_without_fmmus_pass_untouched() {
        let mut c = chain(2);
        let mut buf = dg(Command::Lrw, 0, 0, &[1, 2, 3]);
        let before = buf.clone();
        assert_eq!(pass(&mut c, &mut buf), vec![Served::Passed, Served::Passed]);
        assert_eq!(buf, before);
    }
}
