//! Motion commands and their operands (SPEC §3; Jetter MovePtp/MoveVelocity/MoveHalt,
//! Logix MAJ, PLCopen buffer modes), and the errors a command can be refused with.
//!
//! Every operand is validated before the command touches the axis: an out-of-range
//! operand gives a [`CommandError`] that names it (like Logix' EXERR) and the axis goes on
//! with what it was doing.

use thiserror::Error;

use super::state::AxisState;
use super::status::FaultSummary;
use crate::profile::{PlanError, RampType};

/// How a MovePtp target is interpreted (seed 000 §6.4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PositioningMode {
    /// Absolute position; normal (non-modulo) axes only.
    AbsNormal,
    /// Relative to the last set target (`RelTarget 0` finishes an interrupted move).
    RelTarget,
    /// Relative to the actual position.
    RelActual,
    /// Modulo axes: absolute position within the period, moving in the positive direction.
    AbsModuloPos,
    /// Modulo axes: absolute position within the period, moving in the negative direction.
    AbsModuloNeg,
    /// Modulo axes: absolute position within the period, the shortest way.
    AbsModuloAuto,
    /// Modulo axes: absolute position within the period, in the direction of the last move.
    AbsModuloKeepDirection,
}

impl PositioningMode {
    /// Whether the mode is only for modulo axes.
    pub const fn is_modulo(self) -> bool {
        matches!(
            self,
            Self::AbsModuloPos
                | Self::AbsModuloNeg
                | Self::AbsModuloAuto
                | Self::AbsModuloKeepDirection
        )
    }

    /// Whether the target is an absolute position (and so needs a homed axis).
    pub const fn is_absolute(self) -> bool {
        !matches!(self, Self::RelTarget | Self::RelActual)
    }
}

/// How a new command joins the one in progress (PLCopen Part 1, "BufferMode").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BufferMode {
    /// Take over at once from the current state.
    #[default]
    Aborting,
    /// Start in the cycle the previous move ends (no standstill cycle).
    Buffered,
    /// Pass the junction at the lower of the two moves' speeds.
    BlendingLow,
    /// Pass the junction at the previous move's speed.
    BlendingPrevious,
    /// Pass the junction at the next move's speed.
    BlendingNext,
    /// Pass the junction at the higher of the two moves' speeds.
    BlendingHigh,
}

impl BufferMode {
    /// Whether the new command waits for the previous one.
    pub const fn is_queued(self) -> bool {
        !matches!(self, Self::Aborting)
    }
}

/// What a new MovePtp does while the current PTP move is on its deceleration ramp
/// (seed 000 §6.1.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum RampBreakMode {
    /// Finish to the first target, then go straight on to the second.
    #[default]
    None,
    /// Abort the deceleration with the new maximum deceleration and go straight to the
    /// second target, when the distance allows it; otherwise as `None`.
    Immediate,
}

/// Direction of a velocity move or jog.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MoveDirection {
    /// Positive (Logix "Forward").
    Positive,
    /// Negative (Logix "Reverse").
    Negative,
}

impl MoveDirection {
    /// +1 or −1.
    pub const fn sign(self) -> f64 {
        match self {
            Self::Positive => 1.0,
            Self::Negative => -1.0,
        }
    }

    /// The other direction.
    pub const fn reversed(self) -> Self {
        match self {
            Self::Positive => Self::Negative,
            Self::Negative => Self::Positive,
        }
    }
}

/// Point-to-point move (Jetter `MovePtp.Start`). `None` operands keep the last value used
/// on this axis (or the configured default), as Jetter does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovePtp {
    /// How `target` is interpreted.
    pub mode: PositioningMode,
    /// Target position or distance (units).
    pub target: f64,
    /// Maximum speed (units/s, > 0).
    pub speed: Option<f64>,
    /// Acceleration (units/s², > 0).
    pub acceleration: Option<f64>,
    /// Deceleration (units/s², > 0).
    pub deceleration: Option<f64>,
    /// Jerk (units/s³, > 0), S-curve only.
    pub jerk: Option<f64>,
    /// Target window (units, ≥ 0) for the "in target window" status.
    pub target_window: Option<f64>,
    /// Ramp type.
    pub ramp: Option<RampType>,
    /// How the move joins the one in progress.
    pub buffer: BufferMode,
}

impl MovePtp {
    /// A move with every optional operand left at its last-used value.
    pub const fn new(mode: PositioningMode, target: f64) -> Self {
        Self {
            mode,
            target,
            speed: None,
            acceleration: None,
            deceleration: None,
            jerk: None,
            target_window: None,
            ramp: None,
            buffer: BufferMode::Aborting,
        }
    }

