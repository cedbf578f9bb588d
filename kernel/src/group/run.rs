//! A group as the kernel runs it: its state, the path segment it moves along, the moves
//! waiting behind it and the braking of MC_GroupStop — the fourth kind of set-value source
//! of an axis (beside its own profile, the homing sequencer and a master relation).
//!
//! What it does (and does not do yet):
//! - MC_GroupEnable / MC_GroupDisable with the rules of `enable.rs`; the axes are
//!   "coordinated" while the group is enabled.
//! - MC_MoveLinear and MC_MoveCircular2D, absolute or relative, from rest to rest: each
//!   segment is planned along its path ([`PathProfile`]) so that no axis exceeds its own
//!   speed, acceleration or jerk; a move given while the group stands starts at once, one
//!   given while it moves (Buffered) starts exactly when the one before ends. Blending
//!   (BlendingLow/Previous/Next/High, CornerSuperimposed) and Aborting a moving group are
//!   refused with a message: not written yet.
//! - MC_GroupStop: the group brakes along its path (the contour is kept) with the path
//!   deceleration of the running segment, then stands in Stopping until released.
//! - An axis of a moving group that leaves it (a fault, its own Stop) puts the group in
//!   ErrorStop; the other axes brake along the path. MC_GroupReset leaves ErrorStop.

pub use crate::axis::command::BufferMode;
use crate::axis::command::{CommandError, GroupPathError};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::Epoch;
pub use crate::path::Transition;
use crate::path::{
    along, AxisLimits, CircAxes, CircMode, PathChoice, PathLimits, PathProfile, PathSegment,
    MAX_AXES,
};
use crate::profile::{plan_velocity, KinematicState, Limits, Profile, RampType};

use super::config::GroupConfig;
use super::state::{GroupCommand, GroupEvent, GroupState};
use super::status::{start_status, GroupCommandError};

/// Where a group move goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GroupPathKind {
    /// MC_MoveLinear: to `target` (A0..A3; axes beyond the group's are ignored).
    Linear {
        /// Target (absolute) or distance (relative) per logical axis.
        target: [f64; MAX_AXES],
    },
    /// MC_MoveCircular2D in the logical axes `circ`.
    Circular {
        /// The two circular axes (logical indices).
        circ: (usize, usize),
        /// Border point, center, or `[radius, _]` as `mode` says.
        aux: [f64; 2],
        /// End point.
        end: [f64; 2],
        /// Border, Center or Radius.
        mode: CircMode,
        /// CW or CCW.
        choice: PathChoice,
    },
}

/// A group move (MC_MoveLinear / MC_MoveCircular2D).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupMove {
    /// Where it goes.
    pub path: GroupPathKind,
    /// Positions relative to where the move starts (MoveMode relative).
    pub relative: bool,
    /// Path velocity (required), acceleration, deceleration, jerk (`f64::INFINITY`: the
    /// axes' limits decide).
    pub dynamics: PathLimits,
    /// How the move joins the one running when it is given: Aborting (brake along the
    /// running path, then go), Buffered (start when it ends), Blending* (pass the
    /// junction at the transit speed the mode names).
    pub buffer: BufferMode,
    /// How a blended junction may leave the programmed path (TransitionMode).
    pub transition: Transition,
    /// With CornerSuperimposed: the largest distance the blended path may pass from the
    /// corner (units; `f64::INFINITY`: the axes' limits alone decide).
    pub corner_deviation: f64,
}

/// What the blends of a group have done so far (since it was created).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CornerReport {
    /// Junctions passed in motion.
    pub blends: u32,
    /// The last one's bound on the distance between the path and the corner (units).
    pub last_deviation: f64,
    /// The largest of those bounds.
    pub max_deviation: f64,
    /// The path speed at the last junction (0 when passed at rest).
    pub last_transit_speed: f64,
}

impl GroupMove {
    /// Function block name.
    pub const fn name(&self) -> &'static str {
        match self.path {
            GroupPathKind::Linear { .. } => "MoveLinear",
            GroupPathKind::Circular { .. } => "MoveCircular2D",
        }
    }
}

/// A command to a group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GroupCmd {
    /// MC_GroupEnable.
    Enable,
    /// MC_GroupDisable.
    Disable,
    /// MC_MoveLinear / MC_MoveCircular2D.
    Move(GroupMove),
    /// MC_GroupStop: brake along the path and lock until [`GroupCmd::Release`].
    Stop,
    /// MC_GroupStop's Execute falling.
    Release,
    /// MC_GroupReset.
    Reset,
}

