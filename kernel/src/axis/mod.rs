//! One axis: its configuration, PLCopen state, set-value source and status.
//!
//! Commands are applied between cycles ([`Axis::apply`], in `apply/`, one module per command family) and plan from the
//! last set values, so a new move continues the old one without a jump; [`Axis::step`]
//! samples the running profile at the cycle's time, chains buffered moves inside the
//! cycle (no standstill cycle between them) and derives the status.

pub mod command;
mod follow;
pub mod handle;
pub mod lend;
pub mod motion;
pub mod state;
pub mod status;

pub(crate) mod apply;

use crate::mechanics::{Direction, Mechanics};
use crate::profile::{KinematicState, Limits, RampType};
use command::{BufferMode, CommandError, RampBreakMode};
use handle::{CommandStatus, HandleTable};
use motion::{Motion, MotionKind, Queue};
use state::{AxisState, Event};
use status::{AxisFault, AxisStatus, SlopeState, StatusBits};

/// What kind of axis (seed 000 §2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AxisKind {
    /// A drive on the bus: set values out, actual values in.
    Real,
    /// Configured like a real axis but not connected: actual = set.
    Simulated,
    /// No drive, a pure set-value generator (master for gearing/camming).
    Virtual,
    /// Encoder only: never enabled, never commanded; actual values in.
    External,
    /// Mirrors set and actual values of the axis with index `source`.
    Shadow {
        /// Index of the mirrored axis in the kernel.
        source: usize,
    },
}

impl AxisKind {
    /// Name for messages and configuration.
    pub const fn name(self) -> &'static str {
        match self {
            AxisKind::Real => "real",
            AxisKind::Simulated => "simulated",
            AxisKind::Virtual => "virtual",
            AxisKind::External => "external",
            AxisKind::Shadow { .. } => "shadow",
        }
    }

    /// Whether the axis takes motion and power commands.
    pub const fn is_commandable(self) -> bool {
        matches!(
            self,
            AxisKind::Real | AxisKind::Simulated | AxisKind::Virtual
        )
    }

    /// Whether the actual values come from the bus.
    pub const fn has_feedback(self) -> bool {
        matches!(
            self,
            AxisKind::Real | AxisKind::External | AxisKind::Shadow { .. }
        )
    }
}

/// Default dynamics of an axis' moves (used when a command leaves an operand out).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dynamics {
    /// Speed (units/s).
    pub speed: f64,
    /// Acceleration (units/s²).
    pub acceleration: f64,
    /// Deceleration (units/s²).
    pub deceleration: f64,
    /// Jerk (units/s³).
    pub jerk: f64,
    /// Ramp type.
    pub ramp: RampType,
    /// Target window (units).
    pub target_window: f64,
}

/// Target position monitoring (TwinCAT's "Target Position Monitoring" with its "In-Target
/// Timeout"): a positioning move (MovePtp) is Done only once the actual position has stayed
/// inside the move's target window for `dwell_s` after the set value reached the target;
/// when that has not happened `timeout_s` after the set value reached the target, the move
/// ends in Error and the axis in ErrorStop, naming the position, the window and the time.
///
/// The window is the move's TargetWindow (default: [`Dynamics::target_window`]). Halt and
/// Stop are not monitored (PLCopen: they are Done at zero velocity). Blending moves take
/// over when the set value reaches the target, as without monitoring; a Buffered move
/// starts when the previous one is Done (PLCopen), so now once it is in position. Axes
/// without feedback (simulated, virtual) have nothing to monitor: their actual is their set
/// value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TargetMonitoring {
    /// Whether positioning moves wait for the actual position (default: on for real axes).
    pub enabled: bool,
    /// How long the actual must stay in the window without a break (s, ≥ 0).
    pub dwell_s: f64,
    /// How long after the set value reached the target the actual may take (s, > dwell).
    pub timeout_s: f64,
}

impl TargetMonitoring {
    /// Default dwell: 20 ms.
    pub const DEFAULT_DWELL_S: f64 = 0.02;
    /// Default timeout: 5 s.
    pub const DEFAULT_TIMEOUT_S: f64 = 5.0;

    /// The defaults, on or off.
    pub const fn new(enabled: bool) -> Self {
        Self {
            enabled,
            dwell_s: Self::DEFAULT_DWELL_S,
            timeout_s: Self::DEFAULT_TIMEOUT_S,
        }
    }
}

/// Configuration of one axis.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisConfig {
    /// Name (e.g. "x").
    pub name: String,
    /// Kind.
    pub kind: AxisKind,
    /// Mechanics: modulo, allowed direction, software limits.
    pub mechanics: Mechanics,
    /// Maximum speed, acceleration, deceleration and jerk the axis may ever be commanded.
    pub max: Limits,
    /// Defaults for moves that leave operands out.
    pub defaults: Dynamics,
    /// Deceleration of QuickStop (units/s²).
    pub quick_stop_deceleration: f64,
    /// What a new MovePtp does during the deceleration ramp.
    pub ramp_break: RampBreakMode,
    /// Whether absolute moves need a homed axis.
    pub homing_required: bool,
    /// Position restored at power-up (e.g. stored encoder value × scaling); not homed.
    pub initial_position: f64,
    /// When a positioning move is Done: in position (on for real axes) or when its set
    /// value reaches the target.
    pub target_monitoring: TargetMonitoring,
    /// Saved MoveHome parameters (seed 000 §5.2.6.2: the axis' parameter file, loaded at
    /// start); a MoveHome call leaves out what it keeps. `None`: [`MoveHome::defaults`]
    /// from the axis maxima.
    ///
    /// [`MoveHome::defaults`]: crate::homing::MoveHome::defaults
    pub move_home: Option<crate::homing::MoveHome>,
    /// The drive layer can latch a limit switch's edges with the touch probe (it routes
    /// the probe to [`AxisSetpoint::probe_on_limit`]). Without it a homing run that looks
    /// for a limit switch's edge (MoveHome with `LimitSwitch`) is refused: the latches
    /// would be another switch's. On in [`AxisConfig::new`]; the master turns it off
    /// unless the drive's touch-probe source (0x60D0) is configured.
    pub limit_edges_latched: bool,
    /// The touch probe latches the reference switch's edges (the switch is wired to the
    /// drive's probe input). Without it a homing run that looks for the reference
    /// switch's edge is refused. On in [`AxisConfig::new`]; the master turns it off for a
    /// reference switch read from an I/O module.
    pub reference_edges_latched: bool,
    /// What a follower does when its master asks more than its limits allow.
    pub sync_limit_reaction: SyncLimitReaction,
}

