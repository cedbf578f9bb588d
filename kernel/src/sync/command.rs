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

/// When a master-driven jog follows its master (Logix MAJ "Lock Direction").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LockDirection {
    /// Follows the master both ways from the start.
    #[default]
    None,
    /// Follows from the start, only while the master moves forward; stops following when
    /// it reverses and follows again when it moves forward again.
    ImmediateForwardOnly,
    /// As [`LockDirection::ImmediateForwardOnly`], backwards.
    ImmediateReverseOnly,
    /// Stands until the master crosses the lock position moving forward, then as
    /// [`LockDirection::ImmediateForwardOnly`].
    PositionForwardOnly,
    /// Stands until the master crosses the lock position moving backwards, then as
    /// [`LockDirection::ImmediateReverseOnly`].
    PositionReverseOnly,
}

impl LockDirection {
    /// Logix' name.
    pub const fn name(self) -> &'static str {
        match self {
            LockDirection::None => "None",
            LockDirection::ImmediateForwardOnly => "ImmediateForwardOnly",
            LockDirection::ImmediateReverseOnly => "ImmediateReverseOnly",
            LockDirection::PositionForwardOnly => "PositionForwardOnly",
            LockDirection::PositionReverseOnly => "PositionReverseOnly",
        }
    }

    /// +1 forward only, −1 reverse only, 0 both ways.
    pub const fn only(self) -> f64 {
        match self {
            LockDirection::None => 0.0,
            LockDirection::ImmediateForwardOnly | LockDirection::PositionForwardOnly => 1.0,
            LockDirection::ImmediateReverseOnly | LockDirection::PositionReverseOnly => -1.0,
        }
    }

    /// Whether the jog waits for the master to cross the lock position.
    pub const fn waits_for_position(self) -> bool {
        matches!(
            self,
            LockDirection::PositionForwardOnly | LockDirection::PositionReverseOnly
        )
    }
}

/// A master-driven jog (Logix MAJ with the axis coupled to a master by MDAC): the jog's
/// speed is in follower units per master unit, so the follower moves as the master does,
/// at that ratio — from the start or once the master crosses the lock position, in both
/// master directions or only one ([`LockDirection`]). With a one-way lock the follower
/// moves in the jog's direction while the lock holds; with `None` it moves in the jog's
/// direction while the master moves forward and back while it moves back. The follower
/// reaches and leaves the master-driven speed with the catch-up dynamics, never with a
/// jump. Ended like any jog (Halt, Stop, a new move).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasterJog {
    /// Index of the master axis.
    pub master: usize,
    /// Set or actual values of the master.
    pub source: MasterValue,
    /// Direction of the jog.
    pub direction: crate::axis::command::MoveDirection,
    /// Follower units per master unit (> 0).
    pub speed: f64,
    /// When the follower follows.
    pub lock: LockDirection,
    /// Master position of the Position* lock directions (master units; within the period
    /// on a modulo master).
    pub lock_position: f64,
    /// How the follower reaches the master-driven speed when the lock takes hold.
    pub catch_up: CatchUp,
}
