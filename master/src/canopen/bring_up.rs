//! Bring-up of the CANopen bus (CiA 301 §7.3.2 NMT start-up, as an NMT master does it):
//! NMT reset communication, every configured node's boot-up awaited, each checked by SDO
//! to be a CiA 402 drive (0x1000) and named (0x1018), its PDOs configured by SDO in
//! pre-operational by the procedure of CiA 301 §7.5.2.35–.38 (COB-ID invalid, mapping
//! count 0, the entries, the count, transmission type 1 = synchronous at every SYNC, COB-ID
//! valid; PDOs 5 and up on COB-IDs gantry lends them, [`super::pdo::CobIdPool`], after
//! the drive is seen to have them: its EDS' `NrOfRXPDO`/`NrOfTXPDO`, or without an EDS an
//! SDO read of their communication objects), its heartbeat producer time (0x1017), its
//! consumer of gantry's own heartbeat
//! (0x1016), the SYNC counter's overflow value (0x1019, when the SYNC carries one) and the
//! communication cycle period (0x1006) set, then NMT start. It blocks, but every wait is bounded (boot-up [`BOOT_UP_TIMEOUT_NS`],
//! each SDO transfer [`SDO_TIMEOUT_NS`]). The same configuration writes
//! ([`config_steps`]) bring a node back in a restore, one per exchange.

use std::io::{self, Write};

use gantry_drives::canopen::cob_id::{CobId, NodeId, RPDO1_BASE, TPDO1_BASE};
use gantry_drives::canopen::heartbeat::{Heartbeat, NmtState};
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::sdo::{
    AbortCode, DownloadMode, Multiplexer, Outcome, SdoClient, SdoConfig, Side, UploadMode,
};
use gantry_drives::canopen::CanFrame;
use gantry_drives::cia402::objects;
use gantry_drives::cia402::pdo::PdoLayout;
use thiserror::Error;

use super::link::CanLink;
use super::load::{BusLoad, LoadError};
use super::pdo::{CobIdPool, CobIdsExhausted, DrivePlan, PdoPlan, Way, PREDEFINED_PDOS};
use crate::config::Config;

/// How long the nodes have to send their boot-up after NMT reset communication.
pub const BOOT_UP_TIMEOUT_NS: u64 = 2_000_000_000;
/// How long a node has to answer each SDO request (CiA 301 leaves it to the application).
pub const SDO_TIMEOUT_NS: u64 = 500_000_000;
/// Longest single wait for a frame in the bring-up's loops (the SDO client's timeout is
/// checked between waits).
const POLL_NS: u64 = 1_000_000;
/// 0x1000 device type.
pub const DEVICE_TYPE: u16 = 0x1000;
/// 0x1006 communication cycle period (µs).
pub const COMMUNICATION_CYCLE_PERIOD: u16 = 0x1006;
/// 0x1017 producer heartbeat time (ms).
pub const PRODUCER_HEARTBEAT_TIME: u16 = 0x1017;
/// 0x1016 consumer heartbeat time: sub 1 = node id << 16 | time in ms (CiA 301
/// §7.5.2.16).
pub const CONSUMER_HEARTBEAT_TIME: u16 = 0x1016;
/// 0x1019 synchronous counter overflow value (CiA 301 §7.5.2.22).
pub const SYNC_COUNTER_OVERFLOW: u16 = 0x1019;
/// 0x1018 identity object.
pub const IDENTITY: u16 = 0x1018;
/// Device profile number of CiA 402 drives (0x1000 bits 0–15).
pub const PROFILE_CIA402: u16 = 402;
/// First RPDO communication parameter (CiA 301 §7.5.2.35).
pub const RPDO_COMMUNICATION: u16 = 0x1400;
/// First RPDO mapping parameter (§7.5.2.37).
pub const RPDO_MAPPING: u16 = 0x1600;
/// First TPDO communication parameter (§7.5.2.36).
pub const TPDO_COMMUNICATION: u16 = 0x1800;
/// First TPDO mapping parameter (§7.5.2.38).
pub const TPDO_MAPPING: u16 = 0x1A00;
/// COB-ID bit 31: the PDO does not exist.
pub const COB_ID_INVALID: u32 = 1 << 31;
/// Transmission type 1: synchronous, every SYNC (CiA 301 §7.5.2.35 Table 70).
pub const TT_SYNC_EVERY: u8 = 1;
/// Bytes of an SDO client's buffer (the bus moves objects of at most 4 bytes).
pub const SDO_BUFFER: usize = 32;

/// An SDO client of the bus.
pub type Client = SdoClient<[u8; SDO_BUFFER]>;

/// Why an SDO transfer of the bring-up failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoFailure {
    /// The node aborted it.
    Refused(AbortCode),
    /// gantry aborted it (a timeout, a protocol error).
    Aborted(AbortCode),
}

impl std::fmt::Display for SdoFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Refused(code) => write!(f, "the node refused: {code}"),
            Self::Aborted(AbortCode::TIMED_OUT) => {
                write!(f, "no answer within {} ms", SDO_TIMEOUT_NS / 1_000_000)
            }
            Self::Aborted(code) => write!(f, "gantry aborted: {code}"),
        }
    }
}

