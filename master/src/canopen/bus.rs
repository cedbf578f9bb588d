//! The CANopen bus in the cycle ([`CanopenBus`], a [`CycleBus`]): each exchange sends
//! every operational drive's RPDOs, then the SYNC (CiA 301 §7.2.5: the drives take the
//! RPDOs' data and sample their inputs at the SYNC; with `[bus] sync_counter` the SYNC
//! counts 1..=N, §7.2.5.2.1), and reads until the deadline the TPDOs they answer with.
//! gantry is a heartbeat producer too (§7.2.8.3.2.2: `[bus] master_node`, every
//! `heartbeat_ms`, sent by the cycle after the SYNC), which every node consumes (0x1016,
//! set at bring-up): a drive stops by its 0x6007 reaction when the cycle stops.
//!
//! It watches the nodes from what they send: a TPDO set missing at the deadline is a lost
//! exchange for its drive (`[bus.faults] lost_frames_limit` in a row faults it), a heartbeat silent for the consumer time, a boot-up (the node reset)
//! or a heartbeat reporting another NMT state fault it; an EMCY hands the drive's error
//! code to its axis ([`CycleBus::drive_error`]). A reset brings a faulted node back one
//! step per exchange: NMT reset communication, its boot-up, its configuration by SDO,
//! NMT start, its first TPDOs. An application's SDO transfer ([`CycleBus::start_sdo`])
//! goes beside the PDOs, sent after the TPDOs: objects up to 255 bytes expedited or
//! segmented (CiA 301 §7.2.4.3; an upload asks for a block with that protocol switch
//! threshold, which a node answers the normal way), larger ones by block. Its frames and
//! the answers they call for fit the bits the bus load leaves in a cycle
//! ([`BusLoad::spare_bits`], paced by a credit of them): the master's own frames never
//! queue in front of the next cycle's RPDOs and SYNC (a CAN controller sends its frames in
//! order), and the node's answers, whose identifiers lose to every PDO, delay the SYNC by
//! at most the one frame already on the wire. A block upload's sub-block is what fits
//! beside its acknowledgement. A node that refuses block transfer (0x05040001) gets the
//! transfer again the normal way, and from then on only that. Nothing in [`CycleBus`]'s
//! methods allocates, locks or panics; all state is made at bring-up (a transfer's client
//! works in the buffer lent with it).

use std::fmt;
use std::io::Write;

use gantry_drives::canopen::cob_id::{CobId, NodeId};
use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::canopen::frame::frame_bits;
use gantry_drives::canopen::heartbeat::{Heartbeat, NmtState};
use gantry_drives::canopen::nmt::{NmtCommand, NmtTarget};
use gantry_drives::canopen::sdo::command::MAX_BLOCK_SIZE;
use gantry_drives::canopen::sdo::{
    AbortCode, DownloadMode, Initiate, Multiplexer, Outcome, SdoClient, SdoConfig, ServerCommand,
    Side, UploadMode,
};
use gantry_drives::canopen::sync::Sync;
use gantry_drives::canopen::CanFrame;
use gantry_kernel::axis::command::CommandError;

use super::bring_up::{self, Client, DriveSetup, NodeInfo, SdoStep, StartError};
use super::link::{CanLink, Received};
use super::load::{BusLoad, HEARTBEAT_BITS};
use super::pdo::DrivePlan;
use crate::config::Config;
use crate::runtime::bus::{
    BusCounters, CanNodeStatus, CycleBus, DriveError, Reply, Restored, Unreachable,
};
use crate::runtime::clock::now_ns;
use crate::runtime::sdo::{SdoBuffer, SdoDirection, SdoEnded, SdoError, SdoTransfer};

/// How long a reset may take to bring a node back (NMT reset, boot-up, ~30 SDO writes
/// at one per cycle, NMT start, the first TPDOs).
pub const RESTORE_TIMEOUT_NS: u64 = 5_000_000_000;
/// How long [`CanopenBus::shut_down`] may take to take its watches back from the nodes
/// (two expedited SDO writes per node, all nodes at once; each write times out after
/// [`bring_up::SDO_TIMEOUT_NS`]).
pub const RELEASE_TIMEOUT_NS: u64 = 2 * bring_up::SDO_TIMEOUT_NS + 100_000_000;
/// The shutdown's longest wait between looks at its SDO timers, SYNC and heartbeat.
const RELEASE_POLL_NS: u64 = 1_000_000;
/// Rounds of the shutdown's loop at most (a lockstep link whose clock stands still).
const RELEASE_MAX_ROUNDS: u32 = 100_000;

/// A watch the bring-up gave a node, taken back at shutdown.
#[derive(Clone, Copy, Debug)]
struct ReleaseStep {
    mux: Multiplexer,
    what: &'static str,
}

/// What [`CanopenBus::shut_down`] writes 0 to on each node, in order, if the bring-up
/// wrote it: the SYNC watchdog first (the SYNC stops once it is off), then the
/// heartbeat consumer (gantry's heartbeat goes on until then).
const RELEASE_STEPS: [ReleaseStep; 2] = [
    ReleaseStep {
        mux: Multiplexer::new(bring_up::COMMUNICATION_CYCLE_PERIOD, 0),
        what: "the SYNC watchdog (0x1006)",
    },
    ReleaseStep {
        mux: Multiplexer::new(bring_up::CONSUMER_HEARTBEAT_TIME, 1),
        what: "the heartbeat consumer (0x1016:01)",
    },
];

/// How one node's release at shutdown ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Release {
    /// Every watch taken back.
    Done,
    /// [`RELEASE_STEPS`]`[step]` and those after it were not.
    Failed {
        /// The step that failed.
        step: usize,
        /// Why.
        why: &'static str,
    },
}

/// Most receives one exchange makes (bounded work: a babbling node cannot hold the cycle
/// past this; the rest waits for the next exchange).
const MAX_FRAMES_PER_EXCHANGE: usize = 512;

/// Why the cycle cannot reach a CANopen drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CanFault {
    /// Its TPDOs missed `in_a_row` exchanges in a row.
    Lost {
        /// The node.
        node: u8,
        /// Exchanges in a row.
        in_a_row: u32,
    },
    /// No heartbeat for `silent_ms`.
    Silent {
        /// The node.
        node: u8,
        /// Silence so far (ms).
        silent_ms: u64,
        /// The consumer time (ms).
        limit_ms: u32,
    },
    /// It sent a boot-up: it reset (power, watchdog, someone's NMT command) and is
    /// pre-operational with its power-on PDOs.
    BootUp {
        /// The node.
        node: u8,
    },
    /// Its heartbeat reports a state other than Operational.
    Left {
        /// The node.
        node: u8,
        /// What it reports.
        state: NmtState,
    },
}

/// A restore that failed, in CANopen's terms (the kernel's wording is bus-neutral).
fn not_operational(drive: usize, node: u16, problem: &'static str) -> CommandError {
    CommandError::DriveNotOperational {
        position: u16::try_from(drive).unwrap_or(u16::MAX),
        unit: "CANopen node",
        id: node,
        problem,
    }
}

