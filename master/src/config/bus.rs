//! `[bus]` and `[rt]`: where the drives are, how often the cycle runs, how it runs.

use serde::Deserialize;

/// `[bus]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BusSection {
    /// `"ethercat"` or `"canopen"`.
    pub kind: String,
    /// Network interface wired to the drives (an Ethernet port for EtherCAT, a SocketCAN
    /// interface such as `can0` for CANopen).
    #[serde(default)]
    pub interface: Option<String>,
    /// Instead of an interface: a `gantry-sim` chain file, simulated in this process by the
    /// `gantry` binary (the library opens no simulator: the binary hands the service its
    /// link, see `ethercat::link::LinkFactory`).
    #[serde(default)]
    pub simulator: Option<String>,
    /// Cycle time (µs): 250 to 4000 on EtherCAT, 250 to 50000 on CANopen.
    pub cycle_us: u32,
    /// With `simulator`: when gantry exits, write what each simulated drive saw of the
    /// setpoints it took here (JSON, as `gantry-sim --record` writes it), so that a run on
    /// the simulator can be judged afterwards (the binary's `drive_records`).
    #[serde(default)]
    pub simulator_record: Option<String>,
    /// Write every frame to this pcap file.
    #[serde(default)]
    pub pcap: Option<String>,
    /// Distributed clocks: SYNC0 on the slaves at the cycle time (when they have DC).
    #[serde(default = "yes")]
    pub dc: bool,
    /// How much trouble on the wire is ridden through.
    #[serde(default)]
    pub faults: FaultsSection,
    /// CANopen only: the CAN bit rate (bit/s, one of CiA 102's: 10k, 20k, 50k, 125k,
    /// 250k, 500k, 800k, 1M). The bus-load check weighs the cycle's frames against it.
    #[serde(default)]
    pub bitrate: Option<u32>,
    /// CANopen only: each node's heartbeat producer time 0x1017 (ms; default
    /// [`DEFAULT_HEARTBEAT_MS`]).
    #[serde(default)]
    pub heartbeat_ms: Option<u16>,
    /// CANopen only: how long gantry, the heartbeat consumer, lets a node stay silent
    /// before its axes stop (ms; default three heartbeat times).
    #[serde(default)]
    pub heartbeat_timeout_ms: Option<u32>,
    /// CANopen only: gantry's own node id, under which it produces its heartbeat
    /// (COB-ID 0x700 + id) for the nodes to consume (default [`DEFAULT_MASTER_NODE`]; no
    /// axis may use it).
    #[serde(default)]
    pub master_node: Option<u8>,
    /// CANopen only: the consumer time each node is given for gantry's heartbeat (0x1016,
    /// ms; default three heartbeat times): a node that hears nothing from gantry for it
    /// reacts by its 0x6007 (the drive faults).
    #[serde(default)]
    pub master_timeout_ms: Option<u16>,
    /// CANopen only: SYNC with a counter counting 1..=N (0x1019 synchronous counter
    /// overflow value, 2..=240, written to every node); none: SYNC without counter.
    #[serde(default)]
    pub sync_counter: Option<u8>,
    /// The largest object `gantry sdo` (an SDO transfer beside the cycle) reads or writes
    /// (bytes, 256 to 16 MiB; default [`crate::runtime::sdo::SDO_MAX_BYTES`], 64 KiB): a
    /// buffer of this size is allocated at start and lent to the cycle thread with each
    /// transfer.
    #[serde(default)]
    pub sdo_max_bytes: Option<usize>,
}

/// Which bus a configuration drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusKind {
    /// EtherCAT.
    Ethercat,
    /// CANopen (CiA 301 / CiA 402).
    Canopen,
}

/// Heartbeat producer time given to every CANopen node unless `[bus] heartbeat_ms` says
/// otherwise (ms).
pub const DEFAULT_HEARTBEAT_MS: u16 = 100;

/// gantry's node id on a CANopen bus unless `[bus] master_node` says otherwise: the
/// highest, which drives rarely ship with.
pub const DEFAULT_MASTER_NODE: u8 = 127;

/// The bit rates of CiA 102 (the CAN physical layer CANopen devices implement; 1 Mbit/s
/// up to 25 m of cable).
pub const CIA_102_BITRATES: [u32; 8] = [
    10_000, 20_000, 50_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
];

fn yes() -> bool {
    true
}

/// `[bus.faults]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields, default)]
pub struct FaultsSection {
    /// Frames lost in a row before every axis stops.
    pub lost_frames_limit: u32,
    /// Cycles in a row with a wrong working counter before every axis stops.
    pub working_counter_limit: u32,
    /// A slave that leaves OP stops every axis, not only its own.
    pub stop_all_on_slave_loss: bool,
}

