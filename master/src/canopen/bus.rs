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
//! NMT start, its first TPDOs. Nothing in [`CycleBus`]'s methods allocates, locks or
//! panics; all state is made at bring-up.

use std::fmt;
use std::io::Write;

use gantry_drives::canopen::cob_id::{CobId, NodeId};
use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::canopen::heartbeat::{Heartbeat, NmtState};
use gantry_drives::canopen::nmt::{NmtCommand, NmtTarget};
use gantry_drives::canopen::sdo::{AbortCode, DownloadMode, Outcome};
use gantry_drives::canopen::sync::Sync;
use gantry_drives::canopen::CanFrame;
use gantry_kernel::axis::command::CommandError;

use super::bring_up::{self, Client, DriveSetup, NodeInfo, SdoStep, StartError};
use super::link::{CanLink, Received};
use super::pdo::DrivePlan;
use crate::config::Config;
use crate::runtime::bus::{BusCounters, CycleBus, DriveError, Reply, Restored, Unreachable};
use crate::runtime::clock::now_ns;

/// Bytes of a drive's process data each way at most (4 PDOs of 8 bytes).
pub const MAX_IMAGE: usize = 32;
/// How long a reset may take to bring a node back (NMT reset, boot-up, ~30 SDO writes
/// at one per cycle, NMT start, the first TPDOs).
pub const RESTORE_TIMEOUT_NS: u64 = 5_000_000_000;
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

#[derive(Clone, Copy, Debug)]
struct Restore {
    drive: usize,
    deadline_ns: u64,
    step: Step,
}

/// One drive (node) of the bus.
struct Drive {
    node: NodeId,
    plan: DrivePlan,
    rpdo_ids: [u16; 4],
    tpdo_ids: [u16; 4],
    inputs: [u8; MAX_IMAGE],
    outputs: [u8; MAX_IMAGE],
    /// TPDOs received this exchange (bit k: plan.tpdos[k]).
    got: u8,
    /// Inputs complete with the last exchange.
    fresh: bool,
    /// A boot-up or another NMT state seen since it was last started.
    left: Option<CanFault>,
    /// When its last heartbeat came (link clock).
    heard_ns: u64,
    lost_in_a_row: u32,
    fault: Option<(CanFault, Unreachable)>,
    /// The error of its last EMCY while in force (0x0000 ends it), and whether it came
    /// with the last exchange.
    emcy: Option<u16>,
    emcy_fresh: bool,
    sdo: Client,
    steps: Vec<SdoStep>,
}

impl Drive {
    fn all_tpdos(&self) -> u8 {
        ((1u16 << self.plan.tpdos.len()) - 1) as u8
    }
}

/// The CANopen bus: its nodes Operational after the bring-up, exchanging synchronous PDOs
/// at each SYNC the cycle sends.
pub struct CanopenBus {
    link: Box<dyn CanLink>,
    drives: Vec<Drive>,
    /// Node id → drive index + 1 (0: not ours).
    node_drive: [u8; 128],
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
    lost_limit: u32,
    consumer_ns: u64,
    counters: BusCounters,
    restore: Option<Restore>,
    restored: Option<Result<Restored, CommandError>>,
    exchanges: u64,
    malformed: u64,
}

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
        let setups = bring_up::drive_setups(config)?;
        let consumer_ns = u64::from(config.bus.heartbeat_consumer_ms()) * 1_000_000;
        let infos = bring_up::run(&mut *link, &setups, consumer_ns, out)?;
        let now = link.now_ns();
        let mut node_drive = [0u8; 128];
        let mut drives = Vec::with_capacity(setups.len());
        for (i, s) in setups.into_iter().enumerate() {
            let DriveSetup {
                node, plan, steps, ..
            } = s;
            if let Some(slot) = node_drive.get_mut(usize::from(node.get())) {
                *slot = i as u8 + 1;
            }
            let mut rpdo_ids = [0u16; 4];
            for (dst, p) in rpdo_ids.iter_mut().zip(&plan.rpdos) {
                *dst = DrivePlan::rpdo_id(node, p);
            }
            let mut tpdo_ids = [0u16; 4];
            for (dst, p) in tpdo_ids.iter_mut().zip(&plan.tpdos) {
                *dst = DrivePlan::tpdo_id(node, p);
            }
            drives.push(Drive {
                node,
                plan,
                rpdo_ids,
                tpdo_ids,
                inputs: [0; MAX_IMAGE],
                outputs: [0; MAX_IMAGE],
                got: 0,
                fresh: false,
                left: None,
                heard_ns: now,
                lost_in_a_row: 0,
                fault: None,
                emcy: None,
                emcy_fresh: false,
                sdo: bring_up::client(node)?,
                steps,
            });
        }
        let master = bring_up::master_node(config)?;
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
            infos,
            sync: Sync::new().emit(),
            sync_overflow: config.bus.sync_counter.unwrap_or(0),
            sync_counter: 0,
            heartbeat: Heartbeat::new(master, NmtState::Operational).emit(),
            heartbeat_ns: u64::from(config.bus.heartbeat_producer_ms()) * 1_000_000,
            // The first with the first exchange: the nodes' monitoring starts with it.
            heartbeat_due_ns: 0,
            heartbeats_sent: 0,
            lost_limit: config.bus.faults.lost_frames_limit.max(1),
            consumer_ns: u64::from(config.bus.heartbeat_consumer_ms()) * 1_000_000,
            counters: BusCounters::default(),
            restore: None,
            restored: None,
            exchanges: 0,
            malformed: 0,
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

    /// Takes the nodes to Pre-operational (their PDOs stop; SDO stays) and hands the link
    /// back.
    pub fn shut_down(mut self, out: &mut (dyn Write + Send)) -> Box<dyn CanLink> {
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
        let _ = writeln!(out, "CANopen: nodes pre-operational");
        self.link
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
            CobId::Tpdo(..) => {
                if !in_window || !self.in_operation(i) {
                    return;
                }
                let Some(d) = self.drives.get_mut(i) else {
                    return;
                };
                let Some(k) = d.tpdo_ids.iter().position(|id| *id == frame.id()) else {
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
                d.got |= 1 << k;
            }
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

    fn on_heartbeat(&mut self, i: usize, hb: Heartbeat, at: u64) {
        let restoring = self.restoring(i);
        let Some(d) = self.drives.get_mut(i) else {
            return;
        };
        d.heard_ns = d.heard_ns.max(at);
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
                self.restore = None;
                self.restored = Some(Ok(Restored::BackInOperation));
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
            d.fault = fault.map(|f| (f, Unreachable::new(&f)));
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
        let now = self.link.now_ns();
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
            for (p, id) in d.plan.rpdos.iter().zip(d.rpdo_ids) {
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
                let frame = CanFrame::new(u32::from(id), data.get(..p.len).unwrap_or(&[]));
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
        let answered = self.judge(now);
        if sent && answered {
            Reply::Answered
        } else {
            Reply::Lost
        }
    }

    fn fault(&self, drive: usize) -> Option<&Unreachable> {
        self.drives.get(drive)?.fault.as_ref().map(|(_, u)| u)
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

    /// Brings the node of `drive` back: at once if it has no fault and is Operational
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
        if d.fault.is_none() && d.left.is_none() {
            self.restored = Some(Ok(Restored::WasOperational));
            return true;
        }
        self.restore = Some(Restore {
            drive,
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
}
