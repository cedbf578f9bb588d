//! The kernel: all axes of a machine, stepped once per cycle.
//!
//! `step` is the RT path: no allocation, no locks, no panics, bounded work. Everything
//! it needs is allocated in [`Kernel::new`].

use crate::axis::command::{Command, CommandError};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::status::AxisStatus;
use crate::axis::{Axis, AxisConfig, AxisFeedback, AxisKind, AxisSetpoint, ConfigError};
use crate::cam::CamTable;
use crate::group::run::{Drive, Group, GroupCmd};
use crate::group::{check_enable, check_move_start, AxisView, GroupConfig, MoveView};
use crate::homing::MoveHomeCall;
use crate::path::{AxisLimits, MAX_AXES};
use crate::sync::MasterSample;

/// Shortest and longest cycle time the kernel accepts (s).
pub const CYCLE_RANGE_S: (f64, f64) = (50e-6, 0.1);

/// How many cam tables the kernel holds (slots 0..CAM_SLOTS).
pub const CAM_SLOTS: usize = 32;

/// Why a cam table could not be put into or taken out of a slot.
#[derive(Clone, Copy, Debug, thiserror::Error, PartialEq, Eq)]
pub enum CamSlotError {
    /// The slot is beyond [`CAM_SLOTS`].
    #[error("cam table slot {slot} does not exist (slots 0..{CAM_SLOTS})")]
    NoSuchSlot {
        /// The slot given.
        slot: usize,
    },
    /// An axis cams on the table in that slot. Carries the axis' index, not its name, so
    /// that the refusal allocates nothing in the cycle thread; the caller names the axis.
    #[error("cam table slot {slot} is in use by axis #{axis}; CamOut first")]
    InUse {
        /// The slot.
        slot: usize,
        /// Index of the axis camming on it.
        axis: usize,
    },
}

/// All axes and the cycle clock.
#[derive(Clone, Debug)]
pub struct Kernel {
    axes: Vec<Axis>,
    /// Order in which axes are stepped: every master (of a gear, a cam or a shadow) before
    /// the axes that follow it; recomputed when a command changes the relations.
    order: Vec<usize>,
    /// Scratch for [`Kernel::reorder`]: each axis' depth in the chains of masters.
    depth: Vec<usize>,
    /// Cam tables by slot.
    cams: Vec<Option<CamTable>>,
    /// Axis groups.
    groups: Vec<Group>,
    /// Per axis, the set values its group's path gives this cycle.
    group_drive: Vec<Option<crate::axis::PathSample>>,
    /// Scratch for MC_GroupEnable's check: every axis as it sees them (filled in place,
    /// so a group command allocates nothing).
    enable_views: Vec<AxisView>,
    setpoints: Vec<AxisSetpoint>,
    handles: HandleTable,
    dt: f64,
    tick: u64,
}

impl Kernel {
    /// A kernel with cycle time `cycle_s` (s) and the given axes (indices follow the order
    /// of `configs`).
    pub fn new(cycle_s: f64, configs: Vec<AxisConfig>) -> Result<Self, ConfigError> {
        if !(cycle_s >= CYCLE_RANGE_S.0 && cycle_s <= CYCLE_RANGE_S.1) {
            return Err(ConfigError::CycleTime { cycle_s });
        }
        for (i, c) in configs.iter().enumerate() {
            if configs.iter().take(i).any(|o| o.name == c.name) {
                return Err(ConfigError::DuplicateName {
                    axis: c.name.clone(),
                });
            }
            if let AxisKind::Shadow { source } = c.kind {
                let ok = configs
                    .get(source)
                    .is_some_and(|s| !matches!(s.kind, AxisKind::Shadow { .. }));
                if !ok {
                    return Err(ConfigError::BadShadowSource {
                        axis: c.name.clone(),
                        source_index: source,
                    });
                }
            }
        }
        let axes = configs
            .into_iter()
            .map(Axis::new)
            .collect::<Result<Vec<_>, _>>()?;
        let n = axes.len();
        let mut k = Self {
            setpoints: vec![AxisSetpoint::default(); n],
            axes,
            order: (0..n).collect(),
            depth: vec![0; n],
            cams: (0..CAM_SLOTS).map(|_| None).collect(),
            groups: Vec::new(),
            group_drive: vec![None; n],
            enable_views: vec![
                AxisView {
                    state: crate::axis::state::AxisState::Disabled,
                    kind: AxisKind::Virtual,
                    homed: false,
                    in_enabled_group: None,
                };
                n
            ],
            handles: HandleTable::new(),
            dt: cycle_s,
            tick: 0,
        };
        k.reorder();
        Ok(k)
    }

