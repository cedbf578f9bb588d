//! The kernel: all axes of a machine, stepped once per cycle.
//!
//! `step` is the RT path: no allocation, no locks, no panics, bounded work. Everything
//! it needs is allocated in [`Kernel::new`].

use crate::axis::command::{Command, CommandError};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::status::AxisStatus;
use crate::axis::{Axis, AxisConfig, AxisFeedback, AxisKind, AxisSetpoint, ConfigError};
use crate::cam::CamTable;
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
                *sp = axis.step(
                    self.tick,
                    self.dt,
                    &fb,
                    master.as_ref(),
                    &self.cams,
                    &mut self.handles,
                );
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
