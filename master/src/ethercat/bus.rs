//! gantry's EtherCAT bus for a configuration: bring-up (discover, check the axes' drives
//! exist, map their PDOs by SDO in PreOp, go to OP) and the cycle's exchange, over a
//! network interface or on a link the caller plugs in ([`LinkFactory`]).

use std::io::Write;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;
use std::time::Duration;

use super::transition;
use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::{DcConfiguration, HasDc, SafeOp};
use ethercrab::{
    Command, MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup, SubDeviceState, Timeouts,
};
use gantry_kernel::axis::command::CommandError;
use thiserror::Error;

use super::coe_sdo::{self, CoeSdo, Mailbox, MailboxAnswer};
use super::doorbell::BlockOn;
use super::frame::{self, ProcessImage};
use super::health::{BusFault, BusHealth, Exchange, HealthConfig, States};
use super::link::{Capture, FrameIo, InterfaceOnly, Link, LinkFactory};
use super::mapping::{download, map_pdos};
use super::raw::RawLink;
use super::recovery::{self, access, Answer, Recovered, Recovery, RecoveryError, RegisterAccess};
use crate::config::Config;
use crate::pcap::PcapWriter;
use crate::runtime::bus::{BusCounters, CycleBus, Reply, Restored, Unreachable};
use crate::runtime::clock::now_ns;
use crate::runtime::cycle::SetupError;
use crate::runtime::sdo::{SdoBuffer, SdoEnded, SdoError, SdoTransfer};

/// Most slaves on one bus.
pub const MAX_SLAVES: usize = 64;
/// Most process data bytes.
pub const MAX_PDI: usize = 4096;
/// Most data bytes in one datagram: a full Ethernet frame (1500 B of payload) less the
/// EtherCAT header, one datagram header and its working counter, so that the process data
/// of up to 1486 bytes goes in one LRW frame.
pub const MAX_DATAGRAM: usize =
    1500 - frame::ECAT_HEADER - frame::DATAGRAM_HEADER - frame::WORKING_COUNTER;
const MAX_PDU_DATA: usize = PduStorage::element_size(MAX_DATAGRAM);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

/// ethercrab's timeouts as gantry sets them: none. ethercrab times its frames and waits
/// with async-io's `Timer`, whose first use starts async-io's reactor thread — from the
/// thread that polls, here the real-time cycle thread, so it would inherit SCHED_FIFO and
/// the CPU — and whose insertions go through a bounded queue that, when full, the
/// inserting thread drains under the reactor's mutex (async-io 2.6 `Reactor::insert_timer`).
/// gantry bounds every exchange itself (the doorbell's deadlines: the cycle's reply
/// deadline, and [`BRING_UP_SILENCE_NS`] and a limit per step during bring-up), so it asks
/// for timeouts that never fire: `Instant::now() + Duration::MAX` overflows, for which
/// async-io makes a timer that never registers with the reactor (`Timer::after` →
/// `Timer::never`), and a wait-loop delay of zero is ready when first polled. No frame,
/// no wait loop of ethercrab's ever touches the reactor, and its thread never starts.
pub const NO_TIMERS: Timeouts = Timeouts {
    state_transition: Duration::MAX,
    pdu: Duration::MAX,
    eeprom: Duration::MAX,
    wait_loop_delay: Duration::ZERO,
    mailbox_echo: Duration::MAX,
    mailbox_response: Duration::MAX,
};

/// During bring-up, frames in flight with no reply for this long mean no slave answers
/// (ethercrab's own PDU timeout is 30 ms; a slave answers in microseconds, a loaded
/// non-real-time host may stall tens of milliseconds).
pub const BRING_UP_SILENCE_NS: u64 = 200_000_000;
/// Longest a bring-up step may take while slaves keep answering: discovery (which reads
/// every EEPROM and measures the DC delays) and each state transition (ETG.2000's default
/// SafeOp→Op timeout is 10 s).
const DISCOVERY_LIMIT_NS: u64 = 60_000_000_000;
const STEP_LIMIT_NS: u64 = 10_000_000_000;

// The groups stay SafeOp-typed: ethercrab exchanges process data from SafeOp on, and
// the cycle asks each slave for OP itself (`EthercatBus::start_operation`), so that ethercrab's
// own transition, which polls without process data, is never used.
type Group = SubDeviceGroup<MAX_SLAVES, MAX_PDI, ethercrab::DefaultLock, SafeOp>;
type GroupDc = SubDeviceGroup<MAX_SLAVES, MAX_PDI, ethercrab::DefaultLock, SafeOp, HasDc>;

/// The group (its slaves in SafeOp, then OP), with or without distributed clocks.
enum Groups {
    Plain(Group),
    Dc(GroupDc),
}

/// Runs `$body` with `$g` bound to whichever group it is.
macro_rules! with_group {
    ($groups:expr, $g:ident => $body:expr) => {
        match $groups {
            Groups::Plain($g) => $body,
            Groups::Dc($g) => $body,
        }
    };
}

/// What distributed clocks say each cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DcStatus {
    /// SYNC0 runs on the slaves at the cycle time.
    pub active: bool,
    /// The reference clock's system time (ns) at the last exchange.
    pub system_time_ns: u64,
    /// Where in the SYNC0 period the last frame reached the reference clock (ns).
    pub cycle_offset_ns: u64,
}

