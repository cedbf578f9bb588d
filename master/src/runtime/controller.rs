//! The application's handle on the cycle: usable from any thread and from async code.
//! Commands go to the cycle thread through the SPSC queue (behind a mutex on *this* side
//! only: the cycle thread never waits for it); their status comes back in the latest
//! snapshot, which [`CommandHandle`] reads. A controller given the axes' saved parameters
//! ([`Controller::saving_to`]) fills in what homing and point-to-point commands leave out
//! from them and saves what the axes accept ([`crate::persist::saver`]), whoever sends
//! the command.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use gantry_kernel::axis::command::Command;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::cam::CamTable;
use gantry_kernel::kernel::{CamSlotError, CAM_SLOTS};
use thiserror::Error;

use super::cam::{CamDone, CamInfo, CamJob};
use super::engine::AppEnds;
use super::protocol::{Request, SdoDone, SdoJob, Snapshot, TraceSample};
use super::sdo::{
    SdoBuffer, SdoData, SdoError, SdoKind, SdoRequest, SdoResult, SDO_LIMIT_BYTES, SDO_MAX_BYTES,
    SDO_MIN_BYTES,
};
use super::stats::{CycleCounters, CycleFigures, FigureBook};
use crate::persist::saver::Saver;
use crate::persist::Saved;

/// Why a request did not reach the cycle.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum ControlError {
    /// No axis of that name.
    #[error("no axis named {0:?}")]
    NoAxis(String),
    /// The queue to the cycle thread is full (it is not keeping up, or has ended).
    #[error("the cycle thread is not taking requests (queue full or ended)")]
    QueueFull,
    /// Waiting for a command timed out.
    #[error("no final status within {0:?}")]
    Timeout(Duration),
    /// The cycle thread has ended: nothing more will be answered.
    #[error("the cycle has ended (the service is shutting down)")]
    Ended,
    /// No cam table of that name.
    #[error("no cam table named {0:?}")]
    NoCam(String),
    /// A cam table needs a name.
    #[error("a cam table needs a name")]
    CamUnnamed,
    /// Every cam slot holds a table: a new name finds none free.
    #[error(
        "no free cam slot for {name:?}: all {CAM_SLOTS} hold tables (remove one, or replace a table by loading it under its name)"
    )]
    CamSlotsFull {
        /// The new table's name.
        name: String,
    },
    /// An axis cams on the table: it cannot be replaced or removed.
    #[error("cam table {name} is in use by axis {axis}; CamOut first")]
    CamInUse {
        /// The table.
        name: String,
        /// The axis camming on it.
        axis: String,
    },
    /// The kernel refused the slot (not reached through [`Controller::load_cam`], which
    /// only names slots that exist).
    #[error("cam table {name}: {source}")]
    CamSlot {
        /// The table.
        name: String,
        /// The kernel's reason.
        source: CamSlotError,
    },
}

/// The application's ends of the SDO channels, the outcomes that arrived for handles
/// other than the one that drained them, and the buffers lent to the cycle thread when
/// they are back.
struct SdoEnds {
    jobs: rtrb::Producer<SdoJob>,
    done: rtrb::Consumer<SdoDone>,
    arrived: Vec<(u64, SdoResult)>,
    /// Buffers back from the cycle thread, for the next transfers.
    free: Vec<SdoBuffer>,
    /// Each buffer's capacity: the largest object a transfer carries.
    max_bytes: usize,
}

impl SdoEnds {
    /// Keeps the outcome of job `id` for its handle.
    fn keep(&mut self, id: u64, result: SdoResult) {
        if self.arrived.len() == SDO_ARRIVED_KEEP {
            // The oldest, of a handle given up.
            drop(self.arrived.remove(0));
        }
        self.arrived.push((id, result));
    }
}

/// The application's ends of the cam channels and what it knows of the kernel's cam
/// slots. Tables handed back by the cycle thread are dropped here.
struct CamEnds {
    jobs: rtrb::Producer<CamJob>,
    done: rtrb::Consumer<CamDone>,
    /// By slot: the table there, as the cycle thread last confirmed it.
    slots: Vec<Option<CamInfo>>,
    /// Jobs sent and not answered: id, slot, what the slot holds once done (`None`: a
    /// removal).
    pending: Vec<(u64, usize, Option<CamInfo>)>,
    /// Outcomes for handles not asking yet: id, the slot or why not.
    arrived: Vec<(u64, Result<usize, ControlError>)>,
}

