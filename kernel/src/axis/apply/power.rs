//! MC_Power: switching the drive on and off (a disable while moving brakes first).

use crate::axis::command::{CommandError, PowerCommand};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::MotionKind;
use crate::axis::state::{AxisState, Event};
use crate::axis::{Axis, AxisKind};
use crate::profile::KinematicState;

impl Axis {
    pub(super) fn power(
        &mut self,
        p: PowerCommand,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        match p {
            PowerCommand::Enable => {
                if self.powered && self.state != AxisState::Disabled {
                    return Ok(CommandStatus::Done);
                }
                self.powered = true;
                // Take over at the actual position: no jump when the drive switches on.
                self.main = KinematicState::at_rest(self.actual_p);
                if self.cfg.kind == AxisKind::Real {
                    self.enable_handle = Some(h);
                    return Ok(CommandStatus::Busy);
                }
                self.enter(Event::PoweredOn);
                Ok(CommandStatus::Done)
            }
            PowerCommand::DisableForced => {
                self.power_off(handles);
                Ok(CommandStatus::Done)
            }
            PowerCommand::Disable => {
                if self.motion.is_none() && self.overlay.is_none() && self.follow.is_none() {
                    self.power_off(handles);
                    return Ok(CommandStatus::Done);
                }
                let decel = self
                    .motion
                    .map(|m| m.params.limits.dmax)
                    .unwrap_or(self.ptp_dynamics.deceleration);
                self.fold_overlay(handles);
                self.abort_all_but_values(handles);
                self.start_stop_motion(MotionKind::Disable, decel, h, "Power.Disable")?;
                self.enter(Event::StopStarted);
                Ok(CommandStatus::Active)
            }
        }
    }
}