    /// Sets the speed.
    pub const fn speed(mut self, v: f64) -> Self {
        self.speed = Some(v);
        self
    }

    /// Sets acceleration and deceleration.
    pub const fn accel(mut self, a: f64, d: f64) -> Self {
        self.acceleration = Some(a);
        self.deceleration = Some(d);
        self
    }

    /// Sets the jerk.
    pub const fn jerk(mut self, j: f64) -> Self {
        self.jerk = Some(j);
        self
    }

    /// Sets the ramp type.
    pub const fn ramp(mut self, r: RampType) -> Self {
        self.ramp = Some(r);
        self
    }

    /// Sets the buffer mode.
    pub const fn buffered(mut self, b: BufferMode) -> Self {
        self.buffer = b;
        self
    }
}

/// Continuous move at constant velocity (Jetter `MoveVelocity.Start`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoveVelocity {
    /// Direction.
    pub direction: MoveDirection,
    /// Speed (units/s, > 0).
    pub speed: Option<f64>,
    /// Acceleration (units/s², > 0).
    pub acceleration: Option<f64>,
    /// Deceleration used when the move is stopped (units/s², > 0).
    pub deceleration: Option<f64>,
    /// Jerk (units/s³, > 0), S-curve only.
    pub jerk: Option<f64>,
    /// Ramp type.
    pub ramp: Option<RampType>,
    /// How the move joins the one in progress.
    pub buffer: BufferMode,
}

impl MoveVelocity {
    /// A velocity move in `direction` at `speed`, other operands last-used.
    pub const fn new(direction: MoveDirection, speed: f64) -> Self {
        Self {
            direction,
            speed: Some(speed),
            acceleration: None,
            deceleration: None,
            jerk: None,
            ramp: None,
            buffer: BufferMode::Aborting,
        }
    }
}

/// Unit of a jog's speed or rate operand (Logix MAJ "Speed Units", "Accel Units").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RateUnits {
    /// Units per second (per s² for rates).
    PerSecond,
    /// Percent of the axis' configured maximum.
    PercentOfMax,
}

/// Unit of a jog's jerk operands (Logix MAJ "Jerk Units").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum JerkUnits {
    /// Units per second³.
    PerSecond3,
    /// Percent of the axis' configured maximum jerk.
    PercentOfMax,
    /// Percent of the ramp time spent changing acceleration (100 % = triangular
    /// acceleration, no constant-acceleration phase).
    PercentOfTime,
}

/// Speed a merging jog runs at (Logix MAJ "Merge Speed").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MergeSpeed {
    /// The jog's own `speed` operand.
    Programmed,
    /// The speed the axis has when the jog starts (the `speed` operand is ignored).
    Current,
}

/// Velocity profile of a jog (Logix MAJ "Profile").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum JogProfile {
    /// Linear ramps.
    Trapezoid,
    /// Jerk-limited ramps.
    SCurve,
}

/// Jog at constant speed until stopped (Logix MAJ).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jog {
    /// Direction.
    pub direction: MoveDirection,
    /// Speed, in `speed_units`.
    pub speed: f64,
    /// Unit of `speed`.
    pub speed_units: RateUnits,
    /// Acceleration, in `accel_units`.
    pub accel: f64,
    /// Unit of `accel`.
    pub accel_units: RateUnits,
    /// Deceleration, in `decel_units`.
    pub decel: f64,
    /// Unit of `decel`.
    pub decel_units: RateUnits,
    /// Trapezoid or S-curve.
    pub profile: JogProfile,
    /// Jerk while speeding up, in `jerk_units` (S-curve only; must still be valid).
    pub accel_jerk: f64,
    /// Jerk while slowing down, in `jerk_units`.
    pub decel_jerk: f64,
    /// Unit of the jerks.
    pub jerk_units: JerkUnits,
    /// `true`: end every other motion and jog alone. `false`: a jog started while another
    /// single-axis move runs is superimposed on it.
    pub merge: bool,
    /// With `merge`, which speed the jog runs at.
    pub merge_speed: MergeSpeed,
}

