//! `[FileInfo]`, `[DeviceInfo]` and a DCF's `[DeviceComissioning]` (CiA 306-1 §4.3,
//! §4.4, §5.2.1).

/// The bit rates an EDS can declare (`BaudRate_10` … `BaudRate_1000`, kbit/s; CiA 301
/// §7.2.1 Table 1 less the 800 kbit/s that CiA 301 dropped and EDS files still list).
pub const BAUD_RATES_KBIT: [u16; 8] = [10, 20, 50, 125, 250, 500, 800, 1000];

/// `[FileInfo]`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FileInfo {
    /// `FileName=`.
    pub file_name: String,
    /// `FileVersion=` (UNSIGNED8).
    pub file_version: u8,
    /// `FileRevision=` (UNSIGNED8).
    pub file_revision: u8,
    /// `EDSVersion=` (e.g. "4.0").
    pub eds_version: String,
    /// `Description=`.
    pub description: String,
    /// `CreationTime=` (hh:mm(AM|PM)).
    pub creation_time: String,
    /// `CreationDate=` (mm-dd-yyyy).
    pub creation_date: String,
    /// `CreatedBy=`.
    pub created_by: String,
    /// `ModificationTime=`.
    pub modification_time: String,
    /// `ModificationDate=`.
    pub modification_date: String,
    /// `ModifiedBy=`.
    pub modified_by: String,
}

/// `[DeviceInfo]`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DeviceInfo {
    /// `VendorName=`.
    pub vendor_name: String,
    /// `VendorNumber=` (0x1018:01).
    pub vendor_number: Option<u32>,
    /// `ProductName=`.
    pub product_name: String,
    /// `ProductNumber=` (0x1018:02).
    pub product_number: Option<u32>,
    /// `RevisionNumber=` (0x1018:03).
    pub revision_number: Option<u32>,
    /// `OrderCode=`.
    pub order_code: String,
    /// `BaudRate_N=1` for each N of [`BAUD_RATES_KBIT`] supported, in that order.
    pub baud_rates: [bool; 8],
    /// `SimpleBootUpMaster=`.
    pub simple_boot_up_master: bool,
    /// `SimpleBootUpSlave=`.
    pub simple_boot_up_slave: bool,
    /// `Granularity=`: the mapping granularity in bits (0: no PDO mapping can be
    /// changed; 8: whole bytes; 1: single bits).
    pub granularity: u8,
    /// `DynamicChannelsSupported=`.
    pub dynamic_channels_supported: u8,
    /// `GroupMessaging=`.
    pub group_messaging: bool,
    /// `NrOfRXPDO=`: receive PDOs the device supports.
    pub nr_of_rx_pdo: u16,
    /// `NrOfTXPDO=`: transmit PDOs.
    pub nr_of_tx_pdo: u16,
    /// `LSS_Supported=`.
    pub lss_supported: bool,
}

impl DeviceInfo {
    /// Whether the device declares `kbit` kbit/s.
    pub fn supports_baud_rate(&self, kbit: u16) -> bool {
        BAUD_RATES_KBIT
            .iter()
            .zip(self.baud_rates)
            .any(|(&r, on)| r == kbit && on)
    }
}

/// A DCF's `[DeviceComissioning]` (CiA 306-1 §5.2.1 spells it with one "m").
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Commissioning {
    /// `NodeID=` 1..=127.
    pub node_id: u8,
    /// `NodeName=`.
    pub node_name: String,
    /// `Baudrate=` (kbit/s).
    pub baudrate_kbit: u16,
    /// `NetNumber=`.
    pub net_number: u32,
    /// `NetworkName=`.
    pub network_name: String,
    /// `CANopenManager=`.
    pub canopen_manager: bool,
    /// `LSS_SerialNumber=`.
    pub lss_serial_number: Option<u32>,
}