/// What made a step of the bring-up fail: ethercrab's error, a stalled step, an I/O or a
/// configuration error; kept as the [`std::error::Error::source`] of a [`StartError`].
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why the bus did not come up. The message says what failed; what caused it is the
/// error's source (printed after it, see `crate::error_chain`).
#[derive(Debug, Error)]
pub enum StartError {
    /// No link for the configuration (no interface, and no factory of the caller's opens
    /// its simulator), or the bus is already up in this process.
    #[error("{0}")]
    NoLink(&'static str),
    /// The link (interface, a plugged-in link, pcap file) could not be opened.
    #[error("{what}")]
    Link {
        /// What was being opened.
        what: String,
        /// Why it failed.
        #[source]
        source: Cause,
    },
    /// A step of the bring-up failed.
    #[error("EtherCAT {step}")]
    Bus {
        /// The step.
        step: &'static str,
        /// Why.
        #[source]
        source: Cause,
    },
    /// The configuration does not fit the bus found (a drive missing, a layout that the
    /// axis' drive cannot carry): the same checks the cycle makes when it is built.
    #[error(transparent)]
    Axes(#[from] SetupError),
    /// The layout does not suit CSP, or the kernel refused the axes.
    #[error("{what}")]
    Setup {
        /// What was being set up.
        what: String,
        /// Why it failed.
        #[source]
        source: Cause,
    },
}

impl StartError {
    /// A link that could not be opened: what it was.
    pub fn link(what: impl Into<String>) -> impl FnOnce(Cause) -> Self {
        let what = what.into();
        move |source| Self::Link { what, source }
    }

    /// A set-up that failed.
    fn setup(what: impl Into<String>) -> impl FnOnce(Cause) -> Self {
        let what = what.into();
        move |source| Self::Setup { what, source }
    }
}

/// The EtherCAT bus: its slaves in SafeOp after the bring-up with the process data
/// running, taken to OP by the cycle ([`CycleBus::start_operation`]).
pub struct EthercatBus {
    md: MainDevice<'static>,
    group: Groups,
    dc: DcStatus,
    /// The reference clock's station address, when DC runs: the cycle reads its system
    /// time (FRMW 0x0910) and so distributes it to the other clocks (ETG.1000.4 §9.3.6).
    dc_reference: Option<u16>,
    /// SYNC0 period (ns).
    sync0_ns: u64,
    /// The last exchange read the reference clock's time (not in a cycle that read the
    /// AL-status summary in its place, nor in a lost one).
    dc_measured: bool,
    /// The process data as the wire carries it (the cycle reads and writes it).
    image: ProcessImage,
    /// What the cycle sent.
    frame_stats: FrameStats,
    /// What the exchanges said about the network.
    health: BusHealth,
    /// Per slave: the fault in force and its reason as the cycle hands it on.
    faults: Vec<Option<(BusFault, Unreachable)>>,
    /// Every slave's AL state, when the last exchange read them.
    states: Vec<SubDeviceState>,
    /// Replies handed back so far (bring-up and shutdown watch it for silence).
    replies: Arc<AtomicU64>,
    /// Runs ethercrab's futures in the cycle thread without a lock, and exchanges their
    /// frames on the link.
    runner: BlockOn,
    /// The slave being brought back to OP: its position, and the machine.
    recovery: Option<(usize, Recovery)>,
    /// A finished recovery, until the engine takes it.
    recovered: Option<Result<Recovered, RecoveryError>>,
    /// Asking the slaves for OP at start.
    op_request: OpRequest,
    /// Per slave: its CoE mailbox as the bring-up left it (`None`: no mailbox).
    mailboxes: Vec<Option<Mailbox>>,
    /// Per slave: the counter of the last mailbox message the cycle sent it.
    mailbox_counters: Vec<Option<u8>>,
    /// Per slave: its last transfer timed out with its request out (a late answer may
    /// still come).
    mailbox_unanswered: Vec<bool>,
    /// The SDO transfer in progress: the slave's position, its station address, the
    /// machine, the buffer lent with it.
    sdo: Option<(usize, u16, CoeSdo, SdoBuffer)>,
    /// A finished SDO transfer and its buffer, until the engine takes them.
    sdo_done: Option<SdoEnded>,
    /// The mailbox message being sent (made once, at bring-up).
    sdo_message: Box<[u8; coe_sdo::MAX_MAILBOX]>,
    /// The answer read (made once, at bring-up).
    sdo_answer: Box<[u8; coe_sdo::ANSWER_KEEP]>,
}

/// The slaves are asked for OP by the cycle, one AL control write per cycle beside the
/// process data, once the cycle is ready (`CycleBus::start_operation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum OpRequest {
    /// Not yet: the slaves wait in SafeOp with the process data running.
    Waiting,
    /// Slave `k` is next.
    Asking(usize),
    /// Every slave was asked.
    Done,
}

impl EthercatBus {
    /// Brings the bus of `config` up: its slaves in SafeOp with the process data mapped
    /// for the configuration's axes, ready for the cycle ([`crate::runtime::cycle::Cycle`]
    /// is built on it from the same configuration) to take them to OP. Prints its steps to
    /// `out`.
    ///
    /// The steps run in a short-lived thread of their own with a large stack
    /// ([`BRING_UP_STACK_BYTES`]; ethercrab's bring-up futures take hundreds of kB of
    /// stack per level in debug builds), started from the calling thread so that it — and
    /// the thread a link's factory may start — inherit the caller's scheduling and CPU.
    ///
    /// The link is a raw socket on `[bus] interface`; this library opens no other (see
    /// [`EthercatBus::bring_up_from`]).
    pub fn bring_up(config: &Config, out: &mut (dyn Write + Send)) -> Result<Self, StartError> {
        Self::bring_up_from(config, &InterfaceOnly, out)
    }