/// Why the CANopen bus did not come up.
#[derive(Debug, Error)]
pub enum StartError {
    /// The frames do not fit the bit rate, or a layout does not fit the PDOs.
    #[error("CANopen: {0}")]
    Load(#[from] LoadError),
    /// An axis names no node (the configuration is not for CANopen).
    #[error("CANopen: axis {axis:?} has no node id")]
    NoNode {
        /// The axis.
        axis: String,
    },
    /// The link failed.
    #[error("CANopen: {what}")]
    Link {
        /// What was being done.
        what: &'static str,
        /// Why.
        #[source]
        source: io::Error,
    },
    /// Nodes that sent no boot-up.
    #[error(
        "CANopen: no boot-up from node{} {} within {} ms of NMT reset communication \
         (powered? node id? bit rate?)",
        if missing.len() == 1 { "" } else { "s" },
        list(missing),
        waited_ms
    )]
    NoBootUp {
        /// Their node ids.
        missing: Vec<u8>,
        /// How long gantry waited.
        waited_ms: u64,
    },
    /// A node is not a CiA 402 drive.
    #[error(
        "CANopen node {node}: device type 0x{device_type:08X} is profile {}, not a CiA 402 \
         drive (0x1000 bits 0–15 = 402)",
        device_type & 0xFFFF
    )]
    NotCia402 {
        /// The node.
        node: u8,
        /// Its 0x1000.
        device_type: u32,
    },
    /// A node an axis' switches read as an I/O module is not a CiA 401 device.
    #[error(
        "CANopen node {node} ({module}): device type 0x{device_type:08X} is profile {}, not \
         a CiA 401 I/O module (0x1000 bits 0–15 = 401)",
        device_type & 0xFFFF
    )]
    NotCia401 {
        /// The node.
        node: u8,
        /// What reads it.
        module: String,
        /// Its 0x1000.
        device_type: u32,
    },
    /// A node's heartbeat did not report Operational after NMT start.
    #[error(
        "CANopen node {node}: not Operational {waited_ms} ms after NMT start (its last \
         heartbeat: {})",
        match state { Some(s) => format!("{s:?}"), None => "none".to_string() }
    )]
    NotStarted {
        /// The node.
        node: u8,
        /// What its last heartbeat said.
        state: Option<NmtState>,
        /// How long gantry waited.
        waited_ms: u64,
    },
    /// `[bus] master_node` is no node id (the configuration's check refuses it first).
    #[error("CANopen: master_node {id} is outside 1..=127")]
    MasterNode {
        /// What was given.
        id: u8,
    },
    /// A node is not the device its axis' EDS describes (CiA 306-1 §4.4 `VendorNumber`,
    /// `ProductNumber` against 0x1018:01/02): the checks made against the EDS would be
    /// of another device's objects.
    #[error(
        "CANopen node {node} (axis {axis:?}): its identity 0x1018:{sub:02X} says {what} \
         0x{read:08X}, {file} describes {what} 0x{want:08X} ({key}): not the device of that EDS"
    )]
    WrongDevice {
        /// The node.
        node: u8,
        /// Its axis.
        axis: String,
        /// "vendor" or "product".
        what: &'static str,
        /// 0x1018's sub-index.
        sub: u8,
        /// What the node said.
        read: u32,
        /// What the EDS says.
        want: u32,
        /// The EDS' key.
        key: &'static str,
        /// The EDS.
        file: String,
    },
    /// The SDO client's configuration.
    #[error("CANopen: SDO client: {0}")]
    SdoConfig(gantry_drives::canopen::sdo::SdoConfigError),
    /// A drive has fewer PDOs of a direction than its axis' process data need.
    #[error(
        "CANopen node {node} (axis {axis:?}): its process data need {needed} {}s ({bytes} \
         {} bytes in PDOs of 8), the drive has {has} ({how})",
        way.name(),
        match way { Way::Rpdo => "output", Way::Tpdo => "input" }
    )]
    TooFewPdos {
        /// The node.
        node: u8,
        /// Its axis.
        axis: String,
        /// Which way.
        way: Way,
        /// PDOs the layout needs.
        needed: usize,
        /// Bytes of the layout that way.
        bytes: usize,
        /// PDOs the drive has.
        has: u16,
        /// How gantry knows ("NrOfTXPDO in acme.eds", "0x1804:01 does not exist …").
        how: String,
    },
    /// PDOs 5 and up found no COB-ID to borrow.
    #[error("CANopen node {node} (axis {axis:?}): {source}")]
    CobIds {
        /// The node.
        node: u8,
        /// Its axis.
        axis: String,
        /// Why.
        source: CobIdsExhausted,
    },
    /// A device outside the configuration speaks with a node id whose predefined
    /// identifier gantry lent to a PDO.
    #[error(
        "CANopen: node {lender} is on the bus (its {heard} came), but gantry gave its \
         predefined COB-ID 0x{cob_id:03X} to {}{pdo} of node {node} (axis {axis:?}): \
         add it to the configuration or give it another node id",
        way.name()
    )]
    CobIdTaken {
        /// The node heard.
        lender: u8,
        /// What it sent.
        heard: &'static str,
        /// The identifier lent.
        cob_id: u16,
        /// Which way the PDO goes.
        way: Way,
        /// Its number.
        pdo: u8,
        /// The node it was lent to.
        node: u8,
        /// Its axis.
        axis: String,
    },
    /// An SDO transfer failed.
    #[error("CANopen node {node}: {what} ({mux}): {failure}")]
    Sdo {
        /// The node.
        node: u8,
        /// What the transfer was for.
        what: &'static str,
        /// The object.
        mux: Multiplexer,
        /// Why it failed.
        failure: SdoFailure,
    },
}

/// What every node's communication is set to besides its PDOs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommSettings {
    /// 0x1017: its heartbeat producer time (ms).
    pub heartbeat_ms: u16,
    /// 0x1006: the communication cycle period (µs).
    pub cycle_us: u32,
    /// gantry's node id, whose heartbeat the node consumes (0x1016:01).
    pub master: NodeId,
    /// The consumer time for gantry's heartbeat (ms).
    pub master_consumer_ms: u16,
    /// 0x1019 (0: SYNC without counter, left as the node has it).
    pub sync_overflow: u8,
}