/// What a follower does when its master asks more than the follower's own speed,
/// acceleration, deceleration or direction allow (never a silent limit violation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SyncLimitReaction {
    /// Go to ErrorStop (the reason names the quantity) and brake with the maximum
    /// deceleration from the last set values that kept the limits.
    #[default]
    ErrorStop,
    /// Go on following and raise `sync_limit_exceeded` in the status every cycle it
    /// happens (for machines whose drives take more than the configured limits).
    Warning,
}

impl SyncLimitReaction {
    /// Name for configuration and messages.
    pub const fn name(self) -> &'static str {
        match self {
            SyncLimitReaction::ErrorStop => "errorstop",
            SyncLimitReaction::Warning => "warning",
        }
    }
}

impl AxisConfig {
    /// A linear axis with generous defaults: vmax 100, amax/dmax 1000, jmax 10000 units,
    /// S-curve, no modulo, no software limits, homing required for absolute moves.
    pub fn new(name: &str, kind: AxisKind) -> Self {
        let max = Limits {
            vmax: 100.0,
            amax: 1000.0,
            dmax: 1000.0,
            jmax: 10_000.0,
        };
        Self {
            name: name.to_string(),
            kind,
            mechanics: Mechanics::default(),
            max,
            defaults: Dynamics {
                speed: max.vmax,
                acceleration: max.amax,
                deceleration: max.dmax,
                jerk: max.jmax,
                ramp: RampType::SCurve,
                target_window: 0.01,
            },
            quick_stop_deceleration: max.dmax,
            ramp_break: RampBreakMode::None,
            homing_required: !matches!(kind, AxisKind::Virtual),
            initial_position: 0.0,
            target_monitoring: TargetMonitoring::new(matches!(kind, AxisKind::Real)),
            move_home: None,
            limit_edges_latched: true,
            reference_edges_latched: true,
            sync_limit_reaction: SyncLimitReaction::ErrorStop,
        }
    }

    /// Checks the configuration; the error names the axis and the field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let name = &self.name;
        let pos = |field: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ConfigError::NotPositive {
                    axis: name.clone(),
                    field,
                    value: v,
                })
            }
        };
        pos("max.speed", self.max.vmax)?;
        pos("max.acceleration", self.max.amax)?;
        pos("max.deceleration", self.max.dmax)?;
        pos("max.jerk", self.max.jmax)?;
        pos("defaults.speed", self.defaults.speed)?;
        pos("defaults.acceleration", self.defaults.acceleration)?;
        pos("defaults.deceleration", self.defaults.deceleration)?;
        pos("defaults.jerk", self.defaults.jerk)?;
        pos("quick_stop_deceleration", self.quick_stop_deceleration)?;
        let over = |field: &'static str, v: f64, max: f64| {
            if v <= max {
                Ok(())
            } else {
                Err(ConfigError::AboveMax {
                    axis: name.clone(),
                    field,
                    value: v,
                    max,
                })
            }
        };
        over("defaults.speed", self.defaults.speed, self.max.vmax)?;
        over(
            "defaults.acceleration",
            self.defaults.acceleration,
            self.max.amax,
        )?;
        over(
            "defaults.deceleration",
            self.defaults.deceleration,
            self.max.dmax,
        )?;
        over("defaults.jerk", self.defaults.jerk, self.max.jmax)?;
        if !(self.defaults.target_window.is_finite() && self.defaults.target_window >= 0.0) {
            return Err(ConfigError::NotPositive {
                axis: name.clone(),
                field: "defaults.target_window",
                value: self.defaults.target_window,
            });
        }
        let tm = self.target_monitoring;
        if !(tm.dwell_s.is_finite()
            && tm.dwell_s >= 0.0
            && tm.timeout_s.is_finite()
            && tm.timeout_s > tm.dwell_s)
        {
            return Err(ConfigError::TargetMonitoring {
                axis: name.clone(),
                dwell_s: tm.dwell_s,
                timeout_s: tm.timeout_s,
            });
        }
        if !self.initial_position.is_finite() {
            return Err(ConfigError::NotPositive {
                axis: name.clone(),
                field: "initial_position",
                value: self.initial_position,
            });
        }
        self.mechanics
            .validate()
            .map_err(|source| ConfigError::Mechanics {
                axis: name.clone(),
                source,
            })
    }
}