    /// The axis `i` takes its values from (its master or its shadow source).
    fn upstream(&self, i: usize) -> Option<usize> {
        let a = self.axes.get(i)?;
        match a.config().kind {
            AxisKind::Shadow { source } => Some(source),
            _ => a.following().map(|(m, _)| m),
        }
    }

    /// Recomputes the stepping order: by depth in the chains of masters, then by index.
    /// No allocation (the vectors keep their length; the sort is in place).
    fn reorder(&mut self) {
        for i in 0..self.axes.len() {
            let mut d = 0;
            let mut at = i;
            // Chains are loop-free (checked when a relation starts), so this ends; the
            // bound guards it anyway.
            while let Some(up) = self.upstream(at) {
                d += 1;
                at = up;
                if d > self.axes.len() {
                    break;
                }
            }
            if let Some(slot) = self.depth.get_mut(i) {
                *slot = d;
            }
        }
        let depth = &self.depth;
        self.order
            .sort_unstable_by_key(|&i| (depth.get(i).copied().unwrap_or(0), i));
    }

    /// Whether `master` is `follower` or takes its values from it, directly or through
    /// other axes.
    fn depends_on(&self, master: usize, follower: usize) -> bool {
        let mut at = master;
        for _ in 0..=self.axes.len() {
            if at == follower {
                return true;
            }
            match self.upstream(at) {
                Some(up) => at = up,
                None => return false,
            }
        }
        true
    }

    /// Puts `table` into cam slot `slot` (`None` empties it); returns what was there, to
    /// be dropped by the caller (outside the RT path). Refused while an axis cams on it.
    pub fn set_cam_table(
        &mut self,
        slot: usize,
        table: Option<CamTable>,
    ) -> Result<Option<CamTable>, CamSlotError> {
        if slot >= CAM_SLOTS {
            return Err(CamSlotError::NoSuchSlot { slot });
        }
        if let Some(axis) = self
            .axes
            .iter()
            .position(|a| a.cam_table_in_use() == Some(slot))
        {
            return Err(CamSlotError::InUse { slot, axis });
        }
        match self.cams.get_mut(slot) {
            Some(s) => Ok(core::mem::replace(s, table)),
            None => Err(CamSlotError::NoSuchSlot { slot }),
        }
    }

    /// Adds an axis group (at set-up, not in the cycle: it allocates); its index.
    pub fn add_group(&mut self, cfg: GroupConfig) -> Result<usize, crate::group::GroupConfigError> {
        let kinds: Vec<AxisKind> = self.axes.iter().map(|a| a.config().kind).collect();
        cfg.validate(&kinds)?;
        let mut limits = [AxisLimits {
            vmax: 1.0,
            amax: 1.0,
            jmax: 1.0,
        }; MAX_AXES];
        for (l, &i) in limits.iter_mut().zip(&cfg.axes) {
            if let Some(a) = self.axes.get(i) {
                let m = a.config().max;
                *l = AxisLimits {
                    vmax: m.vmax,
                    amax: m.amax.min(m.dmax),
                    jmax: m.jmax,
                };
            }
        }
        self.groups.push(Group::new(cfg, limits));
        Ok(self.groups.len() - 1)
    }

    /// The groups.
    pub fn groups(&self) -> &[Group] {
        &self.groups
    }

    /// Submits a command to group `g` (as [`Kernel::submit`] does for an axis).
    pub fn group_command(&mut self, g: usize, cmd: GroupCmd) -> Result<HandleId, CommandError> {
        let h = self.handles.issue(CommandStatus::Busy);
        let status = self
            .group_apply(g, cmd, h)
            .unwrap_or_else(CommandStatus::Error);
        self.handles.set(h, status);
        for a in &mut self.axes {
            a.refresh_status();
        }
        match status {
            CommandStatus::Error(e) => Err(e),
            _ => Ok(h),
        }
    }