impl CommSettings {
    /// The settings of `config`'s `[bus]`.
    pub fn of(config: &Config) -> Result<Self, StartError> {
        Ok(Self {
            heartbeat_ms: config.bus.heartbeat_producer_ms(),
            cycle_us: config.bus.cycle_us,
            master: master_node(config)?,
            master_consumer_ms: config.bus.master_consumer_ms(),
            sync_overflow: config.bus.sync_counter.unwrap_or(0),
        })
    }
}

/// gantry's node id on the bus of `config`.
pub fn master_node(config: &Config) -> Result<NodeId, StartError> {
    let id = config.bus.master_node();
    NodeId::new(id).map_err(|_| StartError::MasterNode { id })
}

fn list(ids: &[u8]) -> String {
    ids.iter().map(u8::to_string).collect::<Vec<_>>().join(", ")
}

/// One SDO download of a node's configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoStep {
    /// The object.
    pub mux: Multiplexer,
    /// Its value, little-endian (first `len` bytes).
    pub data: [u8; 4],
    /// Bytes of the value.
    pub len: u8,
    /// What it is for (for messages).
    pub what: &'static str,
}

impl SdoStep {
    fn new(index: u16, sub: u8, data: &[u8], what: &'static str) -> Self {
        let mut d = [0u8; 4];
        for (dst, src) in d.iter_mut().zip(data) {
            *dst = *src;
        }
        Self {
            mux: Multiplexer::new(index, sub),
            data: d,
            len: data.len().min(4) as u8,
            what,
        }
    }

    /// The value's bytes.
    pub fn value(&self) -> &[u8] {
        self.data.get(..usize::from(self.len)).unwrap_or(&[])
    }
}

/// Every SDO download that configures a node for the cycle, in order: per PDO of each
/// direction, the procedure of CiA 301 §7.5.2.37 for those `plan` uses (COB-ID invalid
/// on its identifier — the predefined one of PDOs 1–4, the lent one of 5 and up —,
/// transmission type 1, mapping count 0, the entries, the count, COB-ID valid) and
/// COB-ID invalid for the others of 1–4 (a vendor's defaults may have them valid; those
/// of 5 and up power up invalid, CiA 301 predefining no identifier for them, and NMT
/// reset communication before each configuration brings them back there); then 0x1017
/// heartbeat producer time, 0x1016:01 the consumer of gantry's heartbeat, with a SYNC counter 0x1006 = 0 and 0x1019 (CiA 301 §7.5.2.22: the
/// overflow value may only change while the communication cycle period is 0), 0x1006
/// communication cycle period, and 0x6060 = CSP when the layout does not carry the mode.
pub fn config_steps(
    node: NodeId,
    plan: &DrivePlan,
    layout: &PdoLayout,
    comm: &CommSettings,
) -> Vec<SdoStep> {
    config_steps_for(node, plan, layout, comm, [4, 4])
}

/// [`config_steps`] for a node with `pdos[0]` RPDOs and `pdos[1]` TPDOs (its EDS'
/// `NrOfRXPDO` / `NrOfTXPDO`): of the first four, the PDOs a node does not have are left
/// alone (a write to their objects would be aborted: 0x06020000, no object); `plan`'s
/// PDOs are all written (that the node has them is checked before).
pub fn config_steps_for(
    node: NodeId,
    plan: &DrivePlan,
    layout: &PdoLayout,
    comm: &CommSettings,
    pdos: [u16; 2],
) -> Vec<SdoStep> {
    let CommSettings {
        heartbeat_ms,
        cycle_us,
        master,
        master_consumer_ms,
        sync_overflow,
    } = *comm;
    let mut steps = Vec::new();
    for ((comm, mapping, base, pdos, what), have) in [
        (
            RPDO_COMMUNICATION,
            RPDO_MAPPING,
            RPDO1_BASE,
            &plan.rpdos,
            "RPDO",
        ),
        (
            TPDO_COMMUNICATION,
            TPDO_MAPPING,
            TPDO1_BASE,
            &plan.tpdos,
            "TPDO",
        ),
    ]
    .into_iter()
    .zip(pdos)
    {
        let touched = usize::from(have).min(PREDEFINED_PDOS).max(pdos.len());
        for n in 0..touched as u8 {
            let comm = comm + u16::from(n);
            let mapping = mapping + u16::from(n);
            let used: Option<&PdoPlan> = pdos.iter().find(|p| p.number == n + 1);
            let cob = u32::from(match used {
                Some(p) => p.cob_id,
                None => base + 0x100 * u16::from(n) + u16::from(node.get()),
            });
            steps.push(SdoStep::new(
                comm,
                1,
                &(COB_ID_INVALID | cob).to_le_bytes(),
                if what == "RPDO" {
                    "RPDO COB-ID invalid"
                } else {
                    "TPDO COB-ID invalid"
                },
            ));
            let Some(p) = used else { continue };
            steps.push(SdoStep::new(comm, 2, &[TT_SYNC_EVERY], "transmission type"));
            steps.push(SdoStep::new(mapping, 0, &[0], "mapping count 0"));
            for (i, value) in p.mapping_values().enumerate() {
                steps.push(SdoStep::new(
                    mapping,
                    i as u8 + 1,
                    &value.to_le_bytes(),
                    "mapping entry",
                ));
            }
            steps.push(SdoStep::new(
                mapping,
                0,
                &[p.entries.len() as u8],
                "mapping count",
            ));
            steps.push(SdoStep::new(
                comm,
                1,
                &cob.to_le_bytes(),
                if what == "RPDO" {
                    "RPDO COB-ID valid"
                } else {
                    "TPDO COB-ID valid"
                },
            ));
        }
    }
    steps.push(SdoStep::new(
        PRODUCER_HEARTBEAT_TIME,
        0,
        &heartbeat_ms.to_le_bytes(),
        "heartbeat producer time",
    ));
    let consumer = u32::from(master.get()) << 16 | u32::from(master_consumer_ms);
    steps.push(SdoStep::new(
        CONSUMER_HEARTBEAT_TIME,
        1,
        &consumer.to_le_bytes(),
        "consumer of gantry's heartbeat",
    ));
    if sync_overflow != 0 {
        steps.push(SdoStep::new(
            COMMUNICATION_CYCLE_PERIOD,
            0,
            &0u32.to_le_bytes(),
            "communication cycle period 0 (before 0x1019)",
        ));
        steps.push(SdoStep::new(
            SYNC_COUNTER_OVERFLOW,
            0,
            &[sync_overflow],
            "synchronous counter overflow value",
        ));
    }
    steps.push(SdoStep::new(
        COMMUNICATION_CYCLE_PERIOD,
        0,
        &cycle_us.to_le_bytes(),
        "communication cycle period",
    ));
    if !layout.outputs.contains(&objects::MODES_OF_OPERATION) {
        let csp = gantry_drives::csp::MODE_CSP;
        steps.push(SdoStep::new(
            objects::MODES_OF_OPERATION.index,
            0,
            &csp.to_le_bytes(),
            "modes of operation = CSP",
        ));
    }
    steps
}

