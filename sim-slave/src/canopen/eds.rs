//! The electronic data sheet of a simulated node (CiA 306-1 EDS, version 4.0): what a
//! vendor ships with a device so that a master knows each object's data type, access
//! and PDO mappability. Built from the node itself — every object its SDO server
//! serves, with the access the server enforces, the PDO direction its mapping rules
//! allow, its power-on value and the range a download may write — into the shared model
//! of `gantry_drives::canopen::eds`, and written by its writer (one EDS writer for the
//! project). The node-relative COB-IDs are written as `$NODEID+…` (one file serves every
//! node id, as a vendor's does). Not on the cycle path: it allocates.

use std::collections::BTreeMap;

use gantry_drives::canopen::eds::{
    self, AccessType, DataType, Eds, Object, ObjectType, SubObject, Value,
};
use gantry_drives::canopen::sdo::{AbortCode, Access, ObjectSize};
use gantry_drives::cia402::objects::{self, DataType as Cia402Type};

use super::device::{profile_array, profile_object, DeviceKind};
use super::dictionary::{
    ABORT_CONNECTION_OPTION_CODE, COB_ID_EMCY, COB_ID_SYNC, COMMUNICATION_CYCLE_PERIOD,
    CONSUMER_HEARTBEAT_TIME, DEVICE_NAME, DEVICE_TYPE, ERROR_BEHAVIOUR, ERROR_HISTORY,
    ERROR_REGISTER, IDENTITY, INHIBIT_TIME_EMCY, MISSED_SETPOINT_LIMIT, PREDEFINED_ERROR_FIELD,
    PRODUCER_HEARTBEAT_TIME, RECORDER, SCRATCH, SOFTWARE_VERSION, SYNC_COUNTER_OVERFLOW,
};
use super::node::{CanNode, CanNodeConfig, CanNodeError, SlaveNodeError};
use super::pdo::{
    self, Direction, MAX_MAPPED, RPDO_COMMUNICATION, RPDO_MAPPING, TPDO_COMMUNICATION, TPDO_MAPPING,
};
use crate::config::SimConfig;

/// The EDS type of a CiA 402 object type.
pub const fn eds_type(kind: Cia402Type) -> DataType {
    match kind {
        Cia402Type::I8 => DataType::Integer8,
        Cia402Type::U8 => DataType::Unsigned8,
        Cia402Type::I16 => DataType::Integer16,
        Cia402Type::U16 => DataType::Unsigned16,
        Cia402Type::I32 => DataType::Integer32,
        Cia402Type::U32 => DataType::Unsigned32,
    }
}

/// One entry to describe: sub-index, name, type.
type Spec = (u8, String, DataType);

fn spec(sub: u8, name: &str, ty: DataType) -> Spec {
    (sub, name.to_string(), ty)
}