impl CamEnds {
    /// The slot of table `name`: its own, or the one a load under way gives it.
    fn slot_of(&self, name: &str) -> Option<usize> {
        self.slots
            .iter()
            .flatten()
            .find(|c| c.name == name)
            .map(|c| c.slot)
            .or_else(|| {
                self.pending
                    .iter()
                    .find(|(_, _, c)| c.as_ref().is_some_and(|c| c.name == name))
                    .map(|&(_, slot, _)| slot)
            })
    }

    /// A slot holding no table and no load under way.
    fn free_slot(&self) -> Option<usize> {
        (0..CAM_SLOTS).find(|&s| {
            self.slots.get(s).is_some_and(Option::is_none)
                && !self.pending.iter().any(|&(_, p, _)| p == s)
        })
    }

    /// Takes what the cycle thread handed back: slots updated, outcomes kept for their
    /// handles, tables dropped. `axes` names the axes for a refusal.
    fn drain(&mut self, axes: &[String]) {
        while let Ok(done) = self.done.pop() {
            let CamDone { id, result, table } = done;
            drop(table);
            let Some(at) = self.pending.iter().position(|(i, ..)| *i == id) else {
                continue;
            };
            let (_, slot, info) = self.pending.remove(at);
            let name = self
                .slots
                .get(slot)
                .and_then(Option::as_ref)
                .or(info.as_ref())
                .map(|c| c.name.clone())
                .unwrap_or_default();
            let outcome = match result {
                Ok(()) => {
                    if let Some(s) = self.slots.get_mut(slot) {
                        *s = info;
                    }
                    Ok(slot)
                }
                Err(CamSlotError::InUse { axis, .. }) => Err(ControlError::CamInUse {
                    name,
                    axis: axes
                        .get(axis)
                        .cloned()
                        .unwrap_or_else(|| format!("#{axis}")),
                }),
                Err(source) => Err(ControlError::CamSlot { name, source }),
            };
            if self.arrived.len() == CAM_ARRIVED_KEEP {
                // The oldest, of a handle given up.
                drop(self.arrived.remove(0));
            }
            self.arrived.push((id, outcome));
        }
    }
}

/// Cam outcomes kept for handles not asking yet (the oldest drop out).
const CAM_ARRIVED_KEEP: usize = 32;

/// Outcomes kept for handles not asking yet (the oldest, of handles given up, drop out).
const SDO_ARRIVED_KEEP: usize = 32;

/// Buffers kept for the next transfers (more are made while transfers queue up, and
/// freed here when they come back).
const SDO_BUFFERS_KEPT: usize = 2;

struct Shared {
    requests: Mutex<rtrb::Producer<Request>>,
    snapshot: Mutex<triple_buffer::Output<Snapshot>>,
    trace: Mutex<rtrb::Consumer<TraceSample>>,
    figures: Mutex<FigureBook>,
    sdo: Mutex<SdoEnds>,
    cams: Mutex<CamEnds>,
    next_id: AtomicU64,
    axes: Vec<String>,
}