/// A configuration mistake; names the axis and the field.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum ConfigError {
    /// A value must be a finite number > 0.
    #[error("axis {axis}: {field} = {value} must be a finite number > 0")]
    NotPositive {
        /// Axis name.
        axis: String,
        /// Field.
        field: &'static str,
        /// Value.
        value: f64,
    },
    /// A default exceeds the axis maximum.
    #[error("axis {axis}: {field} = {value} exceeds the axis maximum {max}")]
    AboveMax {
        /// Axis name.
        axis: String,
        /// Field.
        field: &'static str,
        /// Value.
        value: f64,
        /// Maximum.
        max: f64,
    },
    /// The mechanics are inconsistent.
    #[error("axis {axis}: {source}")]
    Mechanics {
        /// Axis name.
        axis: String,
        /// What is wrong.
        source: crate::mechanics::MechanicsError,
    },
    /// Two axes have the same name.
    #[error("axis name {axis} is used twice")]
    DuplicateName {
        /// Axis name.
        axis: String,
    },
    /// A shadow axis names a missing axis or another shadow axis.
    #[error("shadow axis {axis}: source index {source_index} is not a non-shadow axis")]
    BadShadowSource {
        /// Axis name.
        axis: String,
        /// The index given.
        source_index: usize,
    },
    /// The target monitoring times are not a dwell ≥ 0 below a finite timeout.
    #[error(
        "axis {axis}: dwell_s = {dwell_s} and timeout_s = {timeout_s} of target_monitoring \
         must be finite with 0 <= dwell_s < timeout_s"
    )]
    TargetMonitoring {
        /// Axis name.
        axis: String,
        /// Dwell given (s).
        dwell_s: f64,
        /// Timeout given (s).
        timeout_s: f64,
    },
    /// The cycle time is out of range.
    #[error("cycle time {cycle_s} s is not in [50 µs, 100 ms]")]
    CycleTime {
        /// The value given.
        cycle_s: f64,
    },
}

/// Actual values of one axis from the bus (ignored for simulated and virtual axes).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisFeedback {
    /// Actual position (units; wrapped on modulo axes).
    pub position: f64,
    /// Actual velocity (units/s).
    pub velocity: f64,
    /// The drive is in Operation enabled.
    pub operation_enabled: bool,
    /// The drive reports a fault with this error code.
    pub fault: Option<u16>,
    /// Limit and reference switches, resolved to "active" below (0x60FD or an I/O module).
    pub switches: crate::homing::SwitchInputs,
    /// Touch-probe latches (drive frame, like `position`).
    pub probe: crate::homing::ProbeLatches,
}

/// What one cycle of target position monitoring found.
enum SettleStep {
    /// Not yet in position: go on holding the target.
    Waiting(motion::Settle),
    /// In position; `late`: not in the cycle the set value reached the target.
    Settled {
        /// The move stood at its target for at least one cycle.
        late: bool,
    },
    /// The timeout expired with the actual here.
    TimedOut {
        /// Actual position (axis frame).
        actual: f64,
    },
}

/// What an axis' step may take its set values from besides its own motion: its master's
/// values (a gear, a cam), its group's path, the cam tables.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sources<'a> {
    /// The master's values this cycle, if the axis follows one.
    pub master: Option<&'a crate::sync::MasterSample>,
    /// Its group's set values this cycle, if a group moves it.
    pub path: Option<&'a PathSample>,
    /// The kernel's cam tables.
    pub cams: &'a [Option<crate::cam::CamTable>],
}

/// An axis' set values from its group for one cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PathSample {
    /// The set values.
    pub set: KinematicState,
    /// The group's path ends with this cycle: the axis stands from it on.
    pub last: bool,
}

/// Cycles a Reset waits for the drive to clear its fault before it reports failure.
pub const DRIVE_RESET_TICKS: u64 = 1000;

/// Set values of one axis for the drive layer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisSetpoint {
    /// Set position in the drive's frame (units: the axis' set position minus its
    /// SetPosition offset; wrapped into the period on modulo axes).
    pub position: f64,
    /// Whole modulo periods of that drive-frame position, so the drive layer can count
    /// `turns · period + position` exactly (0 on normal axes). They can differ by one from
    /// the axis' own turns ([`AxisStatus::turns`]) when an offset is set.
    pub turns: i64,
    /// Set velocity (units/s), for velocity feed-forward.
    pub velocity: f64,
    /// Set acceleration (units/s²).
    pub acceleration: f64,
    /// Whether the drive should be enabled.
    pub enable: bool,
    /// A Reset asks the drive to clear its fault (the drive layer sends the fault reset).
    pub reset_fault: bool,
    /// A homing run looks for this limit switch's edge: the drive layer routes the touch
    /// probe to it (CiA 402 0x60D0) until the run ends, so the rising and falling latches
    /// are that switch's. `None`: the probe on the reference switch.
    pub probe_on_limit: Option<crate::homing::LimitSide>,
}

