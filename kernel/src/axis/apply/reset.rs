//! MC_Reset: leaving ErrorStop (after the drive has cleared its own fault).

use crate::axis::command::CommandError;
use crate::axis::handle::{CommandStatus, HandleId};
use crate::axis::state::{AxisState, Event};
use crate::axis::Axis;

impl Axis {
    pub(super) fn reset(&mut self, h: HandleId) -> Result<CommandStatus, CommandError> {
        if self.state != AxisState::ErrorStop {
            return Ok(CommandStatus::Done);
        }
        if self.drive_fault {
            // The drive must clear its fault first (fault reset on the bus).
            self.reset_pending = Some((h, self.last_tick));
            return Ok(CommandStatus::Busy);
        }
        if self.motion.is_some() {
            // Still braking after the error: reset once it stands.
            return Err(CommandError::NotAllowedInState {
                command: "Reset",
                state: AxisState::ErrorStop,
            });
        }
        // Standstill only with the drive's power on (PLCopen MC_Reset): a drive that
        // left Operation enabled without a fault while the axis was in ErrorStop (a
        // CANopen node reset, its power stage off) leaves the axis Disabled, to be
        // enabled again, not Standstill on a drive that takes no set value.
        if self.drive_enabled == Some(false) {
            self.powered = false;
        }
        self.enter(Event::Reset {
            powered: self.powered,
        });
        self.status.error = None;
        self.refresh_status();
        Ok(CommandStatus::Done)
    }
}