/// What bring-up found of one node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeInfo {
    /// The node.
    pub node: NodeId,
    /// 0x1000.
    pub device_type: u32,
    /// 0x1018:01–04 (sub 1 is mandatory, 2–4 optional: None when the node has none).
    pub identity: [Option<u32>; 4],
}

/// One drive as the configuration gives it: its node, layout and PDO plan.
#[derive(Clone, Debug)]
pub struct DriveSetup {
    /// The axis' name.
    pub axis: String,
    /// The node.
    pub node: NodeId,
    /// Its device profile (0x1000 bits 0–15): [`PROFILE_CIA402`] for a drive,
    /// [`super::io_module::PROFILE_CIA401`] for an I/O module.
    pub profile: u16,
    /// The layout.
    pub layout: PdoLayout,
    /// Its PDOs.
    pub plan: DrivePlan,
    /// The SDO writes that configure it.
    pub steps: Vec<SdoStep>,
    /// What the axis' EDS says the node is, when it names one.
    pub expect: Option<ExpectedIdentity>,
    /// Whether the bring-up asks the node (by SDO) whether it has the PDOs beyond the
    /// fourth that the plan uses: a drive without an EDS (one with an EDS was checked
    /// against its `NrOfRXPDO`/`NrOfTXPDO` at configuration).
    pub ask_pdos: bool,
}

/// The identity an axis' EDS gives its node (`[DeviceInfo]`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExpectedIdentity {
    /// The EDS.
    pub file: String,
    /// `VendorNumber=` (0x1018:01).
    pub vendor: Option<u32>,
    /// `ProductNumber=` (0x1018:02).
    pub product: Option<u32>,
}

impl ExpectedIdentity {
    /// The first of vendor and product in which the node's `identity` (0x1018:01–04 as
    /// read) differs from the EDS. A sub-index the node does not have is not compared
    /// (only the vendor id is mandatory, CiA 301 §7.5.2.23).
    pub fn mismatch(&self, setup: &DriveSetup, identity: &[Option<u32>; 4]) -> Option<StartError> {
        [
            ("vendor", 1u8, "VendorNumber", self.vendor, identity[0]),
            ("product", 2, "ProductNumber", self.product, identity[1]),
        ]
        .into_iter()
        .find_map(|(what, sub, key, want, read)| match (want, read) {
            (Some(want), Some(read)) if want != read => Some(StartError::WrongDevice {
                node: setup.node.get(),
                axis: setup.axis.clone(),
                what,
                sub,
                read,
                want,
                key,
                file: self.file.clone(),
            }),
            _ => None,
        })
    }
}

/// The drives of `config`, in the order of its real axes (bus position `k` = the `k`-th
/// real axis; axes of other types have no drive), then the I/O modules its switches read
/// (their positions after the drives'), after the load check.
pub fn drive_setups(config: &Config) -> Result<Vec<DriveSetup>, StartError> {
    BusLoad::of_config(config)?.check()?;
    let mut setups = config
        .drive_axes()
        .into_iter()
        .map(|i| drive_setup(config, i))
        .collect::<Result<Vec<_>, _>>()?;
    for m in config.module_nodes() {
        setups.push(super::io_module::setup(config, &m)?);
    }
    Ok(setups)
}

/// The node and layout of axis `axis` of `config`.
fn axis_node_layout(config: &Config, axis: usize) -> Result<(NodeId, PdoLayout), StartError> {
    let a = config.axes.get(axis).ok_or_else(|| StartError::NoNode {
        axis: format!("#{axis}"),
    })?;
    let node = a
        .node
        .and_then(|n| NodeId::new(n).ok())
        .ok_or_else(|| StartError::NoNode {
            axis: a.name.clone(),
        })?;
    let layout = a.pdo_layout().map_err(|(_, reason)| LoadError::Pdo {
        axis: a.name.clone(),
        reason,
    })?;
    Ok((node, layout))
}