/// One axis.
#[derive(Clone, Debug)]
pub struct Axis {
    cfg: AxisConfig,
    state: AxisState,
    /// Power requested on.
    powered: bool,
    homed: bool,
    /// Set values of the axis' own motion (without a superimposed jog), in the frame.
    main: KinematicState,
    /// The running source; `None` holds `main.p`.
    motion: Option<Motion>,
    /// A jog superimposed on the running motion (MAJ with Merge disabled).
    overlay: Option<Motion>,
    /// Set values of the overlay (relative displacement and its derivatives).
    overlay_set: KinematicState,
    queue: Queue,
    /// Whole periods subtracted from the frame on modulo axes.
    frame_turns: i64,
    /// Last PTP target in the frame (for RelTarget and target window).
    last_target: Option<f64>,
    last_window: f64,
    /// Direction of the last move (for AbsModuloKeepDirection).
    last_direction: f64,
    /// Last-used PTP and velocity dynamics (Jetter: commands without operands use them).
    ptp_dynamics: Dynamics,
    vel_dynamics: Dynamics,
    /// Release arrived while Stop was still decelerating.
    release_pending: bool,
    /// Handle of a pending Power.Enable on a real axis (waits for the drive).
    enable_handle: Option<handle::HandleId>,
    /// A Reset waiting for the drive to clear its fault: handle and the tick it began.
    reset_pending: Option<(handle::HandleId, u64)>,
    /// The drive reported a fault in the last feedback.
    drive_fault: bool,
    /// Whether the drive reported Operation enabled in the last feedback (None: the axis
    /// has had no drive feedback, e.g. stepped without a drive).
    drive_enabled: Option<bool>,
    /// Axis position minus drive position (SetPosition on a real axis moves no motor).
    position_offset: f64,
    actual_p: f64,
    actual_v: f64,
    last_tick: u64,
    status: AxisStatus,
    /// State changes the table refused (a bug if ever non-zero; see [`Axis::enter`]).
    refused_transitions: u64,
    /// Switches seen this cycle (none on axes without feedback).
    switches: crate::homing::SwitchInputs,
    /// Touch-probe latches this cycle, in the axis frame.
    latches: crate::homing::ProbeLatches,
    /// The running homing run and its handle.
    homing: Option<(crate::homing::sequence::Sequencer, handle::HandleId)>,
    /// Homing parameters for homing moves (acceleration, deceleration, jerk, approach speed).
    homing_dynamics: HomingDynamics,
    /// Status bits of the last homing run.
    home_status: crate::homing::HomingStatus,
    /// MoveHome parameters last used (a call leaves out what it keeps).
    move_home: crate::homing::MoveHome,
    /// The drive runs a procedure by itself (see [`lend`]): its handle and what it is.
    lent: Option<lend::Lent>,
    /// The lending ended since the last cycle: the set position takes the drive's actual
    /// position once more (the drive may have moved since the last feedback).
    rejoin: bool,
    /// The master relation that produces the set values (gear, cam); while it runs
    /// `motion` is `None`.
    follow: Option<crate::sync::Follow>,
    /// Status bits of the relation this cycle (in sync, end of profile, limit exceeded).
    sync_bits: follow::SyncBits,
    /// The group whose path drives the set values (a group move or its braking).
    group: Option<usize>,
    /// The axis' group is enabled (Omron Status.Coordinated).
    coordinated: bool,
}

/// Dynamics of the moves of a homing run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct HomingDynamics {
    /// Acceleration (units/s²).
    pub acceleration: f64,
    /// Deceleration (units/s²).
    pub deceleration: f64,
    /// Jerk (units/s³).
    pub jerk: f64,
    /// Speed of the final positioning (units/s).
    pub speed: f64,
}

impl Axis {
    /// A new axis at its configured initial position, disabled and not homed.
    pub fn new(cfg: AxisConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let p0 = cfg.initial_position;
        let mut axis = Self {
            state: AxisState::Disabled,
            powered: false,
            homed: false,
            main: KinematicState::at_rest(p0),
            motion: None,
            overlay: None,
            overlay_set: KinematicState::default(),
            queue: Queue::default(),
            frame_turns: 0,
            last_target: None,
            last_window: cfg.defaults.target_window,
            last_direction: 1.0,
            ptp_dynamics: cfg.defaults,
            vel_dynamics: cfg.defaults,
            release_pending: false,
            enable_handle: None,
            reset_pending: None,
            drive_fault: false,
            drive_enabled: None,
            position_offset: 0.0,
            actual_p: p0,
            actual_v: 0.0,
            last_tick: 0,
            status: AxisStatus::default(),
            refused_transitions: 0,
            switches: crate::homing::SwitchInputs::default(),
            latches: crate::homing::ProbeLatches::default(),
            homing: None,
            homing_dynamics: HomingDynamics {
                acceleration: cfg.max.amax,
                deceleration: cfg.max.dmax,
                jerk: cfg.max.jmax,
                speed: cfg.max.vmax,
            },
            home_status: crate::homing::HomingStatus::default(),
            move_home: cfg.move_home.unwrap_or_else(|| {
                crate::homing::MoveHome::defaults(cfg.max.vmax, cfg.max.amax, cfg.max.jmax)
            }),
            lent: None,
            rejoin: false,
            follow: None,
            sync_bits: follow::SyncBits::default(),
            group: None,
            coordinated: false,
            cfg,
        };
        axis.normalise_frame();
        axis.actual_p = axis.main.p;
        axis.refresh_status();
        Ok(axis)
    }

    /// The configuration.
    pub fn config(&self) -> &AxisConfig {
        &self.cfg
    }

    /// The name.
    pub fn name(&self) -> &str {
        &self.cfg.name
    }

    /// The MoveHome parameters a call without parameters uses (the last used, or the
    /// saved ones): what the master persists per axis (seed 000 §5.2.6.2).
    pub fn move_home_parameters(&self) -> &crate::homing::MoveHome {
        &self.move_home
    }

    /// The status after the last cycle.
    pub fn status(&self) -> &AxisStatus {
        &self.status
    }

    /// PLCopen state.
    pub fn state(&self) -> AxisState {
        self.state
    }

    /// State changes the state table refused since the axis was made: 0 unless the
    /// kernel tried a transition PLCopen's diagram does not have (a kernel bug).
    pub fn refused_transitions(&self) -> u64 {
        self.refused_transitions
    }

    /// Changes the state by applying `event` through the table ([`AxisState::on`]), the
    /// only way the state changes. A transition the table does not list is refused: the
    /// state stays, the refusal is counted, and debug builds stop on it (the RT path never
    /// panics in release). Returns whether the transition was taken.
    fn enter(&mut self, event: Event) -> bool {
        match self.state.on(event) {
            Some(next) => {
                self.state = next;
                true
            }
            None => {
                debug_assert!(
                    false,
                    "axis {}: PLCopen has no transition from {:?} on {:?}",
                    self.cfg.name, self.state, event
                );
                self.refused_transitions = self.refused_transitions.saturating_add(1);
                false
            }
        }
    }

