//! Cam tables in the running cycle: the kernel holds them in slots
//! ([`gantry_kernel::kernel::CAM_SLOTS`]), the application knows them by name.
//!
//! A table loaded at runtime ([`super::controller::Controller::load_cam`]) is built on the
//! application's side and travels to the cycle thread in a [`CamJob`]; the cycle thread
//! puts it into its slot and hands what the slot held back in a [`CamDone`] — or, when an
//! axis cams on the slot, the new table itself with the refusal — so it never allocates
//! nor frees a table (the SDO buffers go the same way).

use gantry_kernel::cam::{CamTable, Interpolation};
use gantry_kernel::kernel::CamSlotError;

/// Cam jobs waiting for the cycle thread at most, and outcomes waiting for the
/// application (the cycle thread takes one job a cycle).
pub const CAM_QUEUE: usize = 8;

/// A cam table as the application sees it: its name, its slot and what it is.
#[derive(Clone, Debug, PartialEq)]
pub struct CamInfo {
    /// Its name (from `[[cam]]` or the load).
    pub name: String,
    /// The kernel's cam slot it is in (what `CamIn` names).
    pub slot: usize,
    /// Its points.
    pub points: usize,
    /// How it is interpolated between them.
    pub interpolation: Interpolation,
    /// Whether it repeats.
    pub periodic: bool,
    /// First and last master position (master units).
    pub master_range: (f64, f64),
    /// slave(last) − slave(first) (slave units): what the slave gains each period.
    pub slave_rise: f64,
}

impl CamInfo {
    /// What the application keeps of `table`, called `name`, in slot `slot`.
    pub fn of(name: &str, slot: usize, table: &CamTable) -> Self {
        Self {
            name: name.to_string(),
            slot,
            points: table.points().len(),
            interpolation: table.interpolation(),
            periodic: table.is_periodic(),
            master_range: table.master_range(),
            slave_rise: table.slave_rise(),
        }
    }
}

/// A cam table for the cycle thread to put into slot `slot` (`None` empties it).
#[derive(Debug)]
pub struct CamJob {
    /// Request id (the handle's).
    pub id: u64,
    /// The kernel's cam slot.
    pub slot: usize,
    /// The table (allocated by the application).
    pub table: Option<CamTable>,
}

/// How a [`CamJob`] ended, with a table for the application to drop: what the slot held
/// (done), or the job's own table (refused).
#[derive(Debug)]
pub struct CamDone {
    /// The job's id.
    pub id: u64,
    /// Done, or why not.
    pub result: Result<(), CamSlotError>,
    /// The table handed back.
    pub table: Option<CamTable>,
}
