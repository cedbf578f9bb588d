//! The cycle: take the application's requests, read the drives, run the kernel, write the
//! drives, exchange with the bus, record the figures, publish the status. Runs in the
//! cycle thread; nothing here allocates, locks or panics once the engine is built.

use std::sync::atomic::{AtomicBool, Ordering};

use gantry_kernel::axis::command::{Command, CommandError, PowerCommand};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::state::AxisState;

use super::bus::{CycleBus, Reply, Restored};
use super::cam::{CamDone, CamInfo, CamJob, CAM_QUEUE};
use super::clock::{now_ns, Clock, CycleClock, Wake};
use super::cycle::{Cycle, COMMUNICATION_FAULT};
use super::phase::PhaseLock;
use super::procedure::{self, DriveProcedure, Running};
use super::protocol::{
    DriveStatus, ProcedureStatus, Request, SdoDone, SdoJob, Snapshot, TraceSample, Tracked,
    TRACE_AXES, TRACKED_COMMANDS,
};
use super::sdo::{SdoBuffer, SdoDirection, SdoEnded, SdoError};
use super::stats::{CycleCounters, CycleFigures, CycleSample, CycleStats};
use gantry_drives::cia402::objects;
use gantry_drives::cia402::procedure::{ModeSwitch, ProcedureInputs};
use gantry_drives::cia402::ModeOfOperation;
use gantry_kernel::kernel::{CamSlotError, CAM_SLOTS};

/// Requests taken per cycle at most (bounded work; the rest wait for the next cycle).
const REQUESTS_PER_CYCLE: usize = 32;
/// SDO transfers waiting for the bus at most, and outcomes waiting for the application
/// (one transfer runs at a time; a commissioning engineer types them one by one).
pub const SDO_QUEUE: usize = 8;
/// Cycles between snapshots.
const PUBLISH_EVERY: u64 = 10;
/// Cycles a shutdown waits for the axes to stop and the drives to switch off.
const SHUTDOWN_CYCLES: u32 = 5000;

/// Error code given to the axes when the cycle overran too often in a row (CiA 301 0x6100
/// "internal software").
pub const OVERRUN_FAULT: u16 = 0x6100;

/// What the cycle does when the bus' reply is not in by the next cycle's start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LateReply {
    /// It is lost: the next cycle starts on time without it. Right for a real-time cycle,
    /// where the bus answers in microseconds and a reply that late is not coming. A cycle
    /// that itself started late still gives its frame half a period: that is an overrun
    /// (the host was late), not a frame the bus lost.
    Lost,
    /// Wait for it, up to `ns` after sending, and let the cycle overrun. Right without
    /// real time (`--no-rt`, tests on a busy machine): then it is the host that is late,
    /// not the bus, and a late reply is not a bus fault.
    Wait {
        /// Longest wait for a reply (and for a reset's register access beside it).
        ns: u64,
    },
}

impl LateReply {
    /// Waiting 30 ms, ethercrab's default PDU timeout (gantry gives ethercrab no timers
    /// of its own: this deadline is the only one).
    pub const WAIT: Self = Self::Wait { ns: 30_000_000 };

