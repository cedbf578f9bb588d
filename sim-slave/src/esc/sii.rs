//! The SII EEPROM (ETG.1000.6 §5.4, ETG.2010): an image generated from a device
//! description, and the EEPROM interface registers 0x0500–0x050F through which the master
//! reads it.
//!
//! Image layout (in 16-bit words): 0x00–0x07 ESC configuration area (PDI control, PDI
//! configuration, sync impulse length, configured station alias, checksum at 0x07),
//! 0x08 vendor id, 0x0A product code, 0x0C revision, 0x0E serial number, 0x18/0x1A
//! standard receive/send mailbox offset and size, 0x1C mailbox protocols, 0x3E EEPROM size,
//! 0x3F version; categories from 0x40: type, size in words, data; 0xFFFF ends the list.

use super::memory::Memory;
use super::registers::{DC_SYNC_PULSE_LENGTH, PDI_CONTROL, SII, STATION_ALIAS};

/// Words of the ESC configuration area (ETG.2010 Table 2), which the ESC loads into its
/// registers after reset and on a reload command.
pub mod config_area {
    /// Word 0: PDI control (low byte, to 0x0140) and ESC configuration (high byte, 0x0141).
    pub const PDI_CONTROL: usize = 0;
    /// Word 1: PDI configuration (0x0150).
    pub const PDI_CONFIGURATION: usize = 1;
    /// Word 2: pulse length of SYNC signals (0x0982, 10 ns units).
    pub const SYNC_IMPULSE_LENGTH: usize = 2;
    /// Word 3: extended PDI configuration (0x0152).
    pub const EXTENDED_PDI_CONFIGURATION: usize = 3;
    /// Word 4: configured station alias (0x0012).
    pub const STATION_ALIAS: usize = 4;
    /// Word 7: checksum (low byte) over words 0–6.
    pub const CHECKSUM: usize = 7;
    /// Words in the area.
    pub const WORDS: usize = 8;
}

/// PDI control a device with a microcontroller behind the ESC has (0x05: SPI slave).
pub const PDI_SPI: u16 = 0x0005;
/// PDI control of a simple I/O terminal (0x04: digital I/O) with ESC configuration bit 0,
/// device emulation, set (0x0141 bit 0: the ESC itself copies AL control to AL status).
pub const PDI_DIGITAL_IO_DEVICE_EMULATION: u16 = 0x0104;

/// How long one EEPROM access keeps the interface busy (chain time, ns). A read is about
/// 110 I²C clock cycles (ESC datasheet section I, 11.3.3.2, Table 45: control byte, word
/// address, repeated start, 8 data bytes, each with its acknowledge) at the few hundred
/// kHz of the ESC's EEPROM clock (11.3.4 gives the read access time).
pub const READ_NS: u64 = 250_000;
/// How long a reload of the configuration area (8 words) keeps it busy.
pub const RELOAD_NS: u64 = 500_000;

/// Category types used here (ETG.2010 Table 3).
pub mod category {
    /// Strings.
    pub const STRINGS: u16 = 10;
    /// General.
    pub const GENERAL: u16 = 30;
    /// FMMU usage.
    pub const FMMU: u16 = 40;
    /// SyncManagers.
    pub const SYNC_MANAGER: u16 = 41;
    /// TxPDO (inputs).
    pub const TXPDO: u16 = 50;
    /// RxPDO (outputs).
    pub const RXPDO: u16 = 51;
    /// Distributed clocks.
    pub const DC: u16 = 60;
    /// End of the list.
    pub const END: u16 = 0xFFFF;
}

/// A SyncManager as the EEPROM describes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SmDescription {
    /// Physical start address.
    pub start: u16,
    /// Default length.
    pub length: u16,
    /// Control register value.
    pub control: u8,
    /// Enable (bit 0) of the activate register.
    pub enable: bool,
    /// Type: 1 mailbox out, 2 mailbox in, 3 process data out, 4 process data in.
    pub kind: u8,
}

/// One mapped object of a PDO.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PdoEntry {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Length in bits.
    pub bits: u8,
}

/// A PDO as the EEPROM describes it (fixed mapping, for slaves without CoE).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoDescription {
    /// PDO index (0x1600… outputs, 0x1A00… inputs).
    pub index: u16,
    /// SyncManager it is assigned to.
    pub sync_manager: u8,
    /// Mapped objects.
    pub entries: Vec<PdoEntry>,
}