    /// Why the axis is in ErrorStop.
    fn error_summary(&self) -> status::FaultSummary {
        self.status
            .error
            .map_or(status::FaultSummary::Unknown, |f| f.summary())
    }

    fn period(&self) -> Option<f64> {
        self.cfg.mechanics.modulo.map(|m| m.period())
    }

    /// Moves whole periods out of the frame so positions stay small on modulo axes.
    fn normalise_frame(&mut self) {
        let Some(period) = self.period() else { return };
        let n = (self.main.p / period).floor();
        if n == 0.0 || !n.is_finite() {
            return;
        }
        let shift = n * period;
        self.main.p -= shift;
        self.actual_p -= shift;
        self.frame_turns = self.frame_turns.saturating_add(n as i64);
        if let Some(t) = self.last_target.as_mut() {
            *t -= shift;
        }
        if let Some(m) = self.motion.as_mut() {
            m.profile.shift(-shift);
            if let MotionKind::Ptp { target, .. } | MotionKind::Halt { target } = &mut m.kind {
                *target -= shift;
            }
        }
    }

    /// Runs one cycle: `now` is the cycle index, `dt` the cycle time (s).
    pub(crate) fn step(
        &mut self,
        now: u64,
        dt: f64,
        fb: &AxisFeedback,
        from: &Sources<'_>,
        handles: &mut HandleTable,
    ) -> AxisSetpoint {
        let (master, path, cams) = (from.master, from.path, from.cams);
        self.last_tick = now;
        self.sync_bits = follow::SyncBits::default();
        if self.cfg.kind.has_feedback() {
            self.take_switches(fb);
            self.take_feedback(fb, handles);
            self.track_lent_drive();
        }
        match (self.follow.is_some(), master) {
            _ if self.group.is_some() => self.group_step(path),
            (true, Some(m)) => self.follow_step(m, cams, now, dt, handles),
            // An encoder's or a shadow's set values are what it reads.
            _ if !self.cfg.kind.is_commandable() => {}
            _ => self.advance(now, dt, handles),
        }
        if let Some(o) = self.overlay {
            self.overlay_set = o.sample(now, dt);
        }
        self.check_software_limits(handles);
        self.check_limit_switches(handles);
        self.run_homing(now, dt, handles);
        if !self.cfg.kind.has_feedback() {
            self.actual_p = self.main.p + self.overlay_set.p;
            self.actual_v = self.main.v + self.overlay_set.v;
        }
        if self.motion.is_none()
            && self.overlay.is_none()
            && self.follow.is_none()
            && self.group.is_none()
        {
            self.normalise_frame();
        }
        self.refresh_status();
        let (drive_position, drive_turns) = self.drive_set_position();
        AxisSetpoint {
            position: drive_position,
            turns: drive_turns,
            velocity: self.status.set.v,
            acceleration: self.status.set.a,
            enable: self.powered,
            reset_fault: self.reset_pending.is_some(),
            probe_on_limit: self
                .homing
                .as_ref()
                .and_then(|(seq, _)| seq.plan().latched_limit()),
        }
    }

    /// The set position in the drive's frame (the axis frame minus the SetPosition
    /// offset): on modulo axes the position within the period and the whole periods *of
    /// that position*, so that `turns · period + position` is the drive's unwrapped set
    /// position. The axis' own turns would be off by one whenever the offset carries the
    /// drive position across a period boundary the axis position has not crossed (axis at
    /// 10° with an offset of 20°: the drive stands at −10° = 350° one period lower), and
    /// the drive layer, which counts `turns` exactly, would step a full period.
    fn drive_set_position(&self) -> (f64, i64) {
        let set = self.status.set.p;
        match self.period() {
            None => (set - self.position_offset, 0),
            Some(_) if self.position_offset == 0.0 => (set, self.status.turns),
            Some(period) => {
                // `set` is in [0, period); the offset may be many periods (SetPositions add up).
                let x = set - self.position_offset;
                let n = (x / period).floor();
                let mut w = x - n * period;
                let mut n = n as i64;
                if w >= period {
                    w -= period;
                    n += 1;
                }
                if w < 0.0 {
                    w += period;
                    n -= 1;
                    if w >= period {
                        w = 0.0;
                        n += 1;
                    }
                }
                (w + 0.0, self.status.turns.saturating_add(n))
            }
        }
    }

