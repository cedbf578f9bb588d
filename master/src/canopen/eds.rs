//! A vendor's EDS in the master (CiA 306-1): an axis that names its drive's EDS
//! (`[[axis]] eds = "drive.eds"`) has its configuration checked against it at load
//! ([`check`]) — the CAN bit rate among those the device declares, each of its PDOs
//! within the device's count and every mapped object mappable that way at its size
//! ([`Eds::check_pdo`]), and every SDO write of the bring-up to an object the device
//! has, writable, with a value of its type within its limits — so a configuration the
//! drive would refuse with an SDO abort in the middle of the bring-up fails at start,
//! naming the object and the file ("0x6081:00 is not PDO-mappable in acme.eds"). The
//! same writes make the DCF of the node ([`dcf`]: CiA 306-1 §5, the EDS with
//! `[DeviceComissioning]` and a `ParameterValue` for each object the bring-up writes),
//! which `gantry dcf` saves. Configuration-time code: it allocates.

use gantry_drives::canopen::eds::{Commissioning, DcfError, Eds, MappingEntry, PdoDirection};
use thiserror::Error;

use super::bring_up::{drive_setup, DriveSetup, StartError};
use crate::config::Config;

/// Why a configuration does not suit its drive's EDS.
#[derive(Debug, Error)]
pub enum EdsCheckError {
    /// The axis' drive setup could not be made (no node, a layout that does not fit).
    #[error(transparent)]
    Setup(Box<StartError>),
    /// The bit rate is not one the device declares (`[DeviceInfo] BaudRate_N`).
    #[error(
        "bus.bitrate {kbit} kbit/s is not one {file} declares (BaudRate_{kbit}=1; it has {has})"
    )]
    BitRate {
        /// The configured bit rate (kbit/s).
        kbit: u32,
        /// Those the EDS declares.
        has: String,
        /// The EDS.
        file: String,
    },
    /// A PDO of the axis' layout that the device would refuse.
    #[error("{direction}{pdo} of pdo = {layout:?}: {source}")]
    Mapping {
        /// "RPDO" or "TPDO".
        direction: &'static str,
        /// Its number (1-based).
        pdo: u8,
        /// The layout's name.
        layout: String,
        /// Why, in the EDS' words.
        source: Box<gantry_drives::canopen::eds::MappingError>,
    },
    /// An SDO write of the bring-up that the device would refuse.
    #[error("the bring-up writes {value} to {object} ({what}): {source}")]
    Write {
        /// What the write is for.
        what: &'static str,
        /// The object (`0x1017:00`).
        object: String,
        /// The value, as hex (the number the SDO's little-endian bytes carry).
        value: String,
        /// Why, in the EDS' words.
        source: Box<DcfError>,
    },
}

/// The bit rates `eds` declares, in kbit/s ("125, 250, 1000" or "none").
fn declared_rates(eds: &Eds) -> String {
    let rates: Vec<String> = gantry_drives::canopen::eds::BAUD_RATES_KBIT
        .iter()
        .filter(|&&r| eds.device_info.supports_baud_rate(r))
        .map(u16::to_string)
        .collect();
    if rates.is_empty() {
        "none".into()
    } else {
        rates.join(", ")
    }
}

/// Checks axis `axis` of `config` against its EDS (nothing to check without one).
pub fn check(config: &Config, axis: usize) -> Result<(), EdsCheckError> {
    let Some(eds) = config.eds_of(axis) else {
        return Ok(());
    };
    let setup = drive_setup(config, axis).map_err(|e| EdsCheckError::Setup(Box::new(e)))?;
    let kbit = config.bus.bitrate.unwrap_or(0) / 1000;
    if !u16::try_from(kbit).is_ok_and(|k| eds.device_info.supports_baud_rate(k)) {
        return Err(EdsCheckError::BitRate {
            kbit,
            has: declared_rates(eds),
            file: eds.file.clone(),
        });
    }
    let layout = config.axes.get(axis).map_or("", |a| a.pdo.as_str());
    for (direction, name, pdos) in [
        (PdoDirection::Receive, "RPDO", &setup.plan.rpdos),
        (PdoDirection::Transmit, "TPDO", &setup.plan.tpdos),
    ] {
        for p in pdos {
            let entries: Vec<MappingEntry> =
                p.mapping_values().map(MappingEntry::from_u32).collect();
            eds.check_pdo(direction, u16::from(p.number), &entries)
                .map_err(|source| EdsCheckError::Mapping {
                    direction: name,
                    pdo: p.number,
                    layout: layout.to_string(),
                    source: Box::new(source),
                })?;
        }
    }
    dcf_of(config, &setup, eds).map(|_| ())
}

/// The DCF of axis `axis`' node, commissioned as `config` configures it (node id, bit
/// rate, the axis' name), with the value of every object the bring-up writes, from
/// `eds` (the axis' own, or one the caller chose for an axis without).
pub fn dcf(config: &Config, axis: usize, eds: &Eds) -> Result<Eds, EdsCheckError> {
    let setup = drive_setup(config, axis).map_err(|e| EdsCheckError::Setup(Box::new(e)))?;
    dcf_of(config, &setup, eds)
}