/// The PDOs of every axis of `config`, in axis order, with their COB-IDs: PDOs 1–4 on
/// their node's predefined identifiers, 5 and up on identifiers lent by the node ids
/// that neither an axis' drive, nor an I/O module the switches read, nor gantry has
/// ([`CobIdPool`], axis by axis: the same configuration gives the same COB-IDs).
pub fn axis_plans(config: &Config) -> Result<Vec<DrivePlan>, StartError> {
    let mut used: Vec<u8> = config.axes.iter().filter_map(|a| a.node).collect();
    used.extend(config.module_nodes().iter().map(|m| m.node));
    used.push(config.bus.master_node());
    let mut pool = CobIdPool::new(&used);
    let mut plans = Vec::with_capacity(config.axes.len());
    for i in config.drive_axes() {
        let Some(a) = config.axes.get(i) else {
            continue;
        };
        let (node, layout) = axis_node_layout(config, i)?;
        let mut plan = DrivePlan::on_node(&layout, node).map_err(|source| LoadError::Layout {
            axis: a.name.clone(),
            pdo: a.pdo.clone(),
            source,
        })?;
        pool.lend(&mut plan).map_err(|source| StartError::CobIds {
            node: node.get(),
            axis: a.name.clone(),
            source,
        })?;
        plans.push(plan);
    }
    Ok(plans)
}

/// The drive of axis `axis` of `config`: its node, layout, PDOs and the SDO writes that
/// configure it (only the PDOs its EDS says it has, when the axis names one; a layout
/// that needs more PDOs than the EDS gives the drive is refused).
pub fn drive_setup(config: &Config, axis: usize) -> Result<DriveSetup, StartError> {
    let (node, layout) = axis_node_layout(config, axis)?;
    let a = config.axes.get(axis).ok_or_else(|| StartError::NoNode {
        axis: format!("#{axis}"),
    })?;
    // Plans are by bus position: the axis' drive.
    let plan = axis_plans(config)?
        .into_iter()
        .nth(a.drive)
        .ok_or_else(|| StartError::NoNode {
            axis: a.name.clone(),
        })?;
    let pdos = match config.eds_of(axis) {
        None => [PREDEFINED_PDOS as u16; 2],
        Some(e) => {
            use gantry_drives::canopen::eds::PdoDirection;
            let has = [
                e.max_pdos(PdoDirection::Receive),
                e.max_pdos(PdoDirection::Transmit),
            ];
            for ((way, pdos, bytes, key), has) in [
                (Way::Rpdo, &plan.rpdos, plan.output_bytes, "NrOfRXPDO"),
                (Way::Tpdo, &plan.tpdos, plan.input_bytes, "NrOfTXPDO"),
            ]
            .into_iter()
            .zip(has)
            {
                if pdos.len() > usize::from(has) {
                    return Err(StartError::TooFewPdos {
                        node: node.get(),
                        axis: a.name.clone(),
                        way,
                        needed: pdos.len(),
                        bytes,
                        has,
                        how: format!("{key} in {}", e.file),
                    });
                }
            }
            has
        }
    };
    let comm = CommSettings::of(config)?;
    let mut steps = config_steps_for(node, &plan, &layout, &comm, pdos);
    // What the switches need of the drive: 0x60D0 for homing on a limit switch's edge.
    let switch_writes = a
        .switches
        .sdo_writes()
        .map_err(|(_, reason)| LoadError::Pdo {
            axis: a.name.clone(),
            reason,
        })?;
    steps.extend(
        switch_writes
            .iter()
            .map(|w| SdoStep::new(w.index, w.sub, &w.value, "touch probe source (0x60D0)")),
    );
    // 0x1006 and 0x1016 are optional (CiA 301 §7.5.2.6, §7.5.2.16): a device whose EDS
    // has no communication cycle period is not told one, one with no heartbeat consumer
    // does not watch gantry's heartbeat (the writes would be aborted, no object); every
    // other write (0x1019 with a SYNC counter among them) is one the drive must take,
    // and its EDS is checked for it.
    if let Some(eds) = config.eds_of(axis) {
        for (index, sub) in [
            (COMMUNICATION_CYCLE_PERIOD, 0),
            (CONSUMER_HEARTBEAT_TIME, 1),
        ] {
            if eds.entry(index, sub).is_none() {
                steps.retain(|s| s.mux.index != index);
            }
        }
    }
    Ok(DriveSetup {
        axis: a.name.clone(),
        node,
        profile: PROFILE_CIA402,
        layout,
        plan,
        steps,
        expect: config.eds_of(axis).map(|e| ExpectedIdentity {
            file: e.file.clone(),
            vendor: e.device_info.vendor_number,
            product: e.device_info.product_number,
        }),
        ask_pdos: config.eds_of(axis).is_none(),
    })
}

/// The SDO client gantry uses for `node` ([`SDO_TIMEOUT_NS`]).
pub fn client(node: NodeId) -> Result<Client, StartError> {
    let config = SdoConfig {
        timeout_ns: SDO_TIMEOUT_NS,
        ..SdoConfig::default()
    };
    SdoClient::new(node, config, [0u8; SDO_BUFFER]).map_err(StartError::SdoConfig)
}

/// Sends `frame`, naming what failed.
pub fn send(
    link: &mut dyn CanLink,
    frame: &CanFrame,
    what: &'static str,
) -> Result<(), StartError> {
    link.send(frame)
        .map_err(|source| StartError::Link { what, source })
}

/// The NMT frame of `command` for `target`.
pub fn nmt(command: NmtCommand, target: NmtTarget) -> CanFrame {
    NmtFrame { command, target }.emit()
}