    /// Until when the cycle that woke at `wake` waits for an answer to what it sends now.
    fn reply_by(self, wake: &Wake, now_ns: u64) -> u64 {
        match self {
            Self::Lost => wake.reply_by_ns.max(now_ns + wake.period_ns / 2),
            Self::Wait { ns } => now_ns + ns,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    id: u64,
    handle: Option<HandleId>,
    status: CommandStatus,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Running,
    /// Quick-stopping and disabling; counts cycles left.
    ShuttingDown(u32),
    Ended,
}

/// The application's side of the channels, handed to [`super::controller::Controller`].
pub struct AppEnds {
    /// Requests to the cycle.
    pub requests: rtrb::Producer<Request>,
    /// Snapshots from the cycle.
    pub snapshot: triple_buffer::Output<Snapshot>,
    /// Trace samples from the cycle.
    pub trace: rtrb::Consumer<TraceSample>,
    /// Each cycle's durations, for the figures the application computes
    /// (`stats::FigureBook`).
    pub samples: rtrb::Consumer<CycleSample>,
    /// SDO transfers to the cycle.
    pub sdo_jobs: rtrb::Producer<SdoJob>,
    /// How they ended.
    pub sdo_done: rtrb::Consumer<SdoDone>,
    /// Cam tables to the cycle.
    pub cam_jobs: rtrb::Producer<CamJob>,
    /// How they ended, with the tables to drop.
    pub cam_done: rtrb::Consumer<CamDone>,
    /// The cam tables the cycle starts with (the configuration's).
    pub cams: Vec<CamInfo>,
}

/// The channels between the cycle thread and the application, made before the bus goes
/// to Op: the trace ring alone is tens of MB, every page populated at once under
/// `mlockall(MCL_FUTURE)` (~12 ms measured for 2¹⁶ samples). Made after Op, that time is a
/// gap in the process data, and drives synchronised to SYNC0 count missed setpoints
/// (0x1C32:0B) and leave Op at their limit (0x10F1:02; ETG.1020 sync error, AL status code
/// 0x001A) before the first cycle runs.
pub struct Channels {
    requests: (rtrb::Producer<Request>, rtrb::Consumer<Request>),
    snapshot: (
        triple_buffer::Input<Snapshot>,
        triple_buffer::Output<Snapshot>,
    ),
    trace: (rtrb::Producer<TraceSample>, rtrb::Consumer<TraceSample>),
    stats: (CycleStats, rtrb::Consumer<CycleSample>),
    sdo_jobs: (rtrb::Producer<SdoJob>, rtrb::Consumer<SdoJob>),
    sdo_done: (rtrb::Producer<SdoDone>, rtrb::Consumer<SdoDone>),
    cam_jobs: (rtrb::Producer<CamJob>, rtrb::Consumer<CamJob>),
    cam_done: (rtrb::Producer<CamDone>, rtrb::Consumer<CamDone>),
}

impl Channels {
    /// Channels for `axes` axes and a trace ring of `trace_capacity` samples (allocates).
    pub fn new(axes: usize, trace_capacity: usize) -> Self {
        Self {
            requests: rtrb::RingBuffer::new(1024),
            snapshot: triple_buffer::triple_buffer(&Snapshot::sized(axes)),
            trace: rtrb::RingBuffer::new(trace_capacity.max(1)),
            stats: CycleStats::new(),
            sdo_jobs: rtrb::RingBuffer::new(SDO_QUEUE),
            sdo_done: rtrb::RingBuffer::new(SDO_QUEUE),
            cam_jobs: rtrb::RingBuffer::new(CAM_QUEUE),
            cam_done: rtrb::RingBuffer::new(CAM_QUEUE),
        }
    }
}

/// Everything the cycle thread owns.
pub struct Engine<B: CycleBus> {
    /// The bus.
    pub bus: B,
    /// Kernel and CiA-402 channels.
    pub cycle: Cycle,
    requests: rtrb::Consumer<Request>,
    snapshot: triple_buffer::Input<Snapshot>,
    trace: rtrb::Producer<TraceSample>,
    stats: CycleStats,
    tracked: Vec<Entry>,
    next_slot: usize,
    newest_id: u64,
    overrun_limit: u32,
    overrun_stop: bool,
    late_reply: LateReply,
    phase_lock: Option<PhaseLock>,
    /// The last exchange was answered (its DC offset is this cycle's).
    answered: bool,
    phase: Phase,
    cycles: u64,
    /// Per axis: the id of a reset waiting for its drive to come back to operation.
    resets: Vec<Option<u64>>,
    /// Per axis: the id of a reset waiting for the kernel to see its drive as it is (see
    /// [`Engine::reset`]).
    unseen_resets: Vec<Option<u64>>,
    /// Per axis: the last cycle in which the kernel was given a fault of gantry's own
    /// instead of what its drive said: a bus fault on its drive in force when the inputs
    /// were read (the communication fault), or the overrun stop (0x6100).
    forced_faults_at: Vec<Option<u64>>,
    /// The axis whose drive the bus is bringing back now.
    recovering: Option<usize>,
    /// The cycle that restore started in.
    recovering_since: u64,
    /// The last restore the bus finished.
    last_restore: Option<RestoreRecord>,
    /// Where the search for the next waiting reset starts (round robin).
    next_reset: usize,
    /// How long a drive may take to come back before its reset fails.
    recovery_timeout_ns: u64,
    /// Answered cycles in a row whose frame the phase lock held, at start; `None` once
    /// the slaves were asked for OP.
    held_before_op: Option<u32>,
    sdo_jobs: rtrb::Consumer<SdoJob>,
    sdo_done: rtrb::Producer<SdoDone>,
    /// Who the SDO transfer the bus is carrying is for.
    sdo_active: Option<SdoOwner>,
    /// An outcome the application's queue had no room for, with its buffer: kept (never
    /// freed here) and handed on first; no other transfer starts meanwhile.
    sdo_unsent: Option<SdoDone>,
    /// The buffer the procedures' transfers use (allocated with the engine); out while
    /// one runs.
    procedure_buffer: Option<SdoBuffer>,
    /// Procedures running on the axes' drives (see [`super::procedure`]).
    procedures: Vec<Option<Running>>,
    cam_jobs: rtrb::Consumer<CamJob>,
    cam_done: rtrb::Producer<CamDone>,
    /// A cam outcome the application's queue had no room for, with its table: kept (never
    /// dropped here) and handed on first; no other cam job is taken meanwhile.
    cam_unsent: Option<CamDone>,
}

/// Who an SDO transfer is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SdoOwner {
    /// The application's job with this id, going this way.
    App(u64, SdoDirection),
    /// The procedure on this axis' drive.
    Procedure(usize),
}

/// A restore the bus finished for a reset ([`Engine::last_restore`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestoreRecord {
    /// The axis whose reset asked for it.
    pub axis: usize,
    /// What the bus did, or why it failed.
    pub outcome: Result<Restored, CommandError>,
    /// Cycles it took, one register access each: 1 when it ended in the cycle it started.
    pub cycles: u64,
}

/// Cycles in a row the phase lock must hold before the slaves are asked for OP: a DC
/// drive in OP counts every SYNC0 period without exactly one setpoint (ETG.1020), so the
/// frames must be settled between its edges before it gets there.
pub const HELD_BEFORE_OP: u32 = 20;

