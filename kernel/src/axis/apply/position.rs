//! MC_SetPosition and marking the axis homed: bookkeeping of the position frame, no motion.

use crate::axis::command::{position, CommandError, Operand};
use crate::axis::handle::CommandStatus;
use crate::axis::Axis;

impl Axis {
    /// Sets the position (absolute: the axis is then referenced) without moving: the set
    /// and actual positions, the last target and the offset to the drive all shift alike.
    pub(super) fn set_position(
        &mut self,
        value: f64,
        relative: bool,
    ) -> Result<CommandStatus, CommandError> {
        let v = position("SetPosition", Operand::Position, value)?;
        let mut new_p = if relative { self.main.p + v } else { v };
        if let Some(m) = self.cfg.mechanics.modulo {
            // The position within the period; whole turns are not the user's to set.
            new_p = self.main.p + m.delta_positive(m.wrap(self.main.p), m.wrap(new_p));
        }
        let shift = new_p - self.main.p;
        self.main.p = new_p;
        self.actual_p += shift;
        self.position_offset += shift;
        if let Some(t) = self.last_target.as_mut() {
            *t += shift;
        }
        if !relative {
            self.homed = true;
        }
        self.normalise_frame();
        self.refresh_status();
        Ok(CommandStatus::Done)
    }

    /// Marks the axis homed (or not) without touching its position.
    pub(super) fn set_homed(&mut self, homed: bool) -> Result<CommandStatus, CommandError> {
        self.homed = homed;
        self.refresh_status();
        Ok(CommandStatus::Done)
    }
}