    /// [`EthercatBus::bring_up`], asking `links` for the link when the configuration has
    /// no `[bus] interface` (the binary's in-process simulator for `[bus] simulator`).
    pub fn bring_up_from(
        config: &Config,
        links: &dyn LinkFactory,
        out: &mut (dyn Write + Send),
    ) -> Result<Self, StartError> {
        on_large_stack("gantry-bring-up", || {
            Self::bring_up_here(config, || open_link(config, links), out)
        })
        .unwrap_or_else(|e| Err(StartError::link("a thread for the bring-up")(e.into())))
    }

    /// [`EthercatBus::bring_up`] on `link`, whatever the configuration's `[bus]` says of
    /// interfaces and simulators (its cycle time, DC, pcap and faults hold).
    pub fn bring_up_on(
        config: &Config,
        link: Box<dyn Link>,
        out: &mut (dyn Write + Send),
    ) -> Result<Self, StartError> {
        on_large_stack("gantry-bring-up", || {
            Self::bring_up_here(config, || Ok(link), out)
        })
        .unwrap_or_else(|e| Err(StartError::link("a thread for the bring-up")(e.into())))
    }

    /// The bring-up's steps, in order, on the link `open_link` opens.
    fn bring_up_here(
        config: &Config,
        open_link: impl FnOnce() -> Result<Box<dyn Link>, StartError>,
        out: &mut (dyn Write + Send),
    ) -> Result<Self, StartError> {
        let capture = open_capture(config)?;
        let (tx, rx, pdu_loop) = PDU_STORAGE
            .try_split()
            .map_err(|_| StartError::NoLink("the EtherCAT bus can start once per process"))?;
        let link = open_link()?;
        let io = FrameIo::new(tx, rx, link, capture);
        let replies = io.replies();
        let md = MainDevice::new(pdu_loop, NO_TIMERS, MainDeviceConfig::default());
        let runner =
            BlockOn::with_io(io).map_err(|e| StartError::link("the cycle's eventfd")(e.into()))?;
        let group = discover(&runner, &md, &replies, out)?;
        map_axes_pdos(config, &runner, &md, &group, &replies, out)?;
        let group = to_safe_op(config, &runner, &md, group, &replies, out)?;
        let image = with_group!(&group, g => ProcessImage::of_group(g, &md, MAX_DATAGRAM))
            .map_err(|e| StartError::setup("the process data image")(e.into()))?;
        let health = watch_health(config, &md, &group, &image);
        let mailboxes = read_mailboxes(&runner, &md, &group, &replies)?;
        let dc = DcStatus {
            active: matches!(group, Groups::Dc(_)),
            ..DcStatus::default()
        };
        // The reference clock: ethercrab's, the first slave with DC (`dc::configure_dc`).
        let dc_reference = with_group!(&group, g => g
            .iter(&md)
            .find(|sd| !matches!(sd.dc_support(), ethercrab::DcSupport::None))
            .map(|sd| sd.configured_address()))
        .filter(|_| dc.active);
        let slaves = with_group!(&group, g => g.len());
        Ok(Self {
            md,
            group,
            dc,
            dc_reference,
            sync0_ns: u64::from(config.bus.cycle_us) * 1000,
            dc_measured: false,
            image,
            frame_stats: FrameStats::default(),
            health,
            faults: vec![None; slaves],
            states: Vec::with_capacity(slaves.max(MAX_SLAVES)),
            replies,
            runner,
            recovery: None,
            recovered: None,
            op_request: OpRequest::Waiting,
            mailbox_counters: vec![None; mailboxes.len()],
            mailbox_unanswered: vec![false; mailboxes.len()],
            mailboxes,
            sdo: None,
            sdo_done: None,
            sdo_message: Box::new([0; coe_sdo::MAX_MAILBOX]),
            sdo_answer: Box::new([0; coe_sdo::ANSWER_KEEP]),
        })
    }

    /// The bus' health: what its exchanges said so far (lost frames, working counters,
    /// the slaves' states).
    pub fn health(&self) -> &BusHealth {
        &self.health
    }

    /// Notes, per slave, the reason the cycle cannot reach it, after each change of the
    /// health's verdicts: made once per new fault, no formatting while a fault stays.
    fn note_faults(&mut self) {
        for (i, slot) in self.faults.iter_mut().enumerate() {
            let fault = self.health.fault(i);
            if slot.map(|(f, _)| f) != fault {
                *slot = fault.map(|f| (f, Unreachable::new(&f)));
            }
        }
    }

    /// Replies the slaves sent back so far (every frame: process data, register
    /// accesses).
    pub fn replies(&self) -> u64 {
        self.replies.load(std::sync::atomic::Ordering::Acquire)
    }

    /// What the cyclic exchanges sent so far.
    pub fn frame_stats(&self) -> FrameStats {
        self.frame_stats
    }

    /// The process data image the cycle sends.
    pub fn image(&self) -> &ProcessImage {
        &self.image
    }

    /// Bytes on the wire per steady cycle (every slave in OP, the working counter right):
    /// the LRW frames and, with DC, the FRMW (in the first LRW's frame).
    pub fn cyclic_wire_bytes(&self) -> usize {
        let dc = self
            .dc_reference
            .map_or(0, |_| frame::datagram_bytes(frame::DC_TIME_BYTES));
        self.image.wire_bytes(dc)
    }

