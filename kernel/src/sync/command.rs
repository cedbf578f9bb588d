//! The synchronised-motion commands (PLCopen MC_GearIn, MC_GearInPos, MC_CamIn; Logix MAJ
//! lock): what a follower is told, before anything is resolved against its master.

use crate::profile::RampType;

/// Which of the master's values the follower follows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MasterValue {
    /// The master's set values (smooth: what it is commanded to do).
    #[default]
    Set,
    /// The master's actual values (what its encoder reads). An external axis' set values
    /// are its actual values.
    Actual,
}

impl MasterValue {
    /// Name for messages and the command line.
    pub const fn name(self) -> &'static str {
        match self {
            MasterValue::Set => "set",
            MasterValue::Actual => "actual",
        }
    }
}

/// Dynamics the follower uses to catch up with its master without a jump (PLCopen's
/// Acceleration, Deceleration and Jerk inputs of MC_GearIn / MC_CamIn). `None`: the
/// follower's configured defaults.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CatchUp {
    /// Acceleration (units/s², > 0).
    pub acceleration: Option<f64>,
    /// Deceleration (units/s², > 0).
    pub deceleration: Option<f64>,
    /// Jerk (units/s³, > 0).
    pub jerk: Option<f64>,
    /// Ramp type (default: the axis' default).
    pub ramp: Option<RampType>,
}

/// MC_GearIn: follow the master at `numerator / denominator` (follower units per master
/// unit), reaching the master's velocity × ratio with the catch-up dynamics; InGear once
/// the velocities match. The position offset is whatever the catching up leaves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GearIn {
    /// Index of the master axis.
    pub master: usize,
    /// Ratio numerator (PLCopen INT; negative turns the other way).
    pub numerator: i32,
    /// Ratio denominator (PLCopen UINT, > 0).
    pub denominator: u32,
    /// Set or actual values of the master.
    pub source: MasterValue,
    /// How the follower catches up.
    pub catch_up: CatchUp,
}

impl GearIn {
    /// A gear with the master's set values and the follower's default dynamics.
    pub const fn new(master: usize, numerator: i32, denominator: u32) -> Self {
        Self {
            master,
            numerator,
            denominator,
            source: MasterValue::Set,
            catch_up: CatchUp {
                acceleration: None,
                deceleration: None,
                jerk: None,
                ramp: None,
            },
        }
    }
}

/// MC_GearInPos: follow at the ratio so that the follower is at `slave_sync_position`
/// exactly when the master is at `master_sync_position` (InSync from there on).
///
/// The follower reaches the gear line along a 5th-order polynomial in the master's
/// position (p, v and a continuous at both ends), starting where the command is given or,
/// with `master_start_distance`, once the master is that far before its sync position
/// (until then the follower stands). On a modulo master the next crossing of the sync
/// position ahead (in the master's direction of motion) is taken; on a modulo follower the
/// nearest position congruent to `slave_sync_position`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GearInPos {
    /// The gear.
    pub gear: GearIn,
    /// Master position at which the follower is in sync (master units).
    pub master_sync_position: f64,
    /// Follower position at that moment (follower units).
    pub slave_sync_position: f64,
    /// Master distance before the sync position over which the follower catches up
    /// (`None`: from where the master is now).
    pub master_start_distance: Option<f64>,
}

/// How MC_CamIn places the table (PLCopen StartMode / MasterAbsolute, SlaveAbsolute).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CamStart {
    /// The table's master axis is the master's position, its slave axis the follower's:
    /// the follower goes to the table's value (catching up without a jump).
    #[default]
    Absolute,
    /// The table starts at its first point where the master is now, and adds to the
    /// follower's position.
    Relative,
}

impl CamStart {
    /// Name for messages.
    pub const fn name(self) -> &'static str {
        match self {
            CamStart::Absolute => "absolute",
            CamStart::Relative => "relative",
        }
    }
}

/// MC_CamIn: follow the master through cam table `table` (a slot of the kernel's cam
/// tables). Table master coordinate = `master_offset + master_scaling · master position`;
/// follower = `slave_offset + slave_scaling · table(…)`. A periodic table repeats
/// (the slave rises by the table's rise each period); a non-periodic one ends at its last
/// point: EndOfProfile, and the follower goes on at its velocity as after MC_CamOut.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CamIn {
    /// Index of the master axis.
    pub master: usize,
    /// Cam table slot.
    pub table: usize,
    /// Set or actual values of the master.
    pub source: MasterValue,
    /// Whether the table repeats.
    pub periodic: bool,
    /// Absolute or relative placement.
    pub start: CamStart,
    /// Shift of the table's master coordinate (table units).
    pub master_offset: f64,
    /// Shift of the follower (follower units).
    pub slave_offset: f64,
    /// Table master units per master unit (≠ 0).
    pub master_scaling: f64,
    /// Follower units per table slave unit (≠ 0).
    pub slave_scaling: f64,
    /// How the follower catches up.
    pub catch_up: CatchUp,
}

impl CamIn {
    /// A cam with unit scaling, no offsets, absolute placement on the master's set values.
    pub const fn new(master: usize, table: usize, periodic: bool) -> Self {
        Self {
            master,
            table,
            source: MasterValue::Set,
            periodic,
            start: CamStart::Absolute,
            master_offset: 0.0,
            slave_offset: 0.0,
            master_scaling: 1.0,
            slave_scaling: 1.0,
            catch_up: CatchUp {
                acceleration: None,
                deceleration: None,
                jerk: None,
                ramp: None,
            },
        }
    }
}