/// The bytes of a TxPDO/RxPDO category (ETG.2010 Table 14).
fn pdo_category(pdos: &[PdoDescription]) -> Vec<u8> {
    let mut out = Vec::new();
    for p in pdos {
        out.extend(p.index.to_le_bytes());
        out.push(p.entries.len().min(255) as u8);
        out.push(p.sync_manager);
        out.extend([0, 0, 0, 0]); // synchronization, name index, flags
        for e in &p.entries {
            out.extend(e.index.to_le_bytes());
            out.push(e.sub);
            out.push(0); // name index
            out.push(0); // data type (not needed by masters that sum bit lengths)
            out.push(e.bits);
            out.extend([0, 0]); // flags
        }
    }
    out
}

/// What a slave says about itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceDescription {
    /// Vendor id.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
    /// Order code, the short name masters show (ETG.2010 General "OrderIdx"; string 1).
    pub order_code: String,
    /// Device name, the long description (General "NameIdx"; string 2).
    pub name: String,
    /// Mailbox (receive offset, receive size, send offset, send size), if any.
    pub mailbox: Option<(u16, u16, u16, u16)>,
    /// Mailbox protocols (bit 2: CoE).
    pub mailbox_protocols: u16,
    /// SyncManagers.
    pub sync_managers: Vec<SmDescription>,
    /// FMMU usage per FMMU (1 outputs, 2 inputs, 3 mailbox state).
    pub fmmus: Vec<u8>,
    /// Whether the device has distributed clocks.
    pub dc: bool,
    /// Fixed TxPDOs (inputs), for slaves without CoE.
    pub tx_pdos: Vec<PdoDescription>,
    /// Fixed RxPDOs (outputs), for slaves without CoE.
    pub rx_pdos: Vec<PdoDescription>,
}

/// Sets word `at` (the image is sized before it is filled).
fn set(words: &mut [u16], at: usize, v: u16) {
    if let Some(x) = words.get_mut(at) {
        *x = v;
    }
}

/// Sets byte `at`.
fn set8(bytes: &mut [u8], at: usize, v: u8) {
    if let Some(x) = bytes.get_mut(at) {
        *x = v;
    }
}

/// Writes one category into `words`.
fn push_category(words: &mut Vec<u16>, kind: u16, data: &[u8]) {
    let mut bytes = data.to_vec();
    if bytes.len() % 2 == 1 {
        bytes.push(0);
    }
    words.push(kind);
    words.push((bytes.len() / 2) as u16);
    words.extend(bytes.chunks(2).map(|c| {
        u16::from_le_bytes([
            c.first().copied().unwrap_or(0),
            c.get(1).copied().unwrap_or(0),
        ])
    }));
}

/// CRC-8 of the configuration area (polynomial 0x07, initial 0xFF), as ETG.2010 §2.2.
pub fn config_checksum(words: &[u16]) -> u8 {
    let mut crc: u8 = 0xFF;
    for w in words.iter().take(7) {
        for b in w.to_le_bytes() {
            crc ^= b;
            for _ in 0..8 {
                crc = if crc & 0x80 != 0 {
                    (crc << 1) ^ 0x07
                } else {
                    crc << 1
                };
            }
        }
    }
    crc
}