    /// Bytes on the wire in the steady cycle that reads the AL-status summary (one in
    /// [`health::AL_STATUS_EVERY`](super::health::AL_STATUS_EVERY)): the LRW frames and the
    /// BRD, which takes the FRMW's place.
    pub fn summary_wire_bytes(&self) -> usize {
        self.image
            .wire_bytes(frame::datagram_bytes(frame::AL_STATUS_BYTES))
    }

    /// Distributed clocks as of the last exchange.
    pub fn dc(&self) -> DcStatus {
        self.dc
    }

    /// Takes the slaves down to PreOp and stops the link.
    /// The transitions run in a thread of their own, as the bring-up's do.
    pub fn shut_down(self, out: &mut (dyn Write + Send)) {
        if let Err(e) = on_large_stack("gantry-shutdown", || self.shut_down_here(&mut *out)) {
            let _ = writeln!(out, "bus: no thread to take the slaves to PreOp: {e}");
        }
    }

    fn shut_down_here(mut self, out: &mut (dyn Write + Send)) {
        let md = &self.md;
        let group = std::mem::replace(&mut self.group, Groups::Plain(Group::default()));
        let result = self.runner.run_step(
            || async {
                // A slave that left Op with an error (its watchdog, a sync error) obeys
                // no request but Init until the error is acknowledged (ETG.1000.6
                // §6.4.1): ask every slave for PreOp with the acknowledge bit first.
                with_group!(&group, g => {
                    for sd in g.iter(md) {
                        let ack = recovery::AL_STATE_PREOP | recovery::AL_ERROR_ACK;
                        let _ = access(&sd, RegisterAccess::WriteAlControl(ack)).await;
                    }
                });
                // Op → PreOp is a transition of its own (ETG.1000.6 Table 10).
                with_group!(group, g => g.into_pre_op(md).await.map(|_| ()))
            },
            &self.replies,
            BRING_UP_SILENCE_NS,
            2 * STEP_LIMIT_NS,
        );
        match result {
            Ok(Ok(())) => {
                let _ = writeln!(out, "bus: slaves in PreOp");
            }
            Ok(Err(e)) => {
                let _ = writeln!(out, "bus: could not take the slaves to PreOp: {e}");
            }
            Err(e) => {
                let _ = writeln!(out, "bus: could not take the slaves to PreOp: {e}");
            }
        }
        // The capture flushed, the link closed (the simulator's thread stops with it).
        self.runner.finish_io();
    }
}

impl EthercatBus {
    /// The SDO transfer's step after an exchange: the answer to its access if it had
    /// one (`accessed`), else only its clock.
    fn step_sdo(&mut self, accessed: bool, answer: Option<MailboxAnswer>) {
        let Some((drive, _, sdo, buffer)) = self.sdo.as_mut() else {
            return;
        };
        if accessed {
            let got = answer.unwrap_or(MailboxAnswer::None);
            sdo.on_answer(got, &self.sdo_answer[..], buffer, now_ns());
        } else {
            sdo.tick(now_ns());
        }
        if let Some(slot) = self.mailbox_counters.get_mut(*drive) {
            *slot = Some(sdo.counter());
        }
        if let Some(Some(mailbox)) = self.mailboxes.get_mut(*drive) {
            *mailbox = sdo.mailbox();
        }
        let Some(result) = sdo.outcome() else {
            return;
        };
        if let Some(slot) = self.mailbox_unanswered.get_mut(*drive) {
            *slot = sdo.left_unanswered();
        }
        if let Some((_, _, _, buffer)) = self.sdo.take() {
            self.sdo_done = Some(SdoEnded { result, buffer });
        }
    }
}

/// What the exchange's one access beside the process data answered.
enum Accessed {
    /// A register access of a reset or of the request for OP.
    Register(Answer),
    /// A mailbox access of an SDO transfer.
    Mailbox(MailboxAnswer),
}

/// The DC system time register (ETG.1000.4 Table 60).
const DC_SYSTEM_TIME: u16 = 0x0910;

/// What the cyclic exchanges sent, counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Cycles exchanged.
    pub cycles: u64,
    /// Cycles that also read every slave's AL status, one by one (at start, after a wrong
    /// working counter or a lost frame, while a fault stands).
    pub state_reads: u64,
    /// Cycles that read the AL-status summary (one BRD, instead of the DC time).
    pub summaries: u64,
}

/// What a cycle read beside the process data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Read {
    /// Nothing: the working counter supervises.
    Nothing,
    /// The AL-status summary: every slave answered it, in OP without error.
    Summary(bool),
    /// Each slave's state (in the bus' `states`).
    Each,
}

/// One cycle's process data: the image's LRW datagrams alone; or with them one BRD of
/// the AL status of all `slaves` (`summary`); or, when `read_states` asks, ethercrab's
/// `tx_rx` (its LRW, with the same outputs, and one FPRD per slave), leaving the states
/// in `states` and the inputs in ethercrab's image (the caller takes those of the slaves
/// whose inputs are fresh). Returns the working counter and what was read.
#[allow(clippy::too_many_arguments)]
async fn cyclic_exchange<DC>(
    group: &SubDeviceGroup<MAX_SLAVES, MAX_PDI, ethercrab::DefaultLock, SafeOp, DC>,
    md: &MainDevice<'static>,
    image: &mut ProcessImage,
    states: &mut Vec<SubDeviceState>,
    stats: &mut FrameStats,
    read_states: bool,
    summary: bool,
    slaves: u16,
) -> Result<(u16, Read), ethercrab::error::Error> {
    stats.cycles += 1;
    if read_states {
        stats.state_reads += 1;
        image.put_outputs(group, md);
        let reply = group.tx_rx(md).await?;
        states.clear();
        // Within the capacity reserved at bring-up (one per slave): no allocation.
        states.extend(reply.subdevice_states.iter().copied());
        return Ok((reply.working_counter, Read::Each));
    }
    if summary {
        stats.summaries += 1;
        // Every slave ORs its AL status in (ETG.1000.4 §5.4.1.2); the working counter
        // counts those that answered.
        let al = Command::brd(recovery::AL_STATUS)
            .with_wkc(slaves)
            .receive::<u16>(md);
        let (lrw, al) = futures_lite::future::zip(image.exchange(md), al).await;
        let all_in_op = al.is_ok_and(|s| {
            s & (recovery::AL_STATE_MASK | recovery::AL_ERROR_ACK) == recovery::AL_STATE_OP
        });
        return Ok((lrw?.working_counter, Read::Summary(all_in_op)));
    }
    Ok((image.exchange(md).await?.working_counter, Read::Nothing))
}

