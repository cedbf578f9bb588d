//! What a drive saw of its master, kept by the drive itself so that a test can judge the
//! master by what arrived on the wire rather than by what the master meant to send.
//!
//! Every drive test asserts on it (see `gantry_tests::invariant`): the target never
//! steps further in one cycle than the axis' maximum speed allows, no following-error
//! fault happens unless the test injects one, and no setpoint is missed or doubled once
//! the master's cycle is locked to SYNC0.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A drive's record of the setpoints it took (serialised as JSON by `gantry-sim --record`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DriveRecord {
    /// Target positions taken while in Operation enabled.
    pub targets: u64,
    /// The largest change between two consecutive targets taken in Operation enabled, per
    /// master cycle (counts, as the drive's 32-bit counter wraps: a step across ±2³¹ is
    /// its short way). A step across setpoints the drive never took — a SYNC0 period with
    /// none, or one overwritten by a second in the same period — spans as many master
    /// cycles more and is divided by them: the master is judged by what it sent per
    /// cycle, the host's timing by `sync_missed` / `sync_doubled`.
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
    #[serde(skip)]
    previous: Option<i32>,
    /// Setpoints the master sent that the drive did not take since its last target.
    #[serde(skip)]
    untaken: u64,
    /// Of those, SYNC0 periods that brought none.
    #[serde(skip)]
    missed_since: u64,
}

/// What a test expects of every drive's record (issue 10 §6), see [`DriveRecord::check`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Expectation {
    /// The largest target step the axis may take (counts): `vmax · T` in counts plus one
    /// count, see [`max_step_counts`].
    pub max_step_counts: u64,
    /// The test injects a following-error fault: do not count them against the master.
    pub injects_following_error: bool,
    /// The master's cycle is locked to SYNC0: no setpoint may be missed or doubled.
    pub phase_locked: bool,
}

/// The largest change of the target between two cycles of `cycle_s` seconds that an axis
/// whose speed is at most `vmax_counts_per_s` may send: `vmax · T` plus one count, as
/// both ends are rounded to whole counts (`|round(a) − round(b)| ≤ |a − b| + 1`).
pub fn max_step_counts(vmax_counts_per_s: f64, cycle_s: f64) -> u64 {
    let exact = (vmax_counts_per_s * cycle_s).abs();
    // A relative 1e-12 keeps an exact product of the kernel's f64 path from rounding to
    // one count less than the set values really moved.
    (exact * (1.0 + 1e-12)).floor() as u64 + 1
}

/// A drive saw its master break the invariant.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum Violation {
    /// The drive never took a target in Operation enabled: the test moved nothing.
    #[error("took no target in Operation enabled (the test did not drive it)")]
    NoTargets,
    /// A target stepped further in one cycle than the axis' maximum speed allows.
    #[error(
        "target stepped {step} counts in one cycle at target #{at}; vmax · T + 1 count is {limit}"
    )]
    TargetStep {
        /// The step (counts).
        step: u64,
        /// Targets taken before it.
        at: u64,
        /// The bound (counts).
        limit: u64,
    },
    /// Following-error faults in a test that injects none.
    #[error("{faults} following-error fault(s) (0x8611) in a test that injects none")]
    FollowingError {
        /// How many.
        faults: u32,
    },
    /// Setpoints missed or doubled while the phase lock held.
    #[error(
        "{missed} setpoint(s) missed and {doubled} doubled at SYNC0 while the phase lock held"
    )]
    Sync {
        /// SYNC0 events without a new setpoint.
        missed: u32,
        /// Setpoints overwritten before the drive took them.
        doubled: u32,
    },
}

impl DriveRecord {
    /// Checks the record against `expect`: the first rule broken, in the order of
    /// [`Violation`]'s variants.
    pub fn check(&self, expect: &Expectation) -> Result<(), Violation> {
        if self.targets == 0 {
            return Err(Violation::NoTargets);
        }
        if self.max_target_step_counts > expect.max_step_counts {
            return Err(Violation::TargetStep {
                step: self.max_target_step_counts,
                at: self.max_target_step_at,
                limit: expect.max_step_counts,
            });
        }
        if !expect.injects_following_error && self.following_error_faults != 0 {
            return Err(Violation::FollowingError {
                faults: self.following_error_faults,
            });
        }
        if expect.phase_locked && (self.sync_missed != 0 || self.sync_doubled != 0) {
            return Err(Violation::Sync {
                missed: self.sync_missed,
                doubled: self.sync_doubled,
            });
        }
        Ok(())
    }
}

impl DriveRecord {
    /// `n` SYNC0 periods passed with no setpoint (the master's frames for them were late
    /// or lost).
    pub fn missed(&mut self, n: u32) {
        self.sync_missed = self.sync_missed.saturating_add(n);
        self.untaken += u64::from(n);
        self.missed_since += u64::from(n);
    }

    /// A second setpoint arrived within one SYNC0 period: the first is never taken.
    pub fn doubled(&mut self) {
        self.sync_doubled = self.sync_doubled.saturating_add(1);
        self.untaken += 1;
    }

    /// SYNC0 periods without a setpoint since the last target taken (the drive's own count
    /// of missed SM events: the next step covers as many periods more).
    pub fn missed_since_target(&self) -> u64 {
        self.missed_since
    }