    fn group_apply(
        &mut self,
        g: usize,
        cmd: GroupCmd,
        h: HandleId,
    ) -> Result<CommandStatus, CommandError> {
        let group = self
            .groups
            .get(g)
            .ok_or(CommandError::NoSuchGroup { group: g })?;
        if let Some(aborted) = group.check_state(&cmd)? {
            return Ok(aborted);
        }
        // The members as a fixed array: a group command allocates nothing.
        let mut member_buf = [0usize; MAX_AXES];
        let count = group.config().axes.len().min(MAX_AXES);
        for (m, &i) in member_buf.iter_mut().zip(&group.config().axes) {
            *m = i;
        }
        let members = member_buf.get(..count).unwrap_or(&[]);
        match cmd {
            GroupCmd::Enable => {
                if group.state() != crate::group::GroupState::Disabled {
                    return Ok(CommandStatus::Done);
                }
                for i in 0..self.axes.len() {
                    let v = self.axis_view(i, g);
                    if let Some(slot) = self.enable_views.get_mut(i) {
                        *slot = v;
                    }
                }
                let group = self
                    .groups
                    .get(g)
                    .ok_or(CommandError::NoSuchGroup { group: g })?;
                check_enable(group.config(), &self.enable_views)
                    .map_err(|e| CommandError::Group(e.into()))?;
                if let Some(group) = self.groups.get_mut(g) {
                    group.enable();
                }
                self.set_coordinated(members, true);
                Ok(CommandStatus::Done)
            }
            GroupCmd::Disable => {
                if let Some(group) = self.groups.get_mut(g) {
                    group.disable(&mut self.handles)?;
                }
                self.set_coordinated(members, false);
                Ok(CommandStatus::Done)
            }
            GroupCmd::Move(m) => {
                let mut views = [MoveView {
                    axis: 0,
                    homed: false,
                    switches: Default::default(),
                }; MAX_AXES];
                for (v, &i) in views.iter_mut().zip(members) {
                    let s = self
                        .axes
                        .get(i)
                        .ok_or(CommandError::NoSuchAxis { axis: i })?
                        .status();
                    *v = MoveView {
                        axis: i,
                        homed: s.bits.homed,
                        switches: s.switches,
                    };
                }
                check_move_start(views.get(..count).unwrap_or(&[])).map_err(|error| {
                    CommandError::Group(crate::group::GroupCommandError::MoveStart {
                        command: m.name(),
                        error,
                    })
                })?;
                let moving = group.drives_axes();
                let mut from = [0.0; MAX_AXES];
                for (f, &i) in from.iter_mut().zip(members) {
                    let a = self
                        .axes
                        .get(i)
                        .ok_or(CommandError::NoSuchAxis { axis: i })?;
                    if a.config().mechanics.modulo.is_some() {
                        return Err(CommandError::GroupPath {
                            command: m.name(),
                            error: crate::axis::command::GroupPathError::ModuloAxis { axis: i },
                        });
                    }
                    if !moving && a.state() != crate::axis::state::AxisState::Standstill {
                        return Err(CommandError::NotAllowedInState {
                            command: m.name(),
                            state: a.state(),
                        });
                    }
                    *f = a.status().set.p;
                }
                let (tick, dt) = (self.tick, self.dt);
                let status = match self.groups.get_mut(g) {
                    Some(group) => group.start_move(m, from, h, tick, dt, &mut self.handles)?,
                    None => return Err(CommandError::NoSuchGroup { group: g }),
                };
                if !moving {
                    for &i in members {
                        if let Some(a) = self.axes.get_mut(i) {
                            a.begin_group_motion(g);
                        }
                    }
                }
                Ok(status)
            }
            GroupCmd::Home => {
                // Each axis runs its own homing (its configured MoveHome parameters).
                let mut runs = [None; MAX_AXES];
                for (r, &i) in runs.iter_mut().zip(members) {
                    let run = self.submit(i, Command::MoveHome(MoveHomeCall::default()));
                    if let CommandStatus::Error(e) = self.command_status(run) {
                        self.halt_runs(&runs, members);
                        return Err(e);
                    }
                    *r = Some(run);
                }
                match self.groups.get_mut(g) {
                    Some(group) => group.begin_homing(h, runs),
                    None => return Err(CommandError::NoSuchGroup { group: g }),
                }
                Ok(CommandStatus::Active)
            }
            GroupCmd::Stop if group.homing().is_some() => {
                // The homing runs are halted; the stop is Done once the axes stand.
                let runs = group.homing().map(|hm| hm.runs).unwrap_or_default();
                let halts = self.halt_runs(&runs, members);
                match self.groups.get_mut(g) {
                    Some(group) => Ok(group.stop_homing(h, halts, &mut self.handles)),
                    None => Err(CommandError::NoSuchGroup { group: g }),
                }
            }
            GroupCmd::Stop => {
                let (tick, dt) = (self.tick, self.dt);
                match self.groups.get_mut(g) {
                    Some(group) => Ok(group.stop(h, tick, dt, &mut self.handles)),
                    None => Err(CommandError::NoSuchGroup { group: g }),
                }
            }
            GroupCmd::Halt => {
                let (tick, dt) = (self.tick, self.dt);
                match self.groups.get_mut(g) {
                    Some(group) => Ok(group.halt(h, tick, dt, &mut self.handles)),
                    None => Err(CommandError::NoSuchGroup { group: g }),
                }
            }
            GroupCmd::Release => match self.groups.get_mut(g) {
                Some(group) => Ok(group.release()),
                None => Err(CommandError::NoSuchGroup { group: g }),
            },
            GroupCmd::Reset => match self.groups.get_mut(g) {
                Some(group) => group.reset(),
                None => Err(CommandError::NoSuchGroup { group: g }),
            },
        }
    }