impl<B: CycleBus> Engine<B> {
    /// An engine and the application's ends of its channels (allocates, once).
    pub fn new(bus: B, cycle: Cycle, overrun_limit: u32, trace_capacity: usize) -> (Self, AppEnds) {
        let channels = Channels::new(cycle.len(), trace_capacity);
        Self::with_channels(bus, cycle, overrun_limit, channels)
    }

    /// An engine on channels made beforehand ([`Channels::new`], before the bus goes to
    /// Op); allocates only its small tables.
    pub fn with_channels(
        bus: B,
        cycle: Cycle,
        overrun_limit: u32,
        channels: Channels,
    ) -> (Self, AppEnds) {
        let Channels {
            requests: (req_tx, req_rx),
            snapshot: (mut snap_in, mut snap_out),
            trace: (trace_tx, trace_rx),
            stats: (stats, samples),
            sdo_jobs: (sdo_tx, sdo_rx),
            sdo_done: (done_tx, done_rx),
            cam_jobs: (cam_tx, cam_rx),
            cam_done: (cam_done_tx, cam_done_rx),
        } = channels;
        let axes = cycle.len();
        // Channels made for another number of axes: a snapshot that fits.
        if snap_in.input_buffer_mut().axes.len() != axes {
            (snap_in, snap_out) = triple_buffer::triple_buffer(&Snapshot::sized(axes));
        }
        let recovery_timeout_ns = bus.restore_timeout_ns();
        let cams = cycle
            .cam_names()
            .iter()
            .filter_map(|(slot, name)| {
                let table = cycle.kernel.cam_table(*slot)?;
                Some(CamInfo::of(name, *slot, table))
            })
            .collect();
        let engine = Self {
            bus,
            cycle,
            requests: req_rx,
            snapshot: snap_in,
            trace: trace_tx,
            stats,
            tracked: vec![
                Entry {
                    id: 0,
                    handle: None,
                    status: CommandStatus::Expired,
                };
                TRACKED_COMMANDS
            ],
            next_slot: 0,
            newest_id: 0,
            overrun_limit: overrun_limit.max(1),
            overrun_stop: false,
            late_reply: LateReply::Lost,
            phase_lock: None,
            answered: false,
            phase: Phase::Running,
            cycles: 0,
            resets: vec![None; axes],
            unseen_resets: vec![None; axes],
            forced_faults_at: vec![None; axes],
            recovering: None,
            recovering_since: 0,
            last_restore: None,
            next_reset: 0,
            recovery_timeout_ns,
            held_before_op: Some(0),
            sdo_jobs: sdo_rx,
            sdo_done: done_tx,
            sdo_active: None,
            sdo_unsent: None,
            procedure_buffer: Some(SdoBuffer::with_capacity(procedure::SDO_BYTES)),
            procedures: vec![None; axes],
            cam_jobs: cam_rx,
            cam_done: cam_done_tx,
            cam_unsent: None,
        };
        let app = AppEnds {
            requests: req_tx,
            snapshot: snap_out,
            trace: trace_rx,
            samples,
            sdo_jobs: sdo_tx,
            sdo_done: done_rx,
            cam_jobs: cam_tx,
            cam_done: cam_done_rx,
            cams,
        };
        (engine, app)
    }

    /// How long a reset waits for its drive to return to operation before it fails
    /// (default: the bus', [`CycleBus::restore_timeout_ns`]).
    pub fn set_recovery_timeout(&mut self, timeout_ns: u64) {
        self.recovery_timeout_ns = timeout_ns;
    }

    /// Sets what happens to a reply that is late (default [`LateReply::Lost`]).
    pub fn set_late_reply(&mut self, late_reply: LateReply) {
        self.late_reply = late_reply;
    }

    /// Holds the cycle in phase with SYNC0 (`None`: free-running). [`Engine::run`] turns
    /// it on by itself when the bus has distributed clocks.
    pub fn set_phase_lock(&mut self, lock: Option<PhaseLock>) {
        self.phase_lock = lock;
    }

    /// How far to move the cycle's next deadlines after this cycle (ns; see
    /// [`PhaseLock`]): 0 without a phase lock, without DC, when the frame was lost or did not
    /// read the reference clock's time (the cycle that reads the AL-status summary).
    pub fn phase_correction_ns(&self) -> i64 {
        match (self.phase_lock, self.bus.dc_offset_ns()) {
            (Some(lock), Some(offset)) if self.answered && self.bus.dc_measured() => {
                lock.correction_ns(offset)
            }
            _ => 0,
        }
    }

    /// Runs cycles every `period_ns` until shut down (a [`Request::Shutdown`], or `stop`
    /// set from outside, e.g. by a signal handler), in phase with SYNC0 when the bus has
    /// distributed clocks. Returns the engine for the bus' shutdown.
    pub fn run(self, period_ns: u64, stop: &AtomicBool) -> Self {
        self.run_on(&mut CycleClock::start(period_ns), stop)
    }

    /// [`Engine::run`] on `clock`.
    pub fn run_on(mut self, clock: &mut impl Clock, stop: &AtomicBool) -> Self {
        loop {
            if stop.load(Ordering::Relaxed) && self.phase == Phase::Running {
                self.begin_shutdown();
            }
            if !self.cycle(clock) {
                return self;
            }
        }
    }

