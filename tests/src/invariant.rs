//! The invariant every drive test asserts (issue 10 §6), judged by what the simulated
//! drives recorded of the setpoints that reached them, not by what gantry meant to send:
//! per cycle the target changes by at most `vmax · T` in counts plus one count, no
//! following-error fault happens in a test that does not inject one, and no setpoint is
//! missed or doubled once the phase lock holds.
//!
//! In-process chains are read directly ([`assert_drive_invariants`]); a separate
//! `gantry-sim` process writes its drives' records as JSON when it exits (`--record FILE`),
//! read with [`read_records`] and judged with [`assert_record_invariants`].

use std::path::Path;

use gantry_kernel::mechanics::Scaling;
use gantry_kernel::AxisConfig;
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::record::{max_step_counts, DriveRecord, Expectation};

/// One drive under test: where it sits and what bounds its axis.
#[derive(Clone, Debug)]
pub struct DriveUnderTest {
    /// The axis' name (for messages).
    pub axis: String,
    /// The drive's position in the chain.
    pub slave: usize,
    /// The axis' maximum speed (units/s, `max.speed`).
    pub vmax: f64,
    /// The axis' scaling (units ⇄ counts).
    pub scaling: Scaling,
}

impl DriveUnderTest {
    /// Axis `config` on the drive at chain position `slave`.
    pub fn new(slave: usize, config: &AxisConfig, scaling: Scaling) -> Self {
        Self {
            axis: config.name.clone(),
            slave,
            vmax: config.max.vmax,
            scaling,
        }
    }

    /// Every axis of `kernel`, axis `i` on the drive at chain position `i`, with
    /// `scaling(i)`.
    pub fn of_kernel(
        kernel: &gantry_kernel::Kernel,
        scaling: impl Fn(usize) -> Scaling,
    ) -> Vec<Self> {
        kernel
            .axes()
            .iter()
            .enumerate()
            .map(|(i, a)| Self::new(i, a.config(), scaling(i)))
            .collect()
    }

    /// Every axis of a gantry configuration, on the drive its `drive` key names.
    pub fn of_config(config: &gantry::config::Config) -> Vec<Self> {
        config
            .axes
            .iter()
            .zip(&config.kernel_axes)
            .map(|(a, k)| {
                let scaling = a
                    .scaling()
                    .unwrap_or_else(|(key, reason)| panic!("axis {}: {key}: {reason}", a.name));
                Self::new(a.drive, k, scaling)
            })
            .collect()
    }

    /// The largest target step this axis may take in a cycle of `cycle_s` seconds.
    pub fn max_step_counts(&self, cycle_s: f64) -> u64 {
        max_step_counts(self.scaling.velocity_to_counts(self.vmax), cycle_s)
    }
}

/// What the test says about itself.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TestConditions {
    /// The test injects a following-error fault.
    pub injects_following_error: bool,
    /// The master's cycle is locked to SYNC0 (no setpoint may be missed or doubled).
    pub phase_locked: bool,
}

/// Checks every drive's record; the message names each axis that broke the invariant and
/// how. `records[i]` is the record of the drive at chain position `i` (`None`: that
/// device is no drive).
pub fn check_records(
    records: &[Option<DriveRecord>],
    drives: &[DriveUnderTest],
    cycle_s: f64,
    conditions: TestConditions,
) -> Result<(), String> {
    assert!(!drives.is_empty(), "the invariant needs at least one drive");
    let mut broken = Vec::new();
    for d in drives {
        let expect = Expectation {
            max_step_counts: d.max_step_counts(cycle_s),
            injects_following_error: conditions.injects_following_error,
            phase_locked: conditions.phase_locked,
        };
        match records.get(d.slave) {
            Some(Some(r)) => {
                if let Err(v) = r.check(&expect) {
                    broken.push(format!("axis {} (drive {}): {v}; {r:?}", d.axis, d.slave));
                }
            }
            _ => broken.push(format!(
                "axis {} (drive {}): no drive record at that chain position",
                d.axis, d.slave
            )),
        }
    }
    if broken.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "drive invariant broken (issue 10 §6):\n  {}",
            broken.join("\n  ")
        ))
    }
}

/// The records of every device in `chain` (`None` for devices that are no drive).
pub fn records(chain: &SlaveChain) -> Vec<Option<DriveRecord>> {
    chain
        .slaves()
        .iter()
        .map(|s| s.device().record().copied())
        .collect()
}

/// Asserts the invariant on every drive in `drives`, from the records the in-process
/// `chain` kept.
pub fn assert_drive_invariants(
    chain: &SlaveChain,
    drives: &[DriveUnderTest],
    cycle_s: f64,
    conditions: TestConditions,
) {
    if let Err(e) = check_records(&records(chain), drives, cycle_s, conditions) {
        panic!("{e}");
    }
}

/// Reads the records a `gantry-sim --record FILE` wrote when it exited: a JSON array with
/// one entry per chain position, `null` for devices that are no drive.
pub fn read_records(path: &Path) -> Result<Vec<Option<DriveRecord>>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Asserts the invariant on the records `gantry-sim --record FILE` wrote.
pub fn assert_record_invariants(
    path: &Path,
    drives: &[DriveUnderTest],
    cycle_s: f64,
    conditions: TestConditions,
) {
    let records = read_records(path).unwrap_or_else(|e| panic!("drive records: {e}"));
    if let Err(e) = check_records(&records, drives, cycle_s, conditions) {
        panic!("{} ({})", e, path.display());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive(slave: usize) -> DriveUnderTest {
        DriveUnderTest {
            axis: format!("a{slave}"),
            slave,
            vmax: 200.0,
            scaling: crate::ball_screw_5mm(),
        }
    }

    #[test]
    fn a_step_beyond_vmax_t_names_the_axis() {
        // 200 mm/s at 2^17 counts per 5 mm: 5242.88 counts per ms, so 5243 is the bound.
        assert_eq!(drive(0).max_step_counts(1e-3), 5243);
        let mut ok = DriveRecord::default();
        ok.target(0);
        ok.target(5243);
        let mut bad = ok;
        bad.target(5243 + 5244);
        let conditions = TestConditions::default();
        assert_eq!(
            check_records(&[Some(ok), None], &[drive(0)], 1e-3, conditions),
            Ok(())
        );
        let e = check_records(
            &[Some(ok), Some(bad)],
            &[drive(0), drive(1)],
            1e-3,
            conditions,
        )
        .unwrap_err();
        assert!(
            e.contains("axis a1 (drive 1): target stepped 5244 counts") && !e.contains("a0"),
            "{e}"
        );
        let e = check_records(&[Some(ok), None], &[drive(1)], 1e-3, conditions).unwrap_err();
        assert!(e.contains("axis a1 (drive 1): no drive record"), "{e}");
    }

    #[test]
    fn records_round_trip_through_the_file_gantry_sim_writes() {
        let mut r = DriveRecord::default();
        r.target(1);
        r.target(3);
        let path = std::env::temp_dir().join(format!("records-{}.json", std::process::id()));
        std::fs::write(&path, serde_json::to_string(&[Some(r), None]).unwrap()).unwrap();
        let back = read_records(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!(back[0].unwrap().max_target_step_counts, 2);
        assert!(back[1].is_none());
        assert!(read_records(Path::new("/nonexistent/records.json"))
            .unwrap_err()
            .starts_with("/nonexistent/records.json: "));
    }
}
