//! SyncManagers (ESC datasheet section I, chapter 8; registers 0x0800 + 8·n): what a
//! SyncManager does is set by its control register, not by its number. Bits 1:0 choose
//! the mode (00 buffered, the 3-buffer mode; 10 mailbox, one buffer), bits 3:2 the
//! direction (00 the master reads, 01 the master writes), bit 6 whether a write triggers
//! the process-data watchdog. The status register (+5) is the ESC's: in mailbox mode bit 3
//! says full; in buffered mode bits 5:4 name the last buffer completed (11: none yet),
//! bit 0 is set when the master completed a buffer it writes, bit 1 when it completed
//! reading one.
//!
//! A buffer is completed by the access to its last byte (section I, 8.1: "a buffer is
//! closed by accessing its last byte"). In 3-buffer mode the application sees only
//! completed buffers: bytes a master wrote without reaching the last byte stay in the
//! buffer being written ([`crate::slave::Slave`] keeps the application's copy).

use super::memory::Memory;
use super::registers::SM0;

/// SyncManagers of the ESC.
pub const COUNT: u16 = 8;
/// Bytes of one SyncManager's registers.
pub const SIZE: u16 = 8;

/// Register address of SyncManager `n`.
pub const fn base(n: u16) -> u16 {
    SM0 + SIZE * n
}

/// Control register (+4) bits.
pub mod control {
    /// Bits 1:0: operation mode.
    pub const MODE_MASK: u8 = 0x03;
    /// Mode 00: buffered (3 buffers).
    pub const MODE_BUFFERED: u8 = 0x00;
    /// Mode 10: mailbox (one buffer).
    pub const MODE_MAILBOX: u8 = 0x02;
    /// Bits 3:2: direction.
    pub const DIRECTION_MASK: u8 = 0x0C;
    /// Direction 00: the master reads, the application writes.
    pub const DIRECTION_READ: u8 = 0x00;
    /// Direction 01: the master writes, the application reads.
    pub const DIRECTION_WRITE: u8 = 0x04;
    /// Bit 6: a write to this SyncManager triggers the process-data watchdog.
    pub const WATCHDOG_TRIGGER: u8 = 0x40;
}

/// Status register (+5) bits.
pub mod status {
    /// Bit 0: the master completed writing a buffer (cleared when the application reads it).
    pub const INTERRUPT_WRITE: u8 = 0x01;
    /// Bit 1: the master completed reading a buffer (cleared when the application writes).
    pub const INTERRUPT_READ: u8 = 0x02;
    /// Bit 3 (mailbox mode): the mailbox is full.
    pub const MAILBOX_FULL: u8 = 0x08;
    /// Bits 5:4 (buffered mode): the last buffer completed.
    pub const BUFFER_MASK: u8 = 0x30;
    /// Bits 5:4 = 11: no buffer completed yet.
    pub const NO_BUFFER: u8 = 0x30;
}

/// Activate register (+6) bits.
pub mod activate {
    /// Bit 0: enabled.
    pub const ENABLE: u8 = 0x01;
    /// Bit 1: repeat request (mailbox).
    pub const REPEAT: u8 = 0x02;
}

/// What a SyncManager's control register says it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// Buffered, the master writes (process data outputs).
    BufferedWrite,
    /// Buffered, the master reads (process data inputs).
    BufferedRead,
    /// Mailbox, the master writes (the slave's receive mailbox).
    MailboxWrite,
    /// Mailbox, the master reads (the slave's send mailbox).
    MailboxRead,
    /// A reserved mode or direction.
    Reserved,
}

/// One SyncManager's registers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncManager {
    /// Physical start address.
    pub start: u16,
    /// Length in bytes (of one buffer).
    pub length: u16,
    /// Control register.
    pub control: u8,
    /// Status register.
    pub status: u8,
    /// Activate register.
    pub activate: u8,
    /// PDI control register.
    pub pdi_control: u8,
}

impl SyncManager {
    /// SyncManager `n` as its registers in `mem` are.
    pub fn read_from(mem: &Memory, n: u16) -> Self {
        let mut b = [0u8; SIZE as usize];
        if let Some(regs) = mem.raw(base(n), SIZE as usize) {
            b.copy_from_slice(regs);
        }
        Self {
            start: u16::from_le_bytes([b[0], b[1]]),
            length: u16::from_le_bytes([b[2], b[3]]),
            control: b[4],
            status: b[5],
            activate: b[6],
            pdi_control: b[7],
        }
    }

    /// Enabled by the master.
    pub const fn enabled(&self) -> bool {
        self.activate & activate::ENABLE != 0
    }