    fn take_feedback(&mut self, fb: &AxisFeedback, handles: &mut HandleTable) {
        let p = fb.position + self.position_offset;
        self.actual_p = match self.cfg.mechanics.modulo {
            Some(m) => m.follow(self.main.p, p),
            None => p,
        };
        self.actual_v = fb.velocity;
        if matches!(self.cfg.kind, AxisKind::External | AxisKind::Shadow { .. }) {
            self.main = KinematicState::at_rest(self.actual_p);
            self.main.v = fb.velocity;
            if self.cfg.kind == AxisKind::External {
                self.take_encoder_fault(fb, handles);
            }
            return;
        }
        self.drive_fault = fb.fault.is_some();
        self.drive_enabled = Some(fb.operation_enabled);
        if let Some((h, since)) = self.reset_pending {
            if fb.fault.is_none() {
                // The drive cleared its fault and dropped power: the axis is Disabled
                // until enabled again.
                self.reset_pending = None;
                self.powered = false;
                self.enter(Event::Reset { powered: false });
                self.status.error = None;
                handles.set(h, CommandStatus::Done);
            } else if self.last_tick.saturating_sub(since) > DRIVE_RESET_TICKS {
                self.reset_pending = None;
                handles.set(
                    h,
                    CommandStatus::Error(CommandError::DriveResetFailed {
                        code: fb.fault.unwrap_or(0),
                    }),
                );
            }
        }
        if let Some(code) = fb.fault {
            if self.state != AxisState::ErrorStop {
                self.fault(AxisFault::Drive { code }, handles);
            }
            // A faulted drive is not driven: the set value follows the actual.
            self.motion = None;
            self.main = KinematicState::at_rest(self.actual_p);
        }
        if !self.powered && self.motion.is_none() {
            // Nor is one that is off (pushed by hand, say): its set value is where it is.
            self.main = KinematicState::at_rest(self.actual_p);
        }
        if let Some(h) = self.enable_handle {
            if fb.operation_enabled {
                handles.set(h, CommandStatus::Done);
                self.enable_handle = None;
                self.enter(Event::PoweredOn);
                // Take over where the drive stands now: the first set value the enabled
                // drive receives must be its actual position, or it would jump.
                self.main = KinematicState::at_rest(self.actual_p);
            }
        }
    }

    /// Samples the running motion, ending it (and starting the next queued move inside
    /// the same cycle) when its profile is over.
    fn advance(&mut self, now: u64, dt: f64, handles: &mut HandleTable) {
        // Each pass either samples or retires one motion; the queue bounds the passes.
        for _ in 0..=motion::QUEUE_CAPACITY + 1 {
            let Some(m) = self.motion else {
                self.main.v = 0.0;
                self.main.a = 0.0;
                self.main.j = 0.0;
                return;
            };
            let ended = m.ended(now, dt);
            let next_waits = !self.queue.is_empty();
            if !ended || (!m.kind.is_finite() && !next_waits) {
                self.main = m.sample(now, dt);
                if ended && m.kind.is_continuous() {
                    self.reanchor_continuous(now, dt);
                }
                return;
            }
            // Target position monitoring: a PTP whose set value stands at the target is
            // Done once the actual is in position (a blending successor does not wait).
            let mut settled_late = false;
            if let MotionKind::Ptp {
                target,
                window,
                settle,
            } = m.kind
            {
                let blends = self
                    .queue
                    .front()
                    .is_some_and(|q| q.buffer().is_queued() && q.buffer() != BufferMode::Buffered);
                if self.monitors_target() && !blends {
                    match self.settle_step(target, window, settle, now, dt) {
                        SettleStep::Waiting(s) => {
                            self.main = m.profile.end_state();
                            if let Some(Motion {
                                kind: MotionKind::Ptp { settle, .. },
                                ..
                            }) = self.motion.as_mut()
                            {
                                *settle = s;
                            }
                            return;
                        }
                        SettleStep::Settled { late } => settled_late = late,
                        SettleStep::TimedOut { actual } => {
                            self.main = m.profile.end_state();
                            let fault = AxisFault::TargetNotReached {
                                target: self.wrapped(target),
                                actual: self.wrapped(actual),
                                window,
                                timeout_s: self.cfg.target_monitoring.timeout_s,
                            };
                            self.fault(fault, handles);
                            return;
                        }
                    }
                }
            }
            // The profile ended at `end`; what comes next starts exactly then — or, behind
            // a velocity move whose ramp ended before the next move was queued, from the
            // last cycle's set values.
            let mut end = m.profile.end_state();
            let mut end_epoch = m.end_epoch(dt);
            let prev = now.saturating_sub(1);
            if !m.kind.is_finite() && m.epoch.elapsed(prev, dt) > m.profile.duration() {
                end = m.sample(prev, dt);
                end.j = 0.0;
                end_epoch = motion::Epoch::at(prev);
            }
            if settled_late {
                // It stood at the target while it settled: what comes next starts now.
                end_epoch = motion::Epoch::at(now);
            }
            self.main = end;
            self.retire(m, handles);
            if let Some(q) = self.queue.pop() {
                if let Err(e) = self.start_queued(q, end, end_epoch, dt, handles) {
                    handles.set(q.handle(), CommandStatus::Error(e));
                    self.fault(AxisFault::Command(e), handles);
                }
            } else if self.overlay.is_some() && self.state == AxisState::Standstill {
                // A superimposed jog still moves the axis.
                self.enter(Event::ContinuousMotionStarted);
            }
        }
    }

    /// Whether positioning moves of this axis wait for the actual position.
    fn monitors_target(&self) -> bool {
        self.cfg.target_monitoring.enabled && self.cfg.kind.has_feedback()
    }

    /// |actual − target| (the shorter way round on modulo axes).
    fn distance_to(&self, target: f64) -> f64 {
        match self.cfg.mechanics.modulo {
            Some(m) => m
                .delta_shortest(m.wrap(target), m.wrap(self.actual_p))
                .abs(),
            None => (self.actual_p - target).abs(),
        }
    }

    /// A position of the axis frame as the user sees it (within the period on modulo axes).
    fn wrapped(&self, p: f64) -> f64 {
        match self.cfg.mechanics.modulo {
            Some(m) => m.wrap(p),
            None => p,
        }
    }

