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
/// 0x0900 Receive time port 0 (local time, 32 bit); a write latches all receive times.
pub const DC_RECEIVE_TIME_PORT0: u16 = 0x0900;
/// 0x0904 Receive time port 1.
pub const DC_RECEIVE_TIME_PORT1: u16 = 0x0904;
/// 0x0908 Receive time port 2.
pub const DC_RECEIVE_TIME_PORT2: u16 = 0x0908;
/// 0x090C Receive time port 3.
pub const DC_RECEIVE_TIME_PORT3: u16 = 0x090C;
/// 0x0910 System time (read: local copy; write: input of the drift control loop).
pub const DC_SYSTEM_TIME: u16 = 0x0910;
/// 0x0918 Receive time ECAT processing unit (64 bit local time, latched with port 0).
pub const DC_RECEIVE_TIME_EPU: u16 = 0x0918;
/// 0x0920 System time offset.
pub const DC_SYSTEM_TIME_OFFSET: u16 = 0x0920;
/// 0x0928 System time delay.
pub const DC_SYSTEM_TIME_DELAY: u16 = 0x0928;
/// 0x092C System time difference (bit 31: local copy smaller than received; 30:0 magnitude).
pub const DC_SYSTEM_TIME_DIFFERENCE: u16 = 0x092C;
/// 0x0930 Speed counter start (bandwidth of the drift control loop; a write resets it).
pub const DC_SPEED_COUNTER_START: u16 = 0x0930;
/// 0x0932 Speed counter diff.
pub const DC_SPEED_COUNTER_DIFF: u16 = 0x0932;
/// 0x0934 System time difference filter depth.
pub const DC_SYSTEM_TIME_DIFF_FILTER_DEPTH: u16 = 0x0934;
/// 0x0935 Speed counter filter depth.
pub const DC_SPEED_COUNTER_FILTER_DEPTH: u16 = 0x0935;
/// 0x0980 Cyclic unit control.
pub const DC_CYCLIC_UNIT_CONTROL: u16 = 0x0980;
/// 0x0981 Activation (bit 0 cyclic operation, bit 1 SYNC0, bit 2 SYNC1).
pub const DC_ACTIVATION: u16 = 0x0981;
/// 0x0982 Pulse length of SyncSignals (10 ns units; 0: acknowledge mode).
pub const DC_SYNC_PULSE_LENGTH: u16 = 0x0982;
/// 0x0984 Activation status (bit 0: first SYNC0 pulse pending).
pub const DC_ACTIVATION_STATUS: u16 = 0x0984;
/// 0x098E SYNC0 status (acknowledge mode: cleared by reading).
pub const DC_SYNC0_STATUS: u16 = 0x098E;
/// 0x098F SYNC1 status.
pub const DC_SYNC1_STATUS: u16 = 0x098F;
/// 0x0990 Start time cyclic operation (write: start time; read: next SYNC0 pulse).
pub const DC_START_TIME_CYCLIC: u16 = 0x0990;
/// 0x0998 Next SYNC1 pulse.
pub const DC_NEXT_SYNC1_PULSE: u16 = 0x0998;
/// 0x09A0 SYNC0 cycle time (ns).
pub const DC_SYNC0_CYCLE_TIME: u16 = 0x09A0;
/// 0x09A4 SYNC1 cycle time (ns).
pub const DC_SYNC1_CYCLE_TIME: u16 = 0x09A4;
/// 0x09A8 Latch unit (control, status, latch times; not emulated, reads zero).
pub const DC_LATCH: u16 = 0x09A8;
/// First address of the DC block.
pub const DC_FIRST: u16 = DC_RECEIVE_TIME_PORT0;
/// One past the DC block an ESC without DC does not map.
pub const DC_END: u16 = 0x09B0;
/// Start of process RAM.
pub const PROCESS_RAM: u16 = 0x1000;