fn state_name(s: NmtState) -> &'static str {
    match s {
        NmtState::BootUp => "Boot-up",
        NmtState::Stopped => "Stopped",
        NmtState::Operational => "Operational",
        NmtState::PreOperational => "Pre-operational",
    }
}

impl fmt::Display for CanFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Lost { node, in_a_row } => write!(
                f,
                "CANopen node {node}: no TPDO for {in_a_row} cycles in a row"
            ),
            Self::Silent {
                node,
                silent_ms,
                limit_ms,
            } => write!(
                f,
                "CANopen node {node}: no heartbeat for {silent_ms} ms (limit {limit_ms} ms)"
            ),
            Self::BootUp { node } => write!(
                f,
                "CANopen node {node}: boot-up message: it reset and is Pre-operational"
            ),
            Self::Left { node, state } => write!(
                f,
                "CANopen node {node}: left Operational: its heartbeat says {}",
                state_name(state)
            ),
        }
    }
}

/// Where a node's restore is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// NMT reset communication to send.
    Reset,
    /// Waiting for its boot-up.
    BootUp,
    /// Configuration write `k` of its steps (started: waiting for the answer).
    Configure { k: usize, started: bool },
    /// NMT start to send.
    Start,
    /// Started: waiting for a complete set of TPDOs.
    FirstTpdos,
}

/// Objects from this size on go by block (smaller ones expedited or segmented, as
/// before block transfer: the most a protocol switch threshold says is 255).
const BLOCK_FROM: usize = 256;
/// The protocol switch threshold a block upload offers (CiA 301 §7.2.4.3.13): a node
/// answers an object of up to this many bytes the normal way.
const PROTOCOL_SWITCH: u8 = 255;

/// The buffer lent with a transfer, whole, as the SDO client works in it.
struct Lent(SdoBuffer);

impl AsRef<[u8]> for Lent {
    fn as_ref(&self) -> &[u8] {
        self.0.storage()
    }
}

impl AsMut<[u8]> for Lent {
    fn as_mut(&mut self) -> &mut [u8] {
        self.0.storage_mut()
    }
}

/// An application's SDO transfer in progress ([`CycleBus::start_sdo`]).
struct Transfer {
    transfer: SdoTransfer,
    client: SdoClient<Lent>,
    /// Bytes to download.
    len: usize,
    /// The buffer's capacity: the largest object it takes.
    capacity: usize,
    /// When the node last sent a frame of it (at first, when it started; link clock).
    heard_ns: u64,
    /// The size an upload announced, when more than the buffer holds.
    too_large: Option<u32>,
    /// Started by block and the node has not answered yet: a refusal (0x05040001) means
    /// it has no block transfer.
    block_unheard: bool,
    /// How it ended, once it has: its last frames (an abort, the block upload's end) go
    /// before the buffer goes back. An upload's bytes are the buffer's first `uploaded`.
    ended: Option<Result<(), SdoError>>,
    uploaded: usize,
}

