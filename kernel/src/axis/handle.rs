//! Command handles: what the application holds to follow one command (PLCopen's
//! Busy/Active/Done/CommandAborted/Error outputs).

use super::command::CommandError;

/// Identifies one submitted command. Ids are never reused (u64 never wraps in practice).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct HandleId(pub u64);

/// Status of one command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CommandStatus {
    /// Accepted, waiting (buffered) — not yet controlling the axis.
    Busy,
    /// Controlling the axis.
    Active,
    /// Finished what it was asked to do.
    Done,
    /// Ended by another command, a stop or power-off before it was done.
    Aborted,
    /// Refused or failed.
    Error(CommandError),
    /// So old that the handle table no longer holds it.
    Expired,
}

impl CommandStatus {
    /// Whether the command will not change status any more.
    pub const fn is_final(&self) -> bool {
        matches!(
            self,
            Self::Done | Self::Aborted | Self::Error(_) | Self::Expired
        )
    }

    /// PLCopen-style name.
    pub const fn name(&self) -> &'static str {
        match self {
            Self::Busy => "Busy",
            Self::Active => "Active",
            Self::Done => "Done",
            Self::Aborted => "CommandAborted",
            Self::Error(_) => "Error",
            Self::Expired => "Expired",
        }
    }
}

/// How many recent handles the table remembers.
pub const HANDLE_SLOTS: usize = 1024;

/// A fixed ring of the most recent handles' statuses: no allocation after construction.
#[derive(Clone, Debug)]
pub struct HandleTable {
    slots: Box<[(u64, CommandStatus)]>,
    next: u64,
}

impl Default for HandleTable {
    fn default() -> Self {
        Self::new()
    }
}

impl HandleTable {
    /// An empty table.
    pub fn new() -> Self {
        Self {
            slots: vec![(u64::MAX, CommandStatus::Expired); HANDLE_SLOTS].into_boxed_slice(),
            next: 0,
        }
    }

    /// Allocates a new id with the given initial status.
    pub fn issue(&mut self, status: CommandStatus) -> HandleId {
        let id = self.next;
        self.next += 1;
        if let Some(slot) = self.slots.get_mut((id as usize) % HANDLE_SLOTS) {
            *slot = (id, status);
        }
        HandleId(id)
    }

    /// Updates a handle's status; ignored for handles already final or expired, so a
    /// Done command can never turn Aborted later.
    pub fn set(&mut self, id: HandleId, status: CommandStatus) {
        if let Some(slot) = self.slots.get_mut((id.0 as usize) % HANDLE_SLOTS) {
            if slot.0 == id.0 && !slot.1.is_final() {
                slot.1 = status;
            }
        }
    }

    /// The status of a handle.
    pub fn get(&self, id: HandleId) -> CommandStatus {
        match self.slots.get((id.0 as usize) % HANDLE_SLOTS) {
            Some(&(slot_id, status)) if slot_id == id.0 => status,
            _ => CommandStatus::Expired,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn final_status_sticks_and_old_handles_expire() {
        let mut t = HandleTable::new();
        let h = t.issue(CommandStatus::Busy);
        t.set(h, CommandStatus::Active);
        t.set(h, CommandStatus::Done);
        t.set(h, CommandStatus::Aborted);
        assert_eq!(t.get(h), CommandStatus::Done);
        for _ in 0..HANDLE_SLOTS {
            t.issue(CommandStatus::Busy);
        }
        assert_eq!(t.get(h), CommandStatus::Expired);
    }
}
