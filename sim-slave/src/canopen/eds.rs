//! The electronic data sheet of a simulated node (CiA 306-1 EDS, version 4.0): what a
//! vendor ships with a device so that a master knows each object's data type, access
//! and PDO mappability. Written from the node itself — every object its SDO server
//! serves, with the access the server enforces and its power-on value — so the file and
//! the device cannot disagree. Not on the cycle path: it allocates.

use std::fmt::Write as _;

use gantry_drives::canopen::sdo::{AbortCode, Access, ObjectSize};
use gantry_drives::cia402::image;
use gantry_drives::cia402::objects::{self, DataType};

use super::dictionary::{
    ABORT_CONNECTION_OPTION_CODE, COB_ID_EMCY, COB_ID_SYNC, COMMUNICATION_CYCLE_PERIOD,
    CONSUMER_HEARTBEAT_TIME, DEVICE_NAME, DEVICE_NAME_VALUE, DEVICE_TYPE, ERROR_BEHAVIOUR,
    ERROR_HISTORY, ERROR_REGISTER, IDENTITY, INHIBIT_TIME_EMCY, MISSED_SETPOINT_LIMIT,
    PREDEFINED_ERROR_FIELD, PRODUCER_HEARTBEAT_TIME, SOFTWARE_VERSION, SYNC_COUNTER_OVERFLOW,
};
use super::node::CanNode;
use super::pdo::{
    MAX_MAPPED, PDO_COUNT, RPDO_COMMUNICATION, RPDO_MAPPING, TPDO_COMMUNICATION, TPDO_MAPPING,
};

/// CiA 301 Table 44 data types an EDS names by number.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EdsType {
    /// INTEGER8 (0x0002).
    I8,
    /// INTEGER16 (0x0003).
    I16,
    /// INTEGER32 (0x0004).
    I32,
    /// UNSIGNED8 (0x0005).
    U8,
    /// UNSIGNED16 (0x0006).
    U16,
    /// UNSIGNED32 (0x0007).
    U32,
    /// VISIBLE_STRING (0x0009).
    VisibleString,
}

impl EdsType {
    /// The data type index (CiA 301 Table 44).
    pub const fn code(self) -> u16 {
        match self {
            Self::I8 => 0x0002,
            Self::I16 => 0x0003,
            Self::I32 => 0x0004,
            Self::U8 => 0x0005,
            Self::U16 => 0x0006,
            Self::U32 => 0x0007,
            Self::VisibleString => 0x0009,
        }
    }

    /// Size in bytes (None: a string).
    pub const fn size(self) -> Option<usize> {
        match self {
            Self::I8 | Self::U8 => Some(1),
            Self::I16 | Self::U16 => Some(2),
            Self::I32 | Self::U32 => Some(4),
            Self::VisibleString => None,
        }
    }

    const fn of(kind: DataType) -> Self {
        match kind {
            DataType::I8 => Self::I8,
            DataType::U8 => Self::U8,
            DataType::I16 => Self::I16,
            DataType::U16 => Self::U16,
            DataType::I32 => Self::I32,
            DataType::U32 => Self::U32,
        }
    }
}

/// One sub-object as the EDS describes it.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Var {
    sub: u8,
    name: String,
    ty: EdsType,
}

/// One object: its name and sub-objects (one at sub 0 for a VAR).
#[derive(Clone, Debug, PartialEq, Eq)]
struct Object {
    index: u16,
    name: String,
    /// 0x7 VAR, 0x8 ARRAY, 0x9 RECORD.
    object_type: u8,
    subs: Vec<Var>,
}

fn var(index: u16, name: &str, ty: EdsType) -> Object {
    Object {
        index,
        name: name.to_string(),
        object_type: 0x7,
        subs: vec![Var {
            sub: 0,
            name: name.to_string(),
            ty,
        }],
    }
}

fn compound(index: u16, name: &str, object_type: u8, subs: &[(u8, &str, EdsType)]) -> Object {
    Object {
        index,
        name: name.to_string(),
        object_type,
        subs: subs
            .iter()
            .map(|&(sub, n, ty)| Var {
                sub,
                name: n.to_string(),
                ty,
            })
            .collect(),
    }
}