impl Jog {
    /// A trapezoid jog at `speed` units/s with rates in units/s², not merging.
    pub const fn new(direction: MoveDirection, speed: f64, accel: f64, decel: f64) -> Self {
        Self {
            direction,
            speed,
            speed_units: RateUnits::PerSecond,
            accel,
            accel_units: RateUnits::PerSecond,
            decel,
            decel_units: RateUnits::PerSecond,
            profile: JogProfile::Trapezoid,
            accel_jerk: 100.0,
            decel_jerk: 100.0,
            jerk_units: JerkUnits::PercentOfTime,
            merge: false,
            merge_speed: MergeSpeed::Programmed,
        }
    }
}

/// How a halt ends (Jetter `MCAxisHaltModes`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HaltMode {
    /// Decelerate to a stop.
    Normal,
    /// Decelerate to a stop, then return to the position the halt was given at.
    AtActualPosition,
}

/// Which power command (Jetter `Power.Enable/Disable`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PowerCommand {
    /// Enable the drive; the axis goes to Standstill at its actual position.
    Enable,
    /// Bring a moving axis to a stop with its deceleration, then disable.
    Disable,
    /// Disable at once, whatever the axis is doing.
    DisableForced,
}

/// Which on-the-fly change of the running move.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DynamicsChange {
    /// New maximum speed.
    Speed,
    /// New acceleration.
    Acceleration,
    /// New deceleration.
    Deceleration,
    /// New jerk.
    Jerk,
}

/// Every command an axis takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// Power on or off.
    Power(PowerCommand),
    /// Leave ErrorStop (acknowledge the error).
    Reset,
    /// Point-to-point move.
    MovePtp(MovePtp),
    /// Constant-velocity move.
    MoveVelocity(MoveVelocity),
    /// Reverse the running velocity move (same speed, other direction, its acceleration).
    Reverse,
    /// Jog.
    Jog(Jog),
    /// Change one dynamic limit of the running move from its current state.
    Change(DynamicsChange, f64),
    /// Halt: decelerate to a stop (`deceleration` `None` keeps the running move's).
    Halt {
        /// Normal or AtActualPosition.
        mode: HaltMode,
        /// Deceleration (units/s², > 0).
        deceleration: Option<f64>,
    },
    /// Stop: abort everything, decelerate, and lock the axis until [`Command::Release`].
    Stop {
        /// Deceleration (units/s², > 0); `None`: the axis' maximum deceleration.
        deceleration: Option<f64>,
    },
    /// Release a stopped axis (the falling edge of MC_Stop's Execute).
    Release,
    /// Quick stop with the configured quick-stop deceleration, then disable.
    QuickStop,
    /// Set the position without moving. Absolute marks the axis homed.
    SetPosition {
        /// New position (absolute) or shift (relative), units.
        position: f64,
        /// Shift by `position` instead of setting it.
        relative: bool,
    },
    /// Explicitly mark the axis homed (or not homed).
    SetHomed(bool),
    /// Jetter MoveHome (seed 000 §6.3.2): a homing run; left-out parameters keep the
    /// axis' last-used ones.
    MoveHome(crate::homing::MoveHomeCall),
    /// Beckhoff MC_StepAbsoluteSwitch (seed 003): a homing run on the reference cam.
    StepAbsoluteSwitch(crate::homing::StepAbsoluteSwitch),
    /// Jetter MoveHome.SetReference (seed 000 §6.3.1): the position becomes this without
    /// moving; the axis is homed and "reference set".
    SetReference(f64),
    /// PLCopen MC_GearIn: follow a master at a ratio.
    GearIn(crate::sync::command::GearIn),
    /// PLCopen MC_GearInPos: follow a master at a ratio, in sync at given positions.
    GearInPos(crate::sync::command::GearInPos),
    /// PLCopen MC_GearOut: stop following; the axis goes on at its velocity.
    GearOut,
    /// PLCopen MC_CamIn: follow a master through a cam table.
    CamIn(crate::sync::command::CamIn),
    /// PLCopen MC_CamOut: stop following the cam; the axis goes on at its velocity.
    CamOut,
    /// Logix MAJ driven by a master (MDAC): a jog whose speed is per master unit, with
    /// lock position and lock direction.
    MasterJog(crate::sync::command::MasterJog),
}