/// Stack of the threads bring-up and shutdown run in.
pub const BRING_UP_STACK_BYTES: usize = 16 << 20;

/// Runs `f` in a thread named `name` with a [`BRING_UP_STACK_BYTES`] stack, started from
/// this one (so it inherits this thread's scheduling and CPU mask), and waits for it.
fn on_large_stack<T: Send>(name: &str, f: impl FnOnce() -> T + Send) -> std::io::Result<T> {
    std::thread::scope(|scope| {
        let handle = std::thread::Builder::new()
            .name(name.into())
            .stack_size(BRING_UP_STACK_BYTES)
            .spawn_scoped(scope, f)?;
        Ok(handle
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic)))
    })
}

/// An error of a bring-up step, with the step's name.
fn step_error(step: &'static str, cause: impl Into<Cause>) -> StartError {
    StartError::Bus {
        step,
        source: cause.into(),
    }
}

/// The group as discovery leaves it: every slave in PreOp.
type GroupPreOp =
    SubDeviceGroup<MAX_SLAVES, MAX_PDI, ethercrab::DefaultLock, ethercrab::subdevice_group::PreOp>;

/// Bring-up, step 1: the capture file of `[bus] pcap`, if any.
fn open_capture(config: &Config) -> Result<Option<Capture>, StartError> {
    let Some(path) = &config.bus.pcap else {
        return Ok(None);
    };
    std::fs::File::create(path)
        .map_err(Cause::from)
        .and_then(|f| PcapWriter::new(std::io::BufWriter::new(f)).map_err(Cause::from))
        .map(Some)
        .map_err(StartError::link(format!("pcap {path}")))
}

/// Bring-up, step 2: the link the cycle thread exchanges its frames on itself — a raw
/// socket on `[bus] interface`, or the link `links` opens for the configuration (the
/// binary's in-process simulator for `[bus] simulator`).
fn open_link(config: &Config, links: &dyn LinkFactory) -> Result<Box<dyn Link>, StartError> {
    if let Some(interface) = &config.bus.interface {
        let link = RawLink::open(interface)
            .map_err(|e| StartError::link(format!("interface {interface}"))(e.into()))?;
        return Ok(Box::new(link));
    }
    match (links.open(config)?, &config.bus.simulator) {
        (Some(link), _) => Ok(link),
        (None, Some(_)) => Err(StartError::NoLink(
            "[bus] simulator: this program has no in-process simulator (the gantry binary has)",
        )),
        (None, None) => Err(StartError::NoLink("no interface and no simulator")),
    }
}

/// Bring-up, step 3: discovery (every slave's EEPROM read, the DC delays measured); prints
/// the slaves found.
#[inline(never)]
fn discover(
    runner: &BlockOn,
    md: &MainDevice<'static>,
    replies: &AtomicU64,
    out: &mut (dyn Write + Send),
) -> Result<GroupPreOp, StartError> {
    // Every step is bounded here (ethercrab has no timeouts, see NO_TIMERS).
    let group = runner
        .run_step(
            || md.init_single_group::<MAX_SLAVES, MAX_PDI>(ethercat_now),
            replies,
            BRING_UP_SILENCE_NS,
            DISCOVERY_LIMIT_NS,
        )
        .map_err(|e| step_error("discovery", e))?
        .map_err(|e| step_error("discovery", e))?;
    let _ = writeln!(out, "found {} EtherCAT slaves", group.len());
    for (i, sd) in group.iter(md).enumerate() {
        let _ = writeln!(
            out,
            "  {i}: {:#06x} {} ({})",
            sd.configured_address(),
            sd.name(),
            sd.identity()
        );
    }
    Ok(group)
}

