//! What a drive saw of its master, kept by the drive itself so that a test can judge the
//! master by what arrived on the wire rather than by what the master meant to send.
//!
//! Every drive test asserts on it (see `gantry_tests::invariant`): the target never
//! steps further in one cycle than the axis' maximum speed allows, no following-error
//! fault happens unless the test injects one, and no setpoint is missed or doubled once
//! the master's cycle is locked to SYNC0.

/// A drive's record of the setpoints it took.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriveRecord {
    /// Target positions taken while in Operation enabled.
    pub targets: u64,
    /// The largest change between two consecutive targets taken in Operation enabled
    /// (counts, as the drive's 32-bit counter wraps: a step across ±2³¹ is its short way).
    pub max_target_step_counts: u64,
    /// When the largest step was taken (number of targets taken before it).
    pub max_target_step_at: u64,
    /// Faults for a following error beyond the window (0x6065) for longer than 0x6066.
    pub following_error_faults: u32,
    /// Faults of any kind (the last code is `last_fault_code`).
    pub faults: u32,
    /// Error code (0x603F) of the last fault, 0 when there was none.
    pub last_fault_code: u16,
    /// SYNC0 events at which no new setpoint had arrived since the previous one.
    pub sync_missed: u32,
    /// Frames that brought a second setpoint within one SYNC0 period (the first one
    /// was overwritten before the drive took it).
    pub sync_doubled: u32,
    previous: Option<i32>,
}

impl DriveRecord {
    /// The drive took `target` in Operation enabled.
    pub fn target(&mut self, target: i32) {
        if let Some(p) = self.previous {
            let step = u64::from(target.wrapping_sub(p).unsigned_abs());
            if step > self.max_target_step_counts {
                self.max_target_step_counts = step;
                self.max_target_step_at = self.targets;
            }
        }
        self.previous = Some(target);
        self.targets += 1;
    }

    /// The drive left Operation enabled: the next target starts a new sequence.
    pub fn disabled(&mut self) {
        self.previous = None;
    }

    /// The drive faulted with `code`.
    pub fn fault(&mut self, code: u16) {
        self.faults += 1;
        self.last_fault_code = code;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_measured_the_short_way_across_the_counter_wrap() {
        let mut r = DriveRecord::default();
        r.target(i32::MAX - 5);
        r.target(i32::MIN + 4);
        assert_eq!(r.max_target_step_counts, 10);
        r.disabled();
        r.target(0);
        assert_eq!(
            r.max_target_step_counts, 10,
            "a new sequence after disabling"
        );
        r.target(-30);
        assert_eq!((r.max_target_step_counts, r.max_target_step_at), (30, 3));
        assert_eq!(r.targets, 4);
    }
}