fn dcf_of(config: &Config, setup: &DriveSetup, eds: &Eds) -> Result<Eds, EdsCheckError> {
    let mut dcf = eds.clone();
    dcf.commission(Commissioning {
        node_id: setup.node.get(),
        node_name: setup.axis.clone(),
        baudrate_kbit: u16::try_from(config.bus.bitrate.unwrap_or(0) / 1000).unwrap_or(0),
        network_name: config.bus.interface.clone().unwrap_or_default(),
        ..Commissioning::default()
    });
    // In order: the last write to an object is its configured value (a mapping's count
    // is 0 while its entries are written, then the count).
    for step in &setup.steps {
        dcf.set_parameter_bytes(step.mux.index, step.mux.sub, step.value())
            .map_err(|source| EdsCheckError::Write {
                what: step.what,
                object: format!("0x{:04X}:{:02X}", step.mux.index, step.mux.sub),
                value: format!(
                    "0x{}",
                    step.value()
                        .iter()
                        .rev()
                        .map(|b| format!("{b:02X}"))
                        .collect::<String>()
                ),
                source: Box::new(source),
            })?;
    }
    Ok(dcf)
}

/// An SDO transfer the drive's EDS says the drive would refuse (CiA 301 §7.2.4.3.17: it
/// would abort 0x06020000, 0x06010001, 0x06010002 or 0x06070010), refused before
/// anything is sent.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum SdoEdsError {
    /// No such entry.
    #[error("0x{index:04X}:{sub:02X} is not in {file}")]
    NotInEds {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The EDS.
        file: String,
    },
    /// Read of an entry that cannot be read, or write of one that cannot be written.
    #[error("0x{index:04X}:{sub:02X} is {access} in {file}: it cannot be {done}")]
    Access {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Its access.
        access: &'static str,
        /// "read" or "written".
        done: &'static str,
        /// The EDS.
        file: String,
    },
    /// A download whose length is not the entry's type's.
    #[error(
        "0x{index:04X}:{sub:02X} is a {data_type} of {want} bytes in {file}; {given} bytes given"
    )]
    Length {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Its type.
        data_type: &'static str,
        /// The type's bytes.
        want: usize,
        /// Bytes given.
        given: usize,
        /// The EDS.
        file: String,
    },
}

/// Checks an SDO upload (`download` None) or a download of `download` bytes of
/// `index`:`sub` against `eds`; the entry it goes to.
pub fn check_sdo(
    eds: &Eds,
    index: u16,
    sub: u8,
    download: Option<usize>,
) -> Result<&gantry_drives::canopen::eds::SubObject, SdoEdsError> {
    let file = || eds.file.clone();
    let e = eds.entry(index, sub).ok_or_else(|| SdoEdsError::NotInEds {
        index,
        sub,
        file: file(),
    })?;
    let (allowed, done) = match download {
        None => (e.access.readable(), "read"),
        Some(_) => (e.access.writable(), "written"),
    };
    if !allowed {
        return Err(SdoEdsError::Access {
            index,
            sub,
            access: e.access.as_str(),
            done,
            file: file(),
        });
    }
    if let (Some(given), Some(want)) = (download, e.data_type.bytes()) {
        if given != want {
            return Err(SdoEdsError::Length {
                index,
                sub,
                data_type: e.data_type.name(),
                want,
                given,
                file: file(),
            });
        }
    }
    Ok(e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::canopen::eds::{AccessType, DataType, Object, SubObject};

    fn sheet() -> Eds {
        let mut eds = Eds::new("drive.eds");
        for (index, ty, access) in [
            (0x2000, DataType::Unsigned8, AccessType::WriteOnly),
            (0x6041, DataType::Unsigned16, AccessType::ReadOnly),
            (0x1008, DataType::VisibleString, AccessType::Const),
            (0x607A, DataType::Integer32, AccessType::ReadWriteOutput),
            (0x2100, DataType::Domain, AccessType::ReadWrite),
        ] {
            eds.insert(Object::var(index, SubObject::new("x", ty, access)));
        }
        eds
    }

    #[test]
    fn an_sdo_the_eds_says_the_drive_would_refuse_is_named() {
        let eds = sheet();
        let e = |index, sub, download| {
            check_sdo(&eds, index, sub, download)
                .unwrap_err()
                .to_string()
        };
        assert_eq!(e(0x2001, 0, None), "0x2001:00 is not in drive.eds");
        assert_eq!(e(0x607A, 1, Some(4)), "0x607A:01 is not in drive.eds");
        assert_eq!(
            e(0x2000, 0, None),
            "0x2000:00 is wo in drive.eds: it cannot be read"
        );
        assert_eq!(
            e(0x6041, 0, Some(2)),
            "0x6041:00 is ro in drive.eds: it cannot be written"
        );
        assert_eq!(
            e(0x1008, 0, Some(3)),
            "0x1008:00 is const in drive.eds: it cannot be written"
        );
        assert_eq!(
            e(0x607A, 0, Some(2)),
            "0x607A:00 is a INTEGER32 of 4 bytes in drive.eds; 2 bytes given"
        );
        // What the drive takes.
        assert_eq!(
            check_sdo(&eds, 0x607A, 0, Some(4)).unwrap().data_type,
            DataType::Integer32
        );
        assert!(check_sdo(&eds, 0x6041, 0, None).is_ok());
        assert!(check_sdo(&eds, 0x2000, 0, Some(1)).is_ok());
        assert!(check_sdo(&eds, 0x1008, 0, None).is_ok());
        // A variable-length entry takes any length.
        assert!(check_sdo(&eds, 0x2100, 0, Some(200)).is_ok());
    }
}