impl Command {
    /// Short name for messages.
    pub const fn name(&self) -> &'static str {
        match self {
            Command::Power(PowerCommand::Enable) => "Power.Enable",
            Command::Power(PowerCommand::Disable) => "Power.Disable",
            Command::Power(PowerCommand::DisableForced) => "Power.Disable(Forced)",
            Command::Reset => "Reset",
            Command::MovePtp(_) => "MovePtp",
            Command::MoveVelocity(_) => "MoveVelocity",
            Command::Reverse => "MoveVelocity.Reverse",
            Command::Jog(_) => "Jog",
            Command::Change(DynamicsChange::Speed, _) => "NewSpeed",
            Command::Change(DynamicsChange::Acceleration, _) => "NewAcceleration",
            Command::Change(DynamicsChange::Deceleration, _) => "NewDeceleration",
            Command::Change(DynamicsChange::Jerk, _) => "NewJerk",
            Command::Halt { .. } => "Halt",
            Command::Stop { .. } => "Stop",
            Command::Release => "Stop.Release",
            Command::QuickStop => "QuickStop",
            Command::SetPosition { .. } => "SetPosition",
            Command::SetHomed(_) => "SetHomed",
            Command::MoveHome(_) => "MoveHome",
            Command::StepAbsoluteSwitch(_) => "StepAbsoluteSwitch",
            Command::SetReference(_) => "MoveHome.SetReference",
            Command::GearIn(_) => "GearIn",
            Command::GearInPos(_) => "GearInPos",
            Command::GearOut => "GearOut",
            Command::CamIn(_) => "CamIn",
            Command::CamOut => "CamOut",
            Command::MasterJog(_) => "Jog.MasterDriven",
        }
    }
}

/// A command operand, numbered like Logix' EXERR (the first operand after the axis is 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Operand {
    /// Target position or distance.
    Target,
    /// Speed.
    Speed,
    /// Acceleration.
    Acceleration,
    /// Deceleration.
    Deceleration,
    /// Jerk (for jogs: accel jerk).
    Jerk,
    /// Decel jerk of a jog.
    DecelJerk,
    /// Target window.
    TargetWindow,
    /// Position of SetPosition.
    Position,
    /// Positioning mode.
    Mode,
    /// Direction.
    Direction,
    /// Gear ratio numerator or denominator.
    Ratio,
    /// Master or slave scaling of a cam.
    Scaling,
    /// Master or slave offset of a cam.
    Offset,
    /// Master or slave sync position of GearInPos.
    SyncPosition,
    /// Master start distance of GearInPos.
    StartDistance,
}

impl Operand {
    /// Operand name as in the command's documentation.
    pub const fn name(self) -> &'static str {
        match self {
            Operand::Target => "target",
            Operand::Speed => "speed",
            Operand::Acceleration => "acceleration",
            Operand::Deceleration => "deceleration",
            Operand::Jerk => "jerk",
            Operand::DecelJerk => "decel jerk",
            Operand::TargetWindow => "target window",
            Operand::Position => "position",
            Operand::Mode => "mode",
            Operand::Direction => "direction",
            Operand::Ratio => "ratio",
            Operand::Scaling => "scaling",
            Operand::Offset => "offset",
            Operand::SyncPosition => "sync position",
            Operand::StartDistance => "master start distance",
        }
    }
}

impl core::fmt::Display for Operand {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// Why an operand is out of range.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RangeProblem {
    /// NaN or infinite.
    NotFinite,
    /// Must be > 0.
    NotPositive,
    /// Must be ≥ 0.
    Negative,
    /// Above the axis' configured maximum.
    AboveAxisMax,
    /// Percent operand outside (0, 100].
    PercentOutOfRange,
    /// A position beyond ±[`MAX_POSITION`], where f64 no longer resolves a count.
    BeyondPositionRange,
    /// A modulo position outside [0, period).
    OutsidePeriod,
}

/// Largest |position| (units) a command may name: beyond it an f64 no longer resolves
/// 0.1 µm, so such a value is a mistake, not a position.
pub const MAX_POSITION: f64 = 1e9;

impl RangeProblem {
    const fn text(self) -> &'static str {
        match self {
            RangeProblem::NotFinite => "is not a finite number",
            RangeProblem::NotPositive => "must be > 0",
            RangeProblem::Negative => "must be >= 0",
            RangeProblem::AboveAxisMax => "exceeds the axis maximum",
            RangeProblem::PercentOutOfRange => "must be a percentage in (0, 100]",
            RangeProblem::BeyondPositionRange => "is beyond the position range",
            RangeProblem::OutsidePeriod => "must lie in [0, period)",
        }
    }
}

impl core::fmt::Display for RangeProblem {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.text())
    }
}

