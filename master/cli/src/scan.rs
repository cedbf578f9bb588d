//! `gantry scan --interface IFACE`: what is on the wire. Brings the slaves to PreOp
//! (identity and name from their EEPROMs), then to SafeOp to learn their process data
//! sizes, prints one row per slave, and leaves them in Init (through PreOp).

use std::io::Write;

use ethercrab::std::ethercat_now;
use ethercrab::{AlStatusCode, MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use serde::Serialize;
use thiserror::Error;

use gantry::ethercat::raw::RawBus;
use gantry::pcap::{PcapError, PcapWriter};

const MAX_SLAVES: usize = 64;
const MAX_PDI: usize = 4096;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

/// Why the scan failed.
#[derive(Debug, Error)]
pub enum ScanError {
    /// The interface could not be opened.
    #[error(transparent)]
    Socket(#[from] gantry_link::raw_socket::RawSocketError),
    /// The pcap file could not be written.
    #[error("pcap {path}")]
    Pcap {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: PcapError,
    },
    /// The network did not answer as expected.
    #[error("{step} on {interface}")]
    Bus {
        /// What the master was doing.
        step: &'static str,
        /// The interface.
        interface: String,
        /// ethercrab's error.
        source: ethercrab::error::Error,
    },
    /// Nobody answered.
    #[error("no EtherCAT slave answered on {0} (cable, link, or the wrong interface?)")]
    NoSlaves(String),
    /// The output could not be written.
    #[error("writing the table")]
    Output(#[from] std::io::Error),
}

/// One row of the table.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct SlaveRow {
    /// Position in the chain (0 = next to the master).
    pub position: usize,
    /// Configured station address.
    pub address: u16,
    /// Station alias from the EEPROM (0: none).
    pub alias: u16,
    /// Vendor ID.
    pub vendor: u32,
    /// Product code.
    pub product: u32,
    /// Revision.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
    /// Device name from the EEPROM.
    pub name: String,
    /// AL state when the scan looked (SafeOp if all went well).
    pub state: String,
    /// Distributed clocks support.
    pub dc: String,
    /// Input process data (bytes).
    pub inputs: usize,
    /// Output process data (bytes).
    pub outputs: usize,
}

/// Scans the network on `interface`.
pub fn scan(interface: &str, pcap: Option<&str>) -> Result<Vec<SlaveRow>, ScanError> {
    let bus_error = |step| {
        let interface = interface.to_string();
        move |source| ScanError::Bus {
            step,
            interface,
            source,
        }
    };
    let capture = match pcap {
        Some(path) => Some(
            std::fs::File::create(path)
                .map_err(PcapError::from)
                .and_then(|f| PcapWriter::new(std::io::BufWriter::new(f)))
                .map_err(|source| ScanError::Pcap {
                    path: path.into(),
                    source,
                })?,
        ),
        None => None,
    };
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().map_err(|_| ScanError::Bus {
        step: "PDU storage",
        interface: interface.into(),
        source: ethercrab::error::Error::Internal,
    })?;
    let bus = RawBus::open(interface, tx, rx, capture)?;
    let maindevice = MainDevice::new(pdu_loop, Timeouts::default(), MainDeviceConfig::default());
    let rows = futures_lite::future::block_on(async {
        let group = maindevice
            .init_single_group::<MAX_SLAVES, MAX_PDI>(ethercat_now)
            .await
            .map_err(bus_error("discovery"))?;
        if group.is_empty() {
            return Err(ScanError::NoSlaves(interface.into()));
        }
        let group = group
            .into_safe_op(&maindevice)
            .await
            .map_err(bus_error("PreOp to SafeOp"))?;
        let mut rows = Vec::with_capacity(group.len());
        for (position, sd) in group.iter(&maindevice).enumerate() {
            let id = sd.identity();
            let state = match sd.status().await {
                Ok((state, AlStatusCode::NoError)) => format!("{state}"),
                Ok((state, code)) => format!("{state} ({code})"),
                Err(e) => format!("unknown ({e})"),
            };
            rows.push(SlaveRow {
                position,
                address: sd.configured_address(),
                alias: sd.alias_address(),
                vendor: id.vendor_id,
                product: id.product_id,
                revision: id.revision,
                serial: id.serial,
                name: sd.name().to_string(),
                state,
                dc: format!("{:?}", sd.dc_support()),
                inputs: sd.inputs_raw().len(),
                outputs: sd.outputs_raw().len(),
            });
        }
        group
            .into_pre_op(&maindevice)
            .await
            .map_err(bus_error("back to PreOp"))?
            .into_init(&maindevice)
            .await
            .map_err(bus_error("back to Init"))?;
        Ok(rows)
    });
    bus.stop();
    rows
}

/// Prints the rows as a table.
pub fn print_table(rows: &[SlaveRow], out: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        out,
        "{:>3} {:>7} {:>6} {:>10} {:>10} {:>8} {:<32} {:<16} {:<8} {:>6} {:>6}",
        "pos",
        "address",
        "alias",
        "vendor",
        "product",
        "revision",
        "name",
        "state",
        "dc",
        "in B",
        "out B"
    )?;
    for r in rows {
        writeln!(
            out,
            "{:>3} {:>#7x} {:>6} {:>#10x} {:>#10x} {:>8} {:<32} {:<16} {:<8} {:>6} {:>6}",
            r.position,
            r.address,
            r.alias,
            r.vendor,
            r.product,
            r.revision,
            r.name,
            r.state,
            r.dc,
            r.inputs,
            r.outputs
        )?;
    }
    Ok(())
}