/// The objects of the node, in index order: (index, name, object type, entries).
fn layout(node: &CanNode) -> Vec<(u16, String, ObjectType, Vec<Spec>)> {
    use DataType::{Integer16 as I16, Unsigned16 as U16, Unsigned32 as U32, Unsigned8 as U8};
    let var = |index: u16, name: &str, ty: DataType| {
        (
            index,
            name.to_string(),
            ObjectType::Var,
            vec![spec(0, name, ty)],
        )
    };
    let highest = |n| spec(0, "Highest sub-index supported", n);
    let mut v = vec![
        var(DEVICE_TYPE, "Device type", U32),
        var(ERROR_REGISTER, "Error register", U8),
    ];
    let mut errors = vec![spec(0, "Number of errors", U8)];
    for s in 1..=ERROR_HISTORY as u8 {
        errors.push(spec(s, "Standard error field", U32));
    }
    v.push((
        PREDEFINED_ERROR_FIELD,
        "Pre-defined error field".into(),
        ObjectType::Array,
        errors,
    ));
    v.push(var(COB_ID_SYNC, "COB-ID SYNC message", U32));
    v.push(var(
        COMMUNICATION_CYCLE_PERIOD,
        "Communication cycle period",
        U32,
    ));
    v.push(var(
        DEVICE_NAME,
        "Manufacturer device name",
        DataType::VisibleString,
    ));
    v.push(var(
        SOFTWARE_VERSION,
        "Manufacturer software version",
        DataType::VisibleString,
    ));
    v.push(var(COB_ID_EMCY, "COB-ID EMCY", U32));
    v.push(var(INHIBIT_TIME_EMCY, "Inhibit time EMCY", U16));
    v.push((
        CONSUMER_HEARTBEAT_TIME,
        "Consumer heartbeat time".into(),
        ObjectType::Array,
        vec![highest(U8), spec(1, "Consumer heartbeat time", U32)],
    ));
    v.push(var(PRODUCER_HEARTBEAT_TIME, "Producer heartbeat time", U16));
    v.push((
        IDENTITY,
        "Identity object".into(),
        ObjectType::Record,
        vec![
            highest(U8),
            spec(1, "Vendor-ID", U32),
            spec(2, "Product code", U32),
            spec(3, "Revision number", U32),
            spec(4, "Serial number", U32),
        ],
    ));
    v.push(var(
        SYNC_COUNTER_OVERFLOW,
        "Synchronous counter overflow value",
        U8,
    ));
    v.push((
        ERROR_BEHAVIOUR,
        "Error behavior".into(),
        ObjectType::Array,
        vec![highest(U8), spec(1, "Communication error", U8)],
    ));
    let mut mapping = vec![spec(0, "Number of mapped objects", U8)];
    for s in 1..=MAX_MAPPED as u8 {
        mapping.push((s, format!("Mapping entry {s}"), U32));
    }
    for n in 0..u16::from(node.dictionary().comm.pdo_count) {
        v.push((
            RPDO_COMMUNICATION + n,
            format!("RPDO {} communication parameter", n + 1),
            ObjectType::Record,
            vec![
                highest(U8),
                spec(1, "COB-ID used by RPDO", U32),
                spec(2, "Transmission type", U8),
                spec(5, "Event timer", U16),
            ],
        ));
        v.push((
            RPDO_MAPPING + n,
            format!("RPDO {} mapping parameter", n + 1),
            ObjectType::Record,
            mapping.clone(),
        ));
        v.push((
            TPDO_COMMUNICATION + n,
            format!("TPDO {} communication parameter", n + 1),
            ObjectType::Record,
            vec![
                highest(U8),
                spec(1, "COB-ID used by TPDO", U32),
                spec(2, "Transmission type", U8),
                spec(3, "Inhibit time", U16),
                spec(5, "Event timer", U16),
                spec(6, "SYNC start value", U8),
            ],
        ));
        v.push((
            TPDO_MAPPING + n,
            format!("TPDO {} mapping parameter", n + 1),
            ObjectType::Record,
            mapping.clone(),
        ));
    }
    v.push(var(
        MISSED_SETPOINT_LIMIT,
        "Missed SYNC setpoint limit",
        U16,
    ));
    if node.dictionary().recorder_len() > 0 {
        v.push(var(RECORDER, "Recorder", DataType::Domain));
    }
    if node.dictionary().scratch_capacity() > 0 {
        v.push(var(SCRATCH, "Scratch", DataType::Domain));
    }
    // The device's profile objects: typed by the CiA 402 table (the servo's) or the
    // device's own (CiA 406, CiA 401); an index with sub-indices above 0 is an ARRAY.
    let kind = node.dictionary().kind();
    let mut entries: Vec<(u16, u8)> = node.dictionary().device_objects().collect();
    entries.sort_unstable();
    entries.dedup();
    let mut by_index: BTreeMap<u16, Vec<Spec>> = BTreeMap::new();
    for (index, sub) in entries {
        let (name, ty) = match (
            objects::lookup(index, sub),
            profile_object(kind, index, sub),
        ) {
            (_, Some((name, t))) => (name.to_string(), eds_type(t)),
            (Some(o), None) => (o.name.to_string(), eds_type(o.kind)),
            (None, None) if index == ABORT_CONNECTION_OPTION_CODE => {
                ("Abort connection option code".to_string(), I16)
            }
            (None, None) => {
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
        by_index.entry(index).or_default().push((sub, name, ty));
    }
    for (index, specs) in by_index {
        match specs.as_slice() {
            [(0, name, ty)] => v.push(var(index, name, *ty)),
            _ => {
                let name = profile_array(kind, index)
                    .map_or_else(|| format!("Object {index:04X}"), str::to_string);
                v.push((index, name, ObjectType::Array, specs));
            }
        }
    }
    v.sort_by_key(|o| o.0);
    v
}

/// Whether the node's PDO rules let `index`:`sub` of `ty` into a PDO going `direction`.
fn node_maps(kind: DeviceKind, direction: Direction, index: u16, sub: u8, ty: DataType) -> bool {
    let bits = ty.bits().unwrap_or(0);
    let entry = (u32::from(index) << 16) | (u32::from(sub) << 8) | bits;
    bits > 0 && bits <= 64 && pdo::mappable(kind, direction, entry).is_ok()
}

/// The EDS access of an entry the server gives `access`: a read-write entry the node
/// maps only into RPDOs is `rww` (process output), only into TPDOs `rwr` (CiA 306-1
/// §4.6.3).
fn access_type(access: Access, rpdo: bool, tpdo: bool) -> AccessType {
    match access {
        Access::ReadOnly => AccessType::ReadOnly,
        Access::WriteOnly => AccessType::WriteOnly,
        Access::Const => AccessType::Const,
        Access::ReadWrite if rpdo && !tpdo => AccessType::ReadWriteOutput,
        Access::ReadWrite if tpdo && !rpdo => AccessType::ReadWriteInput,
        Access::ReadWrite => AccessType::ReadWrite,
    }
}

/// Objects whose power-on value is a node's predefined COB-ID (`$NODEID` + base).
fn node_relative(index: u16, sub: u8) -> bool {
    // PDOs 1–4: the predefined connection set (5 and up have no node-relative default).
    let n = 4;
    (index == COB_ID_EMCY && sub == 0)
        || (sub == 1
            && [RPDO_COMMUNICATION, TPDO_COMMUNICATION]
                .iter()
                .any(|&base| (base..base + n).contains(&index)))
}

/// The power-on value of `index`:`sub`, as the node reads it now.
fn default_value(node: &mut CanNode, index: u16, sub: u8, ty: DataType) -> Option<Value> {
    let mut buf = [0u8; 64];
    let bytes = match node.read_object(index, sub, &mut buf) {
        Ok(n) => buf.get(..n).unwrap_or(&[]),
        // 0x1003 beyond the errors recorded: none at power-on.
        Err(AbortCode::NO_DATA) | Err(_) => return None,
    };
    let v = Value::from_le_bytes(bytes, ty).ok()?;
    match v {
        Value::Integer(raw) if node_relative(index, sub) => {
            let node_id = i128::from(node.node().get());
            // The predefined COB-ID's identifier is base + node id; bit 31 may be set.
            Some(if raw & 0x7F == node_id & 0x7F {
                Value::NodeRelative(raw - node_id)
            } else {
                Value::Integer(raw)
            })
        }
        v => Some(v),
    }
}

/// The EDS of `node` as it powers on (call it on a node fresh from `CanNode::new`: the
/// default values are the values its objects hold now), named `file_name`.
pub fn model(node: &mut CanNode, file_name: &str) -> Eds {
    let identity = |node: &mut CanNode, sub| {
        let mut b = [0u8; 4];
        match node.read_object(IDENTITY, sub, &mut b) {
            Ok(4) => Some(u32::from_le_bytes(b)),
            _ => None,
        }
    };
    let kind = node.dictionary().kind();
    let mut e = Eds::new(file_name);
    e.file_info.file_version = 1;
    e.file_info.description = format!(
        "Simulated {} (written for node {})",
        match kind {
            DeviceKind::Servo => "CiA 402 servo drive",
            DeviceKind::Encoder => "CiA 406 incremental encoder",
            DeviceKind::Switches => "CiA 401 digital inputs (switch cams)",
        },
        node.node().get()
    );
    e.file_info.created_by = format!("gantry-sim {}", env!("CARGO_PKG_VERSION"));
    let d = &mut e.device_info;
    d.vendor_name = "gantry".into();
    d.product_name = kind.name().into();
    d.vendor_number = identity(node, 1);
    d.product_number = identity(node, 2);
    d.revision_number = identity(node, 3);
    // Every bit rate of CiA 301 (the simulated bus runs any).
    e.device_info.baud_rates = [true; 8];
    e.device_info.simple_boot_up_slave = true;
    // Whole objects only (bit lengths are multiples of 8, CiA 301 §7.4.7.1).
    e.device_info.granularity = 8;
    let pdos = u16::from(node.dictionary().comm.pdo_count);
    e.device_info.nr_of_rx_pdo = pdos;
    e.device_info.nr_of_tx_pdo = pdos;
    // Dummy entries the node's RPDOs take (not BOOLEAN).
    for d in pdo::DUMMIES {
        if let Some(slot) = e.dummy_usage.get_mut(usize::from(d.index)) {
            *slot = true;
        }
    }
    for (index, name, object_type, specs) in layout(node) {
        let mut subs = Vec::with_capacity(specs.len());
        for (sub, sub_name, ty) in specs {
            let rpdo = node_maps(kind, Direction::Receive, index, sub, ty);
            let tpdo = node_maps(kind, Direction::Transmit, index, sub, ty);
            let access = node
                .object_info(index, sub)
                .map(|i| i.access)
                .unwrap_or(Access::ReadOnly);
            let mut s = SubObject::new(&sub_name, ty, access_type(access, rpdo, tpdo));
            s.pdo_mapping = rpdo || tpdo;
            s.default_value = default_value(node, index, sub, ty);
            if let Some((lo, hi)) = node.dictionary().servo_range(index, sub) {
                s.low_limit = Some(Value::Integer(i128::from(lo)));
                s.high_limit = Some(Value::Integer(i128::from(hi)));
            }
            subs.push((sub, s));
        }
        let object = if object_type == ObjectType::Var {
            match subs.pop() {
                Some((_, s)) => Object::var(index, s),
                None => continue,
            }
        } else {
            Object::compound(index, &name, object_type, subs)
        };
        e.insert(object);
    }
    e
}

/// A chain node whose EDS cannot be written.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum ChainEdsError {
    /// No slave has that node id.
    #[error("no slave of the chain has node = {node} (the slaves' node ids: {known})")]
    NoSuchNode {
        /// The id asked for.
        node: u8,
        /// Those there are.
        known: String,
    },
    /// The slave cannot be a node.
    #[error(transparent)]
    Slave(#[from] SlaveNodeError),
    /// The node cannot be built.
    #[error(transparent)]
    Node(#[from] CanNodeError),
}

/// The EDS of the slave with CANopen node id `node` in a chain description, as that
/// node powers on, named `file_name` (what `gantry-sim eds` writes).
pub fn for_chain_node(config: &SimConfig, node: u8, file_name: &str) -> Result<Eds, ChainEdsError> {
    let index = config
        .slaves
        .iter()
        .position(|s| s.node() == Some(node))
        .ok_or_else(|| ChainEdsError::NoSuchNode {
            node,
            known: {
                let ids: Vec<String> = config
                    .slaves
                    .iter()
                    .filter_map(|s| s.node().map(|n| n.to_string()))
                    .collect();
                if ids.is_empty() {
                    "none".to_string()
                } else {
                    ids.join(", ")
                }
            },
        })?;
    let mut n = CanNode::new(CanNodeConfig::from_slave(config, index)?)?;
    Ok(model(&mut n, file_name))
}

/// The EDS text of `node` as it powers on (see [`model`]).
pub fn write(node: &mut CanNode, file_name: &str) -> String {
    eds::write_eds(&model(node, file_name))
}
