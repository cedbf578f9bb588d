//! A group as the kernel runs it: its state, the path segment it moves along, the moves
//! waiting behind it and the braking of MC_GroupStop — the fourth kind of set-value source
//! of an axis (beside its own profile, the homing sequencer and a master relation).
//!
//! What it does:
//! - MC_GroupEnable / MC_GroupDisable with the rules of `enable.rs`; the axes are
//!   "coordinated" while the group is enabled.
//! - MC_MoveLinear and MC_MoveCircular2D, absolute or relative: each segment is planned
//!   along its path ([`PathProfile`]) so that no axis exceeds its own speed, acceleration
//!   or jerk. A move given while the group stands starts at once; on a moving group:
//!   - Buffered: it starts exactly when the one before ends, from rest;
//!   - BlendingLow/Previous/Next/High: the junction is passed in motion at the transit
//!     speed the mode names, as far as the axes, both segments' lengths and the allowed
//!     corner deviation let it (`path::blend`: the next segment is superimposed on the end
//!     of the one before; TransitionMode None only where two lines are collinear) — else
//!     at rest, as Buffered. The corner is decided when the move is queued behind the last
//!     segment, or when that segment starts;
//!   - Aborting: the segments on the way brake along their path and the move starts from
//!     where they stop (a relative move counts from where the group was when it was
//!     given).
//! - MC_GroupStop: the group brakes along its path (the contour is kept) with the path
//!   deceleration of the running segment, then stands in Stopping until released. In a
//!   blend, the ending segment finishes its ramp and the starting one brakes after its own.
//! - An axis of a moving group that leaves it (a fault, its own Stop) puts the group in
//!   ErrorStop; the other axes brake along the path. MC_GroupReset leaves ErrorStop.

pub use crate::axis::command::BufferMode;
use crate::axis::command::{CommandError, GroupPathError};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::Epoch;
use crate::path::blend::{transit_speed, Corner};
pub use crate::path::Transition;
use crate::path::{
    AxisLimits, CircAxes, CircMode, PathChoice, PathLimits, PathProfile, PathSegment, MAX_AXES,
};
use crate::profile::KinematicState;

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
    /// MC_GroupHalt: brake along the path to standstill, without locking (a move given
    /// meanwhile takes over as it would from a moving group).
    Halt,
    /// MC_GroupHome: every axis runs its own homing (MoveHome with its configured
    /// parameters), all at once; Done when every axis is homed.
    Home,
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
            GroupCmd::Halt => "GroupHalt",
            GroupCmd::Home => "GroupHome",
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
            GroupCmd::Halt => GroupCommand::Halt,
            GroupCmd::Home => GroupCommand::Home,
            GroupCmd::Release => GroupCommand::Release,
            GroupCmd::Reset => GroupCommand::Reset,
        }
    }
}

/// How many moves may wait behind the running one.
pub const GROUP_QUEUE: usize = 8;

/// A segment on the way, and when it started.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Running {
    profile: PathProfile,
    epoch: Epoch,
    /// Its command's handle (taken once the command is aborted).
    handle: Option<HandleId>,
}

impl Running {
    fn elapsed(&self, now: u64, dt: f64) -> f64 {
        self.epoch.elapsed(now, dt)
    }
}

/// The next segment, planned with its ramp in behind the last one on the way, waiting
/// for that one's ramp out to start.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Planned {
    profile: PathProfile,
    handle: HandleId,
    corner: Corner,
}

/// MC_GroupHome on the way: its handle, each axis' homing run, and the halts a stop sent
/// to the runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Homing {
    pub(crate) handle: HandleId,
    pub(crate) runs: [Option<HandleId>; MAX_AXES],
    pub(crate) halts: [Option<HandleId>; MAX_AXES],
}

/// One group at run time.
#[derive(Clone, Debug)]
pub struct Group {
    cfg: GroupConfig,
    state: GroupState,
    /// The segment the path is on; in a blend, the one ending.
    running: Option<Running>,
    /// In a blend: the segment starting, superimposed on `running`.
    incoming: Option<Running>,
    /// Blended behind the last segment on the way, not started yet.
    planned: Option<Planned>,
    queue: [Option<(GroupMove, HandleId)>; GROUP_QUEUE],
    /// Where the group stands when it does not move (A0..A3 set positions).
    rest: [f64; MAX_AXES],
    /// The segments on the way brake to rest (a stop, an error, an Aborting move).
    braking: bool,
    /// MC_GroupStop's handle, Done once the group stands.
    stop_handle: Option<HandleId>,
    /// MC_GroupHalt's handle, Done once the group stands.
    halt_handle: Option<HandleId>,
    /// MC_GroupHome's runs.
    homing: Option<Homing>,
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
            incoming: None,
            planned: None,
            queue: [None; GROUP_QUEUE],
            rest: [0.0; MAX_AXES],
            braking: false,
            stop_handle: None,
            halt_handle: None,
            homing: None,
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
        self.running.is_some()
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

