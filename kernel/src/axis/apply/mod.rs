//! Applying commands to an axis, one module per command family: operand validation, how a
//! new command joins the running one (aborting, buffered, blending, ramp break), and
//! planning from the last set values.
//!
//! Everything here runs between two cycles with the state of the last cycle, so a new
//! profile starts exactly where the old one was: no jump in position or velocity (nor in
//! acceleration for S-curves).

mod buffer;
mod change;
mod home;
mod jog;
mod operands;
mod plan;
mod position;
mod power;
mod ptp;
mod reset;
mod stop;
mod sync;
mod velocity;

pub(crate) use sync::SyncContext;

use super::command::{Command, CommandError, PowerCommand};
use super::handle::{CommandStatus, HandleId, HandleTable};
use super::state::{accepts, AxisState};
use super::Axis;

impl Axis {
    /// Applies `cmd` with handle `h`. Returns the handle's initial status, or the error
    /// that refused the command (the axis then goes on unchanged).
    pub(crate) fn apply(
        &mut self,
        cmd: &Command,
        sync: &SyncContext<'_>,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let r = self.apply_to_source(cmd, sync, h, handles);
        if r.is_ok() && self.motion.is_some() {
            // A move of the axis' own (MovePtp, MoveVelocity, Halt, Stop…) took over from
            // the master relation, from the relation's last set values.
            if let Some(f) = self.follow.take() {
                handles.set(f.handle, CommandStatus::Aborted);
            }
        }
        r
    }

    fn apply_to_source(
        &mut self,
        cmd: &Command,
        sync: &SyncContext<'_>,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let name = cmd.name();
        // Reset acknowledges an external axis' encoder failure as it does a drive's.
        let bookkeeping = matches!(
            cmd,
            Command::SetPosition { .. }
                | Command::SetHomed(_)
                | Command::SetReference(_)
                | Command::Reset
        );
        if !self.cfg.kind.is_commandable() && !bookkeeping {
            return Err(CommandError::NotCommandable {
                command: name,
                kind: self.cfg.kind.name(),
            });
        }
        if self.state == AxisState::ErrorStop && !accepts(self.state, cmd) {
            // PLCopen: ErrorStop is left only through Reset; say why the axis is there.
            return Err(CommandError::InErrorStop {
                command: name,
                cause: self.error_summary(),
            });
        }
        if !accepts(self.state, cmd) {
            return Err(CommandError::NotAllowedInState {
                command: name,
                state: self.state,
            });
        }
        if matches!(
            self.state,
            AxisState::Homing | AxisState::SynchronizedMotion
        ) && queued(cmd)
        {
            // A homing run or a master relation has no end to buffer behind: abort it
            // (Aborting) instead.
            return Err(CommandError::NotAllowedInState {
                command: name,
                state: self.state,
            });
        }
        if let Some(r) = self.lent_command(cmd, handles) {
            return r;
        }
        if let Some(group) = self.group {
            match cmd {
                // Braking and power off take the axis off its group's path (the group then
                // goes to ErrorStop and brakes its other axes along the path).
                Command::Stop { .. }
                | Command::QuickStop
                | Command::Power(PowerCommand::Disable | PowerCommand::DisableForced) => {
                    self.group = None;
                }
                Command::Reset | Command::SetHomed(_) => {}
                _ => {
                    return Err(CommandError::MovesWithGroup {
                        command: name,
                        group,
                    })
                }
            }
        }
        self.check_towards_limit(cmd)?;
        match *cmd {
            Command::MoveHome(ref c) => self.move_home(c, h, handles),
            Command::StepAbsoluteSwitch(ref p) => self.step_absolute_switch(p, h, handles),
            Command::SetReference(p) => self.set_reference(p),
            Command::Power(p) => self.power(p, h, handles),
            Command::Reset => self.reset(h),
            Command::MovePtp(m) => self.move_ptp(m, h, handles),
            Command::MoveVelocity(v) => self.move_velocity(v, h, handles),
            Command::Reverse => self.reverse(handles),
            Command::Jog(j) => self.jog(&j, h, handles),
            Command::Change(what, value) => self.change(what, value),
            Command::Halt { mode, deceleration } => self.halt(mode, deceleration, h, handles),
            Command::Stop { deceleration } => self.stop(deceleration, h, handles),
            Command::Release => self.release(),
            Command::QuickStop => self.quick_stop(h, handles),
            Command::SetPosition { position, relative } => self.set_position(position, relative),
            Command::SetHomed(b) => self.set_homed(b),
            Command::GearIn(g) => self.gear_in(&g, sync, h, handles),
            Command::GearInPos(g) => self.gear_in_pos(&g, sync, h, handles),
            Command::CamIn(c) => self.cam_in(&c, sync, h, handles),
            Command::GearOut => self.sync_out("GearOut", false, h, handles),
            Command::CamOut => self.sync_out("CamOut", true, h, handles),
            Command::MasterJog(j) => self.master_jog(&j, sync, h, handles),
        }
    }
}

/// Whether `cmd` waits behind the running move (a buffer mode other than Aborting).
fn queued(cmd: &Command) -> bool {
    match cmd {
        Command::MovePtp(m) => m.buffer.is_queued(),
        Command::MoveVelocity(v) => v.buffer.is_queued(),
        _ => false,
    }
}