/// A handle on the running cycle. Cheap to clone.
#[derive(Clone)]
pub struct Controller {
    shared: Arc<Shared>,
    saver: Option<Arc<Saver>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic in another app thread must not take the controller down with it.
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl Controller {
    /// A controller over the application's ends of an engine's channels, whose SDO
    /// transfers carry objects of up to [`SDO_MAX_BYTES`].
    pub fn new(ends: AppEnds, axes: Vec<String>) -> Self {
        Self::with_sdo_max_bytes(ends, axes, SDO_MAX_BYTES)
    }

    /// A controller whose SDO transfers carry objects of up to `sdo_max_bytes` (kept
    /// within [`SDO_MIN_BYTES`]`..=`[`SDO_LIMIT_BYTES`]): the buffer lent to the cycle
    /// thread with a transfer is allocated here, once, at that size.
    pub fn with_sdo_max_bytes(ends: AppEnds, axes: Vec<String>, sdo_max_bytes: usize) -> Self {
        let max_bytes = sdo_max_bytes.clamp(SDO_MIN_BYTES, SDO_LIMIT_BYTES);
        let mut slots = vec![None; CAM_SLOTS];
        for info in ends.cams {
            if let Some(s) = slots.get_mut(info.slot) {
                *s = Some(info);
            }
        }
        Self {
            shared: Arc::new(Shared {
                requests: Mutex::new(ends.requests),
                snapshot: Mutex::new(ends.snapshot),
                trace: Mutex::new(ends.trace),
                figures: Mutex::new(FigureBook::new(ends.samples)),
                sdo: Mutex::new(SdoEnds {
                    jobs: ends.sdo_jobs,
                    done: ends.sdo_done,
                    arrived: Vec::with_capacity(SDO_ARRIVED_KEEP),
                    free: vec![SdoBuffer::with_capacity(max_bytes)],
                    max_bytes,
                }),
                cams: Mutex::new(CamEnds {
                    jobs: ends.cam_jobs,
                    done: ends.cam_done,
                    slots,
                    pending: Vec::new(),
                    arrived: Vec::with_capacity(CAM_ARRIVED_KEEP),
                }),
                next_id: AtomicU64::new(1),
                axes,
            }),
            saver: None,
        }
    }

    /// This controller saving into `saved`: a homing or point-to-point command sent
    /// through it runs with the saved values for what it leaves out, and what the axis
    /// accepts is saved ([`crate::persist::saver`]). Clones made before do not save. A
    /// controller already saving into `saved` is returned as it is.
    pub fn saving_to(mut self, saved: Arc<Saved>) -> std::io::Result<Self> {
        if !self
            .saver
            .as_ref()
            .is_some_and(|s| Arc::ptr_eq(s.saved(), &saved))
        {
            self.saver = Some(Saver::new(saved)?);
        }
        Ok(self)
    }

    /// The saver, when this controller saves.
    pub fn saver(&self) -> Option<&Arc<Saver>> {
        self.saver.as_ref()
    }

    /// Axis names, in order.
    pub fn axes(&self) -> &[String] {
        &self.shared.axes
    }

    /// The index of axis `name`.
    pub fn axis(&self, name: &str) -> Result<usize, ControlError> {
        self.shared
            .axes
            .iter()
            .position(|a| a == name)
            .ok_or_else(|| ControlError::NoAxis(name.into()))
    }

    fn send(&self, make: impl FnOnce(u64) -> Request) -> Result<CommandHandle, ControlError> {
        let id = self.shared.next_id.fetch_add(1, Ordering::Relaxed);
        lock(&self.shared.requests)
            .push(make(id))
            .map_err(|_| ControlError::QueueFull)?;
        Ok(CommandHandle {
            id,
            controller: self.clone(),
        })
    }

    /// Sends `command` to axis `axis` (saving what it is to save, see
    /// [`Controller::saving_to`]).
    pub fn command(&self, axis: usize, command: Command) -> Result<CommandHandle, ControlError> {
        let Some(saver) = &self.saver else {
            return self.send(|id| Request::Axis { id, axis, command });
        };
        let (command, save) = saver.prepare(axis, command);
        let h = self.send(|id| Request::Axis { id, axis, command })?;
        if let Some(save) = save {
            let name = self.shared.axes.get(axis).cloned().unwrap_or_default();
            saver.submit(h.clone(), axis, name, save);
        }
        Ok(h)
    }

    /// Runs `procedure` on axis `axis`' drive, out of CSP ([`super::procedure`]): the
    /// handle is Active while it runs, Done when the drive is back in CSP (drive homing:
    /// the axis is homed), Error naming what failed, Aborted by power off.
    pub fn drive_procedure(
        &self,
        axis: usize,
        procedure: super::procedure::DriveProcedure,
    ) -> Result<CommandHandle, ControlError> {
        self.send(|id| Request::Procedure {
            id,
            axis,
            procedure,
        })
    }

    /// Sends `command` to axis group `group` (`[[group]]` order); the handle follows it
    /// as an axis command's does.
    pub fn group_command(
        &self,
        group: usize,
        command: gantry_kernel::group::run::GroupCmd,
    ) -> Result<CommandHandle, ControlError> {
        self.send(|id| Request::Group { id, group, command })
    }

    /// Resets axis `axis` (its slave back to OP if needed, then the axis' Reset).
    pub fn reset(&self, axis: usize) -> Result<CommandHandle, ControlError> {
        self.send(|id| Request::Reset { id, axis })
    }

    /// Asks the cycle to quick-stop, disable and end.
    pub fn shutdown(&self) -> Result<(), ControlError> {
        lock(&self.shared.requests)
            .push(Request::Shutdown)
            .map_err(|_| ControlError::QueueFull)
    }

    /// The latest snapshot, its figures' percentiles computed here from every cycle's
    /// durations (at most every 100 ms; see [`FigureBook`]).
    pub fn snapshot(&self) -> Snapshot {
        let mut snap = lock(&self.shared.snapshot).read().clone();
        snap.figures = lock(&self.shared.figures).figures(counters(&snap.figures), false);
        snap
    }

    /// The cycle figures now, every duration the cycle recorded so far included (e.g.
    /// after it ended).
    pub fn figures(&self) -> CycleFigures {
        let published = lock(&self.shared.snapshot).read().figures;
        lock(&self.shared.figures).figures(counters(&published), true)
    }

    /// Trace samples since the last call.
    pub fn drain_trace(&self, into: &mut Vec<TraceSample>) {
        let mut t = lock(&self.shared.trace);
        while let Ok(s) = t.pop() {
            into.push(s);
        }
    }

    /// Starts an SDO transfer on the bus, beside the process data
    /// ([`crate::runtime::bus::CycleBus::start_sdo`]); its outcome follows on the handle.
    /// Data to write larger than [`Controller::sdo_max_bytes`] ends at once with
    /// [`SdoError::TooLarge`]; an upload larger than that is aborted at the drive.
    pub fn sdo(&self, request: SdoRequest) -> Result<SdoHandle, ControlError> {
        let id = self.shared.next_id.fetch_add(1, Ordering::Relaxed);
        let handle = SdoHandle {
            id,
            controller: self.clone(),
        };
        let transfer = request.transfer();
        let mut ends = lock(&self.shared.sdo);
        let max = ends.max_bytes;
        let mut buffer = ends
            .free
            .pop()
            .unwrap_or_else(|| SdoBuffer::with_capacity(max));
        let fits = match &request.kind {
            SdoKind::Upload => {
                buffer.clear();
                true
            }
            SdoKind::Download(data) => buffer.fill(data.as_slice()),
        };
        if !fits {
            ends.free.push(buffer);
            let size = match &request.kind {
                SdoKind::Download(data) => u32::try_from(data.len()).unwrap_or(u32::MAX),
                SdoKind::Upload => 0,
            };
            let refused = Err(SdoError::too_large(&transfer, Some(size), max));
            ends.keep(id, refused);
            return Ok(handle);
        }
        let job = SdoJob {
            id,
            transfer,
            buffer,
        };
        match ends.jobs.push(job) {
            Ok(()) => Ok(handle),
            Err(rtrb::PushError::Full(job)) => {
                ends.free.push(job.buffer);
                Err(ControlError::QueueFull)
            }
        }
    }

    /// The largest object an SDO transfer carries (bytes).
    pub fn sdo_max_bytes(&self) -> usize {
        lock(&self.shared.sdo).max_bytes
    }

    /// The outcome of SDO job `id`, once the cycle thread has handed it back.
    fn sdo_outcome(&self, id: u64) -> Option<SdoResult> {
        let mut ends = lock(&self.shared.sdo);
        while let Ok(done) = ends.done.pop() {
            let buffer = done.ended.buffer;
            let result = done.ended.result.map(|()| SdoData::new(buffer.as_slice()));
            if ends.free.len() < SDO_BUFFERS_KEPT {
                ends.free.push(buffer);
            }
            ends.keep(done.id, result);
        }
        let at = ends.arrived.iter().position(|(i, _)| *i == id)?;
        Some(ends.arrived.remove(at).1)
    }

    /// The slot of cam table `name` (what `CamIn` names), once it is loaded.
    pub fn cam_slot(&self, name: &str) -> Option<usize> {
        let mut cams = lock(&self.shared.cams);
        cams.drain(&self.shared.axes);
        cams.slots
            .iter()
            .flatten()
            .find(|c| c.name == name)
            .map(|c| c.slot)
    }

    /// The cam tables loaded, by slot.
    pub fn cam_tables(&self) -> Vec<CamInfo> {
        let mut cams = lock(&self.shared.cams);
        cams.drain(&self.shared.axes);
        cams.slots.iter().flatten().cloned().collect()
    }

    /// Loads `table` as cam table `name`: a new name takes a free slot, a known one has its
    /// table replaced. The table goes to the cycle thread, which puts it into the slot
    /// between two cycles; the handle says when, or why not (an axis cams on the table:
    /// [`ControlError::CamInUse`]).
    pub fn load_cam(&self, name: &str, table: CamTable) -> Result<CamHandle, ControlError> {
        if name.trim().is_empty() {
            return Err(ControlError::CamUnnamed);
        }
        let mut cams = lock(&self.shared.cams);
        cams.drain(&self.shared.axes);
        let slot = cams
            .slot_of(name)
            .or_else(|| cams.free_slot())
            .ok_or_else(|| ControlError::CamSlotsFull { name: name.into() })?;
        let info = CamInfo::of(name, slot, &table);
        self.send_cam(&mut cams, slot, Some(table), Some(info))
    }

    /// Removes cam table `name`, freeing its slot (refused while an axis cams on it).
    pub fn remove_cam(&self, name: &str) -> Result<CamHandle, ControlError> {
        let mut cams = lock(&self.shared.cams);
        cams.drain(&self.shared.axes);
        let slot = cams
            .slot_of(name)
            .ok_or_else(|| ControlError::NoCam(name.into()))?;
        self.send_cam(&mut cams, slot, None, None)
    }

    fn send_cam(
        &self,
        cams: &mut CamEnds,
        slot: usize,
        table: Option<CamTable>,
        info: Option<CamInfo>,
    ) -> Result<CamHandle, ControlError> {
        let id = self.shared.next_id.fetch_add(1, Ordering::Relaxed);
        cams.jobs
            .push(CamJob { id, slot, table })
            .map_err(|_| ControlError::QueueFull)?;
        cams.pending.push((id, slot, info));
        Ok(CamHandle {
            id,
            controller: self.clone(),
        })
    }

    /// The outcome of cam job `id`, once the cycle thread has handed it back.
    fn cam_outcome(&self, id: u64) -> Option<Result<usize, ControlError>> {
        let mut cams = lock(&self.shared.cams);
        cams.drain(&self.shared.axes);
        let at = cams.arrived.iter().position(|(i, _)| *i == id)?;
        Some(cams.arrived.remove(at).1)
    }

    fn status_of(&self, id: u64) -> Option<CommandStatus> {
        lock(&self.shared.snapshot).read().status_of(id)
    }
}

fn counters(f: &CycleFigures) -> CycleCounters {
    CycleCounters {
        cycles: f.cycles,
        overruns: f.overruns,
        worst_overrun_run: f.worst_overrun_run,
        samples_dropped: f.samples_dropped,
    }
}

/// A command on its way: its status follows the cycle thread.
#[derive(Clone)]
pub struct CommandHandle {
    id: u64,
    controller: Controller,
}

impl CommandHandle {
    /// Request id.
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Current status; `None` until the cycle thread has taken the request.
    pub fn status(&self) -> Option<CommandStatus> {
        self.controller.status_of(self.id)
    }