/// The objects of the node, in index order.
fn objects(node: &CanNode) -> Vec<Object> {
    use EdsType::*;
    let mut v = vec![
        var(DEVICE_TYPE, "Device type", U32),
        var(ERROR_REGISTER, "Error register", U8),
    ];
    let mut errors = vec![(0u8, "Number of errors", U8)];
    for s in 1..=ERROR_HISTORY as u8 {
        errors.push((s, "Standard error field", U32));
    }
    v.push(compound(
        PREDEFINED_ERROR_FIELD,
        "Pre-defined error field",
        0x8,
        &errors,
    ));
    v.push(var(COB_ID_SYNC, "COB-ID SYNC message", U32));
    v.push(var(
        COMMUNICATION_CYCLE_PERIOD,
        "Communication cycle period",
        U32,
    ));
    v.push(var(DEVICE_NAME, "Manufacturer device name", VisibleString));
    v.push(var(
        SOFTWARE_VERSION,
        "Manufacturer software version",
        VisibleString,
    ));
    v.push(var(COB_ID_EMCY, "COB-ID EMCY", U32));
    v.push(var(INHIBIT_TIME_EMCY, "Inhibit time EMCY", U16));
    v.push(compound(
        CONSUMER_HEARTBEAT_TIME,
        "Consumer heartbeat time",
        0x8,
        &[
            (0, "Highest sub-index supported", U8),
            (1, "Consumer heartbeat time", U32),
        ],
    ));
    v.push(var(PRODUCER_HEARTBEAT_TIME, "Producer heartbeat time", U16));
    v.push(compound(
        IDENTITY,
        "Identity object",
        0x9,
        &[
            (0, "Highest sub-index supported", U8),
            (1, "Vendor-ID", U32),
            (2, "Product code", U32),
            (3, "Revision number", U32),
            (4, "Serial number", U32),
        ],
    ));
    v.push(var(
        SYNC_COUNTER_OVERFLOW,
        "Synchronous counter overflow value",
        U8,
    ));
    v.push(compound(
        ERROR_BEHAVIOUR,
        "Error behavior",
        0x8,
        &[
            (0, "Highest sub-index supported", U8),
            (1, "Communication error", U8),
        ],
    ));
    let mut mapping = vec![(0u8, "Number of mapped objects", U8)];
    for s in 1..=MAX_MAPPED as u8 {
        mapping.push((s, "Mapping entry", U32));
    }
    for n in 0..PDO_COUNT as u16 {
        v.push(compound(
            RPDO_COMMUNICATION + n,
            "RPDO communication parameter",
            0x9,
            &[
                (0, "Highest sub-index supported", U8),
                (1, "COB-ID used by RPDO", U32),
                (2, "Transmission type", U8),
                (5, "Event timer", U16),
            ],
        ));
        v.push(compound(
            RPDO_MAPPING + n,
            "RPDO mapping parameter",
            0x9,
            &mapping,
        ));
        v.push(compound(
            TPDO_COMMUNICATION + n,
            "TPDO communication parameter",
            0x9,
            &[
                (0, "Highest sub-index supported", U8),
                (1, "COB-ID used by TPDO", U32),
                (2, "Transmission type", U8),
                (3, "Inhibit time", U16),
                (5, "Event timer", U16),
                (6, "SYNC start value", U8),
            ],
        ));
        v.push(compound(
            TPDO_MAPPING + n,
            "TPDO mapping parameter",
            0x9,
            &mapping,
        ));
    }
    v.push(var(
        MISSED_SETPOINT_LIMIT,
        "Missed SYNC setpoint limit",
        U16,
    ));
    // The servo's objects, typed by the CiA 402 table (all are VARs at sub 0).
    let mut servo: Vec<(u16, u8)> = node.dictionary().servo_objects().collect();
    servo.sort_unstable();
    servo.dedup();
    for (index, sub) in servo {
        let (name, ty) = match objects::lookup(index, sub) {
            Some(o) => (o.name.to_string(), EdsType::of(o.kind)),
            None if index == ABORT_CONNECTION_OPTION_CODE => {
                ("Abort connection option code".to_string(), I16)
            }
            None => {
                let size = match node.object_info(index, sub).map(|i| i.size) {
                    Ok(ObjectSize::Fixed(n)) => n,
                    _ => 4,
                };
                let ty = match size {
                    1 => U8,
                    2 => U16,
                    _ => U32,
                };
                (format!("Object {index:04X}sub{sub}"), ty)
            }
        };
        v.push(var(index, &name, ty));
    }
    v.sort_by_key(|o| o.index);
    v
}

fn access_type(access: Access, rpdo: bool) -> &'static str {
    match access {
        Access::ReadOnly => "ro",
        Access::WriteOnly => "wo",
        Access::Const => "const",
        // CiA 306 §4.6.3: "rww" is rw and mappable into an RPDO.
        Access::ReadWrite if rpdo => "rww",
        Access::ReadWrite => "rw",
    }
}

fn default_value(node: &mut CanNode, index: u16, sub: u8, ty: EdsType) -> String {
    let mut buf = [0u8; 64];
    let bytes = match node.read_object(index, sub, &mut buf) {
        Ok(n) => buf.get(..n).unwrap_or(&[]).to_vec(),
        // 0x1003 beyond the errors recorded: none at power-on.
        Err(AbortCode::NO_DATA) | Err(_) => Vec::new(),
    };
    let mut le = [0u8; 8];
    for (d, s) in le.iter_mut().zip(&bytes) {
        *d = *s;
    }
    let raw = u64::from_le_bytes(le);
    match ty {
        EdsType::VisibleString => String::from_utf8_lossy(&bytes).into_owned(),
        EdsType::I8 => (raw as u8 as i8).to_string(),
        EdsType::I16 => (raw as u16 as i16).to_string(),
        EdsType::I32 => (raw as u32 as i32).to_string(),
        EdsType::U8 | EdsType::U16 | EdsType::U32 => format!("0x{raw:X}"),
    }
}

