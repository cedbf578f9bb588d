//! The synchronised-motion requests (`gear`, `gear_out`, `cam`, `cam_out`, and `jog` with
//! a master) as kernel commands: the wire's words and names resolved, the numbers
//! checked. The kernel checks the rest (ratios, scalings, loops, the table's range) and
//! its refusal reaches the client as the command's error.

use gantry_kernel::axis::command::{Command, MoveDirection};
use gantry_kernel::sync::command::{
    CamIn, CamStart, CatchUp, GearIn, GearInPos, LockDirection as KernelLock, MasterJog,
    MasterValue,
};

use super::protocol::{CamStartMode, JogDirection, LockDirection, MasterSource};
use super::server::Refused;

/// The finite number `value` of `field`, or why not.
fn number(field: &'static str, value: Option<f64>) -> Result<Option<f64>, Refused> {
    match value {
        Some(v) if !v.is_finite() => Err(Refused::NotFinite { field, value: v }),
        v => Ok(v),
    }
}

fn source(s: Option<MasterSource>) -> MasterValue {
    match s.unwrap_or_default() {
        MasterSource::Set => MasterValue::Set,
        MasterSource::Actual => MasterValue::Actual,
    }
}

/// Catch-up dynamics as given.
pub fn catch_up(
    acceleration: Option<f64>,
    deceleration: Option<f64>,
    jerk: Option<f64>,
) -> Result<CatchUp, Refused> {
    Ok(CatchUp {
        acceleration: number("acceleration", acceleration)?,
        deceleration: number("deceleration", deceleration)?,
        jerk: number("jerk", jerk)?,
        ramp: None,
    })
}

/// What a `gear` request asks: the master's index, the ratio, the source, the catch-up
/// and, for GearInPos, the sync positions.
pub struct GearRequest {
    /// Master index.
    pub master: usize,
    /// Ratio numerator.
    pub numerator: i32,
    /// Ratio denominator.
    pub denominator: u32,
    /// Set or actual values.
    pub source: Option<MasterSource>,
    /// Catch-up dynamics.
    pub catch_up: CatchUp,
    /// Master sync position (GearInPos).
    pub master_sync_position: Option<f64>,
    /// Slave sync position (GearInPos).
    pub slave_sync_position: Option<f64>,
    /// Master start distance (GearInPos).
    pub master_start_distance: Option<f64>,
}

impl GearRequest {
    /// MC_GearIn, or MC_GearInPos when both sync positions are given.
    pub fn command(&self) -> Result<Command, Refused> {
        let gear = GearIn {
            master: self.master,
            numerator: self.numerator,
            denominator: self.denominator,
            source: source(self.source),
            catch_up: self.catch_up,
        };
        let ms = number("master_sync_position", self.master_sync_position)?;
        let ss = number("slave_sync_position", self.slave_sync_position)?;
        let distance = number("master_start_distance", self.master_start_distance)?;
        match (ms, ss) {
            (None, None) if distance.is_some() => Err(Refused::Sync(
                "master_start_distance is for a gear in sync at positions: give \
                 master_sync_position and slave_sync_position",
            )),
            (None, None) => Ok(Command::GearIn(gear)),
            (Some(m), Some(s)) => Ok(Command::GearInPos(GearInPos {
                gear,
                master_sync_position: m,
                slave_sync_position: s,
                master_start_distance: distance,
            })),
            _ => Err(Refused::Sync(
                "a gear in sync at positions needs both master_sync_position and \
                 slave_sync_position",
            )),
        }
    }
}

/// What a `cam` request asks, its names resolved.
pub struct CamRequest {
    /// Master index.
    pub master: usize,
    /// Table slot.
    pub table: usize,
    /// Whether the table repeats (default true).
    pub periodic: Option<bool>,
    /// Placement.
    pub start: Option<CamStartMode>,
    /// Set or actual values.
    pub source: Option<MasterSource>,
    /// Offsets and scalings: master offset, slave offset, master scaling, slave scaling.
    pub placement: [Option<f64>; 4],
    /// Catch-up dynamics.
    pub catch_up: CatchUp,
}

impl CamRequest {
    /// MC_CamIn.
    pub fn command(&self) -> Result<Command, Refused> {
        let [mo, so, ms, ss] = self.placement;
        let mut c = CamIn::new(self.master, self.table, self.periodic.unwrap_or(true));
        c.source = source(self.source);
        c.start = match self.start.unwrap_or_default() {
            CamStartMode::Absolute => CamStart::Absolute,
            CamStartMode::Relative => CamStart::Relative,
        };
        c.master_offset = number("master_offset", mo)?.unwrap_or(0.0);
        c.slave_offset = number("slave_offset", so)?.unwrap_or(0.0);
        c.master_scaling = number("master_scaling", ms)?.unwrap_or(1.0);
        c.slave_scaling = number("slave_scaling", ss)?.unwrap_or(1.0);
        c.catch_up = self.catch_up;
        Ok(Command::CamIn(c))
    }
}

/// A master-driven jog (Logix MAJ with MDAC).
pub fn master_jog(
    master: usize,
    direction: JogDirection,
    speed: f64,
    lock: Option<LockDirection>,
    lock_position: Option<f64>,
    catch_up: CatchUp,
) -> Result<Command, Refused> {
    let lock = match lock.unwrap_or_default() {
        LockDirection::None => KernelLock::None,
        LockDirection::ImmediateForward => KernelLock::ImmediateForwardOnly,
        LockDirection::ImmediateReverse => KernelLock::ImmediateReverseOnly,
        LockDirection::PositionForward => KernelLock::PositionForwardOnly,
        LockDirection::PositionReverse => KernelLock::PositionReverseOnly,
    };
    let lock_position = number("lock_position", lock_position)?;
    if lock.waits_for_position() && lock_position.is_none() {
        return Err(Refused::Sync(
            "a position-forward or position-reverse lock needs lock_position",
        ));
    }
    Ok(Command::MasterJog(MasterJog {
        master,
        source: MasterValue::Set,
        direction: match direction {
            JogDirection::Positive => MoveDirection::Positive,
            JogDirection::Negative => MoveDirection::Negative,
        },
        speed: number("speed", Some(speed))?.unwrap_or(0.0),
        lock,
        lock_position: lock_position.unwrap_or(0.0),
        catch_up,
    }))
}