    /// One cycle on `clock`: waits for its start, runs it, holds the clock in phase with
    /// SYNC0 (with distributed clocks; the lock starts with the first cycle). False once
    /// the engine has ended.
    pub fn cycle(&mut self, clock: &mut impl Clock) -> bool {
        let wake = clock.wait();
        if self.phase_lock.is_none() && self.bus.dc_offset_ns().is_some() {
            self.phase_lock = Some(PhaseLock::new(wake.period_ns));
        }
        let running = self.step(wake);
        clock.shift(self.phase_correction_ns());
        running
    }

    /// One cycle; false once the engine has ended.
    pub fn step(&mut self, wake: Wake) -> bool {
        let t0 = now_ns();
        self.take_requests();
        self.take_cam_job();
        self.apply_seen_resets();
        self.mark_forced_faults();
        let _ = self.cycle.read_from(&self.bus);
        if self.overrun_stop {
            for axis in 0..self.cycle.len() {
                let _ = self.cycle.force_fault(axis, OVERRUN_FAULT);
            }
        }
        self.run_procedures();
        self.cycle.step();
        let _ = self.cycle.write_to(&mut self.bus);
        let t1 = now_ns();
        let reply_by = self.late_reply.reply_by(&wake, t1);
        self.start_recovery(t1);
        self.start_sdo(t1);
        self.answered = self.bus.exchange(reply_by) == Reply::Answered;
        self.finish_recovery();
        self.finish_sdo();
        self.start_operation_when_ready();
        let t2 = now_ns();
        let in_a_row = self
            .stats
            .record(wake, t1.saturating_sub(t0), t2.saturating_sub(t1));
        if in_a_row >= self.overrun_limit {
            self.overrun_stop = true;
        }
        self.cycles += 1;
        self.update_tracked();
        self.push_trace();
        self.advance_shutdown();
        if self.cycles % PUBLISH_EVERY == 0 || self.phase == Phase::Ended {
            self.publish();
        }
        self.phase != Phase::Ended
    }

    fn take_requests(&mut self) {
        for _ in 0..REQUESTS_PER_CYCLE {
            let Ok(request) = self.requests.pop() else {
                return;
            };
            match request {
                Request::Axis { id, axis, command } => {
                    let taken = self.cycle.kernel.command(axis, command);
                    let entry = self.entry(id, taken);
                    self.track(entry);
                }
                Request::Reset { id, axis } => {
                    let entry = self.reset(id, axis);
                    self.track(entry);
                }
                Request::Group { id, group, command } => {
                    let taken = self.cycle.kernel.group_command(group, command);
                    let entry = self.entry(id, taken);
                    self.track(entry);
                }
                Request::Shutdown => self.begin_shutdown(),
                Request::Procedure {
                    id,
                    axis,
                    procedure,
                } => {
                    let entry = self.start_procedure(id, axis, procedure);
                    self.track(entry);
                }
            }
        }
    }

    /// A reset. With the bus in fault, the axis' drive first goes back to operation (if it
    /// left; on EtherCAT, its slave to OP): the reset waits (Busy) while the bus does one
    /// step of it per cycle beside the process data, inside the cycle's reply deadline, so
    /// no cycle is stretched ([`CycleBus::start_restore`]); once the drive is back, the
    /// bus faults are forgotten (they come back next cycle if they are
    /// still there). A reset also ends the overrun stop (for every axis).
    ///
    /// Then the axis' Reset follows as soon as the kernel has seen its drive as it is —
    /// one cycle with no fault of gantry's own (no bus fault in force when the inputs
    /// were read, no overrun stop) — so that what the Reset leaves the axis in is decided
    /// by the drive alone, as PLCopen's MC_Reset wants (ErrorStop → Standstill when the
    /// power is on, Disabled when it is off): an axis whose drive stayed in Operation
    /// enabled through the fault is back in Standstill, one whose drive faulted gets the
    /// fault reset and is Disabled (CiA 402 leaves a reset drive in Switch on disabled)
    /// until enabled again — whatever the order and the timing of the resets. Before that
    /// cycle the kernel holds gantry's communication fault (0x8100) or overrun stop
    /// (0x6100), which no drive raised, for the drive's own, and its Reset would take
    /// the power from a powered drive. If the bus fault on its drive is back by then, the
    /// reset fails (the drive still has the communication fault, 0x8100). Otherwise the
    /// axis' Reset at once. A second reset of the same axis while one waits replaces it
    /// (the first is Aborted).
    fn reset(&mut self, id: u64, axis: usize) -> Entry {
        self.overrun_stop = false;
        self.reset_when_seen(id, axis)
    }

    /// [`Engine::reset`] past the overrun stop: waits for the bus, or for the kernel to
    /// see the drive, or resets the axis now.
    fn reset_when_seen(&mut self, id: u64, axis: usize) -> Entry {
        // An axis with nothing on the bus does not wait for the bus.
        let on_bus = self.cycle.drive_of(axis) != usize::MAX;
        let waiting = if on_bus && self.bus.any_fault() {
            self.resets.get_mut(axis)
        } else if !self.kernel_saw_the_drive(axis) {
            self.unseen_resets.get_mut(axis)
        } else {
            None
        };
        if let Some(slot) = waiting {
            if let Some(replaced) = slot.replace(id) {
                self.set_status(replaced, CommandStatus::Aborted);
            }
            return Entry {
                id,
                handle: None,
                status: CommandStatus::Busy,
            };
        }
        self.axis_reset(id, axis)
    }