/// The EDS of `node` as it powers on (call it on a node fresh from `CanNode::new`: the
/// default values are the values its objects hold now).
pub fn write(node: &mut CanNode, file_name: &str) -> String {
    let objs = objects(node);
    let identity = |node: &mut CanNode, sub| {
        let mut b = [0u8; 4];
        match node.read_object(IDENTITY, sub, &mut b) {
            Ok(4) => u32::from_le_bytes(b),
            _ => 0,
        }
    };
    let (vendor, product, revision) = (identity(node, 1), identity(node, 2), identity(node, 3));
    let mut s = String::new();
    let _ = writeln!(s, "[FileInfo]");
    let _ = writeln!(s, "FileName={file_name}");
    let _ = writeln!(s, "FileVersion=1\nFileRevision=0\nEDSVersion=4.0");
    let _ = writeln!(
        s,
        "Description=Simulated CiA 402 servo drive, node {}",
        node.node().get()
    );
    let _ = writeln!(s, "CreatedBy=gantry-sim {}", env!("CARGO_PKG_VERSION"));
    let _ = writeln!(s);
    let _ = writeln!(s, "[DeviceInfo]");
    let _ = writeln!(s, "VendorName=gantry");
    let _ = writeln!(s, "VendorNumber=0x{vendor:X}");
    let _ = writeln!(s, "ProductName={DEVICE_NAME_VALUE}");
    let _ = writeln!(s, "ProductNumber=0x{product:X}");
    let _ = writeln!(s, "RevisionNumber=0x{revision:X}");
    for rate in [10, 20, 50, 125, 250, 500, 800, 1000] {
        let _ = writeln!(s, "BaudRate_{rate}=1");
    }
    let _ = writeln!(
        s,
        "SimpleBootUpMaster=0\nSimpleBootUpSlave=1\nGranularity=8"
    );
    let _ = writeln!(s, "DynamicChannelsSupported=0\nGroupMessaging=0");
    let _ = writeln!(
        s,
        "NrOfRXPDO={PDO_COUNT}\nNrOfTXPDO={PDO_COUNT}\nLSS_Supported=0"
    );
    let _ = writeln!(s);
    let _ = writeln!(s, "[DummyUsage]");
    // CiA 306 §4.5: which data types may be mapped as dummies (RPDOs; not BOOLEAN).
    for d in 1..=7 {
        let _ = writeln!(s, "Dummy000{d}={}", u8::from(d >= 2));
    }
    let _ = writeln!(s);
    let mandatory = [DEVICE_TYPE, ERROR_REGISTER, IDENTITY];
    let lists: [(&str, Vec<u16>); 3] = [
        ("MandatoryObjects", mandatory.to_vec()),
        (
            "OptionalObjects",
            objs.iter()
                .map(|o| o.index)
                .filter(|i| !mandatory.contains(i) && !(0x2000..0x6000).contains(i))
                .collect(),
        ),
        (
            "ManufacturerObjects",
            objs.iter()
                .map(|o| o.index)
                .filter(|i| (0x2000..0x6000).contains(i))
                .collect(),
        ),
    ];
    for (section, list) in lists {
        let _ = writeln!(s, "[{section}]");
        let _ = writeln!(s, "SupportedObjects={}", list.len());
        for (k, i) in list.iter().enumerate() {
            let _ = writeln!(s, "{}=0x{i:04X}", k + 1);
        }
        let _ = writeln!(s);
    }
    for o in &objs {
        let _ = writeln!(s, "[{:04X}]", o.index);
        let _ = writeln!(s, "ParameterName={}", o.name);
        let _ = writeln!(s, "ObjectType=0x{:X}", o.object_type);
        if o.object_type == 0x7 {
            if let Some(v) = o.subs.first() {
                entry(&mut s, node, o.index, v);
            }
            let _ = writeln!(s);
            continue;
        }
        let _ = writeln!(s, "SubNumber={}", o.subs.len());
        let _ = writeln!(s);
        for v in &o.subs {
            let _ = writeln!(s, "[{:04X}sub{:X}]", o.index, v.sub);
            let _ = writeln!(s, "ParameterName={}", v.name);
            let _ = writeln!(s, "ObjectType=0x7");
            entry(&mut s, node, o.index, v);
            let _ = writeln!(s);
        }
    }
    s
}

fn entry(s: &mut String, node: &mut CanNode, index: u16, v: &Var) {
    let rpdo = image::OUTPUT_OBJECTS
        .iter()
        .any(|o| o.index == index && o.sub == v.sub);
    let tpdo = image::INPUT_OBJECTS
        .iter()
        .any(|o| o.index == index && o.sub == v.sub);
    let access = node
        .object_info(index, v.sub)
        .map(|i| i.access)
        .unwrap_or(Access::ReadOnly);
    let _ = writeln!(s, "DataType=0x{:04X}", v.ty.code());
    let _ = writeln!(s, "AccessType={}", access_type(access, rpdo));
    let _ = writeln!(
        s,
        "DefaultValue={}",
        default_value(node, index, v.sub, v.ty)
    );
    let _ = writeln!(s, "PDOMapping={}", u8::from(rpdo || tpdo));
}