    /// Halts every axis of `members` whose homing run in `runs` is still on its way; the
    /// halts' handles.
    fn halt_runs(
        &mut self,
        runs: &[Option<HandleId>; MAX_AXES],
        members: &[usize],
    ) -> [Option<HandleId>; MAX_AXES] {
        let mut halts = [None; MAX_AXES];
        for ((halt, run), &i) in halts.iter_mut().zip(runs).zip(members) {
            if run.is_some_and(|r| !self.command_status(r).is_final()) {
                *halt = Some(self.submit(
                    i,
                    Command::Halt {
                        mode: crate::axis::command::HaltMode::Normal,
                        deceleration: None,
                    },
                ));
            }
        }
        halts
    }

    /// MC_GroupHome's runs after a cycle: Done when every axis is homed; an axis' run that
    /// fails or is taken over puts the group in ErrorStop and halts the others; a stopped
    /// homing ends its stop once the halts are over.
    fn follow_group_homing(&mut self) {
        for g in 0..self.groups.len() {
            let Some((hm, members)) = self.groups.get(g).and_then(|group| {
                let mut members = [usize::MAX; MAX_AXES];
                for (m, &i) in members.iter_mut().zip(&group.config().axes) {
                    *m = i;
                }
                group.homing().map(|hm| (hm, members))
            }) else {
                continue;
            };
            let status = |h: &HandleId| self.handles.get(*h);
            if hm.halts.iter().any(Option::is_some) {
                let over = hm
                    .halts
                    .iter()
                    .chain(&hm.runs)
                    .flatten()
                    .all(|h| status(h).is_final());
                if over {
                    if let Some(group) = self.groups.get_mut(g) {
                        group.homing_stopped(&mut self.handles);
                    }
                }
                continue;
            }
            let failed =
                hm.runs
                    .iter()
                    .zip(members)
                    .find_map(|(run, axis)| match run.map(|h| status(&h)) {
                        Some(CommandStatus::Error(_)) => Some((axis, "in an error")),
                        Some(CommandStatus::Aborted | CommandStatus::Expired) => {
                            Some((axis, "aborted"))
                        }
                        _ => None,
                    });
            if let Some((axis, how)) = failed {
                let count = self.groups.get(g).map_or(0, |gr| gr.config().axes.len());
                self.halt_runs(&hm.runs, members.get(..count).unwrap_or(&[]));
                if let Some(group) = self.groups.get_mut(g) {
                    group.homing_failed(
                        crate::group::GroupCommandError::HomingFailed { axis, how },
                        &mut self.handles,
                    );
                }
            } else if hm
                .runs
                .iter()
                .flatten()
                .all(|h| status(h) == CommandStatus::Done)
            {
                if let Some(group) = self.groups.get_mut(g) {
                    group.homing_done(&mut self.handles);
                }
            }
        }
    }

    /// Axis `i` as MC_GroupEnable of group `g` sees it.
    fn axis_view(&self, i: usize, g: usize) -> AxisView {
        let a = self.axes.get(i);
        AxisView {
            state: a.map_or(crate::axis::state::AxisState::Disabled, Axis::state),
            kind: a.map_or(AxisKind::Virtual, |a| a.config().kind),
            homed: a.is_some_and(|a| a.status().bits.homed),
            in_enabled_group: self.groups.iter().enumerate().position(|(k, other)| {
                k != g && other.state().is_enabled() && other.config().axes.contains(&i)
            }),
        }
    }