impl GroupCmd {
    /// Function block name.
    pub const fn name(&self) -> &'static str {
        match self {
            GroupCmd::Enable => "GroupEnable",
            GroupCmd::Disable => "GroupDisable",
            GroupCmd::Move(m) => m.name(),
            GroupCmd::Stop => "GroupStop",
            GroupCmd::Release => "GroupStop.Release",
            GroupCmd::Reset => "GroupReset",
        }
    }

    const fn as_state_command(&self) -> GroupCommand {
        match self {
            GroupCmd::Enable => GroupCommand::Enable,
            GroupCmd::Disable => GroupCommand::Disable,
            GroupCmd::Move(GroupMove {
                path: GroupPathKind::Linear { .. },
                ..
            }) => GroupCommand::MoveLinear,
            GroupCmd::Move(_) => GroupCommand::MoveCircular2D,
            GroupCmd::Stop => GroupCommand::Stop,
            GroupCmd::Release => GroupCommand::Release,
            GroupCmd::Reset => GroupCommand::Reset,
        }
    }
}

/// How many moves may wait behind the running one.
pub const GROUP_QUEUE: usize = 8;

/// The segment the group moves along.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Running {
    profile: PathProfile,
    epoch: Epoch,
    handle: HandleId,
}

/// MC_GroupStop (or an error) braking along the path.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Braking {
    segment: PathSegment,
    path: Profile,
    epoch: Epoch,
    handle: Option<HandleId>,
}

/// One group at run time.
#[derive(Clone, Debug)]
pub struct Group {
    cfg: GroupConfig,
    state: GroupState,
    running: Option<Running>,
    braking: Option<Braking>,
    queue: [Option<(GroupMove, HandleId)>; GROUP_QUEUE],
    /// Where the group stands when it does not move (A0..A3 set positions).
    rest: [f64; MAX_AXES],
    release_pending: bool,
    /// Each group axis' own limits (A0..A3).
    limits: [AxisLimits; MAX_AXES],
    corners: CornerReport,
}

/// What the axes need from their group this cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Drive {
    /// The group does not drive its axes now.
    None,
    /// Set values of A0..A3 (the group's axes in order).
    Axes([KinematicState; MAX_AXES]),
}