/// Why a command was refused or ended in error. `Copy`, so it can live in the RT status.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum CommandError {
    /// The axis is lent to a procedure its drive runs by itself (see
    /// [`crate::Kernel::lend_to_drive`]): only power off, Stop and QuickStop reach it, and
    /// they end the procedure first.
    #[error("{command}: the axis is lent to its drive for {procedure}; stop it first")]
    LentToDrive {
        /// Command name.
        command: &'static str,
        /// What the drive is doing ("drive homing").
        procedure: &'static str,
    },
    /// A procedure the drive ran by itself failed (the master's sequence says why).
    #[error("{0}")]
    DriveProcedure(crate::axis::lend::DriveProcedureError),
    /// Reset: the drive kept its fault through the fault reset.
    #[error("Reset: the drive still reports fault {code:#06x} after the fault reset")]
    DriveResetFailed {
        /// The drive's error code.
        code: u16,
    },
    /// An operand is out of range.
    #[error("{command}: operand {operand} = {value} {problem} (limit {limit})")]
    OperandOutOfRange {
        /// Command name.
        command: &'static str,
        /// Which operand.
        operand: Operand,
        /// Its value.
        value: f64,
        /// What is wrong.
        problem: RangeProblem,
        /// The limit it was checked against (NaN where there is none).
        limit: f64,
    },
    /// A modulo positioning mode on an axis without a modulo period.
    #[error("{command}: mode {mode:?} needs a modulo axis")]
    ModuloModeOnNormalAxis {
        /// Command name.
        command: &'static str,
        /// The mode given.
        mode: PositioningMode,
    },
    /// AbsNormal on a modulo axis.
    #[error("{command}: mode AbsNormal is for normal (non-modulo) axes; use an AbsModulo mode")]
    AbsNormalOnModuloAxis {
        /// Command name.
        command: &'static str,
    },
    /// The target lies outside the software limits.
    #[error("{command}: target {target} is outside the software limits [{min}, {max}]")]
    OutsideSoftwareLimits {
        /// Command name.
        command: &'static str,
        /// The target.
        target: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// The move would run in a direction the axis may not move in.
    #[error("{command}: the axis may only move {allowed}, this move goes {wanted}")]
    DirectionNotAllowed {
        /// Command name.
        command: &'static str,
        /// "positive" or "negative".
        allowed: &'static str,
        /// "positive" or "negative".
        wanted: &'static str,
    },
    /// The command is not allowed in the axis' PLCopen state.
    #[error("{command} is not allowed in state {state:?}")]
    NotAllowedInState {
        /// Command name.
        command: &'static str,
        /// The axis state.
        state: AxisState,
    },
    /// The axis is in ErrorStop, which only Reset leaves (PLCopen state diagram): the
    /// refusal names the error that put it there.
    #[error(
        "{command} is refused: the axis is in ErrorStop ({cause}); only Reset leaves ErrorStop"
    )]
    InErrorStop {
        /// Command name.
        command: &'static str,
        /// Why the axis is in ErrorStop.
        cause: FaultSummary,
    },
    /// Target position monitoring: the actual position did not settle in the target window
    /// within the timeout after the set value reached the target.
    #[error(
        "{command}: the actual position {actual} did not stay within ±{window} of the target \
         {target} for the dwell time within {timeout_s} s after the set value reached it"
    )]
    TargetNotReached {
        /// Command name.
        command: &'static str,
        /// The target (units, axis frame; wrapped on modulo axes).
        target: f64,
        /// The actual position when the timeout expired (same frame).
        actual: f64,
        /// The target window (units).
        window: f64,
        /// The timeout (s).
        timeout_s: f64,
    },
    /// The command needs a homed axis.
    #[error(
        "{command}: the axis is not homed (home it, set an absolute position or mark it homed)"
    )]
    NotHomed {
        /// Command name.
        command: &'static str,
    },
    /// The axis kind takes no such command (external and shadow axes are never commanded;
    /// they take SetPosition and, for an encoder's failure, Reset).
    #[error("{command}: the axis is of type {kind}, which takes no motion or power commands")]
    NotCommandable {
        /// Command name.
        command: &'static str,
        /// Axis kind name.
        kind: &'static str,
    },
    /// No move is running that the command could change.
    #[error("{command}: no move of the right kind is running")]
    NothingToChange {
        /// Command name.
        command: &'static str,
    },
    /// Too many commands are waiting (buffered) on this axis.
    #[error("{command}: the axis' buffer of {capacity} waiting moves is full")]
    QueueFull {
        /// Command name.
        command: &'static str,
        /// Queue capacity.
        capacity: usize,
    },
    /// The profile planner failed.
    #[error("{command}: planning failed: {error}")]
    Plan {
        /// Command name.
        command: &'static str,
        /// The planner's error.
        error: PlanError,
    },
    /// A homing run failed (distance exceeded, switch not found, limit switch).
    #[error(transparent)]
    Homing(#[from] crate::homing::HomingError),
    /// A homing parameter is out of range or the combination is not possible.
    #[error("{command}: parameter {parameter} = {value} {problem}")]
    HomingParameter {
        /// Command name.
        command: &'static str,
        /// Which parameter.
        parameter: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        problem: &'static str,
    },
    /// A homing run on an axis whose switches and encoder the kernel does not see
    /// (simulated and virtual axes have no feedback): it could never find a reference.
    #[error(
        "{command}: a {kind} axis has no switches or encoder to home on; use MoveHome.SetReference"
    )]
    NothingToHomeOn {
        /// Command name.
        command: &'static str,
        /// The axis kind.
        kind: &'static str,
    },
    /// A hardware limit switch stopped the axis while the command ran.
    #[error("{command}: stopped by the {side}")]
    LimitSwitch {
        /// Command name.
        command: &'static str,
        /// Which switch.
        side: crate::homing::LimitSide,
    },
    /// The move would go towards an active hardware limit switch: only moves away from it
    /// are allowed until the axis has left it.
    #[error("{command}: the {side} is active; only moves away from it are allowed")]
    TowardsLimitSwitch {
        /// Command name.
        command: &'static str,
        /// Which switch.
        side: crate::homing::LimitSide,
    },
    /// The command was accepted but the axis went to ErrorStop while it ran.
    #[error("the axis went to ErrorStop while {command} ran")]
    AxisFault {
        /// Command name.
        command: &'static str,
    },
    /// A synchronised-motion command names a master that is missing, is the follower
    /// itself, or follows the follower (directly or through others): the relations would
    /// go round in a loop.
    #[error("{command}: axis {master} cannot be this axis' master ({why})")]
    BadMaster {
        /// Command name.
        command: &'static str,
        /// The master's index.
        master: usize,
        /// Why not.
        why: &'static str,
    },
    /// The master's values cannot be followed: its encoder or drive failed (it is in
    /// ErrorStop).
    #[error("{command}: master axis {master} is not available (its encoder or drive failed)")]
    MasterNotAvailable {
        /// Command name.
        command: &'static str,
        /// The master's index.
        master: usize,
    },
    /// CamIn names an empty cam table slot.
    #[error("{command}: no cam table in slot {table}")]
    NoSuchCamTable {
        /// Command name.
        command: &'static str,
        /// The slot given.
        table: usize,
    },
    /// A synchronised move cannot start from here.
    #[error("{command}: {why}")]
    CannotSynchronise {
        /// Command name.
        command: &'static str,
        /// Why not.
        why: &'static str,
    },
    /// GearOut or CamOut on an axis that does not follow a master that way.
    #[error("{command}: the axis is not {what}")]
    NotSynchronised {
        /// Command name.
        command: &'static str,
        /// "gearing" or "camming".
        what: &'static str,
    },
    /// A group command failed at its start (state, enable rules, a move's start checks).
    #[error(transparent)]
    Group(#[from] crate::group::GroupCommandError),
    /// A group move's path cannot be made or planned (the circular rules, the limits).
    #[error("{command}: {error}")]
    GroupPath {
        /// Function block name.
        command: &'static str,
        /// Why.
        error: GroupPathError,
    },
    /// A single-axis command on an axis its group moves.
    #[error("{command}: the axis moves with group {group}; stop the group first")]
    MovesWithGroup {
        /// Command name.
        command: &'static str,
        /// The group's index.
        group: usize,
    },
    /// No group with that index.
    #[error("no group with index {group}")]
    NoSuchGroup {
        /// The index given.
        group: usize,
    },
    /// No axis with that index.
    #[error("no axis with index {axis}")]
    NoSuchAxis {
        /// The index given.
        axis: usize,
    },
    /// Reset: the bus slave of the axis' drive did not return to operation (EtherCAT: AL
    /// state OP). Filled by the master, which knows the bus; the kernel only carries it.
    #[error(
        "Reset: bus slave {address:#06x} is not back in operation: {problem}{}",
        AlDetail(*.al_status, *.al_status_code, .code_text)
    )]
    SlaveNotOperational {
        /// The slave's station address.
        address: u16,
        /// What went wrong (refused, timed out, no answer).
        problem: &'static str,
        /// Its last AL status register (0 if it never answered).
        al_status: u16,
        /// Its AL status code (ETG.1000.6 Table 11).
        al_status_code: u16,
        /// The code's text.
        code_text: &'static str,
    },
    /// Reset: the drive did not return to operation, in the words of its bus (a CANopen
    /// node, say, that sent no boot-up after NMT reset communication). Filled by the
    /// master, which knows the bus; the kernel only carries it.
    #[error("Reset: the drive at bus position {position} ({unit} {id}) is not back in operation: {problem}")]
    DriveNotOperational {
        /// Its position on the bus (the configuration's drive index).
        position: u16,
        /// What the bus calls its devices ("CANopen node").
        unit: &'static str,
        /// Its address on the bus (a CANopen node id).
        id: u16,
        /// What went wrong, in the bus' terms.
        problem: &'static str,
    },
}