impl DeviceDescription {
    /// The EEPROM image (words).
    pub fn image(&self) -> Vec<u16> {
        let mut w = vec![0u16; 0x40];
        // The configuration area: what the ESC loads at reset (PDI control, alias…).
        set(&mut w, config_area::PDI_CONTROL, PDI_SPI);
        let cks = config_checksum(&w);
        set(&mut w, config_area::CHECKSUM, u16::from(cks));
        let put32 = |w: &mut Vec<u16>, at: usize, v: u32| {
            set(w, at, v as u16);
            set(w, at + 1, (v >> 16) as u16);
        };
        put32(&mut w, 0x08, self.vendor_id);
        put32(&mut w, 0x0A, self.product_code);
        put32(&mut w, 0x0C, self.revision);
        put32(&mut w, 0x0E, self.serial);
        if let Some((ro, rs, so, ss)) = self.mailbox {
            set(&mut w, 0x18, ro);
            set(&mut w, 0x19, rs);
            set(&mut w, 0x1A, so);
            set(&mut w, 0x1B, ss);
        }
        set(&mut w, 0x1C, self.mailbox_protocols);
        // EEPROM size in KiBit minus one: 16 KiBit.
        set(&mut w, 0x3E, 0x000F);
        set(&mut w, 0x3F, 0x0001);
        // Strings: count, then length-prefixed strings (1: order code, 2: name).
        let mut strings = vec![2u8];
        for text in [&self.order_code, &self.name] {
            strings.push(text.len().min(255) as u8);
            strings.extend(text.bytes().take(255));
        }
        push_category(&mut w, category::STRINGS, &strings);
        // General: group idx, image idx, order idx, name idx (1), physical layer, CoE details…
        let mut general = vec![0u8; 32];
        set8(&mut general, 2, 1); // order code string index
        set8(&mut general, 3, 2); // name string index
        set8(
            &mut general,
            5,
            if self.mailbox_protocols & 0x04 != 0 {
                0x01
            } else {
                0
            },
        ); // CoE: SDO
        push_category(&mut w, category::GENERAL, &general);
        if !self.fmmus.is_empty() {
            push_category(&mut w, category::FMMU, &self.fmmus);
        }
        let mut sms = Vec::new();
        for sm in &self.sync_managers {
            sms.extend(sm.start.to_le_bytes());
            sms.extend(sm.length.to_le_bytes());
            sms.push(sm.control);
            sms.push(0); // status
            sms.push(u8::from(sm.enable));
            sms.push(sm.kind);
        }
        if !sms.is_empty() {
            push_category(&mut w, category::SYNC_MANAGER, &sms);
        }
        if !self.tx_pdos.is_empty() {
            push_category(&mut w, category::TXPDO, &pdo_category(&self.tx_pdos));
        }
        if !self.rx_pdos.is_empty() {
            push_category(&mut w, category::RXPDO, &pdo_category(&self.rx_pdos));
        }
        if self.dc {
            push_category(&mut w, category::DC, &[0u8; 24]);
        }
        w.push(category::END);
        w.push(0);
        w
    }
}

/// Register offsets inside the SII block.
mod reg {
    pub const CONTROL: u16 = 0x0502;
    pub const ADDRESS: u16 = 0x0504;
    pub const DATA: u16 = 0x0508;
}

/// Control/status bits of 0x0502.
pub mod control {
    /// Read 8 bytes per read command (64-bit read support).
    pub const READ_8_BYTES: u16 = 1 << 6;
    /// Read command.
    pub const READ: u16 = 1 << 8;
    /// Write command.
    pub const WRITE: u16 = 1 << 9;
    /// Reload command.
    pub const RELOAD: u16 = 1 << 10;
    /// Checksum error in the ESC configuration area (it was not loaded).
    pub const CHECKSUM_ERROR: u16 = 1 << 11;
    /// EEPROM loading status: 1 = not loaded (device information not available).
    pub const NOT_LOADED: u16 = 1 << 12;
    /// Error: command error (unknown or several commands at once).
    pub const COMMAND_ERROR: u16 = 1 << 13;
    /// Busy.
    pub const BUSY: u16 = 1 << 15;
}

/// An access the interface is busy with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Pending {
    /// Reading 4 words from this word address.
    Read(usize),
    /// Reloading the configuration area.
    Reload,
}

/// The EEPROM and its interface state.
#[derive(Clone, Debug)]
pub struct Sii {
    words: Vec<u16>,
    /// The access in progress and when (chain time, ns) it completes.
    busy: Option<(Pending, u64)>,
    /// The read-only bits of 0x0502 the interface keeps whatever the master writes:
    /// the 8-byte read capability and the load status of the configuration area.
    status: u16,
}

impl Sii {
    /// An EEPROM holding `words`.
    pub fn new(words: Vec<u16>) -> Self {
        Self {
            words,
            busy: None,
            status: control::READ_8_BYTES,
        }
    }

    /// The word at `addr` (0xFFFF past the end, as an erased EEPROM reads).
    pub fn word(&self, addr: usize) -> u16 {
        self.words.get(addr).copied().unwrap_or(0xFFFF)
    }

    /// Sets word `addr` and, when it lies in the configuration area, its checksum (as a
    /// programming tool does); the ESC sees it at the next reset or reload.
    pub fn program(&mut self, addr: usize, value: u16) {
        if let Some(w) = self.words.get_mut(addr) {
            *w = value;
        }
        if addr < config_area::CHECKSUM {
            let crc = config_checksum(&self.words);
            let keep = self.word(config_area::CHECKSUM) & 0xFF00;
            if let Some(w) = self.words.get_mut(config_area::CHECKSUM) {
                *w = keep | u16::from(crc);
            }
        }
    }