    /// One cycle of target position monitoring for a PTP whose set value stands at
    /// `target` (since `settle.since`, or since now).
    fn settle_step(
        &self,
        target: f64,
        window: f64,
        settle: motion::Settle,
        now: u64,
        dt: f64,
    ) -> SettleStep {
        let tm = self.cfg.target_monitoring;
        let since = settle.since.unwrap_or(now);
        let in_window_since =
            (self.distance_to(target) <= window).then(|| settle.in_window_since.unwrap_or(now));
        // Whole cycles, compared with a margin of a millionth of a cycle so that a dwell
        // of exactly n cycles takes n cycles despite rounding.
        let held = |from: u64| now.saturating_sub(from) as f64 * dt >= tm.dwell_s - 1e-6 * dt;
        if in_window_since.is_some_and(held) {
            return SettleStep::Settled { late: now > since };
        }
        if now.saturating_sub(since) as f64 * dt >= tm.timeout_s - 1e-6 * dt {
            return SettleStep::TimedOut {
                actual: self.actual_p,
            };
        }
        SettleStep::Waiting(motion::Settle {
            since: Some(since),
            in_window_since,
        })
    }

    /// A velocity move past its ramp: restart its profile from the current state so
    /// positions never grow large inside one profile.
    fn reanchor_continuous(&mut self, now: u64, dt: f64) {
        let Some(period) = self.period() else { return };
        if self.main.p.abs() < 2.0 * period {
            return;
        }
        let _ = dt;
        self.normalise_frame();
        if let Some(m) = self.motion.as_mut() {
            m.profile = crate::profile::Profile::new(self.main);
            m.epoch = motion::Epoch::at(now);
        }
    }

    /// Ends a motion whose profile is over.
    fn retire(&mut self, m: Motion, handles: &mut HandleTable) {
        self.motion = None;
        match m.kind {
            MotionKind::Ptp { .. } | MotionKind::Halt { .. } => {
                handles.set(m.handle, CommandStatus::Done);
                if self.queue.is_empty() {
                    self.enter(Event::MotionDone);
                }
            }
            MotionKind::Velocity { .. } | MotionKind::Jog => {
                // Ended only because a buffered move takes over.
                handles.set(m.handle, CommandStatus::Done);
            }
            MotionKind::Stop => {
                handles.set(m.handle, CommandStatus::Done);
                if self.release_pending {
                    self.release_pending = false;
                    self.enter(Event::Released);
                }
            }
            MotionKind::QuickStop | MotionKind::Disable => {
                handles.set(m.handle, CommandStatus::Done);
                self.power_off(handles);
            }
            MotionKind::Home => {
                // Only a buffered move would retire it, and none is taken while homing.
                handles.set(m.handle, CommandStatus::Aborted);
                self.homing = None;
            }
        }
        if self.state == AxisState::ErrorStop {
            self.queue
                .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
        }
    }

    /// Power off at once: aborts everything.
    fn power_off(&mut self, handles: &mut HandleTable) {
        self.abort_all(handles, CommandStatus::Aborted);
        self.powered = false;
        self.enter(Event::PoweredOff);
    }

    /// Ends the running motion, the overlay and the queue with `status`.
    fn abort_all(&mut self, handles: &mut HandleTable, status: CommandStatus) {
        if let Some(m) = self.motion.take() {
            handles.set(m.handle, status);
        }
        if let Some(f) = self.follow.take() {
            handles.set(f.handle, status);
        }
        if let Some(o) = self.overlay.take() {
            handles.set(o.handle, status);
            self.fold_overlay_values();
        }
        self.queue.drain(|q| handles.set(q.handle(), status));
        self.main.v = 0.0;
        self.main.a = 0.0;
        self.main.j = 0.0;
    }

    /// Adds the overlay's displacement into the main set values (when the overlay ends).
    fn fold_overlay_values(&mut self) {
        self.main.p += self.overlay_set.p;
        self.main.v += self.overlay_set.v;
        self.main.a += self.overlay_set.a;
        self.overlay_set = KinematicState::default();
    }

    /// Goes to ErrorStop: the running commands end in error and the axis decelerates
    /// with its maximum deceleration.
    fn fault(&mut self, fault: AxisFault, handles: &mut HandleTable) {
        let running = self
            .motion
            .map(|m| m.command)
            .or(self.follow.map(|f| f.command));
        let err = match fault {
            AxisFault::Command(e) => e,
            AxisFault::TargetNotReached {
                target,
                actual,
                window,
                timeout_s,
            } => CommandError::TargetNotReached {
                command: running.unwrap_or("MovePtp"),
                target,
                actual,
                window,
                timeout_s,
            },
            AxisFault::LimitSwitch { side } => CommandError::LimitSwitch {
                command: running.unwrap_or("no command"),
                side,
            },
            _ => CommandError::AxisFault {
                command: running.unwrap_or("no command"),
            },
        };
        if let Some(f) = self.follow.take() {
            handles.set(f.handle, CommandStatus::Error(err));
        }
        // Off its group's path: the group sees it and goes to ErrorStop.
        self.group = None;
        self.homing = None;
        if let Some(l) = self.lent.take() {
            handles.set(l.handle, CommandStatus::Error(err));
        }
        if let Some(m) = self.motion.take() {
            handles.set(m.handle, CommandStatus::Error(err));
        }
        if let Some(o) = self.overlay.take() {
            handles.set(o.handle, CommandStatus::Error(err));
            self.fold_overlay_values();
        }
        self.queue
            .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
        self.enter(Event::Error);
        self.status.error = Some(fault);
        if let Some(h) = self.enable_handle.take() {
            // The drive will not come on now: the enable ends here, not after a timeout.
            handles.set(
                h,
                CommandStatus::Error(CommandError::InErrorStop {
                    command: "Power.Enable",
                    cause: fault.summary(),
                }),
            );
        }
        // A Release given during an MC_Stop does not carry over: only Reset leaves ErrorStop.
        self.release_pending = false;
        if !self.cfg.kind.is_commandable() {
            // An encoder or a shadow has no set values of its own to brake.
            return;
        }
        // Decelerate to a stop with the axis' maximum deceleration.
        let _ = self.start_stop_motion(
            MotionKind::Stop,
            self.cfg.max.dmax,
            handle::HandleId(u64::MAX),
            "ErrorStop",
        );
    }