/// One blocking SDO transfer: a download of `data`, or an upload (`data` None) whose
/// bytes are left in the client's buffer. Of the frames that are not the node's answer,
/// one that shows a clash with a COB-ID gantry lent ([`Lent::check`]) ends the bring-up.
fn transfer(
    link: &mut dyn CanLink,
    client: &mut Client,
    mux: Multiplexer,
    data: Option<&[u8]>,
    what: &'static str,
    lent: &Lent,
) -> Result<(), StartError> {
    let node = client.node().get();
    let now = link.now_ns();
    let started = match data {
        Some(d) => client.download(mux, d, DownloadMode::Auto, now),
        None => client.upload(mux, UploadMode::Normal, now),
    };
    // A client made for this transfer is idle and the values fit: cannot fail.
    if started.is_err() {
        return Err(StartError::Sdo {
            node,
            what,
            mux,
            failure: SdoFailure::Aborted(AbortCode::GENERAL_ERROR),
        });
    }
    let failed = |failure| StartError::Sdo {
        node,
        what,
        mux,
        failure,
    };
    loop {
        while let Some(f) = client.transmit() {
            send(link, &f, "sending an SDO request")?;
        }
        let now = link.now_ns();
        let outcome = match client.poll(now) {
            Some(o) => Some(o),
            None => match link
                .receive(now + POLL_NS)
                .map_err(|source| StartError::Link {
                    what: "receiving",
                    source,
                })? {
                Some(r) if r.frame.id() == CobId::SdoTx(client.node()).id() => {
                    client.receive(&r.frame, link.now_ns())
                }
                Some(r) => match lent.check(&r.frame) {
                    Some(clash) => return Err(clash),
                    None => None,
                },
                None => None,
            },
        };
        match outcome {
            None => continue,
            Some(Outcome::Downloaded { .. } | Outcome::Uploaded { .. }) => return Ok(()),
            Some(Outcome::Aborted { code, by, .. }) => {
                // The abort frame of ours goes out.
                while let Some(f) = client.transmit() {
                    send(link, &f, "sending an SDO abort")?;
                }
                return Err(failed(match by {
                    Side::Server => SdoFailure::Refused(code),
                    Side::Client => SdoFailure::Aborted(code),
                }));
            }
        }
    }
}

/// An upload of a 32-bit value.
fn upload_u32(
    link: &mut dyn CanLink,
    client: &mut Client,
    mux: Multiplexer,
    what: &'static str,
    lent: &Lent,
) -> Result<u32, StartError> {
    transfer(link, client, mux, None, what, lent)?;
    let d = client.data();
    let mut b = [0u8; 4];
    for (dst, src) in b.iter_mut().zip(d) {
        *dst = *src;
    }
    Ok(u32::from_le_bytes(b))
}

/// An I/O module whose TPDO1 maps, as CiA 401 §6 has it by default, 0x6000:01..=n with
/// n at least the input groups the switches need: that mapping is taken as it is (a
/// module may have a static one that refuses to be written, CiA 301 §7.5.2.38) — its
/// mapping writes leave `d.steps`, which keep the transmission type, and its layout and
/// plan become the n groups the TPDO carries. Any other mapping is written by SDO.
fn take_default_mapping(
    link: &mut dyn CanLink,
    client: &mut Client,
    d: &mut DriveSetup,
    out: &mut (dyn Write + Send),
    lent: &Lent,
) -> Result<(), StartError> {
    let mapping = |sub| Multiplexer::new(TPDO_MAPPING, sub);
    let n = upload_u32(link, client, mapping(0), "TPDO1 mapping count", lent)?;
    let needed = d.layout.inputs.len() as u32;
    if !(needed..=8).contains(&n) {
        return Ok(());
    }
    for k in 1..=n as u8 {
        let entry = upload_u32(link, client, mapping(k), "TPDO1 mapping entry", lent)?;
        let want = gantry_drives::cia402::pdo::mapping_entry(&super::io_module::read_input_8(k));
        if entry != want {
            return Ok(());
        }
    }
    let layout = super::io_module::layout(n as u8);
    let Ok(plan) = DrivePlan::on_node(&layout, d.node) else {
        return Ok(());
    };
    d.steps.retain(|s| s.mux.index != TPDO_MAPPING);
    d.layout = layout;
    d.plan = plan;
    let _ = writeln!(
        out,
        "  node {}: TPDO1 taken as its CiA 401 default mapping (0x6000:01..={n:02X})",
        d.node.get()
    );
    Ok(())
}

/// Whether the node of `d` has the PDOs beyond the fourth that its plan uses (a drive
/// without an EDS): an SDO read of each one's COB-ID (0x1404:01, 0x1804:01, …). One the
/// node does not have (abort 0x06020000, no object) refuses the drive, naming how many
/// it has (PDOs are numbered from 1 without gaps).
fn ask_pdos(
    link: &mut dyn CanLink,
    client: &mut Client,
    d: &DriveSetup,
    lent: &Lent,
) -> Result<(), StartError> {
    for (way, comm, pdos, bytes) in [
        (
            Way::Rpdo,
            RPDO_COMMUNICATION,
            &d.plan.rpdos,
            d.plan.output_bytes,
        ),
        (
            Way::Tpdo,
            TPDO_COMMUNICATION,
            &d.plan.tpdos,
            d.plan.input_bytes,
        ),
    ] {
        for p in pdos
            .iter()
            .filter(|p| usize::from(p.number) > PREDEFINED_PDOS)
        {
            let index = comm + u16::from(p.number) - 1;
            let mux = Multiplexer::new(index, 1);
            match transfer(link, client, mux, None, "PDO COB-ID (is it there?)", lent) {
                Ok(()) => {}
                Err(StartError::Sdo {
                    failure: SdoFailure::Refused(code),
                    ..
                }) if code == AbortCode::OBJECT_DOES_NOT_EXIST => {
                    return Err(StartError::TooFewPdos {
                        node: d.node.get(),
                        axis: d.axis.clone(),
                        way,
                        needed: pdos.len(),
                        bytes,
                        has: u16::from(p.number) - 1,
                        how: format!("0x{index:04X}:01 does not exist: SDO abort {code}"),
                    })
                }
                Err(e) => return Err(e),
            }
        }
    }
    Ok(())
}