/// Bring-up, step 4: each axis' drive is there and gets its PDO layout, by SDO in PreOp.
#[inline(never)]
fn map_axes_pdos(
    config: &Config,
    runner: &BlockOn,
    md: &MainDevice<'static>,
    group: &GroupPreOp,
    replies: &AtomicU64,
    out: &mut (dyn Write + Send),
) -> Result<(), StartError> {
    // Axes without a drive (simulated, virtual, external, shadow) map nothing: an
    // external axis' encoder module has fixed PDOs (its SII's).
    for a in config
        .axes
        .iter()
        .filter(|a| a.axis_type == crate::config::AxisType::Real)
    {
        if a.drive >= group.len() {
            return Err(SetupError::MissingDrive {
                path: config.path.clone(),
                axis: a.name.clone(),
                drive: a.drive,
                slaves: group.len(),
            }
            .into());
        }
        let layout = a.pdo_layout().map_err(|(key, reason)| SetupError::Axis {
            axis: a.name.clone(),
            key,
            reason,
        })?;
        let settings = a
            .switches
            .sdo_writes()
            .map_err(|(key, reason)| SetupError::Axis {
                axis: a.name.clone(),
                key,
                reason,
            })?;
        let sd = group
            .subdevice(md, a.drive)
            .map_err(|e| step_error("addressing", e))?;
        runner
            .run_step(
                || async {
                    map_pdos(&sd, &layout).await?;
                    download(&sd, settings.clone()).await
                },
                replies,
                BRING_UP_SILENCE_NS,
                STEP_LIMIT_NS,
            )
            .map_err(|e| step_error("PDO mapping", e))?
            .map_err(|e| StartError::setup(format!("axis {:?}: PDO mapping", a.name))(e.into()))?;
    }
    let _ = writeln!(out, "PDOs mapped for {} axes", config.axes.len());
    Ok(())
}

/// Bring-up, step 5: the process data set up and the slaves to SafeOp, with distributed
/// clocks (SYNC0 at the cycle time) when the configuration asks for them and a slave has
/// them. The cycle takes the slaves on to OP.
#[inline(never)]
fn to_safe_op(
    config: &Config,
    runner: &BlockOn,
    md: &MainDevice<'static>,
    mut group: GroupPreOp,
    replies: &AtomicU64,
    out: &mut (dyn Write + Send),
) -> Result<Groups, StartError> {
    let dc_capable = group
        .iter(md)
        .any(|sd| !matches!(sd.dc_support(), ethercrab::DcSupport::None));
    let group = if config.bus.dc && dc_capable {
        // SYNC0 at the cycle time, starting well after OP is reached.
        let dc = DcConfiguration {
            start_delay: Duration::from_millis(100),
            sync0_period: Duration::from_micros(u64::from(config.bus.cycle_us)),
            sync0_shift: Duration::ZERO,
        };
        // Every slave with DC generates SYNC0 (its AssignActivate).
        for mut sd in group.iter_mut(md) {
            if !matches!(sd.dc_support(), ethercrab::DcSupport::None) {
                sd.set_dc_sync(ethercrab::DcSync::Sync0);
            }
        }
        let group = dc_to_op(runner, md, group, dc, replies)?;
        let _ = writeln!(
            out,
            "distributed clocks: SYNC0 every {} µs",
            config.bus.cycle_us
        );
        Groups::Dc(group)
    } else {
        let group = plain_to_op(runner, md, group, replies)?;
        if config.bus.dc {
            let _ = writeln!(out, "distributed clocks: no slave has DC; free run");
        }
        Groups::Plain(group)
    };
    let _ = writeln!(
        out,
        "all slaves in SafeOp: the cycle takes them to OP (at most {} s)",
        transition::OP_TIMEOUT.as_secs()
    );
    Ok(group)
}

/// Bring-up, step 7: each slave's mailbox, read back from its SyncManager 0 and 1
/// registers as the bring-up set them (the cycle's SDO transfers use them).
#[inline(never)]
fn read_mailboxes(
    runner: &BlockOn,
    md: &MainDevice<'static>,
    group: &Groups,
    replies: &AtomicU64,
) -> Result<Vec<Option<Mailbox>>, StartError> {
    runner
        .run_step(
            || async {
                let mut found = Vec::new();
                with_group!(group, g => {
                    for sd in g.iter(md) {
                        let regs = sd
                            .register_read::<[u8; 2 * coe_sdo::SM_REGISTERS]>(coe_sdo::SM0)
                            .await?;
                        found.push(Mailbox::from_sync_managers(&regs));
                    }
                });
                Ok::<_, ethercrab::error::Error>(found)
            },
            replies,
            BRING_UP_SILENCE_NS,
            STEP_LIMIT_NS,
        )
        .map_err(|e| step_error("reading the mailboxes", e))?
        .map_err(|e| step_error("reading the mailboxes", e))
}

/// Bring-up, step 6: the health monitor of the bus' slaves and process data, with the
/// configuration's fault limits, the slaves given [`transition::OP_TIMEOUT`] to reach OP.
fn watch_health(
    config: &Config,
    md: &MainDevice<'static>,
    group: &Groups,
    image: &ProcessImage,
) -> BusHealth {
    let addresses: Vec<u16> =
        with_group!(group, g => g.iter(md).map(|sd| sd.configured_address()).collect());
    let f = config.bus.faults;
    // LRW: a slave counts 2 per datagram its outputs are in, 1 per datagram its inputs are.
    BusHealth::new(
        HealthConfig {
            lost_frames_limit: f.lost_frames_limit,
            working_counter_limit: f.working_counter_limit,
            stop_all_on_slave_loss: f.stop_all_on_slave_loss,
        },
        addresses,
        image.slave_working_counters(),
    )
    .starting(
        (transition::OP_TIMEOUT.as_micros() as u64 / u64::from(config.bus.cycle_us)) as u32,
        transition::OP_TIMEOUT.as_millis() as u64,
    )
}