impl Default for FaultsSection {
    fn default() -> Self {
        Self {
            lost_frames_limit: 3,
            working_counter_limit: 3,
            stop_all_on_slave_loss: false,
        }
    }
}

impl BusSection {
    /// The bus kind (`kind` was checked at parse time; anything else reads as EtherCAT).
    pub fn bus_kind(&self) -> BusKind {
        match self.kind.as_str() {
            "canopen" => BusKind::Canopen,
            _ => BusKind::Ethercat,
        }
    }

    /// CANopen: the heartbeat producer time given to the nodes (ms).
    pub fn heartbeat_producer_ms(&self) -> u16 {
        self.heartbeat_ms.unwrap_or(DEFAULT_HEARTBEAT_MS)
    }

    /// CANopen: the silence after which a node's axes stop (ms).
    pub fn heartbeat_consumer_ms(&self) -> u32 {
        self.heartbeat_timeout_ms
            .unwrap_or(3 * u32::from(self.heartbeat_producer_ms()))
    }

    /// CANopen: gantry's node id (its heartbeat's).
    pub fn master_node(&self) -> u8 {
        self.master_node.unwrap_or(DEFAULT_MASTER_NODE)
    }

    /// CANopen: the consumer time the nodes get for gantry's heartbeat (ms; three
    /// heartbeat times unless given, at most 65535, what 0x1016 holds).
    pub fn master_consumer_ms(&self) -> u16 {
        self.master_timeout_ms.unwrap_or_else(|| {
            u16::try_from(3 * u32::from(self.heartbeat_producer_ms())).unwrap_or(u16::MAX)
        })
    }

    /// The largest object an SDO transfer beside the cycle carries (bytes).
    pub fn sdo_max_bytes(&self) -> usize {
        self.sdo_max_bytes
            .unwrap_or(crate::runtime::sdo::SDO_MAX_BYTES)
    }

    /// Checks values; the error names the key (below `bus.`) and the reason.
    pub(super) fn check(&self) -> Result<(), (String, String)> {
        let kind = match self.kind.as_str() {
            "ethercat" => BusKind::Ethercat,
            "canopen" => BusKind::Canopen,
            _ => {
                return Err((
                    "kind".into(),
                    format!(
                        "{:?} is not a bus gantry drives (\"ethercat\" or \"canopen\")",
                        self.kind
                    ),
                ))
            }
        };
        match kind {
            BusKind::Ethercat => self.check_ethercat()?,
            BusKind::Canopen => self.check_canopen()?,
        }
        match (&self.interface, &self.simulator) {
            (Some(_), Some(_)) => {
                return Err((
                    "simulator".into(),
                    "give either interface or simulator, not both".into(),
                ))
            }
            (None, None) => return Err((
                "interface".into(),
                "missing: the network interface wired to the drives (or simulator = \"sim.toml\")"
                    .into(),
            )),
            _ => {}
        }
        if self.simulator_record.is_some() && self.simulator.is_none() {
            return Err((
                "simulator_record".into(),
                "records what simulated drives saw: give it with simulator = \"sim.toml\", \
                 not with a network interface (gantry-sim --record FILE records its own drives)"
                    .into(),
            ));
        }
        // CANopen machines cycle slower than EtherCAT ones: a SYNC every 1 to 10 ms is
        // common, and a bit rate below 1 Mbit/s needs the time for its frames.
        let (low, high) = match kind {
            BusKind::Ethercat => (250, 4000),
            BusKind::Canopen => (250, 50_000),
        };
        if !(low..=high).contains(&self.cycle_us) {
            return Err((
                "cycle_us".into(),
                format!("{} µs is outside {low} to {high} µs", self.cycle_us),
            ));
        }
        use crate::runtime::sdo::{SDO_LIMIT_BYTES, SDO_MIN_BYTES};
        if let Some(n) = self.sdo_max_bytes {
            if !(SDO_MIN_BYTES..=SDO_LIMIT_BYTES).contains(&n) {
                return Err((
                    "sdo_max_bytes".into(),
                    format!("{n} bytes is outside {SDO_MIN_BYTES} to {SDO_LIMIT_BYTES}"),
                ));
            }
        }
        if self.faults.lost_frames_limit == 0 || self.faults.working_counter_limit == 0 {
            return Err((
                "faults".into(),
                "limits count cycles in a row and must be at least 1".into(),
            ));
        }
        Ok(())
    }

