//! Writes an [`Eds`] as an EDS, or with its commissioning and configured values as a
//! DCF (CiA 306-1 §4, §5): the sections in the specification's order, every ARRAY and
//! RECORD with explicit sub-index sections (the form every reader takes), unsigned
//! values in hex, signed in decimal, `$NODEID` kept in an EDS. What [`super::read`]
//! reads back is the same model.

use std::fmt::Write as _;

use super::device::BAUD_RATES_KBIT;
use super::object::{ObjectList, SubObject};
use super::Eds;

/// An EDS value or name on one line: line breaks would end the entry.
fn one_line(s: &str) -> String {
    s.chars()
        .map(|c| if c == '\r' || c == '\n' { ' ' } else { c })
        .collect::<String>()
        .trim()
        .to_string()
}

fn key(out: &mut String, k: &str, v: &str) {
    let _ = writeln!(out, "{k}={}", one_line(v));
}

fn key_if(out: &mut String, k: &str, v: &str) {
    if !v.is_empty() {
        key(out, k, v);
    }
}

fn section(out: &mut String, name: &str) {
    if !out.is_empty() {
        out.push('\n');
    }
    let _ = writeln!(out, "[{name}]");
}

fn entry(out: &mut String, e: &SubObject, dcf: bool) {
    key(out, "ParameterName", &e.name);
    key(out, "ObjectType", &format!("0x{:X}", e.object_type.code()));
    key(out, "DataType", &format!("0x{:04X}", e.data_type.code()));
    key(out, "AccessType", e.access.as_str());
    if let Some(v) = &e.default_value {
        key(out, "DefaultValue", &v.to_eds(e.data_type));
    }
    if let Some(v) = &e.low_limit {
        key(out, "LowLimit", &v.to_eds(e.data_type));
    }
    if let Some(v) = &e.high_limit {
        key(out, "HighLimit", &v.to_eds(e.data_type));
    }
    key(out, "PDOMapping", if e.pdo_mapping { "1" } else { "0" });
    if dcf {
        if let Some(v) = &e.parameter_value {
            key(out, "ParameterValue", &v.to_eds(e.data_type));
        }
    }
}

fn flag(b: bool) -> &'static str {
    if b {
        "1"
    } else {
        "0"
    }
}