    /// Mode and direction.
    pub const fn kind(&self) -> Kind {
        let mode = self.control & control::MODE_MASK;
        let dir = self.control & control::DIRECTION_MASK;
        match (mode, dir) {
            (control::MODE_BUFFERED, control::DIRECTION_WRITE) => Kind::BufferedWrite,
            (control::MODE_BUFFERED, control::DIRECTION_READ) => Kind::BufferedRead,
            (control::MODE_MAILBOX, control::DIRECTION_WRITE) => Kind::MailboxWrite,
            (control::MODE_MAILBOX, control::DIRECTION_READ) => Kind::MailboxRead,
            _ => Kind::Reserved,
        }
    }

    /// The address of the last byte of its buffer (None when empty or past 0xFFFF).
    pub fn last(&self) -> Option<u16> {
        if self.length == 0 {
            return None;
        }
        self.start.checked_add(self.length - 1)
    }

    /// Whether `[ado, ado + len)` touches its buffer.
    pub fn overlaps(&self, ado: u16, len: usize) -> bool {
        let (s, e) = (
            u32::from(self.start),
            u32::from(self.start) + u32::from(self.length),
        );
        let (a, b) = (u32::from(ado), u32::from(ado) + len as u32);
        self.length > 0 && a < e && b > s
    }

    /// Whether `[ado, ado + len)` contains its last byte (the access completes the buffer).
    pub fn completed_by(&self, ado: u16, len: usize) -> bool {
        self.last().is_some_and(|last| {
            u32::from(ado) <= u32::from(last) && u32::from(last) < u32::from(ado) + len as u32
        })
    }

    /// Bytes of memory it occupies: three buffers in buffered mode (the datasheet: the
    /// memory of buffers 2 and 3 cannot be used otherwise), one in mailbox mode.
    pub fn footprint(&self) -> u32 {
        let n = if self.kind() == Kind::MailboxWrite || self.kind() == Kind::MailboxRead {
            1
        } else {
            3
        };
        n * u32::from(self.length)
    }

    /// The status a buffered SyncManager shows after the buffer it shows now: the next of
    /// the three (0, 1, 2), 0 after none.
    pub const fn next_buffer(status_byte: u8) -> u8 {
        match status_byte & status::BUFFER_MASK {
            0x00 => 0x10,
            0x10 => 0x20,
            _ => 0x00,
        }
    }
}

/// Writes SyncManager `n`'s status register (the ESC's own byte).
pub fn set_status(mem: &mut Memory, n: u16, value: u8) {
    mem.pdi_write(base(n) + 5, &[value]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_control_register_says_what_a_syncmanager_is() {
        let mut mem = Memory::new();
        // SM5 configured as a receive mailbox, SM0 as buffered inputs: the number is not
        // what counts.
        assert!(mem.ecat_write(base(5), &[0x00, 0x18, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00]));
        assert!(mem.ecat_write(base(0), &[0x00, 0x11, 0x06, 0x00, 0x20, 0x00, 0x01, 0x00]));
        let sm5 = SyncManager::read_from(&mem, 5);
        assert_eq!(sm5.kind(), Kind::MailboxWrite);
        assert_eq!(SyncManager::read_from(&mem, 0).kind(), Kind::BufferedRead);
        assert_eq!(sm5.last(), Some(0x187F));
        assert!(sm5.completed_by(0x1870, 16) && !sm5.completed_by(0x1800, 0x7F));
        assert_eq!(sm5.footprint(), 0x80);
        assert_eq!(SyncManager::read_from(&mem, 0).footprint(), 18);
        mem.ecat_write(base(1), &[0, 0x11, 6, 0, 0x64, 0, 1, 0]);
        assert_eq!(SyncManager::read_from(&mem, 1).kind(), Kind::BufferedWrite);
        mem.ecat_write(base(2), &[0, 0x11, 6, 0, 0x0C, 0, 1, 0]);
        assert_eq!(SyncManager::read_from(&mem, 2).kind(), Kind::Reserved);
        let end = SyncManager {
            start: 0xFFFF,
            length: 2,
            control: 0,
            status: 0,
            activate: 1,
            pdi_control: 0,
        };
        assert_eq!(end.last(), None, "past the address space");
    }

    #[test]
    fn buffers_cycle_through_three() {
        assert_eq!(SyncManager::next_buffer(status::NO_BUFFER), 0x00);
        assert_eq!(SyncManager::next_buffer(0x00), 0x10);
        assert_eq!(SyncManager::next_buffer(0x10), 0x20);
        assert_eq!(SyncManager::next_buffer(0x21), 0x00);
    }
}