    /// Notes, before this cycle's inputs are read, which axes the kernel gets a fault of
    /// gantry's own for instead of their drive's inputs — or no new inputs at all (a lost
    /// frame, a wrong working counter not yet explained: it keeps what it had, which may
    /// be such a fault).
    fn mark_forced_faults(&mut self) {
        for axis in 0..self.forced_faults_at.len() {
            let drive = self.cycle.drive_of(axis);
            // An axis with nothing on the bus (simulated, virtual, shadow) has no inputs.
            let on_bus = drive != usize::MAX;
            let forced = self.overrun_stop
                || (on_bus && (self.bus.fault(drive).is_some() || !self.bus.inputs_fresh(drive)));
            if let (true, Some(at)) = (forced, self.forced_faults_at.get_mut(axis)) {
                *at = Some(self.cycles);
            }
        }
    }

    /// The kernel stepped at least once on `axis`' drive's own inputs since it was last
    /// given a fault of gantry's own for it.
    fn kernel_saw_the_drive(&self, axis: usize) -> bool {
        // Inputs read in cycle `c` reach the kernel's state in cycle `c`'s step; a command
        // applied at the start of cycle `c + 2` is judged on cycle `c + 1`'s, clean ones.
        self.forced_faults_at
            .get(axis)
            .copied()
            .flatten()
            .is_none_or(|c| self.cycles >= c.saturating_add(2))
    }

    /// Resets that waited for the kernel to see their drive: applied once it has. One
    /// whose drive's bus fault came back meanwhile fails (the axis stays in ErrorStop with
    /// the communication fault; `gantry status` says why) rather than wait again: a bus
    /// that keeps failing would bring the slave back and lose it over and over.
    fn apply_seen_resets(&mut self) {
        for axis in 0..self.unseen_resets.len() {
            let fault_back = self.bus.fault(self.cycle.drive_of(axis)).is_some();
            if !fault_back && !self.kernel_saw_the_drive(axis) {
                continue;
            }
            let Some(id) = self.unseen_resets.get_mut(axis).and_then(Option::take) else {
                continue;
            };
            let entry = if fault_back {
                Entry {
                    id,
                    handle: None,
                    status: CommandStatus::Error(CommandError::DriveResetFailed {
                        code: COMMUNICATION_FAULT,
                    }),
                }
            } else {
                self.axis_reset(id, axis)
            };
            if let Some(slot) = self.tracked.iter_mut().find(|e| e.id == id) {
                *slot = entry;
            }
        }
    }

    /// The kernel's Reset of `axis`, for request `id`.
    fn axis_reset(&mut self, id: u64, axis: usize) -> Entry {
        let taken = self.cycle.kernel.command(axis, Command::Reset);
        self.entry(id, taken)
    }

    /// At start: asks the bus to take the drives to operation (EtherCAT: the slaves to OP)
    /// once the cycle is ready for them —
    /// at once when it is not locked to SYNC0 (no DC, or no phase lock: free run is the
    /// user's choice), else after [`HELD_BEFORE_OP`] answered frames in a row held in phase.
    fn start_operation_when_ready(&mut self) {
        let Some(held) = self.held_before_op else {
            return;
        };
        let held = match (self.phase_lock, self.bus.dc_offset_ns()) {
            (Some(_), Some(_)) if self.answered && !self.bus.dc_measured() => held,
            (Some(lock), Some(offset)) if self.answered && lock.holds(offset) => held + 1,
            (Some(_), Some(_)) => 0,
            _ => HELD_BEFORE_OP,
        };
        self.held_before_op = if held >= HELD_BEFORE_OP {
            self.bus.start_operation();
            None
        } else {
            Some(held)
        };
    }

    /// Hands the next waiting reset's drive to the bus, if the bus is free.
    fn start_recovery(&mut self, now_ns: u64) {
        if self.recovering.is_some() {
            return;
        }
        let n = self.resets.len();
        for k in 0..n {
            let axis = (self.next_reset + k) % n;
            if self.resets.get(axis).is_some_and(Option::is_some)
                && self.bus.start_restore(
                    self.cycle.drive_of(axis),
                    now_ns,
                    self.recovery_timeout_ns,
                )
            {
                self.recovering = Some(axis);
                self.recovering_since = self.cycles;
                self.next_reset = (axis + 1) % n;
                return;
            }
        }
    }

    /// Takes a finished recovery: the reset goes on to the axis, or fails with the reason.
    fn finish_recovery(&mut self) {
        let Some(outcome) = self.bus.take_restored() else {
            return;
        };
        let Some(axis) = self.recovering.take() else {
            return;
        };
        self.last_restore = Some(RestoreRecord {
            axis,
            outcome,
            cycles: self.cycles - self.recovering_since + 1,
        });
        let Some(id) = self.resets.get_mut(axis).and_then(Option::take) else {
            return;
        };
        let entry = match outcome {
            Ok(_) => {
                self.bus.clear_faults();
                // The kernel still holds this cycle's communication fault: the Reset
                // waits until it has seen the drive (see `reset`).
                self.reset_when_seen(id, axis)
            }
            Err(e) => Entry {
                id,
                handle: None,
                status: CommandStatus::Error(e),
            },
        };
        if let Some(slot) = self.tracked.iter_mut().find(|e| e.id == id) {
            *slot = entry;
        }
    }

