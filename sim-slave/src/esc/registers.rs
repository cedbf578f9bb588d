//! ESC registers (ETG.1000.4 Table 31 and the ESC datasheets' register maps): one table of
//! address, width, ECAT access and reset value. Registers not in the table read as zero
//! and ignore writes, as unused addresses of a real ESC do.

/// Access from the EtherCAT side.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Read only (written by the ESC or its PDI side).
    Read,
    /// Read and write.
    ReadWrite,
}

/// One register (or register block).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Register {
    /// Address.
    pub address: u16,
    /// Width in bytes.
    pub width: u16,
    /// ECAT access.
    pub access: Access,
    /// Reset value (little-endian, up to 8 bytes).
    pub reset: u64,
    /// Datasheet name.
    pub name: &'static str,
}

const fn reg(address: u16, width: u16, access: Access, reset: u64, name: &'static str) -> Register {
    Register {
        address,
        width,
        access,
        reset,
        name,
    }
}

use Access::{Read as R, ReadWrite as RW};

/// 0x0000 Type.
pub const TYPE: u16 = 0x0000;
/// 0x0001 Revision.
pub const REVISION: u16 = 0x0001;
/// 0x0002 Build.
pub const BUILD: u16 = 0x0002;
/// 0x0004 FMMUs supported.
pub const FMMU_COUNT: u16 = 0x0004;
/// 0x0005 SyncManagers supported.
pub const SM_COUNT: u16 = 0x0005;
/// 0x0006 RAM size (KiB).
pub const RAM_SIZE: u16 = 0x0006;
/// 0x0007 Port descriptor.
pub const PORT_DESCRIPTOR: u16 = 0x0007;
/// 0x0008 ESC features supported.
pub const FEATURES: u16 = 0x0008;
/// 0x0010 Configured station address.
pub const STATION_ADDRESS: u16 = 0x0010;
/// 0x0012 Configured station alias.
pub const STATION_ALIAS: u16 = 0x0012;
/// 0x0100 DL control.
pub const DL_CONTROL: u16 = 0x0100;
/// 0x0110 DL status.
pub const DL_STATUS: u16 = 0x0110;
/// 0x0120 AL control.
pub const AL_CONTROL: u16 = 0x0120;
/// 0x0130 AL status.
pub const AL_STATUS: u16 = 0x0130;
/// 0x0134 AL status code.
pub const AL_STATUS_CODE: u16 = 0x0134;
/// 0x0140 PDI control.
pub const PDI_CONTROL: u16 = 0x0140;
/// 0x0141 ESC configuration (loaded from the EEPROM's configuration area).
pub const ESC_CONFIG: u16 = 0x0141;
/// 0x0200 ECAT event mask.
pub const ECAT_EVENT_MASK: u16 = 0x0200;
/// 0x0300 RX error counters (4 ports × 2 bytes).
pub const RX_ERROR_COUNTER: u16 = 0x0300;
/// 0x0400 Watchdog divider.
pub const WATCHDOG_DIVIDER: u16 = 0x0400;
/// 0x0410 Watchdog time PDI.
pub const WATCHDOG_TIME_PDI: u16 = 0x0410;
/// 0x0420 Watchdog time process data.
pub const WATCHDOG_TIME_PD: u16 = 0x0420;
/// 0x0440 Watchdog status process data (bit 0: 1 = running or off, 0 = expired).
pub const WATCHDOG_STATUS_PD: u16 = 0x0440;
/// 0x0442 Watchdog counter process data (expirations; cleared by a write).
pub const WATCHDOG_COUNTER_PD: u16 = 0x0442;
/// 0x0500 SII EEPROM configuration/control/address/data block.
pub const SII: u16 = 0x0500;
/// 0x0600 FMMU 0 (16 bytes each).
pub const FMMU0: u16 = 0x0600;
/// 0x0800 SyncManager 0 (8 bytes each).
pub const SM0: u16 = 0x0800;
/// 0x0900 DC receive times and system time block.
pub const DC: u16 = 0x0900;
/// Start of process RAM.
pub const PROCESS_RAM: u16 = 0x1000;