/// PreOp to OP with distributed clocks: process data (SyncManagers, FMMUs) first, then
/// the clocks. Its own function (never inlined) so that these large futures do not
/// share the stack frame of the rest of the bring-up.
#[inline(never)]
fn dc_to_op(
    runner: &BlockOn,
    md: &MainDevice<'static>,
    group: GroupPreOp,
    dc: DcConfiguration,
    replies: &AtomicU64,
) -> Result<GroupDc, StartError> {
    let group = runner
        .run_step(
            move || group.into_pre_op_pdi(md),
            replies,
            BRING_UP_SILENCE_NS,
            STEP_LIMIT_NS,
        )
        .map_err(|e| step_error("process data set-up", e))?
        .map_err(|e| step_error("process data set-up", e))?;
    let group = runner
        .run_step(
            move || group.configure_dc_sync(md, dc),
            replies,
            BRING_UP_SILENCE_NS,
            STEP_LIMIT_NS,
        )
        .map_err(|e| step_error("distributed clocks", e))?
        .map_err(|e| step_error("distributed clocks", e))?;
    runner
        .run_step(
            move || group.into_safe_op(md),
            replies,
            BRING_UP_SILENCE_NS,
            STEP_LIMIT_NS,
        )
        .map_err(|e| step_error("to SafeOp", e))?
        .map_err(|e| step_error("to SafeOp", e))
}

/// PreOp to OP without distributed clocks (see [`dc_to_op`]).
#[inline(never)]
fn plain_to_op(
    runner: &BlockOn,
    md: &MainDevice<'static>,
    group: GroupPreOp,
    replies: &AtomicU64,
) -> Result<Group, StartError> {
    runner
        .run_step(
            move || group.into_safe_op(md),
            replies,
            BRING_UP_SILENCE_NS,
            2 * STEP_LIMIT_NS,
        )
        .map_err(|e| step_error("to SafeOp", e))?
        .map_err(|e| step_error("to SafeOp", e))
}

impl CycleBus for EthercatBus {
    fn drives(&self) -> usize {
        // Positions, not bytes.
        self.image.slaves()
    }

    fn inputs(&self, drive: usize) -> &[u8] {
        self.image.inputs(drive)
    }

    fn outputs(&self, drive: usize) -> &[u8] {
        self.image.outputs(drive)
    }

    fn outputs_mut(&mut self, drive: usize) -> &mut [u8] {
        self.image.outputs_mut(drive)
    }

    fn exchange(&mut self, deadline_ns: u64) -> Reply {
        // A recovery in progress does one register access beside the process data,
        // under the same deadline.
        let (md, runner) = (&self.md, &self.runner);
        let recovering = self
            .recovery
            .as_ref()
            .and_then(|(drive, r)| Some((*drive, r.next_access()?)));
        // Otherwise the request for OP at start, slave by slave.
        let asking = match (recovering, self.op_request) {
            (None, OpRequest::Asking(k)) => Some(k),
            _ => None,
        };
        let pending = recovering
            .or(asking.map(|k| (k, RegisterAccess::WriteAlControl(recovery::AL_STATE_OP))));
        // Otherwise a step of the SDO transfer in progress, through the slave's mailbox.
        let mailbox = match (&pending, &self.sdo) {
            (None, Some((_, address, sdo, buffer))) => sdo
                .next_access(&mut self.sdo_message[..], buffer.as_slice())
                .map(|a| (*address, a)),
            _ => None,
        };
        let (message, answer_buf) = (&self.sdo_message[..], &mut self.sdo_answer[..]);
        // While the slaves are on their way to OP, the cycle after anything went wrong, and
        // while a fault stands, each slave's state is read (ethercrab's `tx_rx`); one
        // steady cycle in `AL_STATUS_EVERY` reads their summary; otherwise the LRW goes
        // alone (see `BusHealth::reads_states`).
        let read_states = self.health.reads_states();
        let summary = !read_states && self.health.reads_summary();
        let (image, states, stats) = (&mut self.image, &mut self.states, &mut self.frame_stats);
        let (dc_reference, group) = (self.dc_reference, &self.group);
        let (answer, accessed) = with_group!(group, g => {
            let sd = pending.and_then(|(drive, a)| Some((g.subdevice(md, drive).ok()?, a)));
            let register = sd.as_ref().map(|(sd, a)| access(sd, *a));
            let mailbox = mailbox.map(|(address, a)| {
                coe_sdo::mailbox_access(md, address, a, message, answer_buf)
            });
            let access_fut = (register.is_some() || mailbox.is_some()).then_some(async move {
                match (register, mailbox) {
                    (Some(r), _) => Accessed::Register(r.await),
                    (None, Some(m)) => Accessed::Mailbox(m.await),
                    (None, None) => Accessed::Register(Answer::None),
                }
            });
            let cyclic = cyclic_exchange(g, md, image, states, stats, read_states, summary, g.len() as u16);
            // With DC the reference clock's time goes round too (one FRMW), but in the
            // cycle whose BRD of AL status takes its place: one fixed datagram at most.
            let time = async {
                match dc_reference.filter(|_| !summary) {
                    Some(reference) => Command::frmw(reference, DC_SYSTEM_TIME)
                        .ignore_wkc()
                        .receive::<u64>(md)
                        .await
                        .ok(),
                    None => None,
                }
            };
            // Queued in one poll, the LRW and the FRMW (or the BRD) go as one frame (the
            // runner's exchange joins them, see `coalesce`).
            runner.run_both_until(futures_lite::future::zip(cyclic, time), access_fut, deadline_ns)
        });
        self.dc_measured = false;
        let answer = match answer {
            Some((cyclic, time)) => {
                if let Some(time) = time {
                    self.dc.system_time_ns = time;
                    self.dc.cycle_offset_ns = time % self.sync0_ns.max(1);
                    self.dc_measured = true;
                }
                cyclic.ok()
            }
            // No reply by the deadline.
            None => None,
        };
        let reply = match answer {
            Some((working_counter, read)) => {
                let states = match read {
                    Read::Nothing => States::NotRead,
                    Read::Summary(all_in_op) => States::Summary { all_in_op },
                    Read::Each => States::Each(&self.states),
                };
                self.health.record(Exchange::Answered {
                    working_counter,
                    states,
                });
                // ethercrab's `tx_rx` left every slave's inputs in its own image: those
                // of the slaves that exchanged are taken (the others' are whatever
                // ethercrab last had).
                if read == Read::Each {
                    let (image, md, health) = (&mut self.image, &self.md, &self.health);
                    with_group!(&self.group, g => image.take_inputs(g, md, |i| health.inputs_fresh(i)));
                }
                Reply::Answered
            }
            // No reply by the deadline, or the frame could not be sent.
            None => {
                self.health.record(Exchange::Lost);
                Reply::Lost
            }
        };
        self.note_faults();
        let (accessed, mailbox_answer) = match accessed {
            Some(Accessed::Register(a)) => (Some(a), None),
            Some(Accessed::Mailbox(m)) => (None, Some(m)),
            None => (None, None),
        };
        self.step_sdo(mailbox.is_some(), mailbox_answer);
        if let Some(k) = asking {
            // Not taken (lost frame, no answer): the same slave again next cycle.
            if accessed == Some(Answer::Written) {
                let slaves = with_group!(&self.group, g => g.len());
                self.op_request = if k + 1 >= slaves {
                    OpRequest::Done
                } else {
                    OpRequest::Asking(k + 1)
                };
            }
        } else if let Some((_, recovery)) = self.recovery.as_mut() {
            recovery.on_answer(accessed.unwrap_or(Answer::None), now_ns());
            if let Some(outcome) = recovery.outcome() {
                self.recovered = Some(outcome);
                self.recovery = None;
            }
        }
        reply
    }