    /// Hands the next SDO transfer to the bus when none runs — a procedure's first (it
    /// holds a drive out of CSP while it waits), then the application's; one the bus
    /// refuses at once (no such drive, not supported) ends here. The application's
    /// buffer goes to the bus with its transfer and back to the application with the
    /// outcome: never dropped here.
    fn start_sdo(&mut self, now_ns: u64) {
        if let Some(done) = self.sdo_unsent.take() {
            self.hand_back(done);
        }
        if self.sdo_active.is_some() {
            return;
        }
        for axis in 0..self.procedures.len() {
            let drive = self.cycle.drive_of(axis);
            let Some(r) = self.procedures.get_mut(axis).and_then(Option::as_mut) else {
                continue;
            };
            let Some(access) = r.wanted.take() else {
                continue;
            };
            let Some(mut buffer) = self.procedure_buffer.take() else {
                // Out with a transfer (none runs, so it cannot be): asked again.
                r.wanted = Some(access);
                return;
            };
            let transfer = procedure::transfer(drive, &access, &mut buffer);
            match self.bus.start_sdo(&transfer, buffer, now_ns) {
                Ok(()) => {
                    r.active = Some(access);
                    self.sdo_active = Some(SdoOwner::Procedure(axis));
                    return;
                }
                Err(refused) => {
                    self.procedure_buffer = Some(refused.buffer);
                    match refused.result {
                        // Asked again next cycle.
                        Err(SdoError::Busy) => r.wanted = Some(access),
                        Err(e) => r.outcome = Some(procedure::failure(&e)),
                        Ok(()) => r.wanted = Some(access),
                    }
                }
            }
        }
        if self.sdo_unsent.is_some() {
            return;
        }
        let Ok(job) = self.sdo_jobs.pop() else {
            return;
        };
        match self.bus.start_sdo(&job.transfer, job.buffer, now_ns) {
            Ok(()) => self.sdo_active = Some(SdoOwner::App(job.id, job.transfer.direction)),
            Err(ended) => self.hand_back(SdoDone { id: job.id, ended }),
        }
    }

    /// Takes the application's next cam job, if its last outcome is handed on: the table
    /// goes into its slot and what the slot held goes back; refused (an axis cams on the
    /// slot), the job's own table goes back. Checked here before the kernel is asked, so
    /// that the kernel, which drops the table it refuses, never refuses one.
    fn take_cam_job(&mut self) {
        if let Some(done) = self.cam_unsent.take() {
            self.hand_back_cam(done);
            if self.cam_unsent.is_some() {
                return;
            }
        }
        let Ok(CamJob { id, slot, table }) = self.cam_jobs.pop() else {
            return;
        };
        let user = self
            .cycle
            .kernel
            .axes()
            .iter()
            .position(|a| a.cam_table_in_use() == Some(slot));
        let done = match user {
            _ if slot >= CAM_SLOTS => CamDone {
                id,
                result: Err(CamSlotError::NoSuchSlot { slot }),
                table,
            },
            Some(axis) => CamDone {
                id,
                result: Err(CamSlotError::InUse { slot, axis }),
                table,
            },
            None => match self.cycle.kernel.set_cam_table(slot, table) {
                Ok(old) => CamDone {
                    id,
                    result: Ok(()),
                    table: old,
                },
                // Not reached: both refusals are checked above.
                Err(e) => CamDone {
                    id,
                    result: Err(e),
                    table: None,
                },
            },
        };
        self.hand_back_cam(done);
    }

    /// Hands a cam outcome and its table to the application, or keeps it for the next
    /// cycle if its queue is full.
    fn hand_back_cam(&mut self, done: CamDone) {
        if let Err(rtrb::PushError::Full(done)) = self.cam_done.push(done) {
            self.cam_unsent = Some(done);
        }
    }

    /// Hands an outcome and its buffer to the application, or keeps it for the next
    /// cycle if its queue is full.
    fn hand_back(&mut self, done: SdoDone) {
        if let Err(rtrb::PushError::Full(done)) = self.sdo_done.push(done) {
            self.sdo_unsent = Some(done);
        }
    }

    /// Hands a finished SDO transfer's outcome to the application or the procedure.
    fn finish_sdo(&mut self) {
        let Some(mut ended) = self.bus.take_sdo() else {
            return;
        };
        match self.sdo_active.take() {
            Some(SdoOwner::App(id, direction)) => {
                if direction == SdoDirection::Download {
                    ended.buffer.clear();
                }
                self.hand_back(SdoDone { id, ended });
            }
            Some(SdoOwner::Procedure(axis)) => {
                let SdoEnded { result, buffer } = ended;
                if let Some(r) = self.procedures.get_mut(axis).and_then(Option::as_mut) {
                    if let Some(access) = r.active.take() {
                        let got = result.map(|()| buffer.as_slice());
                        r.outcome = Some(procedure::outcome(&access, got));
                    }
                }
                self.procedure_buffer = Some(buffer);
            }
            // A transfer started on the bus itself, not through the engine (a test asks
            // the bus directly): its buffer is the caller's affair.
            None => drop(ended),
        }
    }