    fn set_coordinated(&mut self, members: &[usize], on: bool) {
        for &i in members {
            if let Some(a) = self.axes.get_mut(i) {
                a.set_coordinated(on);
                a.refresh_status();
            }
        }
    }

    /// The cam table in slot `slot`.
    pub fn cam_table(&self, slot: usize) -> Option<&CamTable> {
        self.cams.get(slot).and_then(Option::as_ref)
    }

    /// Cycle time (s).
    pub fn cycle_time(&self) -> f64 {
        self.dt
    }

    /// Index of the last cycle run (0 before the first).
    pub fn tick(&self) -> u64 {
        self.tick
    }

    /// Time of the last cycle (s).
    pub fn time(&self) -> f64 {
        self.tick as f64 * self.dt
    }

    /// The axes.
    pub fn axes(&self) -> &[Axis] {
        &self.axes
    }

    /// Index of the axis called `name`.
    pub fn axis_index(&self, name: &str) -> Option<usize> {
        self.axes.iter().position(|a| a.name() == name)
    }

    /// Status of axis `axis` after the last cycle.
    pub fn axis_status(&self, axis: usize) -> Option<&AxisStatus> {
        self.axes.get(axis).map(Axis::status)
    }

    /// Submits a command; it takes effect from the current set values and is visible in
    /// the next cycle. The handle's status says whether it was accepted: a refused command
    /// has status `Error` and changed nothing.
    pub fn submit(&mut self, axis: usize, cmd: Command) -> HandleId {
        let h = self.handles.issue(CommandStatus::Busy);
        let status = self.submit_inner(axis, &cmd, h);
        let status = status.unwrap_or_else(CommandStatus::Error);
        self.handles.set(h, status);
        if matches!(
            cmd,
            Command::GearIn(_) | Command::GearInPos(_) | Command::CamIn(_) | Command::MasterJog(_)
        ) && status != CommandStatus::Error(CommandError::NoSuchAxis { axis })
        {
            self.reorder();
        }
        h
    }

    fn submit_inner(
        &mut self,
        axis: usize,
        cmd: &Command,
        h: HandleId,
    ) -> Result<CommandStatus, CommandError> {
        let master = match *cmd {
            Command::GearIn(g) => Some((g.master, g.source)),
            Command::GearInPos(g) => Some((g.gear.master, g.gear.source)),
            Command::CamIn(c) => Some((c.master, c.source)),
            Command::MasterJog(j) => Some((j.master, j.source)),
            _ => None,
        };
        let mut sync = crate::axis::apply::SyncContext {
            master: None,
            cams: &self.cams,
        };
        if let Some((m, source)) = master {
            if axis < self.axes.len() && m < self.axes.len() && self.depends_on(m, axis) {
                return Err(CommandError::BadMaster {
                    command: cmd.name(),
                    master: m,
                    why: if m == axis {
                        "an axis cannot follow itself"
                    } else {
                        "it follows this axis: the relations would go round in a loop"
                    },
                });
            }
            sync.master = self.axes.get(m).map(|a| a.master_sample(source));
        }
        match self.axes.get_mut(axis) {
            None => Err(CommandError::NoSuchAxis { axis }),
            Some(a) => {
                let r = a.apply(cmd, &sync, h, &mut self.handles);
                a.refresh_status();
                r
            }
        }
    }

    /// Like [`Kernel::submit`], but a refused command is returned as an error.
    pub fn command(&mut self, axis: usize, cmd: Command) -> Result<HandleId, CommandError> {
        let h = self.submit(axis, cmd);
        match self.handles.get(h) {
            CommandStatus::Error(e) => Err(e),
            _ => Ok(h),
        }
    }

    /// Lends axis `axis` to its drive for `procedure` (see [`crate::axis::lend`]): from
    /// Standstill; `homing`: the axis is in Homing and not homed until the procedure ends
    /// well. The handle is Active until [`Kernel::end_drive_procedure`], Aborted by power
    /// off, Stop or QuickStop, Error on a fault.
    pub fn lend_to_drive(
        &mut self,
        axis: usize,
        procedure: &'static str,
        homing: bool,
    ) -> Result<HandleId, CommandError> {
        let h = self.handles.issue(CommandStatus::Busy);
        let status = match self.axes.get_mut(axis) {
            None => Err(CommandError::NoSuchAxis { axis }),
            Some(a) => {
                let r = a.lend(procedure, homing, h);
                a.refresh_status();
                r
            }
        };
        let status = status.unwrap_or_else(CommandStatus::Error);
        self.handles.set(h, status);
        match status {
            CommandStatus::Error(e) => Err(e),
            _ => Ok(h),
        }
    }