    /// Power-up: the interface is idle and the ESC loads its configuration area (ESC
    /// datasheet section I, 11.2: PDI control, PDI configuration, SYNC pulse length and
    /// station alias) when its checksum is right; otherwise it sets the checksum-error
    /// and not-loaded bits and leaves the registers at their reset values. Returns whether
    /// it loaded (DL status bit 0, "PDI operational / EEPROM loaded", follows).
    pub fn reset(&mut self, mem: &mut Memory) -> bool {
        self.busy = None;
        self.load(mem)
    }

    fn load(&mut self, mem: &mut Memory) -> bool {
        let area: Vec<u16> = (0..config_area::WORDS).map(|i| self.word(i)).collect();
        let ok = self.word(config_area::CHECKSUM) as u8 == config_checksum(&area);
        let mut status = control::READ_8_BYTES;
        if ok {
            let pdi = self.word(config_area::PDI_CONTROL);
            mem.pdi_write(PDI_CONTROL, &pdi.to_le_bytes());
            let pulse = self.word(config_area::SYNC_IMPULSE_LENGTH);
            mem.pdi_write(DC_SYNC_PULSE_LENGTH, &pulse.to_le_bytes());
            let alias = self.word(config_area::STATION_ALIAS);
            mem.pdi_write(STATION_ALIAS, &alias.to_le_bytes());
        } else {
            status |= control::CHECKSUM_ERROR | control::NOT_LOADED;
        }
        self.status = status;
        mem.pdi_write(reg::CONTROL, &status.to_le_bytes());
        ok
    }

    /// Whether an access is in progress.
    pub fn busy(&self) -> bool {
        self.busy.is_some()
    }

    /// Acts on a master's write to the control register at chain time `now` (a command
    /// in bits 8–10). A read starts an access that keeps the busy bit set for
    /// [`READ_NS`]; the data register gets the 4 words when it completes
    /// ([`Sii::advance`]). A reload re-reads the configuration area. While busy, a new
    /// command is ignored (the register keeps its busy status). Writes are refused with
    /// the command-error bit, as a write-protected EEPROM does.
    pub fn on_control_write(&mut self, mem: &mut Memory, now: u64) {
        let ctrl = mem.read_u16(reg::CONTROL);
        let kept = self.status;
        if self.busy.is_some() {
            mem.pdi_write(reg::CONTROL, &(kept | control::BUSY).to_le_bytes());
            return;
        }
        let cmd = ctrl & (control::READ | control::WRITE | control::RELOAD);
        let mut status = kept;
        match cmd {
            0 => {}
            control::READ => {
                let addr = mem.read_u32(reg::ADDRESS) as usize;
                self.busy = Some((Pending::Read(addr), now.saturating_add(READ_NS)));
                status |= control::READ | control::BUSY;
            }
            control::RELOAD => {
                self.busy = Some((Pending::Reload, now.saturating_add(RELOAD_NS)));
                status |= control::RELOAD | control::BUSY;
            }
            _ => status |= control::COMMAND_ERROR,
        }
        mem.pdi_write(reg::CONTROL, &status.to_le_bytes());
    }

    /// The chain's time is `now`: an access due by then completes (data in 0x0508, busy
    /// and command bits cleared). Returns whether a reload completed and what it loaded
    /// (DL status follows).
    pub fn advance(&mut self, mem: &mut Memory, now: u64) -> Option<bool> {
        let (pending, due) = self.busy?;
        if now < due {
            return None;
        }
        self.busy = None;
        match pending {
            Pending::Read(addr) => {
                let mut data = [0u8; 8];
                for (i, chunk) in data.chunks_mut(2).enumerate() {
                    chunk.copy_from_slice(&self.word(addr.saturating_add(i)).to_le_bytes());
                }
                mem.pdi_write(reg::DATA, &data);
                mem.pdi_write(reg::CONTROL, &self.status.to_le_bytes());
                None
            }
            Pending::Reload => Some(self.load(mem)),
        }
    }
}