    /// Blocks until the status is final (Done, Aborted, Error) or `timeout` passes.
    pub fn wait(&self, timeout: Duration) -> Result<CommandStatus, ControlError> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(s) = self.status().filter(CommandStatus::is_final) {
                return Ok(s);
            }
            if Instant::now() >= end {
                return Err(ControlError::Timeout(timeout));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Resolves when the status is final.
    pub async fn done(&self) -> CommandStatus {
        loop {
            if let Some(s) = self.status().filter(CommandStatus::is_final) {
                return s;
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    }
}

/// An SDO transfer on its way.
#[derive(Clone)]
pub struct SdoHandle {
    id: u64,
    controller: Controller,
}

impl SdoHandle {
    /// How it ended, once it has (taken once).
    pub fn outcome(&self) -> Option<SdoResult> {
        self.controller.sdo_outcome(self.id)
    }

    /// Blocks until it ends, the cycle ends, or `timeout` passes.
    pub fn wait(&self, timeout: Duration) -> Result<SdoResult, ControlError> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(r) = self.outcome() {
                return Ok(r);
            }
            if lock(&self.controller.shared.snapshot).read().ended {
                return Err(ControlError::Ended);
            }
            if Instant::now() >= end {
                return Err(ControlError::Timeout(timeout));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// A cam table load (or removal) on its way.
#[derive(Clone)]
pub struct CamHandle {
    id: u64,
    controller: Controller,
}

impl std::fmt::Debug for CamHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CamHandle").field("id", &self.id).finish()
    }
}

impl CamHandle {
    /// How it ended, once it has (taken once): the table's slot, or why not.
    pub fn outcome(&self) -> Option<Result<usize, ControlError>> {
        self.controller.cam_outcome(self.id)
    }

    /// Blocks until it ends, the cycle ends, or `timeout` passes: the table's slot.
    pub fn wait(&self, timeout: Duration) -> Result<usize, ControlError> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(r) = self.outcome() {
                return r;
            }
            if lock(&self.controller.shared.snapshot).read().ended {
                return Err(ControlError::Ended);
            }
            if Instant::now() >= end {
                return Err(ControlError::Timeout(timeout));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Resolves when it ends, or with [`ControlError::Ended`] once the cycle has.
    pub async fn done(&self) -> Result<usize, ControlError> {
        loop {
            if let Some(r) = self.outcome() {
                return r;
            }
            if lock(&self.controller.shared.snapshot).read().ended {
                return Err(ControlError::Ended);
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    }
}