    /// Starts `procedure` on `axis`' drive for request `id`: the axis is lent to it.
    fn start_procedure(&mut self, id: u64, axis: usize, procedure: DriveProcedure) -> Entry {
        let busy = self.procedures.get(axis).is_some_and(Option::is_some);
        let lent = if busy {
            // Still returning a drive to CSP after the last one.
            Err(CommandError::LentToDrive {
                command: procedure.name(),
                procedure: "the return to CSP",
            })
        } else {
            self.cycle
                .kernel
                .lend_to_drive(axis, procedure.name(), procedure.homes())
        };
        match lent {
            Ok(h) => {
                if let Some(slot) = self.procedures.get_mut(axis) {
                    *slot = Some(Running::new(procedure));
                }
                Entry {
                    id,
                    handle: Some(h),
                    status: self.cycle.kernel.command_status(h),
                }
            }
            Err(e) => Entry {
                id,
                handle: None,
                status: CommandStatus::Error(e),
            },
        }
    }

    /// One cycle of every running procedure, on the inputs just read (before the kernel
    /// steps, so that an ended lending has the kernel take the drive back this cycle).
    fn run_procedures(&mut self) {
        let now_s = self.cycle.kernel.time();
        for axis in 0..self.procedures.len() {
            let Some(mut r) = self.procedures.get(axis).copied().flatten() else {
                continue;
            };
            let inputs = self.cycle.inputs(axis).copied().unwrap_or_default();
            let mode_mapped = self.cycle.channel(axis).is_some_and(|c| {
                c.offsets
                    .map()
                    .output_offset(objects::MODES_OF_OPERATION)
                    .is_some()
            });
            let io = ProcedureInputs {
                statusword: inputs.statusword,
                mode_display: inputs.mode_display,
                mode_mapped,
                position: inputs.position,
                now_s,
                sdo: if r.active.is_some() {
                    None
                } else {
                    r.outcome.take()
                },
            };
            if r.active.is_some() {
                // One access at a time: wait for its outcome (`r` is unchanged).
                continue;
            }
            let keep = if !self.cycle.kernel.is_lent(axis) && r.restore.is_none() && !r.ended {
                // Power off or a fault ended the lending: the drive is the kernel's again
                // at once; where 0x6060 is not in the process data it is set back by SDO.
                let _ = self.cycle.set_procedure_outputs(axis, None);
                r.ended = true;
                r.wanted = None;
                if !mode_mapped {
                    r.restore = Some(ModeSwitch::to(ModeOfOperation::CyclicSyncPosition));
                    !r.restore_step(&io)
                } else {
                    false
                }
            } else if r.ended {
                !r.restore_step(&io)
            } else {
                let cancel = self.cycle.kernel.cancel_requested(axis);
                let step = r.step(&io, cancel);
                let _ = self.cycle.set_procedure_outputs(axis, step.outputs);
                match step.end {
                    Some(result) => {
                        let _ = self.cycle.set_procedure_outputs(axis, None);
                        let outcome = result.map_err(|f| r.procedure.error(f));
                        self.cycle.kernel.end_drive_procedure(axis, outcome);
                        false
                    }
                    None => true,
                }
            };
            if let Some(slot) = self.procedures.get_mut(axis) {
                *slot = keep.then_some(r);
            }
        }
    }

    fn set_status(&mut self, id: u64, status: CommandStatus) {
        if let Some(e) = self.tracked.iter_mut().find(|e| e.id == id) {
            e.status = status;
        }
    }

    fn track(&mut self, entry: Entry) {
        self.newest_id = self.newest_id.max(entry.id);
        if let Some(slot) = self.tracked.get_mut(self.next_slot) {
            *slot = entry;
        }
        self.next_slot = (self.next_slot + 1) % TRACKED_COMMANDS;
    }

    fn update_tracked(&mut self) {
        for e in &mut self.tracked {
            if let (Some(h), false) = (e.handle, e.status.is_final()) {
                e.status = self.cycle.kernel.command_status(h);
            }
        }
    }

    fn push_trace(&mut self) {
        if self.trace.slots() == 0 {
            return;
        }
        let mut s = TraceSample {
            time_s: self.cycle.kernel.time(),
            set: [0.0; TRACE_AXES],
            set_velocity: [0.0; TRACE_AXES],
            actual: [0.0; TRACE_AXES],
        };
        for i in 0..self.cycle.len().min(TRACE_AXES) {
            if let Some(st) = self.cycle.kernel.axis_status(i) {
                s.set[i] = st.set.p;
                s.set_velocity[i] = st.set.v;
                s.actual[i] = st.actual_position;
            }
        }
        let _ = self.trace.push(s);
    }

    fn begin_shutdown(&mut self) {
        if self.phase != Phase::Running {
            return;
        }
        for axis in 0..self.cycle.len() {
            let moving =
                self.cycle.kernel.axis_status(axis).is_some_and(|s| {
                    !matches!(s.state, AxisState::Disabled | AxisState::ErrorStop)
                });
            let command = if moving {
                Command::QuickStop
            } else {
                Command::Power(PowerCommand::DisableForced)
            };
            let _ = self.cycle.kernel.command(axis, command);
        }
        self.phase = Phase::ShuttingDown(SHUTDOWN_CYCLES);
    }