/// Whether an ECAT write touched the SII control register.
pub fn touches_control(address: u16, len: usize) -> bool {
    let end = address as usize + len;
    (address as usize) <= reg::CONTROL as usize + 1 && end > reg::CONTROL as usize && address >= SII
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive() -> DeviceDescription {
        DeviceDescription {
            vendor_id: 0x0000_0A5A,
            product_code: 0x0000_0402,
            revision: 1,
            serial: 42,
            order_code: "GS-402".into(),
            name: "gantry servo".into(),
            mailbox: Some((0x1000, 128, 0x1080, 128)),
            mailbox_protocols: 0x0004,
            sync_managers: vec![
                SmDescription {
                    start: 0x1000,
                    length: 128,
                    control: 0x26,
                    enable: true,
                    kind: 1,
                },
                SmDescription {
                    start: 0x1080,
                    length: 128,
                    control: 0x22,
                    enable: true,
                    kind: 2,
                },
                SmDescription {
                    start: 0x1100,
                    length: 0,
                    control: 0x64,
                    enable: true,
                    kind: 3,
                },
                SmDescription {
                    start: 0x1400,
                    length: 0,
                    control: 0x20,
                    enable: true,
                    kind: 4,
                },
            ],
            fmmus: vec![1, 2, 3],
            dc: true,
            tx_pdos: vec![],
            rx_pdos: vec![PdoDescription {
                index: 0x1600,
                sync_manager: 2,
                entries: vec![PdoEntry {
                    index: 0x6040,
                    sub: 0,
                    bits: 16,
                }],
            }],
        }
    }

    /// Finds a category's data in an image.
    fn find(words: &[u16], kind: u16) -> Option<&[u16]> {
        let mut at = 0x40;
        while at + 1 < words.len() {
            let (k, n) = (words[at], words[at + 1] as usize);
            if k == category::END {
                return None;
            }
            if k == kind {
                return words.get(at + 2..at + 2 + n);
            }
            at += 2 + n;
        }
        None
    }

    #[test]
    fn image_carries_identity_mailbox_and_categories() {
        let w = drive().image();
        assert_eq!(u32::from(w[0x08]) | u32::from(w[0x09]) << 16, 0x0A5A);
        assert_eq!(u32::from(w[0x0A]) | u32::from(w[0x0B]) << 16, 0x0402);
        assert_eq!(w[0x18..0x1C], [0x1000, 128, 0x1080, 128]);
        assert_eq!(w[0x07] as u8, config_checksum(&w));
        let strings = find(&w, category::STRINGS).unwrap();
        let bytes: Vec<u8> = strings.iter().flat_map(|x| x.to_le_bytes()).collect();
        assert_eq!(bytes[0], 2);
        assert_eq!(&bytes[2..2 + bytes[1] as usize], b"GS-402");
        let at = 2 + bytes[1] as usize;
        assert_eq!(&bytes[at + 1..at + 1 + bytes[at] as usize], b"gantry servo");
        let sm = find(&w, category::SYNC_MANAGER).unwrap();
        assert_eq!(sm.len(), 4 * 4, "4 SyncManagers of 8 bytes");
        assert_eq!(sm[0], 0x1000);
        assert!(find(&w, category::DC).is_some());
        assert!(find(&w, category::FMMU).is_some());
        assert!(find(&w, category::TXPDO).is_none());
        let rx = find(&w, category::RXPDO).unwrap();
        assert_eq!(rx.len(), 8, "one PDO header and one entry, 8 bytes each");
        assert_eq!(rx[0], 0x1600);
        assert_eq!(rx[4], 0x6040);
        assert_eq!(rx[6] >> 8, 16, "bit length");
    }

    /// 0x0502 as the master reads it (2 bytes, little-endian).
    fn control_bytes(mem: &Memory) -> [u8; 2] {
        let mut b = [0u8; 2];
        assert!(mem.ecat_read(reg::CONTROL, &mut b, false));
        b
    }

    #[test]
    fn reads_through_the_interface_return_four_words() {
        let mut sii = Sii::new(drive().image());
        let mut mem = Memory::new();
        assert!(sii.reset(&mut mem));
        assert_eq!(
            mem.read_u16(reg::CONTROL) & control::READ_8_BYTES,
            control::READ_8_BYTES
        );
        assert!(mem.ecat_write(reg::ADDRESS, &0x08u32.to_le_bytes()));
        assert!(mem.ecat_write(reg::CONTROL, &control::READ.to_le_bytes()));
        assert!(touches_control(reg::CONTROL, 2));
        sii.on_control_write(&mut mem, 1_000);
        sii.advance(&mut mem, 1_000 + READ_NS);
        let mut data = [0u8; 8];
        assert!(mem.ecat_read(reg::DATA, &mut data, false));
        assert_eq!(u32::from_le_bytes(data[0..4].try_into().unwrap()), 0x0A5A);
        assert_eq!(u32::from_le_bytes(data[4..8].try_into().unwrap()), 0x0402);
        assert_eq!(mem.read_u16(reg::CONTROL) & control::BUSY, 0);
        // Past the end an erased EEPROM reads 0xFFFF.
        assert_eq!(sii.word(100_000), 0xFFFF);
    }

    #[test]
    fn a_read_keeps_the_interface_busy_until_the_data_is_there() {
        let mut sii = Sii::new(drive().image());
        let mut mem = Memory::new();
        sii.reset(&mut mem);
        mem.ecat_write(reg::DATA, &[0xEE; 8]);
        mem.ecat_write(reg::ADDRESS, &0x08u32.to_le_bytes());
        mem.ecat_write(reg::CONTROL, &control::READ.to_le_bytes());
        sii.on_control_write(&mut mem, 5_000);
        // Busy (bit 15) with the read command (bit 8) and the 8-byte capability (bit 6).
        assert_eq!(control_bytes(&mem), [0x40, 0x81]);
        sii.advance(&mut mem, 5_000 + READ_NS - 1);
        assert_eq!(control_bytes(&mem), [0x40, 0x81], "still busy 1 ns before");
        let mut data = [0u8; 8];
        mem.ecat_read(reg::DATA, &mut data, false);
        assert_ne!(&data[0..2], &[0x5A, 0x0A], "no data while busy");
        // A second command while busy is ignored.
        mem.ecat_write(reg::ADDRESS, &0x0Au32.to_le_bytes());
        mem.ecat_write(reg::CONTROL, &control::READ.to_le_bytes());
        sii.on_control_write(&mut mem, 5_100);
        sii.advance(&mut mem, 5_000 + READ_NS);
        assert_eq!(control_bytes(&mem), [0x40, 0x00], "idle");
        mem.ecat_read(reg::DATA, &mut data, false);
        assert_eq!(
            &data[0..2],
            &[0x5A, 0x0A],
            "word 8 (vendor id), not word 10"
        );
    }

    #[test]
    fn reset_loads_alias_and_pdi_control_from_the_configuration_area() {
        use crate::esc::registers::{ESC_CONFIG, PDI_CONTROL, STATION_ALIAS};
        let mut sii = Sii::new(drive().image());
        sii.program(config_area::STATION_ALIAS, 0x1234);
        sii.program(config_area::PDI_CONTROL, PDI_DIGITAL_IO_DEVICE_EMULATION);
        let mut mem = Memory::new();
        assert!(sii.reset(&mut mem));
        let mut b = [0u8; 2];
        mem.ecat_read(STATION_ALIAS, &mut b, false);
        assert_eq!(b, [0x34, 0x12]);
        mem.ecat_read(PDI_CONTROL, &mut b, false);
        assert_eq!(b, [0x04, 0x01], "PDI digital I/O, device emulation");
        assert_eq!(mem.raw(ESC_CONFIG, 1), Some(&[0x01][..]));
        assert_eq!(control_bytes(&mem), [0x40, 0x00], "loaded, no error");
        // A corrupt checksum: nothing loaded, error and not-loaded bits (11, 12) set.
        let mut words = drive().image();
        words[config_area::STATION_ALIAS] = 0x0042;
        let mut bad = Sii::new(words);
        let mut mem = Memory::new();
        assert!(!bad.reset(&mut mem));
        assert_eq!(mem.read_u16(STATION_ALIAS), 0);
        assert_eq!(control_bytes(&mem), [0x40, 0x18]);
        // A reload (after the tool fixed the checksum) loads it, after being busy.
        bad.program(config_area::STATION_ALIAS, 0x0042);
        mem.ecat_write(reg::CONTROL, &control::RELOAD.to_le_bytes());
        bad.on_control_write(&mut mem, 0);
        assert_eq!(control_bytes(&mem), [0x40, 0x9C]);
        assert_eq!(bad.advance(&mut mem, RELOAD_NS), Some(true));
        assert_eq!(mem.read_u16(STATION_ALIAS), 0x0042);
        assert_eq!(control_bytes(&mem), [0x40, 0x00]);
    }

    #[test]
    fn write_commands_are_refused_with_the_error_bit() {
        let mut sii = Sii::new(drive().image());
        let mut mem = Memory::new();
        mem.ecat_write(reg::CONTROL, &control::WRITE.to_le_bytes());
        sii.on_control_write(&mut mem, 0);
        assert_ne!(mem.read_u16(reg::CONTROL) & control::COMMAND_ERROR, 0);
        assert!(!touches_control(0x0508, 8));
    }
}