/// Why a group move's path cannot be made or planned.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum GroupPathError {
    /// The segment's geometry (MC_MoveCircular2D's rules, the circular axes).
    #[error(transparent)]
    Segment(#[from] crate::path::SegmentError),
    /// Its planning under the axes' limits.
    #[error(transparent)]
    Plan(#[from] crate::path::PathPlanError),
    /// A circular move on a modulo axis (Omron 544A).
    #[error("axis {axis} is a modulo axis: a circular move needs linear axes")]
    ModuloAxis {
        /// The axis' kernel index.
        axis: usize,
    },
}

/// The AL registers a slave last answered with, or nothing if it never did (both 0).
struct AlDetail<'a>(u16, u16, &'a str);

impl core::fmt::Display for AlDetail<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            AlDetail(0, 0, _) => Ok(()),
            AlDetail(status, code, text) => write!(
                f,
                " (AL status {status:#06x}, AL status code {code:#06x}: {text})"
            ),
        }
    }
}

impl CommandError {
    /// The command the error is about ("a command" where it names none).
    pub const fn command(&self) -> &'static str {
        match self {
            CommandError::OperandOutOfRange { command, .. }
            | CommandError::ModuloModeOnNormalAxis { command, .. }
            | CommandError::AbsNormalOnModuloAxis { command }
            | CommandError::OutsideSoftwareLimits { command, .. }
            | CommandError::DirectionNotAllowed { command, .. }
            | CommandError::NotAllowedInState { command, .. }
            | CommandError::InErrorStop { command, .. }
            | CommandError::TargetNotReached { command, .. }
            | CommandError::NotHomed { command }
            | CommandError::NotCommandable { command, .. }
            | CommandError::NothingToChange { command }
            | CommandError::QueueFull { command, .. }
            | CommandError::Plan { command, .. }
            | CommandError::HomingParameter { command, .. }
            | CommandError::LimitSwitch { command, .. }
            | CommandError::NothingToHomeOn { command, .. }
            | CommandError::TowardsLimitSwitch { command, .. }
            | CommandError::AxisFault { command }
            | CommandError::BadMaster { command, .. }
            | CommandError::MasterNotAvailable { command, .. }
            | CommandError::NoSuchCamTable { command, .. }
            | CommandError::CannotSynchronise { command, .. }
            | CommandError::NotSynchronised { command, .. }
            | CommandError::GroupPath { command, .. }
            | CommandError::MovesWithGroup { command, .. }
            | CommandError::LentToDrive { command, .. } => command,
            CommandError::Homing(e) => e.command(),
            CommandError::DriveProcedure(e) => e.procedure,
            CommandError::DriveResetFailed { .. }
            | CommandError::SlaveNotOperational { .. }
            | CommandError::DriveNotOperational { .. } => "Reset",
            CommandError::NoSuchAxis { .. } | CommandError::NoSuchGroup { .. } => "a command",
            CommandError::Group(_) => "a group command",
        }
    }

    /// Logix-style EXERR: the number of the offending operand (first after the axis = 1),
    /// or 0 where the error is not about one operand.
    pub const fn operand_number(&self) -> u8 {
        match self {
            CommandError::OperandOutOfRange { operand, .. } => match operand {
                Operand::Mode | Operand::Direction => 1,
                Operand::Target | Operand::Position => 2,
                Operand::Speed => 3,
                Operand::Acceleration => 4,
                Operand::Deceleration => 5,
                Operand::Jerk => 6,
                Operand::DecelJerk => 7,
                Operand::TargetWindow => 8,
                Operand::Ratio => 2,
                Operand::Scaling | Operand::Offset => 3,
                Operand::SyncPosition => 3,
                Operand::StartDistance => 4,
            },
            CommandError::ModuloModeOnNormalAxis { .. }
            | CommandError::AbsNormalOnModuloAxis { .. } => 1,
            CommandError::OutsideSoftwareLimits { .. } => 2,
            _ => 0,
        }
    }
}