    fn advance_shutdown(&mut self) {
        let Phase::ShuttingDown(left) = self.phase else {
            return;
        };
        let all_off = (0..self.cycle.len()).all(|axis| {
            let axis_off = self
                .cycle
                .kernel
                .axis_status(axis)
                .is_some_and(|s| matches!(s.state, AxisState::Disabled | AxisState::ErrorStop));
            let drive_off = self.cycle.inputs(axis).is_none_or(|i| {
                i.statusword.state() != Some(gantry_drives::cia402::State::OperationEnabled)
            });
            axis_off && drive_off
        });
        self.phase = if all_off || left == 0 {
            Phase::Ended
        } else {
            Phase::ShuttingDown(left - 1)
        };
    }

    /// The entry of request `id` as the kernel took it: its handle, or the error that
    /// refused it.
    fn entry(
        &self,
        id: u64,
        taken: Result<
            gantry_kernel::axis::handle::HandleId,
            gantry_kernel::axis::command::CommandError,
        >,
    ) -> Entry {
        match taken {
            Ok(h) => Entry {
                id,
                handle: Some(h),
                status: self.cycle.kernel.command_status(h),
            },
            Err(e) => Entry {
                id,
                handle: None,
                status: CommandStatus::Error(e),
            },
        }
    }

    fn publish(&mut self) {
        let n = self.cycle.len();
        let snap = self.snapshot.input_buffer_mut();
        snap.cycle = self.cycles;
        snap.time_s = self.cycle.kernel.time();
        for (i, (slot, corners)) in snap
            .groups
            .iter_mut()
            .zip(snap.group_corners.iter_mut())
            .enumerate()
        {
            let group = self.cycle.kernel.groups().get(i);
            *slot = group.map(|g| g.state());
            *corners = group.map(|g| g.corners()).unwrap_or_default();
        }
        for i in 0..n {
            if let (Some(dst), Some(src)) = (snap.axes.get_mut(i), self.cycle.kernel.axis_status(i))
            {
                *dst = *src;
            }
            if let Some(d) = snap.drives.get_mut(i) {
                let inputs = self.cycle.inputs(i).copied().unwrap_or_default();
                let drive = self.cycle.drive_of(i);
                *d =
                    DriveStatus {
                        state: inputs.statusword.state(),
                        statusword: inputs.statusword.0,
                        // A layout without 0x603F: the code the drive reported by EMCY.
                        error_code: inputs
                            .error_code
                            .or(self.bus.drive_error(drive).map(|e| e.code)),
                        bus_fault: self.bus.fault(drive).copied(),
                        can_node: self.bus.can_node(drive),
                        procedure: self.procedures.get(i).copied().flatten().map(|r| {
                            ProcedureStatus {
                                name: r.procedure.name(),
                                method: r.procedure.method(),
                                phase: if r.ended {
                                    "returning to CSP"
                                } else {
                                    r.procedure.phase_name()
                                },
                            }
                        }),
                        mode_display: inputs.mode_display,
                    };
            }
        }
        let counters = self.bus.counters();
        snap.lost_frames = counters.lost;
        snap.working_counter_errors = counters.incomplete;
        // Counters only: the percentiles are the application's work (FigureBook).
        snap.figures = CycleFigures::from_counters(self.stats.counters());
        snap.dc_offset_ns = self.bus.dc_offset_ns();
        snap.dc_target_ns = self.phase_lock.map(|l| l.target_ns());
        for (dst, src) in snap.commands.iter_mut().zip(&self.tracked) {
            *dst = Tracked {
                id: src.id,
                status: src.status,
            };
        }
        snap.newest_id = self.newest_id;
        snap.overrun_stop = self.overrun_stop;
        snap.ended = self.phase == Phase::Ended;
        self.snapshot.publish();
    }

    /// The last restore the bus finished for a reset (what `gantry status` does not show:
    /// whether the drive had stayed operational or was brought back, and how long it took).
    pub fn last_restore(&self) -> Option<RestoreRecord> {
        self.last_restore
    }

    /// The status of request `id` as of the end of the last cycle (the snapshot, which
    /// [`CommandHandle`](crate::runtime::controller::CommandHandle) reads, publishes it only
    /// every few cycles): for a caller that steps the engine itself and needs the cycle a
    /// command ended in. None once its slot was reused or before it was taken.
    pub fn command_status(&self, id: u64) -> Option<CommandStatus> {
        // Free slots hold id 0, which no request has (the controller counts from 1).
        self.tracked
            .iter()
            .find(|e| e.id == id && id != 0)
            .map(|e| e.status)
    }

    /// The bus.
    pub fn bus(&self) -> &B {
        &self.bus
    }

    /// The bus, for its shutdown after the last cycle.
    pub fn into_bus(self) -> B {
        self.bus
    }

    /// The cycle's counters so far (the percentiles come from the samples, see
    /// [`AppEnds::samples`]).
    pub fn counters(&self) -> CycleCounters {
        self.stats.counters()
    }
}