    /// Continuous moves with software limits: brake so the set position stops at the
    /// limit, and go to ErrorStop.
    fn check_software_limits(&mut self, handles: &mut HandleTable) {
        let Some((min, max)) = self.cfg.mechanics.software_limits else {
            return;
        };
        if !self.homed || self.period().is_some() {
            return;
        }
        let continuous =
            self.motion.is_some_and(|m| m.kind.is_continuous()) || self.overlay.is_some();
        if !continuous {
            return;
        }
        let mut s = self.main;
        s.p += self.overlay_set.p;
        s.v += self.overlay_set.v;
        s.a += self.overlay_set.a;
        let limit = if s.v > 0.0 { max } else { min };
        let stop = self.stopping_point(s);
        let beyond = if s.v > 0.0 {
            stop >= limit
        } else {
            stop <= limit
        };
        if beyond && s.v != 0.0 {
            self.fault(AxisFault::SoftwareLimit { limit }, handles);
            // Replace the plain stop by one that ends exactly at the limit when possible.
            let params = motion::MoveParams {
                limits: self.cfg.max,
                ramp: self.ptp_dynamics.ramp,
            };
            if let Ok(p) =
                crate::profile::plan_position(params.ramp, self.main, limit, 0.0, &params.limits)
            {
                if let Some(m) = self.motion.as_mut() {
                    m.profile = p;
                    m.kind = MotionKind::Halt { target: limit };
                }
            }
        }
    }

    /// Where the axis would stop from `s` with its running deceleration.
    fn stopping_point(&self, s: KinematicState) -> f64 {
        let params = self.motion.map(|m| m.params).unwrap_or(motion::MoveParams {
            limits: self.cfg.max,
            ramp: self.vel_dynamics.ramp,
        });
        match crate::profile::plan_velocity(params.ramp, s, 0.0, &params.limits) {
            Ok(p) => p.end_state().p,
            Err(_) => s.p,
        }
    }

    /// Recomputes the status from the current values.
    pub(crate) fn refresh_status(&mut self) {
        let mut set = self.main;
        set.p += self.overlay_set.p;
        set.v += self.overlay_set.v;
        set.a += self.overlay_set.a;
        set.j += self.overlay_set.j;
        let (p_wrapped, turns) = match self.period() {
            Some(period) => {
                let n = (set.p / period).floor();
                let mut w = set.p - n * period;
                let mut n = n as i64;
                if w >= period {
                    w -= period;
                    n += 1;
                }
                (w, self.frame_turns.saturating_add(n))
            }
            None => (set.p, 0),
        };
        let shift = set.p - p_wrapped;
        let actual = self.actual_p - shift;
        let eps_v = 1e-9 * self.cfg.max.vmax.max(1e-9);
        let eps_a = 1e-9 * self.cfg.max.amax.max(1e-9);
        let slope = SlopeState::of(&set, eps_v, eps_a);
        let target = self.last_target.map(|t| match self.cfg.mechanics.modulo {
            Some(m) => m.wrap(t),
            None => t,
        });
        let in_window = self
            .last_target
            .is_some_and(|t| self.distance_to(t) <= self.last_window);
        let continuous_jog = self
            .motion
            .is_some_and(|m| matches!(m.kind, MotionKind::Jog));
        self.status = AxisStatus {
            state: self.state,
            slope,
            set: KinematicState {
                p: p_wrapped,
                ..set
            },
            actual_position: actual,
            actual_velocity: self.actual_v,
            turns,
            bits: StatusBits {
                accelerating: slope == SlopeState::Accelerating,
                decelerating: slope == SlopeState::Decelerating,
                moving: set.v.abs() > eps_v,
                jogging: continuous_jog
                    || self.overlay.is_some()
                    || self.follow.is_some_and(|f| f.jog_lock().is_some()),
                jog_locked: self.follow.and_then(|f| f.jog_lock()).unwrap_or(false),
                gearing: self.follow.is_some_and(|f| f.is_gear()),
                camming: self.follow.is_some_and(|f| f.is_cam()),
                coordinated: self.coordinated,
                in_sync: self.sync_bits.in_sync,
                end_of_profile: self.sync_bits.end_of_profile,
                sync_limit_exceeded: self.sync_bits.limit_exceeded,
                homing: self.state == AxisState::Homing,
                stopping: self.state == AxisState::Stopping
                    || self.motion.is_some_and(|m| {
                        matches!(m.kind, MotionKind::Stop | MotionKind::QuickStop)
                    }),
                homed: self.homed,
                in_target_window: in_window,
                max_speed_exceeded: set.v.abs() > self.cfg.max.vmax * (1.0 + 1e-9),
                error: self.state == AxisState::ErrorStop,
            },
            target,
            error: if self.state == AxisState::ErrorStop {
                self.status.error
            } else {
                None
            },
            homing: self.home_status,
            switches: self.switches,
            master: self.follow.map(|f| f.master),
            position_offset: self.position_offset,
        };
    }

    /// Whether the direction `sign` (+1/−1) is allowed on this axis.
    fn direction_allowed(&self, sign: f64) -> bool {
        match self.cfg.mechanics.direction {
            Direction::Both => true,
            Direction::PositiveOnly => sign >= 0.0,
            Direction::NegativeOnly => sign <= 0.0,
        }
    }
}