/// Checks that `value` is finite and > 0 and at most `max`.
pub(crate) fn positive(
    command: &'static str,
    operand: Operand,
    value: f64,
    max: f64,
) -> Result<f64, CommandError> {
    let problem = if !value.is_finite() {
        RangeProblem::NotFinite
    } else if value <= 0.0 {
        RangeProblem::NotPositive
    } else if value > max * (1.0 + 1e-12) {
        RangeProblem::AboveAxisMax
    } else {
        return Ok(value.min(max));
    };
    Err(CommandError::OperandOutOfRange {
        command,
        operand,
        value,
        problem,
        limit: max,
    })
}

/// Checks that `value` is finite.
pub(crate) fn finite(
    command: &'static str,
    operand: Operand,
    value: f64,
) -> Result<f64, CommandError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(CommandError::OperandOutOfRange {
            command,
            operand,
            value,
            problem: RangeProblem::NotFinite,
            limit: f64::NAN,
        })
    }
}

/// Checks that a position or distance is finite and within ±[`MAX_POSITION`].
pub(crate) fn position(
    command: &'static str,
    operand: Operand,
    value: f64,
) -> Result<f64, CommandError> {
    let v = finite(command, operand, value)?;
    if v.abs() > MAX_POSITION {
        return Err(CommandError::OperandOutOfRange {
            command,
            operand,
            value,
            problem: RangeProblem::BeyondPositionRange,
            limit: MAX_POSITION,
        });
    }
    Ok(v)
}

