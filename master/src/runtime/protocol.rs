//! What crosses between the application and the cycle thread: requests one way (a
//! lock-free SPSC queue), a latest-wins snapshot the other way (a triple buffer), and
//! trace samples (a second SPSC queue). Every type here is fixed-size or preallocated, so
//! the cycle thread neither allocates nor locks to use them.

use gantry_drives::cia402::State;
use gantry_kernel::axis::command::Command;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::status::AxisStatus;

use super::bus::{CanNodeStatus, Unreachable};
use super::sdo::{SdoBuffer, SdoEnded, SdoTransfer};
use super::stats::CycleFigures;

/// Axes a trace sample holds.
pub const TRACE_AXES: usize = 16;
/// Commands whose status the snapshot keeps (the oldest drop out).
pub const TRACKED_COMMANDS: usize = 256;

/// A request from the application.
// Inline on purpose (a drive procedure is the largest): boxed, the cycle thread would free
// it.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// A motion or power command for an axis.
    Axis {
        /// Request id (the handle's).
        id: u64,
        /// Axis index.
        axis: usize,
        /// The command.
        command: Command,
    },
    /// Reset an axis: bring its slave back to OP if it left, then the axis' Reset.
    Reset {
        /// Request id.
        id: u64,
        /// Axis index.
        axis: usize,
    },
    /// A command to an axis group.
    Group {
        /// Request id.
        id: u64,
        /// Group index (`[[group]]` order).
        group: usize,
        /// The command.
        command: gantry_kernel::group::run::GroupCmd,
    },
    /// Stop moving axes, disable the drives, end the cycle.
    Shutdown,
    /// Run a procedure on an axis' drive, out of CSP (see [`super::procedure`]); the
    /// handle follows it (Active until it ends).
    Procedure {
        /// Request id.
        id: u64,
        /// Axis index.
        axis: usize,
        /// The procedure.
        procedure: super::procedure::DriveProcedure,
    },
}

/// A procedure running on a drive, for the status.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProcedureStatus {
    /// Its name ("drive homing").
    pub name: &'static str,
    /// Its method, where it has one.
    pub method: Option<i16>,
    /// What it is doing ("homing").
    pub phase: &'static str,
}

/// An SDO transfer for the cycle thread to hand to the bus, with the buffer the
/// application lends it (allocated on the application's side; handed back in
/// [`SdoDone`], never freed by the cycle thread).
#[derive(Debug)]
pub struct SdoJob {
    /// Request id (the handle's).
    pub id: u64,
    /// The transfer.
    pub transfer: SdoTransfer,
    /// Its bytes: the data to download, or room for the upload.
    pub buffer: SdoBuffer,
}

/// How an SDO transfer ended, from the cycle thread, with its buffer back.
#[derive(Debug)]
pub struct SdoDone {
    /// The job's id.
    pub id: u64,
    /// Done (the buffer holds an upload's bytes) or why not.
    pub ended: SdoEnded,
}

/// Status of one request as the cycle thread last saw it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tracked {
    /// Request id.
    pub id: u64,
    /// Its status.
    pub status: CommandStatus,
}

/// What a drive reports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriveStatus {
    /// Power state from the statusword.
    pub state: Option<State>,
    /// Statusword.
    pub statusword: u16,
    /// Error code 0x603F (when mapped).
    pub error_code: Option<u16>,
    /// The bus cannot reach it: why.
    pub bus_fault: Option<Unreachable>,
    /// On CANopen: its node as the bus sees it.
    pub can_node: Option<CanNodeStatus>,
    /// A procedure it runs by itself, out of CSP.
    pub procedure: Option<ProcedureStatus>,
    /// 0x6061 Modes of operation display, where mapped.
    pub mode_display: Option<i8>,
}

/// Everything the application can see, replaced as a whole every few cycles.
#[derive(Clone, Debug, Default)]
pub struct Snapshot {
    /// Cycles run.
    pub cycle: u64,
    /// Kernel time (s).
    pub time_s: f64,
    /// The axes, in configuration order.
    pub axes: Vec<AxisStatus>,
    /// The groups' states, in configuration order (`None` past the last group).
    pub groups: [Option<gantry_kernel::group::GroupState>; crate::config::MAX_GROUPS],
    /// What each group's blended junctions did, beside its state.
    pub group_corners: [gantry_kernel::group::run::CornerReport; crate::config::MAX_GROUPS],
    /// The drive of each axis.
    pub drives: Vec<DriveStatus>,
    /// Frames lost since start.
    pub lost_frames: u64,
    /// Cycles with a wrong working counter since start.
    pub working_counter_errors: u64,
    /// Cycle figures.
    pub figures: CycleFigures,
    /// Recent requests and their status (ring; see `newest_id`).
    pub commands: Vec<Tracked>,
    /// Highest request id the cycle thread has taken.
    pub newest_id: u64,
    /// Distributed clocks: where in the SYNC0 period the last frame reached the reference
    /// clock (ns); `None` without DC.
    pub dc_offset_ns: Option<u64>,
    /// Where the cycle holds that point when it is phase-locked to SYNC0 (ns).
    pub dc_target_ns: Option<u64>,
    /// The cycle thread stopped every axis because of overruns in a row.
    pub overrun_stop: bool,
    /// The cycle thread has ended.
    pub ended: bool,
}

impl Snapshot {
    /// An empty snapshot sized for `axes` axes (allocates once, here).
    pub fn sized(axes: usize) -> Self {
        Self {
            axes: vec![AxisStatus::default(); axes],
            drives: vec![DriveStatus::default(); axes],
            commands: vec![
                Tracked {
                    id: 0,
                    status: CommandStatus::Expired,
                };
                TRACKED_COMMANDS
            ],
            ..Self::default()
        }
    }

    /// The status of request `id`: `None` while the cycle thread has not taken it yet.
    pub fn status_of(&self, id: u64) -> Option<CommandStatus> {
        if id > self.newest_id {
            return None;
        }
        Some(
            self.commands
                .iter()
                .find(|t| t.id == id)
                .map_or(CommandStatus::Expired, |t| t.status),
        )
    }
}

/// One cycle's set and actual positions of the first [`TRACE_AXES`] axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceSample {
    /// Kernel time (s).
    pub time_s: f64,
    /// Set positions.
    pub set: [f64; TRACE_AXES],
    /// Set velocities.
    pub set_velocity: [f64; TRACE_AXES],
    /// Actual positions.
    pub actual: [f64; TRACE_AXES],
}