    /// The command (Stop, QuickStop) that asked to cancel axis `axis`' drive procedure, if
    /// one did: the master halts the drive, hands it back and ends the lending.
    pub fn cancel_requested(&self, axis: usize) -> Option<&'static str> {
        self.axes.get(axis).and_then(Axis::cancel_requested)
    }

    /// Whether axis `axis` is lent to its drive (false for no such axis).
    pub fn is_lent(&self, axis: usize) -> bool {
        self.axes.get(axis).is_some_and(Axis::is_lent)
    }

    /// Ends the lending of axis `axis`: its drive's procedure is done (a homing procedure
    /// homes the axis on the drive's position) or failed. False when the axis was not lent.
    pub fn end_drive_procedure(
        &mut self,
        axis: usize,
        outcome: Result<(), crate::axis::lend::DriveProcedureError>,
    ) -> bool {
        match self.axes.get_mut(axis) {
            Some(a) => {
                let ended = a.end_lending(outcome, &mut self.handles);
                a.refresh_status();
                ended
            }
            None => false,
        }
    }

    /// Status of a command.
    pub fn command_status(&self, h: HandleId) -> CommandStatus {
        self.handles.get(h)
    }

    /// Runs one cycle: `feedback[i]` holds the actual values of axis `i` (missing entries
    /// count as default; simulated and virtual axes ignore them). Returns the set values.
    pub fn step(&mut self, feedback: &[AxisFeedback]) -> &[AxisSetpoint] {
        self.tick += 1;
        let none = AxisFeedback::default();
        // Groups first: their paths give their axes' set values of this cycle.
        for d in self.group_drive.iter_mut() {
            *d = None;
        }
        for group in &mut self.groups {
            if let Drive::Axes(states) = group.step(self.tick, self.dt, &mut self.handles) {
                let last = !group.drives_axes();
                for (s, &i) in states.iter().zip(&group.config().axes) {
                    if let Some(d) = self.group_drive.get_mut(i) {
                        *d = Some(crate::axis::PathSample { set: *s, last });
                    }
                }
            }
        }
        for &i in &self.order {
            let (kind, following) = match self.axes.get(i) {
                Some(a) => (a.config().kind, a.following()),
                None => continue,
            };
            let fb = match kind {
                AxisKind::Shadow { source } => self.shadow_feedback(source),
                _ => *feedback.get(i).unwrap_or(&none),
            };
            // The master was stepped before (see `order`): its values of this cycle.
            let master: Option<MasterSample> =
                following.and_then(|(m, source)| self.axes.get(m).map(|a| a.master_sample(source)));
            if let (Some(axis), Some(sp)) = (self.axes.get_mut(i), self.setpoints.get_mut(i)) {
                let path = self.group_drive.get(i).copied().flatten();
                let from = crate::axis::Sources {
                    master: master.as_ref(),
                    path: path.as_ref(),
                    cams: &self.cams,
                };
                *sp = axis.step(self.tick, self.dt, &fb, &from, &mut self.handles);
            }
        }
        self.follow_group_homing();
        // A group whose axis left its path (a fault, its own stop) goes to ErrorStop and
        // brakes the others along the path.
        for (g, group) in self.groups.iter_mut().enumerate() {
            let left = group.drives_axes()
                && group.config().axes.iter().any(|&i| {
                    self.axes
                        .get(i)
                        .is_some_and(|a| a.driven_by_group() != Some(g))
                });
            if left && group.state() == crate::group::GroupState::Moving {
                group.axis_left(self.tick, self.dt, &mut self.handles);
            }
        }
        &self.setpoints
    }

    /// A shadow axis reads its source's set and actual values as its own feedback.
    fn shadow_feedback(&self, source: usize) -> AxisFeedback {
        match self.axes.get(source) {
            Some(src) => {
                let s = src.status();
                AxisFeedback {
                    position: s.actual_position,
                    velocity: s.actual_velocity,
                    operation_enabled: false,
                    fault: None,
                    // A shadow has no switches of its own.
                    ..AxisFeedback::default()
                }
            }
            None => AxisFeedback::default(),
        }
    }
}