/// Checks that `value` is finite and ≥ 0.
pub(crate) fn non_negative(
    command: &'static str,
    operand: Operand,
    value: f64,
) -> Result<f64, CommandError> {
    let v = finite(command, operand, value)?;
    if v < 0.0 {
        return Err(CommandError::OperandOutOfRange {
            command,
            operand,
            value,
            problem: RangeProblem::Negative,
            limit: 0.0,
        });
    }
    Ok(v)
}

/// Converts a rate given in `units` to units/s^n: percent of `max` or as is.
pub(crate) fn rate(
    command: &'static str,
    operand: Operand,
    value: f64,
    units: RateUnits,
    max: f64,
) -> Result<f64, CommandError> {
    match units {
        RateUnits::PerSecond => positive(command, operand, value, max),
        RateUnits::PercentOfMax => percent(command, operand, value).map(|p| p / 100.0 * max),
    }
}

/// Checks a percentage in (0, 100].
pub(crate) fn percent(
    command: &'static str,
    operand: Operand,
    value: f64,
) -> Result<f64, CommandError> {
    if value.is_finite() && value > 0.0 && value <= 100.0 {
        Ok(value)
    } else {
        Err(CommandError::OperandOutOfRange {
            command,
            operand,
            value,
            problem: if value.is_finite() {
                RangeProblem::PercentOutOfRange
            } else {
                RangeProblem::NotFinite
            },
            limit: 100.0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positive_names_operand_and_problem() {
        let e = positive("MovePtp", Operand::Speed, -1.0, 10.0).unwrap_err();
        assert_eq!(e.operand_number(), 3);
        assert_eq!(
            e.to_string(),
            "MovePtp: operand speed = -1 must be > 0 (limit 10)"
        );
        assert!(matches!(
            positive("MovePtp", Operand::Speed, f64::NAN, 10.0),
            Err(CommandError::OperandOutOfRange {
                problem: RangeProblem::NotFinite,
                ..
            })
        ));
        assert!(matches!(
            positive("MovePtp", Operand::Speed, 11.0, 10.0),
            Err(CommandError::OperandOutOfRange {
                problem: RangeProblem::AboveAxisMax,
                ..
            })
        ));
        assert_eq!(positive("MovePtp", Operand::Speed, 10.0, 10.0), Ok(10.0));
    }

    #[test]
    fn percent_rates_scale_the_axis_maximum() {
        assert_eq!(
            rate("Jog", Operand::Speed, 50.0, RateUnits::PercentOfMax, 200.0),
            Ok(100.0)
        );
        assert!(rate("Jog", Operand::Speed, 150.0, RateUnits::PercentOfMax, 200.0).is_err());
        assert!(rate("Jog", Operand::Speed, 0.0, RateUnits::PercentOfMax, 200.0).is_err());
    }
}