    /// The drive took `target` in Operation enabled.
    pub fn target(&mut self, target: i32) {
        if let Some(p) = self.previous {
            let cycles = 1 + self.untaken;
            let step = u64::from(target.wrapping_sub(p).unsigned_abs()).div_ceil(cycles);
            if step > self.max_target_step_counts {
                self.max_target_step_counts = step;
                self.max_target_step_at = self.targets;
            }
        }
        self.previous = Some(target);
        self.untaken = 0;
        self.missed_since = 0;
        self.targets += 1;
    }

    /// The drive left Operation enabled: the next target starts a new sequence.
    pub fn disabled(&mut self) {
        self.previous = None;
        self.untaken = 0;
        self.missed_since = 0;
    }

    /// The drive faulted with `code`.
    pub fn fault(&mut self, code: u16) {
        self.faults += 1;
        self.last_fault_code = code;
    }
}

/// The drive records file could not be written or read.
#[derive(Debug, Error)]
pub enum RecordsFileError {
    /// Writing it failed.
    #[error("cannot write the drive records to {path}: {reason}")]
    Write {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// Reading it failed, or it is no records file.
    #[error("{path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

/// Writes `records` (one entry per chain position, `None` for devices that are no drive;
/// see [`crate::chain::SlaveChain::records`]) to `path` as a JSON array, through a
/// temporary file beside it so that a reader never sees half of it. `gantry-sim --record`,
/// `gantry run` with `bus.simulator_record` and `gantry demo` write this file.
pub fn write_records(
    path: &std::path::Path,
    records: &[Option<DriveRecord>],
) -> Result<(), RecordsFileError> {
    let write = |reason: String| RecordsFileError::Write {
        path: path.display().to_string(),
        reason,
    };
    let text = serde_json::to_string_pretty(records).map_err(|e| write(e.to_string()))?;
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| write(e.to_string()))
}

/// Reads a file [`write_records`] wrote.
pub fn read_records(path: &std::path::Path) -> Result<Vec<Option<DriveRecord>>, RecordsFileError> {
    let read = |reason: String| RecordsFileError::Read {
        path: path.display().to_string(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|e| read(e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| read(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_records_file_round_trips_and_errors_name_the_file() {
        let mut r = DriveRecord::default();
        r.target(1);
        r.target(3);
        let dir = std::env::temp_dir().join(format!("gantry-sim-records-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("records.json");
        write_records(&path, &[Some(r), None]).unwrap();
        assert!(!path.with_extension("tmp").exists());
        let back = read_records(&path).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!(back[0].map(|r| r.max_target_step_counts), Some(2));
        assert!(back[1].is_none());
        let missing = dir.join("missing/records.json");
        let e = write_records(&missing, &[]).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!(
                "cannot write the drive records to {}: ",
                missing.display()
            )),
            "{e}"
        );
        std::fs::write(&path, "[{\"targets\": 1}]").unwrap();
        let e = read_records(&path).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}: missing field", path.display())),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
        let e = read_records(&missing).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", missing.display())), "{e}");
    }

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

    #[test]
    fn a_step_across_untaken_setpoints_counts_per_master_cycle() {
        let mut r = DriveRecord::default();
        r.target(0);
        r.target(100);
        // One period without a setpoint, then one overwritten: the next step spans three
        // master cycles.
        r.missed(1);
        r.doubled();
        r.target(400);
        assert_eq!(r.max_target_step_counts, 100);
        assert_eq!((r.sync_missed, r.sync_doubled), (1, 1));
        r.target(550);
        assert_eq!(
            r.max_target_step_counts, 150,
            "counted anew after each target"
        );
    }

    #[test]
    fn the_check_names_each_broken_rule() {
        let expect = Expectation {
            max_step_counts: max_step_counts(26_214.4 * 1000.0, 1e-3),
            injects_following_error: false,
            phase_locked: true,
        };
        assert_eq!(expect.max_step_counts, 26_215, "floor(26214.4) + 1");
        let mut r = DriveRecord::default();
        assert_eq!(r.check(&expect), Err(Violation::NoTargets));
        r.target(0);
        r.target(26_215);
        assert_eq!(r.check(&expect), Ok(()));
        r.target(2 * 26_215 + 1);
        assert_eq!(
            r.check(&expect).unwrap_err().to_string(),
            "target stepped 26216 counts in one cycle at target #2; vmax · T + 1 count is 26215"
        );
        let mut r = DriveRecord::default();
        r.target(0);
        r.following_error_faults = 1;
        assert_eq!(
            r.check(&expect),
            Err(Violation::FollowingError { faults: 1 })
        );
        let injected = Expectation {
            injects_following_error: true,
            ..expect
        };
        assert_eq!(r.check(&injected), Ok(()));
        r.sync_doubled = 2;
        assert_eq!(
            r.check(&injected).unwrap_err().to_string(),
            "0 setpoint(s) missed and 2 doubled at SYNC0 while the phase lock held"
        );
        let free_running = Expectation {
            phase_locked: false,
            ..injected
        };
        assert_eq!(r.check(&free_running), Ok(()));
    }

    #[test]
    fn a_record_survives_json_without_its_private_state() {
        let mut r = DriveRecord::default();
        r.target(5);
        r.target(-7);
        r.fault(0x8611);
        let text = serde_json::to_string(&r).unwrap();
        let back: DriveRecord = serde_json::from_str(&text).unwrap();
        assert_eq!(back.max_target_step_counts, 12);
        assert_eq!(
            (back.targets, back.faults, back.last_fault_code),
            (2, 1, 0x8611)
        );
    }
}