fn write_file(eds: &Eds, dcf: bool) -> String {
    let mut out = String::new();
    let f = &eds.file_info;
    section(&mut out, "FileInfo");
    key(&mut out, "FileName", &f.file_name);
    key(&mut out, "FileVersion", &f.file_version.to_string());
    key(&mut out, "FileRevision", &f.file_revision.to_string());
    key(&mut out, "EDSVersion", &f.eds_version);
    key(&mut out, "Description", &f.description);
    key_if(&mut out, "CreationTime", &f.creation_time);
    key_if(&mut out, "CreationDate", &f.creation_date);
    key_if(&mut out, "CreatedBy", &f.created_by);
    key_if(&mut out, "ModificationTime", &f.modification_time);
    key_if(&mut out, "ModificationDate", &f.modification_date);
    key_if(&mut out, "ModifiedBy", &f.modified_by);

    let d = &eds.device_info;
    section(&mut out, "DeviceInfo");
    key(&mut out, "VendorName", &d.vendor_name);
    if let Some(n) = d.vendor_number {
        key(&mut out, "VendorNumber", &format!("0x{n:X}"));
    }
    key(&mut out, "ProductName", &d.product_name);
    if let Some(n) = d.product_number {
        key(&mut out, "ProductNumber", &format!("0x{n:X}"));
    }
    if let Some(n) = d.revision_number {
        key(&mut out, "RevisionNumber", &format!("0x{n:X}"));
    }
    key_if(&mut out, "OrderCode", &d.order_code);
    for (rate, on) in BAUD_RATES_KBIT.iter().zip(d.baud_rates) {
        key(&mut out, &format!("BaudRate_{rate}"), flag(on));
    }
    key(
        &mut out,
        "SimpleBootUpMaster",
        flag(d.simple_boot_up_master),
    );
    key(&mut out, "SimpleBootUpSlave", flag(d.simple_boot_up_slave));
    key(&mut out, "Granularity", &d.granularity.to_string());
    key(
        &mut out,
        "DynamicChannelsSupported",
        &d.dynamic_channels_supported.to_string(),
    );
    key(&mut out, "GroupMessaging", flag(d.group_messaging));
    key(&mut out, "NrOfRXPDO", &d.nr_of_rx_pdo.to_string());
    key(&mut out, "NrOfTXPDO", &d.nr_of_tx_pdo.to_string());
    key(&mut out, "LSS_Supported", flag(d.lss_supported));

    if dcf {
        if let Some(c) = &eds.commissioning {
            section(&mut out, "DeviceComissioning");
            key(&mut out, "NodeID", &c.node_id.to_string());
            key_if(&mut out, "NodeName", &c.node_name);
            key(&mut out, "Baudrate", &c.baudrate_kbit.to_string());
            key(&mut out, "NetNumber", &c.net_number.to_string());
            key_if(&mut out, "NetworkName", &c.network_name);
            key(&mut out, "CANopenManager", flag(c.canopen_manager));
            if let Some(n) = c.lss_serial_number {
                key(&mut out, "LSS_SerialNumber", &format!("0x{n:X}"));
            }
        }
    }

    section(&mut out, "DummyUsage");
    for (i, on) in eds.dummy_usage.iter().enumerate().skip(1) {
        key(&mut out, &format!("Dummy{i:04X}"), flag(*on));
    }

    if !eds.comments.is_empty() {
        section(&mut out, "Comments");
        key(&mut out, "Lines", &eds.comments.len().to_string());
        for (i, l) in eds.comments.iter().enumerate() {
            key(&mut out, &format!("Line{}", i + 1), l);
        }
    }

    for list in [
        ObjectList::Mandatory,
        ObjectList::Optional,
        ObjectList::Manufacturer,
    ] {
        let indices: Vec<u16> = eds
            .objects
            .values()
            .filter(|o| o.list == list)
            .map(|o| o.index)
            .collect();
        section(&mut out, list.section());
        key(&mut out, "SupportedObjects", &indices.len().to_string());
        for (i, index) in indices.iter().enumerate() {
            key(&mut out, &(i + 1).to_string(), &format!("0x{index:04X}"));
        }
    }

    for o in eds.objects.values() {
        let name = format!("{:04X}", o.index);
        section(&mut out, &name);
        if o.object_type.is_single() {
            match o.subs.get(&0) {
                Some(e) => {
                    let mut e = e.clone();
                    e.object_type = o.object_type;
                    e.name.clone_from(&o.name);
                    entry(&mut out, &e, dcf);
                }
                None => {
                    key(&mut out, "ParameterName", &o.name);
                    key(
                        &mut out,
                        "ObjectType",
                        &format!("0x{:X}", o.object_type.code()),
                    );
                }
            }
            continue;
        }
        key(&mut out, "ParameterName", &o.name);
        key(
            &mut out,
            "ObjectType",
            &format!("0x{:X}", o.object_type.code()),
        );
        key(&mut out, "SubNumber", &o.subs.len().to_string());
        for (sub, e) in &o.subs {
            section(&mut out, &format!("{name}sub{sub:X}"));
            entry(&mut out, e, dcf);
        }
    }
    out
}

/// The EDS text of `eds` (no commissioning, no `ParameterValue`).
pub fn write_eds(eds: &Eds) -> String {
    write_file(eds, false)
}

/// The DCF text of `eds`: its `[DeviceComissioning]` and every `ParameterValue` set
/// (see [`Eds::set_parameter`]).
pub fn write_dcf(eds: &Eds) -> String {
    write_file(eds, true)
}