/// A COB-ID gantry lent to a PDO 5 or up: the node id whose predefined identifier it
/// is, and the PDO that has it.
struct LentId {
    lender: u8,
    cob_id: u16,
    way: Way,
    pdo: u8,
    node: u8,
    axis: String,
}

/// The COB-IDs gantry lent: a frame from a node id that lent one (a device outside the
/// configuration) is a clash.
struct Lent(Vec<LentId>);

impl Lent {
    fn of(drives: &[DriveSetup]) -> Self {
        let mut v = Vec::new();
        for d in drives {
            for (way, pdos) in [(Way::Rpdo, &d.plan.rpdos), (Way::Tpdo, &d.plan.tpdos)] {
                for p in pdos
                    .iter()
                    .filter(|p| usize::from(p.number) > PREDEFINED_PDOS)
                {
                    v.push(LentId {
                        lender: (p.cob_id & 0x7F) as u8,
                        cob_id: p.cob_id,
                        way,
                        pdo: p.number,
                        node: d.node.get(),
                        axis: d.axis.clone(),
                    });
                }
            }
        }
        Self(v)
    }

    /// The clash `frame` shows: the boot-up or heartbeat of a node id that lent.
    fn check(&self, frame: &CanFrame) -> Option<StartError> {
        let hb = Heartbeat::parse(frame).ok()?;
        let l = self.0.iter().find(|l| l.lender == hb.node.get())?;
        Some(StartError::CobIdTaken {
            lender: l.lender,
            heard: if hb.is_boot_up() {
                "boot-up"
            } else {
                "heartbeat"
            },
            cob_id: l.cob_id,
            way: l.way,
            pdo: l.pdo,
            node: l.node,
            axis: l.axis.clone(),
        })
    }
}