    fn fault(&self, drive: usize) -> Option<&Unreachable> {
        self.faults.get(drive)?.as_ref().map(|(_, reason)| reason)
    }

    fn inputs_fresh(&self, drive: usize) -> bool {
        self.health.inputs_fresh(drive)
    }

    fn any_fault(&self) -> bool {
        self.health.any_fault()
    }

    fn clear_faults(&mut self) {
        self.health.clear();
        self.note_faults();
    }

    fn counters(&self) -> BusCounters {
        BusCounters {
            lost: self.health.lost_total,
            incomplete: self.health.wkc_total,
        }
    }

    fn start_operation(&mut self) {
        if self.op_request == OpRequest::Waiting {
            self.op_request = OpRequest::Asking(0);
        }
    }

    /// Brings the slave at `drive` back to OP (`ethercat::recovery`: its error
    /// acknowledged, then OP requested, one register access per exchange).
    fn start_restore(&mut self, drive: usize, now_ns: u64, timeout_ns: u64) -> bool {
        if self.recovery.is_some() {
            return false;
        }
        let address = with_group!(&self.group, g => g
            .subdevice(&self.md, drive)
            .map(|sd| sd.configured_address()));
        match address {
            Ok(address) => {
                self.recovery = Some((drive, Recovery::new(address, now_ns, timeout_ns)))
            }
            // No such slave: it cannot come back.
            Err(_) => {
                self.recovered = Some(Err(RecoveryError::NoAnswer {
                    address: 0,
                    waited_ms: 0,
                }))
            }
        }
        true
    }

    fn take_restored(&mut self) -> Option<Result<Restored, CommandError>> {
        let outcome = self.recovered.take()?;
        Some(match outcome {
            Ok(Recovered::WasInOp) => Ok(Restored::WasOperational),
            Ok(Recovered::BackInOp) => Ok(Restored::BackInOperation),
            Err(e) => Err(e.command_error()),
        })
    }

    fn restore_timeout_ns(&self) -> u64 {
        recovery::RECOVERY_TIMEOUT_NS
    }

    fn dc_offset_ns(&self) -> Option<u64> {
        self.dc.active.then_some(self.dc.cycle_offset_ns)
    }

    /// A CoE SDO transfer through the slave's mailbox (`ethercat::coe_sdo`: one mailbox
    /// register access per exchange, when no reset uses the exchange's access).
    fn start_sdo(
        &mut self,
        transfer: &SdoTransfer,
        buffer: SdoBuffer,
        now_ns: u64,
    ) -> Result<(), SdoEnded> {
        if self.sdo.is_some() || self.sdo_done.is_some() {
            return Err(SdoEnded::refused(SdoError::Busy, buffer));
        }
        let drive = transfer.drive;
        let address = with_group!(&self.group, g => g
            .subdevice(&self.md, drive)
            .map(|sd| sd.configured_address()));
        let Ok(address) = address else {
            return Err(SdoEnded::refused(SdoError::NoDrive { drive }, buffer));
        };
        let Some(mailbox) = self.mailboxes.get(drive).copied().flatten() else {
            return Err(SdoEnded::refused(SdoError::NoChannel { drive }, buffer));
        };
        let last = self.mailbox_counters.get(drive).copied().flatten();
        let late = self.mailbox_unanswered.get(drive).copied().unwrap_or(false);
        let sdo = CoeSdo::new(mailbox, *transfer, last, now_ns).after_unanswered(late);
        self.sdo = Some((drive, address, sdo, buffer));
        Ok(())
    }

    fn take_sdo(&mut self) -> Option<SdoEnded> {
        self.sdo_done.take()
    }

    fn dc_measured(&self) -> bool {
        self.dc_measured
    }
}