impl Transfer {
    /// The application's result of the client's `outcome`.
    fn result(&self, outcome: Outcome, now: u64) -> Result<(), SdoError> {
        let t = &self.transfer;
        match outcome {
            Outcome::Uploaded { .. } | Outcome::Downloaded { .. } => Ok(()),
            Outcome::Aborted {
                code,
                by: Side::Client,
                ..
            } if code == AbortCode::TIMED_OUT => {
                Err(SdoError::timed_out(t, now.saturating_sub(self.heard_ns)))
            }
            // The client aborts so only when the object does not fit the buffer.
            Outcome::Aborted {
                code,
                by: Side::Client,
                ..
            } if code == AbortCode::OUT_OF_MEMORY => {
                Err(SdoError::too_large(t, self.too_large, self.capacity))
            }
            Outcome::Aborted { code, .. } => Err(SdoError::aborted(t, code)),
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct Restore {
    /// The node being brought back (a drive, or an I/O module `origin`'s axis reads).
    drive: usize,
    /// The drive whose reset asked for it: once `drive` is back, the I/O modules its axis
    /// reads that are out are brought back too, under the same deadline.
    origin: usize,
    deadline_ns: u64,
    step: Step,
}

/// One drive (node) of the bus, or an I/O module the axes' switches read.
struct Drive {
    node: NodeId,
    /// A CiA 401 I/O module, not an axis' drive: its faults say so.
    module: bool,
    /// The bus positions of the I/O modules the axis of this drive reads its switches
    /// from: while one is unreachable, so is the axis' drive to the cycle (its limit
    /// switches are not watched), and a reset brings it back.
    reads: [Option<usize>; 3],
    plan: DrivePlan,
    /// The process data, layout order (made at bring-up to the plan's size).
    inputs: Box<[u8]>,
    outputs: Box<[u8]>,
    /// TPDOs received this exchange (bit k: plan.tpdos[k]; at most
    /// [`super::pdo::MAX_PDOS`] = 64).
    got: u64,
    /// Inputs complete with the last exchange.
    fresh: bool,
    /// A boot-up or another NMT state seen since it was last started.
    left: Option<CanFault>,
    /// When its last heartbeat came (link clock).
    heard_ns: u64,
    /// The NMT state its last heartbeat reported.
    nmt: Option<NmtState>,
    lost_in_a_row: u32,
    /// Exchanges its TPDOs missed, since start.
    lost_total: u64,
    fault: Option<(CanFault, Unreachable)>,
    /// The error of its last EMCY while in force (0x0000 ends it), and whether it came
    /// with the last exchange.
    emcy: Option<u16>,
    emcy_fresh: bool,
    sdo: Client,
    steps: Vec<SdoStep>,
    /// The node has not refused an application's block transfer (0x05040001).
    sdo_block: bool,
}

impl Drive {
    fn all_tpdos(&self) -> u64 {
        match self.plan.tpdos.len() {
            n if n >= 64 => u64::MAX,
            n => (1u64 << n) - 1,
        }
    }
}

/// Which drive's TPDO a COB-ID carries: (bus position, index into its plan's TPDOs).
type TpdoRoute = Option<(u8, u8)>;

/// The CANopen bus: its nodes Operational after the bring-up, exchanging synchronous PDOs
/// at each SYNC the cycle sends.
pub struct CanopenBus {
    link: Box<dyn CanLink>,
    drives: Vec<Drive>,
    /// Node id → drive index + 1 (0: not ours).
    node_drive: [u8; 128],
    /// COB-ID (11 bits) → the drive and TPDO it carries (PDOs 5 and up are on identifiers
    /// of other node ids: a TPDO is known by its COB-ID, not by the node bits).
    tpdo_route: Box<[TpdoRoute]>,
    infos: Vec<NodeInfo>,
    sync: CanFrame,
    /// 0x1019 the nodes were given (0: SYNC without counter), and the last counter sent.
    sync_overflow: u8,
    sync_counter: u8,
    /// gantry's heartbeat (CiA 301 §7.2.8.3.2.2: the master is a heartbeat producer the
    /// nodes consume by 0x1016): the frame, its period on the link's clock, when it is due.
    heartbeat: CanFrame,
    heartbeat_ns: u64,
    heartbeat_due_ns: u64,
    heartbeats_sent: u64,
    /// The cycle's period (the SYNC's, kept up while the nodes are released at shutdown).
    period_ns: u64,
    lost_limit: u32,
    consumer_ns: u64,
    counters: BusCounters,
    restore: Option<Restore>,
    restored: Option<Result<Restored, CommandError>>,
    exchanges: u64,
    malformed: u64,
    /// The link's clock at the last exchange.
    last_exchange_ns: u64,
    /// The application's SDO transfer in progress, and how the last one ended.
    sdo: Option<Transfer>,
    sdo_done: Option<SdoEnded>,
    /// Bits an SDO transfer's frames and their answers may take per cycle
    /// ([`BusLoad::spare_bits`]), what is left of them now (the credit grows by them each
    /// exchange, up to the cost of one step), and the sub-block a block upload asks for.
    sdo_spare_bits: u64,
    sdo_credit_bits: u64,
    sdo_block_size: u8,
}

/// Bits an SDO frame takes at worst (8 data bytes with stuff bits).
const SDO_FRAME_BITS: u64 = frame_bits(8);

impl CanopenBus {
    /// Brings the bus of `config` up on `link` (see [`bring_up`](super::bring_up)),
    /// printing its steps to `out`: the nodes Operational with their PDOs mapped for the
    /// configuration's axes (axis `i` on bus position `i`, its `node`), ready for the
    /// cycle ([`crate::runtime::cycle::Cycle::from_config`]). Blocks for the bring-up,
    /// bounded by its timeouts.
    pub fn bring_up_on(
        config: &Config,
        mut link: Box<dyn CanLink>,
        out: &mut (dyn Write + Send),
    ) -> Result<Self, StartError> {
        let mut setups = bring_up::drive_setups(config)?;
        let consumer_ns = u64::from(config.bus.heartbeat_consumer_ms()) * 1_000_000;
        let infos = bring_up::run(&mut *link, &mut setups, consumer_ns, out)?;
        let now = link.now_ns();
        let mut node_drive = [0u8; 128];
        let mut tpdo_route: Box<[TpdoRoute]> = vec![None; 0x800].into_boxed_slice();
        let mut drives = Vec::with_capacity(setups.len());
        for (i, s) in setups.into_iter().enumerate() {
            let DriveSetup {
                node,
                plan,
                steps,
                profile,
                ..
            } = s;
            let mut reads = [None; 3];
            if let Some((_, a)) = config.axis_on_drive(i) {
                let inputs = a.switches.module_inputs().unwrap_or_default();
                for (dst, m) in reads.iter_mut().zip(inputs) {
                    *dst = m.map(|m| m.slave);
                }
            }
            if let Some(slot) = node_drive.get_mut(usize::from(node.get())) {
                *slot = i as u8 + 1;
            }
            for (k, p) in plan.tpdos.iter().enumerate() {
                if let Some(slot) = tpdo_route.get_mut(usize::from(p.cob_id)) {
                    *slot = Some((i as u8, k as u8));
                }
            }
            drives.push(Drive {
                node,
                module: profile != bring_up::PROFILE_CIA402,
                reads,
                inputs: vec![0; plan.input_bytes].into_boxed_slice(),
                outputs: vec![0; plan.output_bytes].into_boxed_slice(),
                plan,
                got: 0,
                fresh: false,
                left: None,
                heard_ns: now,
                // The bring-up started it once its heartbeat reported Operational.
                nmt: Some(NmtState::Operational),
                lost_in_a_row: 0,
                lost_total: 0,
                fault: None,
                emcy: None,
                emcy_fresh: false,
                sdo: bring_up::client(node)?,
                steps,
                sdo_block: true,
            });
        }
        let master = bring_up::master_node(config)?;
        let spare_bits = BusLoad::of_config(config).map_or(0, |l| l.spare_bits());
        let _ = writeln!(
            out,
            "CANopen: gantry is node {}: its heartbeat every {} ms, the nodes stop {} ms \
             without it; SYNC {}",
            master.get(),
            config.bus.heartbeat_producer_ms(),
            config.bus.master_consumer_ms(),
            match config.bus.sync_counter {
                Some(n) => format!("with counter 1..={n}"),
                None => "without counter".into(),
            }
        );
        Ok(Self {
            link,
            drives,
            node_drive,
            tpdo_route,
            infos,
            sync: Sync::new().emit(),
            sync_overflow: config.bus.sync_counter.unwrap_or(0),
            sync_counter: 0,
            heartbeat: Heartbeat::new(master, NmtState::Operational).emit(),
            heartbeat_ns: u64::from(config.bus.heartbeat_producer_ms()) * 1_000_000,
            // The first with the first exchange: the nodes' monitoring starts with it.
            heartbeat_due_ns: 0,
            heartbeats_sent: 0,
            period_ns: u64::from(config.bus.cycle_us) * 1000,
            lost_limit: config.bus.faults.lost_frames_limit.max(1),
            consumer_ns: u64::from(config.bus.heartbeat_consumer_ms()) * 1_000_000,
            counters: BusCounters::default(),
            restore: None,
            restored: None,
            exchanges: 0,
            malformed: 0,
            last_exchange_ns: now,
            sdo: None,
            sdo_done: None,
            sdo_spare_bits: spare_bits,
            sdo_credit_bits: 0,
            sdo_block_size: (spare_bits / SDO_FRAME_BITS)
                .saturating_sub(1)
                .clamp(1, u64::from(MAX_BLOCK_SIZE)) as u8,
        })
    }

    /// What bring-up read from each node (device type, identity), in axis order.
    pub fn node_infos(&self) -> &[NodeInfo] {
        &self.infos
    }

    /// The node id of the drive at bus position `drive`.
    pub fn node(&self, drive: usize) -> Option<NodeId> {
        self.drives.get(drive).map(|d| d.node)
    }

    /// The PDOs of the drive at bus position `drive`.
    pub fn plan(&self, drive: usize) -> Option<&DrivePlan> {
        self.drives.get(drive).map(|d| &d.plan)
    }

    /// Frames received that broke their format (a TPDO shorter than its mapping, an EMCY
    /// or heartbeat of the wrong length), since start.
    pub fn malformed(&self) -> u64 {
        self.malformed
    }

    /// Bits an SDO transfer may take per cycle, its frames and their answers: what the
    /// bus load leaves in the cycle's window.
    pub fn sdo_spare_bits(&self) -> u64 {
        self.sdo_spare_bits
    }

    /// The sub-block a block upload asks of a node: what fits a cycle beside its
    /// acknowledgement.
    pub fn sdo_block_size(&self) -> u8 {
        self.sdo_block_size
    }

    /// Exchanges run since start.
    pub fn exchanges(&self) -> u64 {
        self.exchanges
    }

    /// gantry's heartbeats sent since start.
    pub fn heartbeats_sent(&self) -> u64 {
        self.heartbeats_sent
    }

    /// The SYNC of this exchange: with the next counter 1..=0x1019 when the nodes were
    /// given one (CiA 301 §7.2.5.2.1: it restarts at 1 after the overflow value).
    fn next_sync(&mut self) -> CanFrame {
        match Sync::next_counter(self.sync_counter, self.sync_overflow) {
            Some(c) => {
                self.sync_counter = c;
                Sync::with_counter(c).map_or(self.sync, |s| s.emit())
            }
            None => self.sync,
        }
    }

    /// gantry's heartbeat when it is due (every `[bus] heartbeat_ms` on the link's clock,
    /// keeping its phase; after a longer gap, from now).
    fn produce_heartbeat(&mut self, now: u64) {
        if self.heartbeat_ns == 0 || now < self.heartbeat_due_ns {
            return;
        }
        // A frame the link did not take is tried again next exchange.
        if self.link.send(&self.heartbeat).is_ok() {
            self.heartbeats_sent += 1;
            let next = self.heartbeat_due_ns.saturating_add(self.heartbeat_ns);
            self.heartbeat_due_ns = if next > now {
                next
            } else {
                now.saturating_add(self.heartbeat_ns)
            };
        }
    }

    /// The link (a test reaches its simulated bus through it).
    pub fn link(&self) -> &dyn CanLink {
        &*self.link
    }

    /// Takes the nodes out of the cycle the way an NMT master leaves them (after the
    /// drives were disabled), and hands the link back:
    ///
    /// 1. NMT enter pre-operational to each node: its PDOs stop (CiA 301 §7.3.2.2.1,
    ///    Table 41); SDO, SYNC and heartbeat go on.
    /// 2. The watches the bring-up gave each node are taken back by SDO, on every node at
    ///    once: 0x1006 = 0 (the SYNC consumer's watchdog unused, §7.5.2.6) and 0x1016:01
    ///    = 0 (a consumer entry with time 0 is not used, §7.5.2.16). Meanwhile gantry goes
    ///    on sending the SYNC at the cycle's period (until no node watches it) and its
    ///    heartbeat, so no watch fires before it is taken back.
    /// 3. gantry's heartbeat stops.
    ///
    /// Bounded by [`RELEASE_TIMEOUT_NS`] on the link's clock. A node that did not confirm
    /// is named with what it may still watch: it reports the loss (EMCY 0x8100 or 0x8130)
    /// when that watch's time runs out. Each step is printed to `out`. Returns the link.
    pub fn shut_down(mut self, out: &mut (dyn Write + Send)) -> Box<dyn CanLink> {
        let started = self.link.now_ns();
        // An application transfer still running is cut short: the channel is needed.
        if let Some(mut t) = self.sdo.take() {
            let _ = t.client.abort(AbortCode::GENERAL_ERROR);
            while let Some(f) = t.client.transmit() {
                let _ = self.link.send(&f);
            }
        }
        for d in &self.drives {
            let f = bring_up::nmt(NmtCommand::EnterPreOperational, NmtTarget::Node(d.node));
            if let Err(e) = self.link.send(&f) {
                let _ = writeln!(
                    out,
                    "CANopen node {}: NMT pre-operational: {e}",
                    d.node.get()
                );
            }
        }
        let released = self.release_nodes();
        let took_ms = self.link.now_ns().saturating_sub(started) / 1_000_000;
        let mut ok = Vec::new();
        for (d, r) in self.drives.iter().zip(&released) {
            match r {
                Release::Done => ok.push(d.node.get().to_string()),
                Release::Failed { step, why } => {
                    let _ = writeln!(
                        out,
                        "CANopen node {}: {} not taken back ({why}): it may still watch {}",
                        d.node.get(),
                        RELEASE_STEPS.get(*step).map_or("?", |r| r.what),
                        if *step == 0 {
                            "gantry's SYNC (EMCY 0x8100 when it stays away) and heartbeat \
                             (EMCY 0x8130)"
                        } else {
                            "gantry's heartbeat (EMCY 0x8130 when it stays away)"
                        },
                    );
                }
            }
        }
        let _ = writeln!(
            out,
            "CANopen: nodes pre-operational; SYNC watchdog and heartbeat consumer taken back \
             on node(s) {} in {took_ms} ms",
            if ok.is_empty() {
                "none".to_string()
            } else {
                ok.join(", ")
            }
        );
        self.link
    }

    /// Step 2 of [`CanopenBus::shut_down`]: each drive's SDO writes of
    /// [`RELEASE_STEPS`] that its bring-up made (a node without 0x1006 in its EDS was
    /// never given it), every node at once, the SYNC and gantry's heartbeat going on
    /// meanwhile.
    fn release_nodes(&mut self) -> Vec<Release> {
        let start = self.link.now_ns();
        let deadline = start.saturating_add(RELEASE_TIMEOUT_NS);
        let n = self.drives.len();
        // Per drive: the step in progress (index into RELEASE_STEPS), or how it ended.
        let mut at = vec![0usize; n];
        let mut ended: Vec<Option<Release>> = vec![None; n];
        for d in &mut self.drives {
            // A restore's transfer in progress ends here.
            if !d.sdo.is_idle() {
                let _ = d.sdo.abort(AbortCode::GENERAL_ERROR);
                while let Some(f) = d.sdo.transmit() {
                    let _ = self.link.send(&f);
                }
            }
        }
        let mut next_sync = start;
        // A link whose clock does not move while it waits (a lockstep bus stepped by a
        // cycle that has ended) cannot run out the deadline: bounded by rounds too.
        let mut rounds = 0u32;
        loop {
            let now = self.link.now_ns();
            // Start each drive's next write that its bring-up made.
            for (i, d) in self.drives.iter_mut().enumerate() {
                let Some(slot) = ended.get_mut(i) else {
                    continue;
                };
                let Some(k) = at.get_mut(i) else {
                    continue;
                };
                if slot.is_some() || !d.sdo.is_idle() {
                    continue;
                }
                while RELEASE_STEPS
                    .get(*k)
                    .is_some_and(|r| !d.steps.iter().any(|s| s.mux == r.mux))
                {
                    *k += 1;
                }
                match RELEASE_STEPS.get(*k) {
                    Some(r) => {
                        if d.sdo
                            .download(r.mux, &[0; 4], DownloadMode::Expedited, now)
                            .is_err()
                        {
                            *slot = Some(Release::Failed {
                                step: *k,
                                why: "the SDO client was busy",
                            });
                        }
                    }
                    None => *slot = Some(Release::Done),
                }
                while let Some(f) = d.sdo.transmit() {
                    let _ = self.link.send(&f);
                }
            }
            if ended.iter().all(Option::is_some) {
                break;
            }
            if now >= deadline || rounds >= RELEASE_MAX_ROUNDS {
                for (i, slot) in ended.iter_mut().enumerate() {
                    if slot.is_none() {
                        *slot = Some(Release::Failed {
                            step: at.get(i).copied().unwrap_or(0),
                            why: "no answer in time",
                        });
                    }
                }
                break;
            }
            rounds += 1;
            // The SYNC while a node may still watch it (0x1006 not yet 0).
            let sync_watched = self.drives.iter().zip(&at).zip(&ended).any(|((d, k), e)| {
                e.is_none()
                    && *k == 0
                    && d.steps
                        .iter()
                        .any(|s| s.mux.index == bring_up::COMMUNICATION_CYCLE_PERIOD)
            });
            if sync_watched && now >= next_sync {
                let f = self.next_sync();
                let _ = self.link.send(&f);
                next_sync = next_sync.saturating_add(self.period_ns).max(now);
            }
            self.produce_heartbeat(now);
            let wake = deadline
                .min(now.saturating_add(RELEASE_POLL_NS))
                .min(if sync_watched { next_sync } else { u64::MAX });
            let outcome = match self.link.receive(wake) {
                Ok(Some(r)) => match CobId::classify(r.frame.id()) {
                    Ok(CobId::SdoTx(node)) => self.drive_of(node).and_then(|i| {
                        let now = self.link.now_ns();
                        let o = self.drives.get_mut(i)?.sdo.receive(&r.frame, now)?;
                        Some((i, o))
                    }),
                    _ => None,
                },
                Ok(None) | Err(_) => None,
            };
            let now = self.link.now_ns();
            let timed_out = self
                .drives
                .iter_mut()
                .enumerate()
                .find_map(|(i, d)| d.sdo.poll(now).map(|o| (i, o)));
            for (i, o) in outcome.into_iter().chain(timed_out) {
                let (Some(k), Some(slot)) = (at.get_mut(i), ended.get_mut(i)) else {
                    continue;
                };
                match o {
                    Outcome::Downloaded { .. } => *k += 1,
                    Outcome::Aborted { code, by, .. } => {
                        if let Some(d) = self.drives.get_mut(i) {
                            while let Some(f) = d.sdo.transmit() {
                                let _ = self.link.send(&f);
                            }
                        }
                        *slot = Some(Release::Failed {
                            step: *k,
                            why: match (by, code) {
                                (_, AbortCode::TIMED_OUT) => "no answer in time",
                                (Side::Server, _) => "the node refused the write",
                                (Side::Client, _) => "the node's answer broke the protocol",
                            },
                        });
                    }
                    Outcome::Uploaded { .. } => {}
                }
            }
        }
        ended
            .into_iter()
            .map(|e| {
                e.unwrap_or(Release::Failed {
                    step: 0,
                    why: "no answer in time",
                })
            })
            .collect()
    }

    fn drive_of(&self, node: NodeId) -> Option<usize> {
        let i = *self.node_drive.get(usize::from(node.get()))?;
        (i > 0).then(|| usize::from(i) - 1)
    }

    fn restoring(&self, drive: usize) -> bool {
        self.restore.is_some_and(|r| r.drive == drive)
    }

    /// Whether the drive exchanges PDOs this cycle: started, not known to have left
    /// Operational, and not being brought back (until its NMT start).
    fn in_operation(&self, drive: usize) -> bool {
        let Some(d) = self.drives.get(drive) else {
            return false;
        };
        match self.restore {
            Some(r) if r.drive == drive => r.step == Step::FirstTpdos,
            _ => d.left.is_none(),
        }
    }

    /// Takes one received frame. `in_window`: it came while this exchange waits for the
    /// TPDOs (before: a late one of the last cycle, not taken as this cycle's inputs).
    fn dispatch(&mut self, r: &Received, in_window: bool, now: u64) {
        let frame = &r.frame;
        if frame.is_remote() {
            return;
        }
        // A TPDO is known by its COB-ID (PDOs 5 and up carry another node id's bits).
        let route = self
            .tpdo_route
            .get(usize::from(frame.id()))
            .copied()
            .flatten();
        if let Some((i, k)) = route {
            self.on_tpdo(usize::from(i), usize::from(k), frame, in_window);
            return;
        }
        let Ok(cob) = CobId::classify(frame.id()) else {
            return;
        };
        let Some(node) = cob.node() else {
            return;
        };
        let Some(i) = self.drive_of(node) else {
            return;
        };
        match cob {
            CobId::Emcy(_) => match Emergency::parse(frame) {
                Ok(e) => {
                    if let Some(d) = self.drives.get_mut(i) {
                        if e.is_reset() {
                            d.emcy = None;
                        } else {
                            d.emcy = Some(e.error_code);
                            d.emcy_fresh = true;
                        }
                    }
                }
                Err(_) => self.malformed += 1,
            },
            CobId::NmtErrorControl(_) => match Heartbeat::parse(frame) {
                Ok(hb) => self.on_heartbeat(i, hb, r.at_ns.unwrap_or(now)),
                Err(_) => self.malformed += 1,
            },
            CobId::SdoTx(_) => {
                if !self.restoring(i) {
                    self.on_transfer_frame(i, frame, now);
                    return;
                }
                let outcome = match self.drives.get_mut(i) {
                    Some(d) => d.sdo.receive(frame, now),
                    None => None,
                };
                if let Some(o) = outcome {
                    self.on_sdo_outcome(o);
                }
            }
            _ => {}
        }
    }

    /// TPDO `k` of drive `i`: its objects into the drive's inputs, when it came in this
    /// exchange's window and the drive is in operation.
    fn on_tpdo(&mut self, i: usize, k: usize, frame: &CanFrame, in_window: bool) {
        if !in_window || !self.in_operation(i) {
            return;
        }
        let Some(d) = self.drives.get_mut(i) else {
            return;
        };
        let Some(p) = d.plan.tpdos.get(k) else {
            return;
        };
        let data = frame.data();
        // CiA 301 §7.2.2: fewer bytes than mapped is not processed.
        if data.len() < p.len {
            self.malformed += 1;
            return;
        }
        for m in &p.entries {
            let n = m.size();
            if let (Some(src), Some(dst)) = (
                data.get(m.in_pdo..m.in_pdo + n),
                d.inputs.get_mut(m.in_image..m.in_image + n),
            ) {
                dst.copy_from_slice(src);
            }
        }
        d.got |= 1u64.checked_shl(k as u32).unwrap_or(0);
    }

    fn on_heartbeat(&mut self, i: usize, hb: Heartbeat, at: u64) {
        let restoring = self.restoring(i);
        let Some(d) = self.drives.get_mut(i) else {
            return;
        };
        d.heard_ns = d.heard_ns.max(at);
        d.nmt = Some(hb.state);
        let node = d.node.get();
        if restoring {
            if let Some(r) = self.restore.as_mut() {
                if hb.is_boot_up() && r.step == Step::BootUp {
                    r.step = Step::Configure {
                        k: 0,
                        started: false,
                    };
                }
            }
            return;
        }
        if d.left.is_some() {
            return;
        }
        d.left = match hb.state {
            NmtState::Operational => None,
            NmtState::BootUp => Some(CanFault::BootUp { node }),
            state => Some(CanFault::Left { node, state }),
        };
    }

    /// An SDO answer for the application's transfer, if it is with that drive.
    fn on_transfer_frame(&mut self, drive: usize, frame: &CanFrame, now: u64) {
        let Some(t) = self
            .sdo
            .as_mut()
            .filter(|t| t.transfer.drive == drive && t.ended.is_none())
        else {
            return;
        };
        t.heard_ns = now;
        // An upload larger than the buffer: the client aborts it (0x05040005); the
        // application is told the size the drive announced.
        let announced = match ServerCommand::parse(frame.data()) {
            Ok(ServerCommand::InitiateUpload {
                payload: Initiate::Segmented { size },
                ..
            })
            | Ok(ServerCommand::BlockUploadInitiate { size, .. }) => size,
            _ => None,
        };
        if let Some(size) = announced.filter(|&s| s as usize > t.capacity) {
            t.too_large = Some(size);
        }
        let outcome = t.client.receive(frame, now);
        match outcome {
            Some(o) => self.on_transfer_outcome(o, now),
            None => t.block_unheard = false,
        }
    }

    /// The application's transfer ended with the client's `outcome` — unless the node
    /// refused block transfer, when it starts again the normal way.
    fn on_transfer_outcome(&mut self, outcome: Outcome, now: u64) {
        let Some(t) = self.sdo.as_mut() else {
            return;
        };
        let refused_block = matches!(
            outcome,
            Outcome::Aborted {
                code: AbortCode::INVALID_COMMAND_SPECIFIER,
                by: Side::Server,
                ..
            }
        ) && t.block_unheard;
        t.block_unheard = false;
        if refused_block {
            if let Some(d) = self.drives.get_mut(t.transfer.drive) {
                d.sdo_block = false;
            }
            let mux = Multiplexer::new(t.transfer.index, t.transfer.sub);
            let again = match t.transfer.direction {
                SdoDirection::Upload => t.client.upload(mux, UploadMode::Normal, now),
                SdoDirection::Download => {
                    t.client
                        .download_buffered(mux, t.len, DownloadMode::Auto, now)
                }
            };
            if again.is_ok() {
                return;
            }
        }
        t.ended = Some(t.result(outcome, now));
        if let Outcome::Uploaded { len, .. } = outcome {
            t.uploaded = len;
        }
    }

    /// The application's transfer after the TPDOs: its timeouts, then its next frames
    /// (as many as the credit pays for); once it has ended, what the client still has to
    /// say (an abort, a block upload's end) goes and the transfer is gone, its buffer
    /// with the outcome.
    fn step_transfer(&mut self, now: u64, own_heartbeat: bool) {
        let Some(t) = self.sdo.as_mut() else {
            return;
        };
        if t.ended.is_none() {
            if let Some(o) = t.client.poll(now) {
                self.on_transfer_outcome(o, now);
            }
        }
        let Some(t) = self.sdo.as_mut() else {
            return;
        };
        if t.ended.is_some() {
            while let Some(f) = t.client.transmit() {
                let _ = self.link.send(&f);
            }
            self.end_transfer(None);
            return;
        }
        // Each frame costs its bits and those of the node's answers to it (a block
        // upload's acknowledgement calls for a sub-block, a block download's segment for
        // none but the sub-block's last). The credit grows by the spare bits each
        // exchange, up to what the dearest step costs (a bus with less room than a step
        // takes one now and then), less the heartbeats of this cycle: gantry's, if it
        // went, and each node's that is due by the end of the cycle — give or take half a
        // cycle: the nodes' come all at once, arriving one after the other.
        let dearest = (1 + u64::from(self.sdo_block_size).max(1)) * SDO_FRAME_BITS;
        let due = if self.heartbeat_ns == 0 {
            0
        } else {
            let by = now.saturating_add(self.period_ns + self.period_ns / 2);
            self.drives
                .iter()
                .filter(|d| d.heard_ns.saturating_add(self.heartbeat_ns) <= by)
                .count() as u64
        };
        let heartbeats = (due + u64::from(own_heartbeat)) * HEARTBEAT_BITS;
        // (At least a bit a cycle: a bus with no room left still gets its transfer done,
        // a step now and then, rather than timed out unsent.)
        self.sdo_credit_bits = self
            .sdo_credit_bits
            .saturating_add(self.sdo_spare_bits.max(1))
            .min(self.sdo_spare_bits.max(dearest))
            .saturating_sub(heartbeats);
        loop {
            let cost = (1 + u64::from(t.client.answers_to_next())) * SDO_FRAME_BITS;
            if self.sdo_credit_bits < cost {
                break;
            }
            let Some(f) = t.client.transmit_at(now) else {
                break;
            };
            self.sdo_credit_bits -= cost;
            // Not taken by the link: the transfer times out, as a lost frame would.
            if self.link.send(&f).is_err() {
                break;
            }
        }
    }

    /// Ends the application's transfer with how it ended (or `instead`), its buffer to
    /// the engine.
    fn end_transfer(&mut self, instead: Option<SdoError>) {
        let Some(t) = self.sdo.take() else {
            return;
        };
        let result = match (t.ended, instead) {
            (Some(r), _) => r,
            (None, Some(e)) => Err(e),
            (None, None) => Err(SdoError::protocol(
                &t.transfer,
                "the transfer was cut short",
            )),
        };
        let mut buffer = t.client.into_buffer().0;
        let len = if result.is_ok() { t.uploaded } else { 0 };
        buffer.set_len(len);
        self.sdo_done = Some(SdoEnded { result, buffer });
    }

    fn fail_restore(&mut self, problem: &'static str) {
        let Some(r) = self.restore.take() else {
            return;
        };
        let id = self
            .drives
            .get(r.drive)
            .map_or(0, |d| u16::from(d.node.get()));
        self.restored = Some(Err(not_operational(r.drive, id, problem)));
    }

    fn on_sdo_outcome(&mut self, o: Outcome) {
        let Some(r) = self.restore.as_mut() else {
            return;
        };
        match (o, r.step) {
            (Outcome::Downloaded { .. }, Step::Configure { k, started: true }) => {
                r.step = Step::Configure {
                    k: k + 1,
                    started: false,
                };
            }
            (Outcome::Aborted { .. }, _) => {
                self.fail_restore("it refused its configuration by SDO")
            }
            _ => {}
        }
    }

    /// One step of the restore in progress, before the PDOs go.
    fn restore_step(&mut self, now: u64) {
        let Some(r) = self.restore else {
            return;
        };
        if now >= r.deadline_ns {
            let problem = match r.step {
                Step::Reset | Step::BootUp => {
                    "no boot-up after NMT reset communication (power, cable?)"
                }
                Step::Configure { .. } => "its configuration by SDO did not finish",
                Step::Start | Step::FirstTpdos => "no TPDOs after NMT start",
            };
            self.fail_restore(problem);
            return;
        }
        if r.step == Step::Reset {
            // The application's transfer with this node ends with the reset.
            if let Some(t) = self.sdo.as_ref().filter(|t| t.transfer.drive == r.drive) {
                let e = SdoError::protocol(
                    &t.transfer,
                    "the node was reset (NMT reset communication) during the transfer",
                );
                self.end_transfer(Some(e));
            }
        }
        let Some(d) = self.drives.get_mut(r.drive) else {
            self.fail_restore("no such drive");
            return;
        };
        // A frame the link did not take leaves the step where it is: it is tried again
        // next exchange, until the restore's deadline.
        let mut step = r.step;
        match r.step {
            Step::Reset => {
                let f = bring_up::nmt(NmtCommand::ResetCommunication, NmtTarget::Node(d.node));
                if self.link.send(&f).is_ok() {
                    // A transfer cut short by the reset is gone with it.
                    let _ = d.sdo.abort(AbortCode::GENERAL_ERROR);
                    while d.sdo.transmit().is_some() {}
                    step = Step::BootUp;
                }
            }
            Step::BootUp | Step::FirstTpdos => {}
            Step::Configure { k, started } => {
                if d.sdo.poll(now).is_some() {
                    self.fail_restore("it did not answer an SDO request in time");
                    return;
                }
                if !started {
                    match d.steps.get(k).copied() {
                        Some(s) => {
                            if d.sdo
                                .download(s.mux, s.value(), DownloadMode::Auto, now)
                                .is_ok()
                            {
                                step = Step::Configure { k, started: true };
                            }
                        }
                        None => step = Step::Start,
                    }
                }
                // A request the link did not take times out in the SDO client.
                while let Some(f) = d.sdo.transmit() {
                    let _ = self.link.send(&f);
                }
            }
            Step::Start => {}
        }
        if step == Step::Start {
            let f = bring_up::nmt(NmtCommand::Start, NmtTarget::Node(d.node));
            if self.link.send(&f).is_ok() {
                d.left = None;
                d.heard_ns = now;
                d.lost_in_a_row = 0;
                d.got = 0;
                step = Step::FirstTpdos;
            }
        }
        if let Some(r) = self.restore.as_mut() {
            r.step = step;
        }
    }

    /// After the TPDOs: a restored node whose TPDOs all came is back.
    fn finish_restore(&mut self) {
        let Some(r) = self.restore else {
            return;
        };
        if r.step != Step::FirstTpdos {
            return;
        }
        if let Some(d) = self.drives.get(r.drive) {
            if d.got == d.all_tpdos() {
                // Next, an I/O module the axis reads that is out too.
                let next = self.drives.get(r.origin).and_then(|o| {
                    o.reads.iter().flatten().copied().find(|m| {
                        *m != r.drive
                            && self
                                .drives
                                .get(*m)
                                .is_some_and(|m| m.fault.is_some() || m.left.is_some())
                    })
                });
                self.restore = next.map(|m| Restore {
                    drive: m,
                    step: Step::Reset,
                    ..r
                });
                if self.restore.is_none() {
                    self.restored = Some(Ok(Restored::BackInOperation));
                }
            }
        }
    }

    /// Receives until `deadline` (link clock) or until every drive in operation has its
    /// TPDOs; then what is already waiting.
    fn receive_tpdos(&mut self, deadline: u64, now: u64) {
        let mut complete = false;
        for _ in 0..MAX_FRAMES_PER_EXCHANGE {
            let until = if complete { now } else { deadline };
            match self.link.receive(until) {
                Ok(Some(r)) => self.dispatch(&r, true, now),
                Ok(None) | Err(_) => {
                    if complete {
                        return;
                    }
                    complete = true;
                    continue;
                }
            }
            if !complete {
                complete = (0..self.drives.len()).all(|i| {
                    !self.in_operation(i)
                        || self.drives.get(i).is_some_and(|d| d.got == d.all_tpdos())
                });
            }
        }
    }

    /// Judges each drive after an exchange: fresh inputs, lost exchanges, silence, and
    /// the fault in force (made once, when it arises).
    fn judge(&mut self, now: u64) -> bool {
        let mut any_answer = false;
        let mut any_expected = false;
        for i in 0..self.drives.len() {
            let operating = self.in_operation(i);
            let restoring = self.restoring(i);
            let (lost_limit, consumer_ns) = (self.lost_limit, self.consumer_ns);
            let Some(d) = self.drives.get_mut(i) else {
                continue;
            };
            let complete = d.got == d.all_tpdos();
            d.fresh = operating && complete;
            if operating {
                any_expected = true;
                if complete {
                    any_answer = true;
                    d.lost_in_a_row = 0;
                } else {
                    d.lost_in_a_row = d.lost_in_a_row.saturating_add(1);
                    d.lost_total += 1;
                    self.counters.lost += 1;
                    if d.got != 0 {
                        self.counters.incomplete += 1;
                    }
                }
            }
            if restoring || d.fault.is_some() {
                continue;
            }
            let node = d.node.get();
            let silent = now.saturating_sub(d.heard_ns);
            let fault = if let Some(f) = d.left {
                Some(f)
            } else if consumer_ns > 0 && silent >= consumer_ns {
                Some(CanFault::Silent {
                    node,
                    silent_ms: silent / 1_000_000,
                    limit_ms: (consumer_ns / 1_000_000) as u32,
                })
            } else if d.lost_in_a_row >= lost_limit {
                Some(CanFault::Lost {
                    node,
                    in_a_row: d.lost_in_a_row,
                })
            } else {
                None
            };
            let module = d.module;
            d.fault = fault.map(|f| {
                let why = if module {
                    Unreachable::new(&format_args!("switch module: {f}"))
                } else {
                    Unreachable::new(&f)
                };
                (f, why)
            });
        }
        any_answer || !any_expected
    }
}

impl CycleBus for CanopenBus {
    fn drives(&self) -> usize {
        self.drives.len()
    }

    fn inputs(&self, drive: usize) -> &[u8] {
        self.drives
            .get(drive)
            .and_then(|d| d.inputs.get(..d.plan.input_bytes))
            .unwrap_or(&[])
    }

    fn outputs(&self, drive: usize) -> &[u8] {
        self.drives
            .get(drive)
            .and_then(|d| d.outputs.get(..d.plan.output_bytes))
            .unwrap_or(&[])
    }

    fn outputs_mut(&mut self, drive: usize) -> &mut [u8] {
        match self.drives.get_mut(drive) {
            Some(d) => d.outputs.get_mut(..d.plan.output_bytes).unwrap_or(&mut []),
            None => &mut [],
        }
    }

    fn exchange(&mut self, deadline_ns: u64) -> Reply {
        self.exchanges += 1;
        let heartbeats_before = self.heartbeats_sent;
        let now = self.link.now_ns();
        self.last_exchange_ns = now;
        // The engine's deadline is CLOCK_MONOTONIC; the wait left, on the link's clock.
        let deadline = now.saturating_add(deadline_ns.saturating_sub(now_ns()));
        for d in &mut self.drives {
            d.got = 0;
            d.emcy_fresh = false;
        }
        // 1. What came since the last exchange: heartbeats, EMCYs, SDO answers, late
        //    TPDOs (not this cycle's inputs).
        for _ in 0..MAX_FRAMES_PER_EXCHANGE {
            match self.link.receive(now) {
                Ok(Some(r)) => self.dispatch(&r, false, now),
                Ok(None) | Err(_) => break,
            }
        }
        // 2. A restore's step (an NMT command or an SDO request).
        self.restore_step(now);
        // 3. RPDOs, then SYNC (CiA 301 §7.2.5: the drives act on the data received
        //    before the SYNC).
        let mut sent = true;
        for i in 0..self.drives.len() {
            if !self.in_operation(i) {
                continue;
            }
            let Some(d) = self.drives.get(i) else {
                continue;
            };
            for p in &d.plan.rpdos {
                let mut data = [0u8; 8];
                for m in &p.entries {
                    let n = m.size();
                    if let (Some(dst), Some(src)) = (
                        data.get_mut(m.in_pdo..m.in_pdo + n),
                        d.outputs.get(m.in_image..m.in_image + n),
                    ) {
                        dst.copy_from_slice(src);
                    }
                }
                let frame = CanFrame::new(u32::from(p.cob_id), data.get(..p.len).unwrap_or(&[]));
                sent &= frame.is_ok_and(|f| self.link.send(&f).is_ok());
            }
        }
        let sync = self.next_sync();
        sent &= self.link.send(&sync).is_ok();
        // gantry's heartbeat, after the SYNC (its identifier loses arbitration to every
        // PDO anyway): the nodes stop if the cycle stops.
        self.produce_heartbeat(now);
        // 4. The TPDOs the SYNC asks for.
        self.receive_tpdos(deadline, now);
        if let Some(d) = self.restore.and_then(|r| self.drives.get_mut(r.drive)) {
            while let Some(f) = d.sdo.transmit() {
                let _ = self.link.send(&f);
            }
        }
        self.finish_restore();
        self.step_transfer(now, self.heartbeats_sent != heartbeats_before);
        let answered = self.judge(now);
        if sent && answered {
            Reply::Answered
        } else {
            Reply::Lost
        }
    }

    /// The drive's own fault, else that of an I/O module its axis reads switches from
    /// (the axis cannot run with its limit switches unwatched).
    fn fault(&self, drive: usize) -> Option<&Unreachable> {
        let d = self.drives.get(drive)?;
        d.fault.as_ref().map(|(_, u)| u).or_else(|| {
            d.reads.iter().flatten().find_map(|m| {
                self.drives
                    .get(*m)
                    .and_then(|m| m.fault.as_ref().map(|(_, u)| u))
            })
        })
    }

    fn inputs_fresh(&self, drive: usize) -> bool {
        self.drives.get(drive).is_some_and(|d| d.fresh)
    }

    fn drive_error(&self, drive: usize) -> Option<DriveError> {
        let d = self.drives.get(drive)?;
        d.emcy.map(|code| DriveError {
            code,
            fresh: d.emcy_fresh,
        })
    }

    fn any_fault(&self) -> bool {
        self.drives.iter().any(|d| d.fault.is_some())
    }

    fn clear_faults(&mut self) {
        for d in &mut self.drives {
            d.fault = None;
            d.lost_in_a_row = 0;
        }
    }

    fn counters(&self) -> BusCounters {
        self.counters
    }

    /// The nodes were started at the end of the bring-up (NMT start): nothing left to do.
    fn start_operation(&mut self) {}

    /// Brings the node of `drive` back — or, when it is fine, an I/O module its axis reads
    /// that is not: at once if it has no fault and is Operational
    /// (heard from within its consumer time); otherwise NMT reset communication, its
    /// boot-up, its configuration by SDO (one write per exchange), NMT start and its first
    /// TPDOs, timed on the link's clock (`now_ns`, the cycle's clock, is not the link's
    /// on a lockstep bus).
    fn start_restore(&mut self, drive: usize, _now_ns: u64, timeout_ns: u64) -> bool {
        if self.restore.is_some() {
            return false;
        }
        let now = self.link.now_ns();
        let Some(d) = self.drives.get(drive) else {
            self.restored = Some(Err(not_operational(drive, 0, "no such drive")));
            return true;
        };
        let out = |d: &Drive| d.fault.is_some() || d.left.is_some();
        let origin = drive;
        // The drive first, then the I/O modules its axis reads (`finish_restore`).
        let drive = if out(d) {
            drive
        } else {
            match d
                .reads
                .iter()
                .flatten()
                .copied()
                .find(|m| self.drives.get(*m).is_some_and(out))
            {
                Some(m) => m,
                None => {
                    self.restored = Some(Ok(Restored::WasOperational));
                    return true;
                }
            }
        };
        self.restore = Some(Restore {
            drive,
            origin,
            deadline_ns: now.saturating_add(timeout_ns),
            step: Step::Reset,
        });
        true
    }

    fn take_restored(&mut self) -> Option<Result<Restored, CommandError>> {
        self.restored.take()
    }

    fn restore_timeout_ns(&self) -> u64 {
        RESTORE_TIMEOUT_NS
    }

    /// An SDO transfer with the drive's node on its default SDO channel (0x600/0x580 +
    /// node): expedited, segmented or block as the size asks (see the module doc), its
    /// frames after the TPDOs, timed on the link's clock. Refused while the node is being
    /// brought back by a reset (its channel carries the restore's configuration).
    fn start_sdo(
        &mut self,
        transfer: &SdoTransfer,
        buffer: SdoBuffer,
        _now_ns: u64,
    ) -> Result<(), SdoEnded> {
        if self.sdo.is_some() || self.sdo_done.is_some() {
            return Err(SdoEnded::refused(SdoError::Busy, buffer));
        }
        let drive = transfer.drive;
        let Some(d) = self.drives.get(drive) else {
            return Err(SdoEnded::refused(SdoError::NoDrive { drive }, buffer));
        };
        if self.restoring(drive) {
            return Err(SdoEnded::refused(SdoError::Busy, buffer));
        }
        let (node, block) = (d.node, d.sdo_block);
        let now = self.link.now_ns();
        let config = SdoConfig {
            timeout_ns: transfer.timeout_ns.max(1),
            block_size: self.sdo_block_size,
            pst: PROTOCOL_SWITCH,
            ..SdoConfig::default()
        };
        let (len, capacity) = (buffer.len(), buffer.capacity());
        let mut client = match SdoClient::with_buffer(node, config, Lent(buffer)) {
            Ok(c) => c,
            Err((_, Lent(buffer))) => {
                let e = SdoError::protocol(transfer, "the SDO client refused its settings");
                return Err(SdoEnded::refused(e, buffer));
            }
        };
        let mux = Multiplexer::new(transfer.index, transfer.sub);
        let (started, by_block) = match transfer.direction {
            SdoDirection::Upload if block => (client.upload(mux, UploadMode::Block, now), true),
            SdoDirection::Upload => (client.upload(mux, UploadMode::Normal, now), false),
            SdoDirection::Download if block && len >= BLOCK_FROM => (
                client.download_buffered(mux, len, DownloadMode::Block, now),
                true,
            ),
            SdoDirection::Download => (
                client.download_buffered(mux, len, DownloadMode::Auto, now),
                false,
            ),
        };
        if started.is_err() {
            let e = SdoError::protocol(transfer, "the SDO client refused the request");
            return Err(SdoEnded::refused(e, client.into_buffer().0));
        }
        self.sdo = Some(Transfer {
            transfer: *transfer,
            client,
            len,
            capacity,
            heard_ns: now,
            too_large: None,
            block_unheard: by_block,
            ended: None,
            uploaded: 0,
        });
        Ok(())
    }

    fn take_sdo(&mut self) -> Option<SdoEnded> {
        self.sdo_done.take()
    }

    fn can_node(&self, drive: usize) -> Option<CanNodeStatus> {
        let d = self.drives.get(drive)?;
        Some(CanNodeStatus {
            node: d.node.get(),
            nmt: d.nmt.map(state_name),
            heard_ms_ago: self.last_exchange_ns.saturating_sub(d.heard_ns) / 1_000_000,
            heartbeat_limit_ms: self.consumer_ns / 1_000_000,
            lost_tpdos: d.lost_total,
            lost_in_a_row: d.lost_in_a_row,
        })
    }
}
