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

use gantry::drive_records::{judge, AxisBound, AxisLimit};
use gantry_drives::scaling::Scaling;
use gantry_kernel::AxisConfig;
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::record::{max_step_counts, DriveRecord};

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
        AxisLimit::of_config(config)
            .unwrap_or_else(|e| panic!("{e}"))
            .into_iter()
            .map(|l| Self {
                axis: l.axis,
                slave: l.drive,
                vmax: l.vmax,
                scaling: l.scaling,
            })
            .collect()
    }

    /// The largest target step this axis may take in a cycle of `cycle_s` seconds.
    pub fn max_step_counts(&self, cycle_s: f64) -> u64 {
        max_step_counts(self.scaling.velocity_to_counts(self.vmax), cycle_s)
    }
}

/// What the test says about itself: whether it injects a following-error fault, and
/// whether the master's cycle is locked to SYNC0 (then no setpoint may be missed or
/// doubled).
pub type TestConditions = gantry::drive_records::Conditions;

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
    let bounds: Vec<AxisBound> = drives
        .iter()
        .map(|d| AxisBound {
            axis: d.axis.clone(),
            drive: d.slave,
            max_step_counts: d.max_step_counts(cycle_s),
        })
        .collect();
    let verdict = judge(records, &bounds, conditions);
    if verdict.holds() {
        Ok(())
    } else {
        Err(format!(
            "drive invariant broken (issue 10 §6):\n  {}",
            verdict.broken.join("\n  ")
        ))
    }
}

/// The records of every device in `chain` (`None` for devices that are no drive).
pub fn records(chain: &SlaveChain) -> Vec<Option<DriveRecord>> {
    chain.records()
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
    gantry_sim::plant::record::read_records(path).map_err(|e| e.to_string())
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
    fn a_records_file_that_is_not_there_is_named() {
        let e = read_records(Path::new("/nonexistent/records.json")).unwrap_err();
        assert!(e.starts_with("/nonexistent/records.json: "), "{e}");
    }
}