    /// What only CANopen has is refused on EtherCAT.
    fn check_ethercat(&self) -> Result<(), (String, String)> {
        for (key, given) in [
            ("bitrate", self.bitrate.is_some()),
            ("heartbeat_ms", self.heartbeat_ms.is_some()),
            ("heartbeat_timeout_ms", self.heartbeat_timeout_ms.is_some()),
            ("master_node", self.master_node.is_some()),
            ("master_timeout_ms", self.master_timeout_ms.is_some()),
            ("sync_counter", self.sync_counter.is_some()),
        ] {
            if given {
                return Err((
                    key.into(),
                    "is a CANopen setting (kind = \"canopen\"); EtherCAT runs at 100 Mbit/s \
                     and its slaves have no heartbeat"
                        .into(),
                ));
            }
        }
        Ok(())
    }

    /// The CANopen settings: a CiA 102 bit rate, heartbeat times that a node can keep.
    fn check_canopen(&self) -> Result<(), (String, String)> {
        let Some(bitrate) = self.bitrate else {
            return Err((
                "bitrate".into(),
                "missing: the CAN bit rate in bit/s (e.g. 1000000), which the bus-load \
                 check weighs the cycle's frames against"
                    .into(),
            ));
        };
        if !CIA_102_BITRATES.contains(&bitrate) {
            return Err((
                "bitrate".into(),
                format!(
                    "{bitrate} bit/s is not a CiA 102 bit rate (10000, 20000, 50000, 125000, \
                     250000, 500000, 800000, 1000000)"
                ),
            ));
        }
        if self.heartbeat_ms == Some(0) {
            return Err((
                "heartbeat_ms".into(),
                "0 switches the heartbeat off; gantry watches every node by it (give 1 to \
                 65535 ms)"
                    .into(),
            ));
        }
        let producer = u32::from(self.heartbeat_producer_ms());
        let consumer = self.heartbeat_consumer_ms();
        if consumer <= producer {
            return Err((
                "heartbeat_timeout_ms".into(),
                format!(
                    "{consumer} ms is not longer than the heartbeat time {producer} ms: every \
                     node would time out between two heartbeats (CiA 301 §7.2.8.3.2.3)"
                ),
            ));
        }
        if !(1..=127).contains(&self.master_node()) {
            return Err((
                "master_node".into(),
                format!(
                    "{} is outside 1..=127 (CiA 301: a 7-bit node id)",
                    self.master_node()
                ),
            ));
        }
        // gantry's heartbeat goes with the first cycle at or after it is due: up to its
        // time plus a cycle apart.
        if u64::from(self.master_consumer_ms()) * 1000
            <= u64::from(producer) * 1000 + u64::from(self.cycle_us)
        {
            return Err((
                "master_timeout_ms".into(),
                format!(
                    "{} ms is not longer than gantry's heartbeat time {producer} ms plus a \
                     cycle ({} µs; the cycle sends it): every node would time gantry out \
                     between two of its heartbeats (CiA 301 §7.2.8.3.2.3)",
                    self.master_consumer_ms(),
                    self.cycle_us
                ),
            ));
        }
        if let Some(n) = self.sync_counter {
            if !(2..=gantry_drives::canopen::sync::MAX_COUNTER).contains(&n) {
                return Err((
                    "sync_counter".into(),
                    format!(
                        "{n} is not a synchronous counter overflow value (0x1019: 2..=240, \
                         CiA 301 §7.5.2.22)"
                    ),
                ));
            }
        }
        if self.pcap.is_some() {
            return Err((
                "pcap".into(),
                "captures EtherCAT frames; on CANopen record the bus with candump".into(),
            ));
        }
        Ok(())
    }
}

/// `[rt]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields, default)]
pub struct RtSection {
    /// SCHED_FIFO priority of the cycle thread (1–99).
    pub priority: u8,
    /// CPU the cycle thread is pinned to (none: not pinned).
    pub cpu: Option<usize>,
    /// Lock all memory (mlockall) so the cycle never waits for a page.
    pub lock_memory: bool,
    /// Overruns in a row after which every axis stops.
    pub overrun_limit: u32,
}

impl Default for RtSection {
    fn default() -> Self {
        Self {
            priority: 80,
            cpu: None,
            lock_memory: true,
            overrun_limit: 10,
        }
    }
}

impl RtSection {
    pub(super) fn check(&self) -> Result<(), (String, String)> {
        if !(1..=99).contains(&self.priority) {
            return Err((
                "priority".into(),
                format!("{} is outside SCHED_FIFO's 1 to 99", self.priority),
            ));
        }
        if self.overrun_limit == 0 {
            return Err(("overrun_limit".into(), "must be at least 1".into()));
        }
        Ok(())
    }
}