    /// Disabled (refused while it drives or homes its axes: stop it first).
    pub(crate) fn disable(&mut self, handles: &mut HandleTable) -> Result<(), CommandError> {
        if self.drives_axes() || self.homing.is_some() {
            return Err(CommandError::Group(GroupCommandError::NotAllowedInState {
                command: "GroupDisable",
                state: self.state,
            }));
        }
        self.abort_waiting(handles);
        self.enter(GroupEvent::Disabled);
        Ok(())
    }

    /// The moves waiting (queued or planned behind) end CommandAborted.
    fn abort_waiting(&mut self, handles: &mut HandleTable) {
        self.queue
            .iter_mut()
            .filter_map(Option::take)
            .for_each(|(_, h)| handles.set(h, CommandStatus::Aborted));
        if let Some(p) = self.planned.take() {
            handles.set(p.handle, CommandStatus::Aborted);
        }
    }

    /// A move: planned at once from `from` (the axes' set positions) when the group
    /// stands; on a moving group queued (Buffered, Blending: blended into the last segment
    /// when it can be) or, Aborting, started where the group comes to rest after braking
    /// along its path.
    pub(crate) fn start_move(
        &mut self,
        m: GroupMove,
        from: [f64; MAX_AXES],
        h: HandleId,
        now: u64,
        dt: f64,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let name = m.name();
        if self.running.is_some() {
            if m.buffer == BufferMode::Aborting {
                // Where it goes is fixed now: relative to where the axes are.
                let m = absolute(m, from, self.cfg.axes.len());
                self.abort_waiting(handles);
                self.brake(now, dt, handles);
                if let Some(slot) = self.queue.first_mut() {
                    *slot = Some((m, h));
                }
                return Ok(CommandStatus::Busy);
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
            self.plan_blend(now, dt);
            return Ok(CommandStatus::Busy);
        }
        let profile = plan(&m, from, &self.limits, self.cfg.axes.len())?;
        self.running = Some(Running {
            profile,
            epoch: Epoch::at(now),
            handle: Some(h),
        });
        self.enter(GroupEvent::MoveStarted);
        Ok(CommandStatus::Active)
    }

    /// When the first waiting move blends: plans it behind the last segment on the way,
    /// the corner decided now (from that segment's state at cycle `now`).
    fn plan_blend(&mut self, now: u64, dt: f64) {
        if self.planned.is_some() || self.braking {
            return;
        }
        let Some((m, h)) = self.queue.first().copied().flatten() else {
            return;
        };
        if !matches!(
            m.buffer,
            BufferMode::BlendingLow
                | BufferMode::BlendingPrevious
                | BufferMode::BlendingNext
                | BufferMode::BlendingHigh
        ) {
            return;
        }
        let n = self.cfg.axes.len();
        let limits = self.limits;
        let Some(tail) = self.incoming.as_mut().or(self.running.as_mut()) else {
            return;
        };
        // A move that cannot be planned waits: its error comes when it would start.
        let Ok(mut next) = plan(&m, tail.profile.segment().end(), &limits, n) else {
            return;
        };
        let t = tail.elapsed(now, dt);
        let wanted = transit_speed(m.buffer, tail.profile.limits().v, next.limits().v);
        let Some(corner) = tail.profile.blend_into(
            &mut next,
            t,
            wanted,
            limits.get(..n).unwrap_or(&[]),
            m.transition,
            m.corner_deviation,
        ) else {
            return;
        };
        self.planned = Some(Planned {
            profile: next,
            handle: h,
            corner,
        });
        self.pop_queue();
    }

    fn pop_queue(&mut self) -> Option<(GroupMove, HandleId)> {
        let first = self.queue.first().copied().flatten();
        self.queue.rotate_left(1);
        if let Some(last) = self.queue.last_mut() {
            *last = None;
        }
        first
    }

    /// MC_GroupStop: brakes along the path (or stands) and locks; `now` is the last cycle.
    pub(crate) fn stop(
        &mut self,
        h: HandleId,
        now: u64,
        dt: f64,
        handles: &mut HandleTable,
    ) -> CommandStatus {
        self.release_pending = false;
        let status = self.brake_for(now, dt, handles);
        self.enter(GroupEvent::StopStarted);
        if status == CommandStatus::Active {
            self.stop_handle = Some(h);
        }
        status
    }

    /// MC_GroupHalt: brakes along the path to standstill (Standby then), the moves waiting
    /// aborted.
    pub(crate) fn halt(
        &mut self,
        h: HandleId,
        now: u64,
        dt: f64,
        handles: &mut HandleTable,
    ) -> CommandStatus {
        let status = self.brake_for(now, dt, handles);
        if status == CommandStatus::Active {
            self.halt_handle = Some(h);
        }
        status
    }

    /// A stop's or a halt's start: the moves waiting aborted, the segments on the way
    /// braking; Active while they brake, Done when nothing moved.
    fn brake_for(&mut self, now: u64, dt: f64, handles: &mut HandleTable) -> CommandStatus {
        self.abort_waiting(handles);
        match self.brake(now, dt, handles) {
            true => CommandStatus::Active,
            false => CommandStatus::Done,
        }
    }

    /// MC_GroupHome started: each axis' run `runs` (A0..A3).
    pub(crate) fn begin_homing(&mut self, h: HandleId, runs: [Option<HandleId>; MAX_AXES]) {
        self.homing = Some(Homing {
            handle: h,
            runs,
            halts: [None; MAX_AXES],
        });
        self.enter(GroupEvent::HomingStarted);
    }

    /// MC_GroupHome on the way, if it is.
    pub(crate) fn homing(&self) -> Option<Homing> {
        self.homing
    }

    /// Every axis is homed: Done, GroupStandby.
    pub(crate) fn homing_done(&mut self, handles: &mut HandleTable) {
        if let Some(hm) = self.homing.take() {
            handles.set(hm.handle, CommandStatus::Done);
            self.enter(GroupEvent::HomingDone);
        }
    }

    /// An axis' run failed (the kernel halts the others): the handle's error, ErrorStop.
    pub(crate) fn homing_failed(&mut self, e: GroupCommandError, handles: &mut HandleTable) {
        if let Some(hm) = self.homing.take() {
            handles.set(hm.handle, CommandStatus::Error(CommandError::Group(e)));
            self.enter(GroupEvent::Error);
        }
    }

    /// MC_GroupStop while homing: the runs are halted (`halts`, sent by the kernel); the
    /// homing ends CommandAborted, the stop is Done once the halts are.
    pub(crate) fn stop_homing(
        &mut self,
        h: HandleId,
        halts: [Option<HandleId>; MAX_AXES],
        handles: &mut HandleTable,
    ) -> CommandStatus {
        self.release_pending = false;
        if let Some(hm) = self.homing.as_mut() {
            handles.set(hm.handle, CommandStatus::Aborted);
            hm.halts = halts;
        }
        self.stop_handle = Some(h);
        self.enter(GroupEvent::StopStarted);
        CommandStatus::Active
    }

    /// The halts of a stopped homing are over: the stop is Done (GroupStandby at once if
    /// released meanwhile).
    pub(crate) fn homing_stopped(&mut self, handles: &mut HandleTable) {
        self.homing = None;
        if let Some(h) = self.stop_handle.take() {
            handles.set(h, CommandStatus::Done);
        }
        if self.release_pending {
            self.release_pending = false;
            self.enter(GroupEvent::StopReleased);
        }
    }

    /// MC_GroupStop's Execute falling: Standby once it stands.
    pub(crate) fn release(&mut self) -> CommandStatus {
        if self.running.is_some() || self.homing.is_some() {
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
        if self.running.is_some() {
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
        self.abort_waiting(handles);
        self.brake(now, dt, handles);
        self.enter(GroupEvent::Error);
    }

    /// The segments on the way brake to rest along the path from cycle `now`, with their
    /// own deceleration and jerk (which keep every axis within its limits); their commands
    /// end CommandAborted. In a blend the ending segment finishes its ramp out and the
    /// starting one brakes from the end of its ramp in (the two ramps only keep the axes
    /// within their limits together). False when nothing moved.
    fn brake(&mut self, now: u64, dt: f64, handles: &mut HandleTable) -> bool {
        if let Some(p) = self.planned.take() {
            handles.set(p.handle, CommandStatus::Aborted);
        }
        // A halt on the way is taken over (by a stop, an error, an Aborting move).
        if let Some(h) = self.halt_handle.take() {
            handles.set(h, CommandStatus::Aborted);
        }
        for r in [self.running.as_mut(), self.incoming.as_mut()]
            .into_iter()
            .flatten()
        {
            if let Some(h) = r.handle.take() {
                handles.set(h, CommandStatus::Aborted);
            }
        }
        let tail = self.incoming.as_mut().or(self.running.as_mut());
        let Some(tail) = tail else {
            return false;
        };
        let t = tail.elapsed(now, dt);
        let n = self.cfg.axes.len();
        tail.profile
            .brake_from(t, self.limits.get(..n).unwrap_or(&[]));
        self.braking = true;
        true
    }

    /// The set values of the group's axes at cycle `now` (dt the cycle time).
    pub(crate) fn step(&mut self, now: u64, dt: f64, handles: &mut HandleTable) -> Drive {
        // Each pass samples, or hands over once: a segment ends, a blend starts, the next
        // waiting move starts.
        for _ in 0..(2 * GROUP_QUEUE + 4) {
            let Some(r) = self.running.as_ref() else {
                return Drive::None;
            };
            let t = r.elapsed(now, dt);
            if let Some(inc) = self.incoming.as_ref() {
                if t < r.profile.duration() {
                    return Drive::Axes(superimpose(r, inc, now, dt));
                }
                // The corner is passed: the starting segment goes on alone.
                if let Some(h) = r.handle {
                    handles.set(h, CommandStatus::Done);
                }
                self.running = self.incoming.take();
                continue;
            }
            let corner_starts = match (r.profile.ramp_out_start(), self.planned.is_some()) {
                (Some(out), true) if t >= out => Some(r.epoch.later(out, dt)),
                _ => None,
            };
            if let Some(epoch) = corner_starts {
                if let Some(p) = self.planned.take() {
                    handles.set(p.handle, CommandStatus::Active);
                    self.incoming = Some(Running {
                        profile: p.profile,
                        epoch,
                        handle: Some(p.handle),
                    });
                    let c = &mut self.corners;
                    c.blends = c.blends.saturating_add(1);
                    c.last_deviation = p.corner.deviation;
                    c.max_deviation = c.max_deviation.max(p.corner.deviation);
                    c.last_transit_speed = p.corner.speed;
                    // The next waiting move may blend behind the new segment.
                    self.plan_blend(now, dt);
                    continue;
                }
            }
            if t < r.profile.duration() {
                return Drive::Axes(r.profile.sample(t));
            }
            // The segment ends at rest (exactly: a blend's ramps end on rounding dust).
            let mut end = r.profile.sample(r.profile.duration());
            for e in &mut end {
                *e = KinematicState::at_rest(e.p);
            }
            let (epoch, ended) = (r.epoch.later(r.profile.duration(), dt), r.handle);
            if let Some(h) = ended {
                handles.set(h, CommandStatus::Done);
            }
            self.running = None;
            self.rest = positions(&end);
            if self.braking {
                self.braking = false;
                for h in [self.stop_handle.take(), self.halt_handle.take()]
                    .into_iter()
                    .flatten()
                {
                    handles.set(h, CommandStatus::Done);
                }
                if self.release_pending {
                    self.release_pending = false;
                    self.enter(GroupEvent::StopReleased);
                }
            }
            let Some((m, h)) = self.pop_queue() else {
                self.enter(GroupEvent::MoveDone);
                return Drive::Axes(end);
            };
            // Starts exactly where and when the one before ended (from rest).
            match plan(&m, self.rest, &self.limits, self.cfg.axes.len()) {
                Ok(profile) => {
                    handles.set(h, CommandStatus::Active);
                    self.running = Some(Running {
                        profile,
                        epoch,
                        handle: Some(h),
                    });
                    self.plan_blend(now, dt);
                }
                Err(e) => {
                    handles.set(h, CommandStatus::Error(e));
                    self.abort_waiting(handles);
                    self.enter(GroupEvent::Error);
                    return Drive::Axes(end);
                }
            }
        }
        Drive::None
    }
}

/// The axes' set values in a blend: the ending segment's motion plus the starting one's,
/// less the corner point they share.
fn superimpose(
    ending: &Running,
    starting: &Running,
    now: u64,
    dt: f64,
) -> [KinematicState; MAX_AXES] {
    let a = ending.profile.sample(ending.elapsed(now, dt));
    let b = starting.profile.sample(starting.elapsed(now, dt));
    let corner = ending.profile.segment().end();
    let mut out = a;
    for ((o, b), c) in out.iter_mut().zip(b).zip(corner) {
        o.p += b.p - c;
        o.v += b.v;
        o.a += b.a;
        o.j += b.j;
    }
    out
}

/// `m` with its positions made absolute from `from` (a relative move's distances count
/// from where the group is when the move is given).
fn absolute(m: GroupMove, from: [f64; MAX_AXES], n: usize) -> GroupMove {
    if !m.relative {
        return m;
    }
    let path = match m.path {
        GroupPathKind::Linear { target } => {
            let mut to = target;
            for (t, f) in to.iter_mut().zip(from).take(n) {
                *t += f;
            }
            GroupPathKind::Linear { target: to }
        }
        GroupPathKind::Circular {
            circ,
            aux,
            end,
            mode,
            choice,
        } => {
            let base = [
                from.get(circ.0).copied().unwrap_or(0.0),
                from.get(circ.1).copied().unwrap_or(0.0),
            ];
            GroupPathKind::Circular {
                circ,
                aux: if mode == CircMode::Radius {
                    aux
                } else {
                    [aux[0] + base[0], aux[1] + base[1]]
                },
                end: [end[0] + base[0], end[1] + base[1]],
                mode,
                choice,
            }
        }
    };
    GroupMove {
        path,
        relative: false,
        ..m
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