/// Bring-up: every step in order on `link`, printing them to `out`. Returns what each
/// node said of itself; the nodes are Operational (each said so in a heartbeat within
/// `consumer_ns` of NMT start), their PDOs synchronous.
pub fn run(
    link: &mut dyn CanLink,
    drives: &mut [DriveSetup],
    consumer_ns: u64,
    out: &mut (dyn Write + Send),
) -> Result<Vec<NodeInfo>, StartError> {
    // What waits from before (a node's power-on boot-up) is not the answer to our reset.
    let now = link.now_ns();
    while link
        .receive(now)
        .map_err(|source| StartError::Link {
            what: "receiving",
            source,
        })?
        .is_some()
    {}
    send(
        link,
        &nmt(NmtCommand::ResetCommunication, NmtTarget::All),
        "sending NMT reset communication",
    )?;
    let start = link.now_ns();
    let deadline = start + BOOT_UP_TIMEOUT_NS;
    let mut booted = vec![false; drives.len()];
    let lent = Lent::of(drives);
    while booted.iter().any(|b| !b) {
        let Some(r) = link.receive(deadline).map_err(|source| StartError::Link {
            what: "waiting for boot-up",
            source,
        })?
        else {
            break;
        };
        if let Some(e) = lent.check(&r.frame) {
            return Err(e);
        }
        if let Ok(hb) = Heartbeat::parse(&r.frame) {
            if hb.is_boot_up() {
                if let Some(i) = drives.iter().position(|d| d.node == hb.node) {
                    booted[i] = true;
                }
            }
        }
    }
    let missing: Vec<u8> = drives
        .iter()
        .zip(&booted)
        .filter(|(_, b)| !**b)
        .map(|(d, _)| d.node.get())
        .collect();
    if !missing.is_empty() {
        return Err(StartError::NoBootUp {
            missing,
            waited_ms: link.now_ns().saturating_sub(start) / 1_000_000,
        });
    }
    let _ = writeln!(
        out,
        "CANopen: {} nodes booted after NMT reset communication",
        drives.len()
    );
    let mut infos = Vec::with_capacity(drives.len());
    for d in drives.iter_mut() {
        let mut c = client(d.node)?;
        let node = d.node.get();
        let device_type = upload_u32(
            link,
            &mut c,
            Multiplexer::new(DEVICE_TYPE, 0),
            "device type",
            &lent,
        )?;
        if device_type & 0xFFFF != u32::from(d.profile) {
            return Err(if d.profile == PROFILE_CIA402 {
                StartError::NotCia402 { node, device_type }
            } else {
                StartError::NotCia401 {
                    node,
                    module: d.axis.clone(),
                    device_type,
                }
            });
        }
        let mut identity = [None; 4];
        for (sub, slot) in (1u8..=4).zip(identity.iter_mut()) {
            match upload_u32(
                link,
                &mut c,
                Multiplexer::new(IDENTITY, sub),
                "identity",
                &lent,
            ) {
                Ok(v) => *slot = Some(v),
                // Only the vendor id is mandatory (CiA 301 §7.5.2.23).
                Err(StartError::Sdo {
                    failure: SdoFailure::Refused(_),
                    ..
                }) if sub > 1 => {}
                Err(e) => return Err(e),
            }
        }
        if let Some(e) = d.expect.as_ref().and_then(|x| x.mismatch(d, &identity)) {
            return Err(e);
        }
        let _ = writeln!(
            out,
            "  node {node} ({}): CiA {} device type 0x{device_type:08X}, vendor \
             0x{:08X}, product 0x{:08X}, revision 0x{:08X}, serial {}",
            if d.profile == PROFILE_CIA402 {
                format!("axis {:?}", d.axis)
            } else {
                d.axis.clone()
            },
            d.profile,
            identity[0].unwrap_or(0),
            identity[1].unwrap_or(0),
            identity[2].unwrap_or(0),
            identity[3].map_or("-".to_string(), |s| s.to_string()),
        );
        if d.profile == super::io_module::PROFILE_CIA401 {
            take_default_mapping(link, &mut c, d, out, &lent)?;
        }
        if d.ask_pdos {
            ask_pdos(link, &mut c, d, &lent)?;
        }
        let mut absent: Vec<u16> = Vec::new();
        for step in &d.steps {
            if absent.contains(&step.mux.index) {
                continue;
            }
            match transfer(link, &mut c, step.mux, Some(step.value()), step.what, &lent) {
                Ok(()) => {}
                // An I/O module has no EDS that says which optional objects it has:
                // without 0x1006 it does not watch the SYNC, without 0x1016 gantry's
                // heartbeat (CiA 301 §7.5.2.6, §7.5.2.16: optional) — harmless for an input
                // module, which has no outputs to make safe; its heartbeat (0x1017) and
                // its TPDO are still watched by gantry.
                Err(StartError::Sdo {
                    failure: SdoFailure::Refused(AbortCode::OBJECT_DOES_NOT_EXIST),
                    ..
                }) if d.profile != PROFILE_CIA402
                    && [COMMUNICATION_CYCLE_PERIOD, CONSUMER_HEARTBEAT_TIME]
                        .contains(&step.mux.index) =>
                {
                    absent.push(step.mux.index);
                    let _ = writeln!(
                        out,
                        "  node {node}: has no 0x{:04X} (optional): not set",
                        step.mux.index
                    );
                }
                Err(e) => return Err(e),
            }
        }
        // Its restores and the shutdown do not write them either.
        d.steps.retain(|s| !absent.contains(&s.mux.index));
        let pdos = |what: &str, pdos: &[PdoPlan]| {
            pdos.iter()
                .map(|p| {
                    if usize::from(p.number) > PREDEFINED_PDOS {
                        format!("{what}{} {} bytes on 0x{:03X}", p.number, p.len, p.cob_id)
                    } else {
                        format!("{what}{} {} bytes", p.number, p.len)
                    }
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        let _ = writeln!(
            out,
            "  node {node}: {}, {}, synchronous every SYNC; {} SDO writes",
            pdos("RPDO", &d.plan.rpdos),
            pdos("TPDO", &d.plan.tpdos),
            d.steps.len()
        );
        infos.push(NodeInfo {
            node: d.node,
            device_type,
            identity,
        });
    }
    for d in drives.iter() {
        send(
            link,
            &nmt(NmtCommand::Start, NmtTarget::Node(d.node)),
            "sending NMT start",
        )?;
    }
    // Each node's next heartbeat (its new 0x1017 time) says it is Operational.
    let start = link.now_ns();
    let deadline = start + consumer_ns;
    let mut state: Vec<Option<NmtState>> = vec![None; drives.len()];
    while state.iter().any(|s| *s != Some(NmtState::Operational)) {
        let Some(r) = link.receive(deadline).map_err(|source| StartError::Link {
            what: "waiting for the nodes' heartbeats",
            source,
        })?
        else {
            break;
        };
        if let Ok(hb) = Heartbeat::parse(&r.frame) {
            if let Some(i) = drives.iter().position(|d| d.node == hb.node) {
                if let Some(slot) = state.get_mut(i) {
                    *slot = Some(hb.state);
                }
            }
        }
    }
    if let Some((d, s)) = drives
        .iter()
        .zip(&state)
        .find(|(_, s)| **s != Some(NmtState::Operational))
    {
        return Err(StartError::NotStarted {
            node: d.node.get(),
            state: *s,
            waited_ms: link.now_ns().saturating_sub(start) / 1_000_000,
        });
    }
    let _ = writeln!(out, "CANopen: {} nodes operational", drives.len());
    Ok(infos)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steps(sync_overflow: u8) -> Vec<SdoStep> {
        let layout = PdoLayout::csp_minimal();
        let plan = DrivePlan::on_node(&layout, NodeId::new(3).unwrap()).unwrap();
        let comm = CommSettings {
            heartbeat_ms: 100,
            cycle_us: 2000,
            master: NodeId::new(127).unwrap(),
            master_consumer_ms: 300,
            sync_overflow,
        };
        config_steps(NodeId::new(3).unwrap(), &plan, &layout, &comm)
    }

    fn at(steps: &[SdoStep], index: u16, sub: u8, value: &[u8]) -> Option<usize> {
        steps
            .iter()
            .position(|s| s.mux == Multiplexer::new(index, sub) && s.value() == value)
    }

    #[test]
    fn every_node_consumes_gantrys_heartbeat() {
        let s = steps(0);
        // 0x1016:01 = node 127 << 16 | 300 ms.
        let consumer = (127u32 << 16 | 300).to_le_bytes();
        assert!(at(&s, CONSUMER_HEARTBEAT_TIME, 1, &consumer).is_some());
        // No SYNC counter: 0x1019 is left alone (an optional object).
        assert!(s.iter().all(|x| x.mux.index != SYNC_COUNTER_OVERFLOW));
        assert_eq!(
            s.iter()
                .filter(|x| x.mux.index == COMMUNICATION_CYCLE_PERIOD)
                .count(),
            1
        );
    }

    #[test]
    fn the_sync_counter_is_written_while_the_cycle_period_is_0() {
        let s = steps(16);
        // CiA 301 §7.5.2.22: 0x1019 only changes while 0x1006 is 0.
        let zero = at(&s, COMMUNICATION_CYCLE_PERIOD, 0, &0u32.to_le_bytes()).unwrap();
        let counter = at(&s, SYNC_COUNTER_OVERFLOW, 0, &[16]).unwrap();
        let period = at(&s, COMMUNICATION_CYCLE_PERIOD, 0, &2000u32.to_le_bytes()).unwrap();
        assert!(
            zero < counter && counter < period,
            "{zero} {counter} {period}"
        );
    }
}