/// The register table (ET1100-like ESC with 8 FMMUs and 8 SyncManagers).
pub const TABLE: [Register; 28] = [
    reg(TYPE, 1, R, 0x11, "Type"),
    reg(REVISION, 1, R, 0x00, "Revision"),
    reg(BUILD, 2, R, 0x0001, "Build"),
    reg(FMMU_COUNT, 1, R, 8, "FMMUs supported"),
    reg(SM_COUNT, 1, R, 8, "SyncManagers supported"),
    reg(RAM_SIZE, 1, R, 8, "RAM size"),
    reg(PORT_DESCRIPTOR, 1, R, 0x0F, "Port descriptor"),
    // Bit 2: DC available, bit 3: 64-bit DC. No distributed clocks are emulated yet (the
    // 0x0900 block is plain memory, its system time does not run), so the ESC says so:
    // a master that believed it (SOEM's config_dc did) configures a clock that never ticks.
    // Bits 9/10 = 0: LRW and the read-write commands are supported.
    reg(FEATURES, 2, R, 0x0000, "ESC features supported"),
    reg(STATION_ADDRESS, 2, RW, 0, "Configured station address"),
    reg(STATION_ALIAS, 2, RW, 0, "Configured station alias"),
    reg(DL_CONTROL, 4, RW, 0x0000_0001, "DL control"),
    reg(DL_STATUS, 2, R, 0x0000, "DL status"),
    reg(AL_CONTROL, 2, RW, 0x0001, "AL control"),
    reg(AL_STATUS, 2, R, 0x0001, "AL status"),
    reg(AL_STATUS_CODE, 2, R, 0, "AL status code"),
    reg(PDI_CONTROL, 1, R, 0x05, "PDI control"),
    reg(ESC_CONFIG, 1, R, 0x00, "ESC configuration"),
    reg(ECAT_EVENT_MASK, 2, RW, 0, "ECAT event mask"),
    reg(RX_ERROR_COUNTER, 8, RW, 0, "RX error counter"),
    reg(WATCHDOG_DIVIDER, 2, RW, 0x09C2, "Watchdog divider"),
    reg(WATCHDOG_TIME_PDI, 2, RW, 0x03E8, "Watchdog time PDI"),
    reg(
        WATCHDOG_TIME_PD,
        2,
        RW,
        0x03E8,
        "Watchdog time process data",
    ),
    reg(
        WATCHDOG_STATUS_PD,
        2,
        R,
        0x0001,
        "Watchdog status process data",
    ),
    reg(
        WATCHDOG_COUNTER_PD,
        1,
        RW,
        0,
        "Watchdog counter process data",
    ),
    reg(SII, 16, RW, 0, "SII EEPROM interface"),
    reg(FMMU0, 8 * 16, RW, 0, "FMMUs"),
    reg(SM0, 8 * 8, RW, 0, "SyncManagers"),
    reg(DC, 0xB0, RW, 0, "Distributed clocks"),
];

/// SyncManager register bytes that are read-only from the EtherCAT side inside the
/// otherwise writable SyncManager block (ESC datasheet section II, 0x0800+y*8): status
/// (+5) and PDI control (+7), both owned by the ESC and its PDI.
pub const fn sm_byte_read_only(address: u16) -> bool {
    address >= SM0 && address < SM0 + 8 * 8 && matches!((address - SM0) % 8, 5 | 7)
}

/// The register containing `address`, if any.
pub fn find(address: u16) -> Option<&'static Register> {
    TABLE
        .iter()
        .find(|r| address >= r.address && (address as u32) < r.address as u32 + r.width as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registers_do_not_overlap_and_are_sorted() {
        for w in TABLE.windows(2) {
            assert!(
                w[0].address as u32 + w[0].width as u32 <= w[1].address as u32,
                "{} overlaps {}",
                w[0].name,
                w[1].name
            );
        }
    }

    #[test]
    fn find_covers_blocks() {
        assert_eq!(find(0x0131).map(|r| r.name), Some("AL status"));
        assert_eq!(find(0x0805).map(|r| r.name), Some("SyncManagers"));
        assert_eq!(find(0x0003).map(|r| r.name), Some("Build"));
        assert_eq!(find(0x0050), None);
        // Registers SOEM touches during its scan: PDI control and ESC configuration as
        // one 16-bit read, and the ECAT event mask it clears.
        assert_eq!(find(0x0141).map(|r| r.name), Some("ESC configuration"));
        assert_eq!(find(0x0201).map(|r| r.name), Some("ECAT event mask"));
        assert!(sm_byte_read_only(0x080D) && sm_byte_read_only(0x080F));
        let features = find(FEATURES).map_or(0xFFFF, |r| r.reset);
        assert_eq!(
            features & 0b1100,
            0,
            "no DC is advertised while none is emulated"
        );
        assert!(!sm_byte_read_only(0x080E) && !sm_byte_read_only(0x0840));
    }
}