impl Group {
    /// A disabled group whose axes A0..A3 have these limits.
    pub fn new(cfg: GroupConfig, limits: [AxisLimits; MAX_AXES]) -> Self {
        Self {
            cfg,
            state: GroupState::Disabled,
            running: None,
            braking: None,
            queue: [None; GROUP_QUEUE],
            rest: [0.0; MAX_AXES],
            release_pending: false,
            limits,
            corners: CornerReport::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &GroupConfig {
        &self.cfg
    }

    /// The state.
    pub fn state(&self) -> GroupState {
        self.state
    }

    /// What the blends have done so far.
    pub fn corners(&self) -> CornerReport {
        self.corners
    }

    /// Whether the group drives its axes' set values (moving or braking).
    pub fn drives_axes(&self) -> bool {
        self.running.is_some() || self.braking.is_some()
    }

    fn enter(&mut self, e: GroupEvent) {
        if let Some(s) = self.state.on(e) {
            self.state = s;
        }
    }

    /// How the command starts in the group's state (`status::start_status`, the seed's
    /// rules): `Ok(None)` when the state takes it, `Ok(Some(Aborted))` for a move given
    /// while the group is in ErrorStop or Stopping (CommandAborted, not Error), the error
    /// otherwise.
    pub(crate) fn check_state(
        &self,
        cmd: &GroupCmd,
    ) -> Result<Option<CommandStatus>, CommandError> {
        match start_status(self.state, cmd.as_state_command(), || Ok(())) {
            Ok(CommandStatus::Aborted) => Ok(Some(CommandStatus::Aborted)),
            Ok(_) => Ok(None),
            Err(e) => Err(CommandError::Group(e)),
        }
    }

    /// Enabled (the kernel checked the rules).
    pub(crate) fn enable(&mut self) {
        self.enter(GroupEvent::Enabled);
    }

    /// Disabled (refused while it drives its axes: stop it first).
    pub(crate) fn disable(&mut self, handles: &mut HandleTable) -> Result<(), CommandError> {
        if self.drives_axes() {
            return Err(CommandError::Group(GroupCommandError::NotAllowedInState {
                command: "GroupDisable",
                state: self.state,
            }));
        }
        self.queue
            .iter_mut()
            .filter_map(Option::take)
            .for_each(|(_, h)| handles.set(h, CommandStatus::Aborted));
        self.enter(GroupEvent::Disabled);
        Ok(())
    }

    /// A move: planned at once from `from` (the axes' set positions) when the group
    /// stands, queued (Buffered) when it moves.
    pub(crate) fn start_move(
        &mut self,
        m: GroupMove,
        from: [f64; MAX_AXES],
        h: HandleId,
        now: u64,
    ) -> Result<CommandStatus, CommandError> {
        let name = m.name();
        if self.running.is_some() {
            if m.buffer == BufferMode::Aborting {
                return Err(CommandError::GroupMoving { command: name });
            }
            let slot =
                self.queue
                    .iter_mut()
                    .find(|q| q.is_none())
                    .ok_or(CommandError::QueueFull {
                        command: name,
                        capacity: GROUP_QUEUE,
                    })?;
            *slot = Some((m, h));
            return Ok(CommandStatus::Busy);
        }
        let profile = plan(&m, from, &self.limits, self.cfg.axes.len())?;
        self.running = Some(Running {
            profile,
            epoch: Epoch::at(now),
            handle: h,
        });
        self.enter(GroupEvent::MoveStarted);
        Ok(CommandStatus::Active)
    }

    /// MC_GroupStop: brakes along the path (or stands) and locks; `now` is the last cycle.
    pub(crate) fn stop(
        &mut self,
        h: HandleId,
        now: u64,
        dt: f64,
        handles: &mut HandleTable,
    ) -> CommandStatus {
        self.queue
            .iter_mut()
            .filter_map(Option::take)
            .for_each(|(_, q)| handles.set(q, CommandStatus::Aborted));
        self.release_pending = false;
        let braking = self.brake_along(now, dt, handles);
        self.enter(GroupEvent::StopStarted);
        match braking {
            true => {
                if let Some(b) = self.braking.as_mut() {
                    b.handle = Some(h);
                }
                CommandStatus::Active
            }
            false => CommandStatus::Done,
        }
    }

    /// MC_GroupStop's Execute falling: Standby once it stands.
    pub(crate) fn release(&mut self) -> CommandStatus {
        if self.braking.is_some() {
            self.release_pending = true;
        } else {
            self.enter(GroupEvent::StopReleased);
        }
        CommandStatus::Done
    }

    /// MC_GroupReset: leaves ErrorStop once the group stands.
    pub(crate) fn reset(&mut self) -> Result<CommandStatus, CommandError> {
        if self.state != GroupState::ErrorStop {
            return Ok(CommandStatus::Done);
        }
        if self.braking.is_some() {
            return Err(CommandError::Group(GroupCommandError::NotAllowedInState {
                command: "GroupReset",
                state: self.state,
            }));
        }
        self.enter(GroupEvent::Reset);
        Ok(CommandStatus::Done)
    }

    /// An axis of the group left it while it moved: ErrorStop, the rest brakes along the
    /// path.
    pub(crate) fn axis_left(&mut self, now: u64, dt: f64, handles: &mut HandleTable) {
        self.queue
            .iter_mut()
            .filter_map(Option::take)
            .for_each(|(_, q)| handles.set(q, CommandStatus::Aborted));
        self.brake_along(now, dt, handles);
        self.enter(GroupEvent::Error);
    }

    /// Replaces the running segment by a braking profile from where the path is at cycle
    /// `now` (with the segment's own path deceleration and jerk, which keep every axis
    /// within its limits); false when nothing moved.
    fn brake_along(&mut self, now: u64, dt: f64, handles: &mut HandleTable) -> bool {
        let Some(r) = self.running.take() else {
            return self.braking.is_some();
        };
        handles.set(r.handle, CommandStatus::Aborted);
        let at = r.profile.path().sample(r.epoch.elapsed(now, dt));
        let l = r.profile.limits();
        let limits = Limits {
            vmax: l.v.max(at.v.abs()),
            amax: l.a,
            dmax: l.d,
            jmax: l.j,
        };
        let path = plan_velocity(RampType::SCurve, at, 0.0, &limits)
            .or_else(|_| plan_velocity(RampType::Trapezoid, at, 0.0, &limits))
            .unwrap_or_else(|_| Profile::new(KinematicState::at_rest(at.p)));
        self.braking = Some(Braking {
            segment: *r.profile.segment(),
            path,
            epoch: Epoch::at(now),
            handle: None,
        });
        true
    }

    /// The set values of the group's axes at cycle `now` (dt the cycle time).
    pub(crate) fn step(&mut self, now: u64, dt: f64, handles: &mut HandleTable) -> Drive {
        if let Some(b) = self.braking {
            let t = b.epoch.elapsed(now, dt);
            let s = b.path.sample(t);
            let out = along(&b.segment, &s);
            if t >= b.path.duration() {
                self.braking = None;
                self.rest = positions(&out);
                if let Some(h) = b.handle {
                    handles.set(h, CommandStatus::Done);
                }
                if self.release_pending {
                    self.release_pending = false;
                    self.enter(GroupEvent::StopReleased);
                }
            }
            return Drive::Axes(out);
        }
        // Each pass either samples the running segment or hands over to the next.
        for _ in 0..=GROUP_QUEUE {
            let Some(r) = self.running else {
                return Drive::None;
            };
            let t = r.epoch.elapsed(now, dt);
            if t < r.profile.duration() {
                return Drive::Axes(r.profile.sample(t));
            }
            let end = r.profile.sample(r.profile.duration());
            handles.set(r.handle, CommandStatus::Done);
            self.running = None;
            self.rest = positions(&end);
            let next = self.queue.first().copied().flatten();
            self.queue.rotate_left(1);
            if let Some(last) = self.queue.last_mut() {
                *last = None;
            }
            match next {
                None => {
                    self.enter(GroupEvent::MoveDone);
                    return Drive::Axes(end);
                }
                Some((m, h)) => {
                    // Starts exactly where and when the one before ended (rest to rest).
                    let epoch = r.epoch.later(r.profile.duration(), dt);
                    match plan(&m, self.rest, &self.limits, self.cfg.axes.len()) {
                        Ok(profile) => {
                            handles.set(h, CommandStatus::Active);
                            self.running = Some(Running {
                                profile,
                                epoch,
                                handle: h,
                            });
                        }
                        Err(e) => {
                            handles.set(h, CommandStatus::Error(e));
                            self.enter(GroupEvent::Error);
                            return Drive::Axes(end);
                        }
                    }
                }
            }
        }
        Drive::None
    }
}

/// The path of move `m` from `from` in the group's first `n` axes, planned under their
/// `limits`.
fn plan(
    m: &GroupMove,
    from: [f64; MAX_AXES],
    limits: &[AxisLimits; MAX_AXES],
    n: usize,
) -> Result<PathProfile, CommandError> {
    let name = m.name();
    let v = m.dynamics.v;
    if !(v.is_finite() && v > 0.0) {
        return Err(CommandError::OperandOutOfRange {
            command: name,
            operand: crate::axis::command::Operand::Speed,
            value: v,
            problem: crate::axis::command::RangeProblem::NotPositive,
            limit: f64::NAN,
        });
    }
    let err = |error: GroupPathError| CommandError::GroupPath {
        command: name,
        error,
    };
    let segment = match m.path {
        GroupPathKind::Linear { target } => {
            let mut to = from;
            for ((t, f), g) in to.iter_mut().zip(from).zip(target).take(n) {
                *t = if m.relative { f + g } else { g };
            }
            PathSegment::line(from, to, n).map_err(|e| err(e.into()))?
        }
        GroupPathKind::Circular {
            circ: (x, y),
            aux,
            end,
            mode,
            choice,
        } => {
            let circ = CircAxes::new(x, y, n).map_err(|e| err(e.into()))?;
            let base = [
                from.get(x).copied().unwrap_or(0.0),
                from.get(y).copied().unwrap_or(0.0),
            ];
            let (mut aux, mut end) = (aux, end);
            if m.relative {
                end = [end[0] + base[0], end[1] + base[1]];
                if mode != CircMode::Radius {
                    aux = [aux[0] + base[0], aux[1] + base[1]];
                }
            }
            PathSegment::circular_2d(from, n, circ, aux, end, mode, choice)
                .map_err(|e| err(e.into()))?
        }
    };
    PathProfile::plan(segment, limits.get(..n).unwrap_or(&[]), &m.dynamics)
        .map_err(|e| err(e.into()))
}

fn positions(s: &[KinematicState; MAX_AXES]) -> [f64; MAX_AXES] {
    let mut p = [0.0; MAX_AXES];
    for (p, s) in p.iter_mut().zip(s) {
        *p = s.p;
    }
    p
}