/// The register table (ET1100-like ESC with 8 FMMUs and 8 SyncManagers).
pub const TABLE: [Register; 53] = [
    reg(TYPE, 1, R, 0x11, "Type"),
    reg(REVISION, 1, R, 0x00, "Revision"),
    reg(BUILD, 2, R, 0x0001, "Build"),
    reg(FMMU_COUNT, 1, R, 8, "FMMUs supported"),
    reg(SM_COUNT, 1, R, 8, "SyncManagers supported"),
    reg(RAM_SIZE, 1, R, 8, "RAM size"),
    reg(PORT_DESCRIPTOR, 1, R, 0x0F, "Port descriptor"),
    // Bit 2: DC supported, bit 3: 64-bit DC, bit 8: enhanced DC SYNC activation. A slave
    // without DC clears them (`Slave::new`).
    reg(FEATURES, 2, R, FEATURES_DC, "ESC features supported"),
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
    reg(DC_RECEIVE_TIME_PORT0, 4, R, 0, "Receive time port 0"),
    reg(DC_RECEIVE_TIME_PORT1, 4, R, 0, "Receive time port 1"),
    reg(DC_RECEIVE_TIME_PORT2, 4, R, 0, "Receive time port 2"),
    reg(DC_RECEIVE_TIME_PORT3, 4, R, 0, "Receive time port 3"),
    reg(DC_SYSTEM_TIME, 8, RW, 0, "System time"),
    reg(
        DC_RECEIVE_TIME_EPU,
        8,
        R,
        0,
        "Receive time ECAT processing unit",
    ),
    reg(DC_SYSTEM_TIME_OFFSET, 8, RW, 0, "System time offset"),
    reg(DC_SYSTEM_TIME_DELAY, 4, RW, 0, "System time delay"),
    reg(DC_SYSTEM_TIME_DIFFERENCE, 4, R, 0, "System time difference"),
    reg(DC_SPEED_COUNTER_START, 2, RW, 0x1000, "Speed counter start"),
    reg(DC_SPEED_COUNTER_DIFF, 2, R, 0, "Speed counter diff"),
    reg(
        DC_SYSTEM_TIME_DIFF_FILTER_DEPTH,
        1,
        RW,
        0x04,
        "System time difference filter depth",
    ),
    reg(
        DC_SPEED_COUNTER_FILTER_DEPTH,
        1,
        RW,
        0x0C,
        "Speed counter filter depth",
    ),
    // Reserved addresses inside the DC block read as zero, so that block reads still work.
    reg(0x0936, 0x4A, R, 0, "Reserved (DC)"),
    reg(DC_CYCLIC_UNIT_CONTROL, 1, RW, 0, "Cyclic unit control"),
    reg(DC_ACTIVATION, 1, RW, 0, "Activation"),
    reg(DC_SYNC_PULSE_LENGTH, 2, R, 0, "Pulse length of SyncSignals"),
    reg(DC_ACTIVATION_STATUS, 1, R, 0, "Activation status"),
    reg(0x0985, 9, R, 0, "Reserved (DC)"),
    reg(DC_SYNC0_STATUS, 1, R, 0, "SYNC0 status"),
    reg(DC_SYNC1_STATUS, 1, R, 0, "SYNC1 status"),
    reg(
        DC_START_TIME_CYCLIC,
        8,
        RW,
        0,
        "Start time cyclic operation",
    ),
    reg(DC_NEXT_SYNC1_PULSE, 8, R, 0, "Next SYNC1 pulse"),
    reg(DC_SYNC0_CYCLE_TIME, 4, RW, 0, "SYNC0 cycle time"),
    reg(DC_SYNC1_CYCLE_TIME, 4, RW, 0, "SYNC1 cycle time"),
    reg(DC_LATCH, 8, R, 0, "Latch unit"),
];

/// SyncManager register bytes that are read-only from the EtherCAT side inside the
/// otherwise writable SyncManager block (ESC datasheet section II, 0x0800+y*8): status
/// (+5) and PDI control (+7), both owned by the ESC and its PDI.
pub const fn sm_byte_read_only(address: u16) -> bool {
    address >= SM0 && address < SM0 + 8 * 8 && matches!((address - SM0) % 8, 5 | 7)
}

/// Feature bits (0x0008) of the DC unit: DC supported, 64-bit system time, enhanced DC
/// SYNC activation.
pub const FEATURES_DC: u64 = 0x010C;

/// Whether `address` is in the DC block (which an ESC without DC leaves unmapped).
pub const fn is_dc(address: u16) -> bool {
    address >= DC_FIRST && address < DC_END
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
        assert_eq!(find(0x0913).map(|r| r.name), Some("System time"));
        assert_eq!(find(0x09AF).map(|r| r.name), Some("Latch unit"));
        assert_eq!(find(DC_END), None);
        // Registers SOEM touches during its scan: PDI control and ESC configuration as
        // one 16-bit read, and the ECAT event mask it clears.
        assert_eq!(find(0x0141).map(|r| r.name), Some("ESC configuration"));
        assert_eq!(find(0x0201).map(|r| r.name), Some("ECAT event mask"));
        assert!(sm_byte_read_only(0x080D) && sm_byte_read_only(0x080F));
        assert!(!sm_byte_read_only(0x080E) && !sm_byte_read_only(0x0840));
    }
}
