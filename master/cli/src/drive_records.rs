//! What simulated drives recorded of the setpoints gantry sent them
//! ([`DriveRecord`], kept by each drive of `gantry-sim`), judged against each axis' bound:
//! the invariant every drive test asserts (issue 10 §6) — per cycle the target changes by
//! at most `vmax · T` in counts plus one count, no following-error fault happens unless
//! one is injected, and no setpoint is missed or doubled once the phase lock holds.
//!
//! `gantry run` on the in-process simulator writes the records when it exits
//! (`bus.simulator_record`) and prints [`Verdict::summary`]; `gantry demo`
//! fails on a broken invariant; the tests judge with [`judge`].

use std::io::Write;
use std::path::Path;

use gantry_drives::scaling::Scaling;
use gantry_sim::plant::record::{max_step_counts, write_records, DriveRecord, Expectation};

use gantry::config::Config;

/// One axis' drive and the largest target step the axis may send it in a cycle.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AxisBound {
    /// The axis' name.
    pub axis: String,
    /// Its drive's position in the chain.
    pub drive: usize,
    /// `vmax · T` in counts plus one count ([`max_step_counts`]).
    pub max_step_counts: u64,
}

impl AxisBound {
    /// Axis `axis` on the drive at chain position `drive`, at most `vmax` units/s scaled
    /// by `scaling`, in cycles of `cycle_s` seconds.
    pub fn new(axis: &str, drive: usize, scaling: &Scaling, vmax: f64, cycle_s: f64) -> Self {
        Self {
            axis: axis.into(),
            drive,
            max_step_counts: max_step_counts(scaling.velocity_to_counts(vmax), cycle_s),
        }
    }

    /// Every axis of a gantry configuration, in cycles of its `bus.cycle_us`.
    pub fn of_config(config: &Config) -> Result<Vec<Self>, String> {
        let cycle_s = f64::from(config.bus.cycle_us) * 1e-6;
        Ok(AxisLimit::of_config(config)?
            .iter()
            .map(|l| l.bound(cycle_s))
            .collect())
    }
}

/// An axis of a configuration as the invariant sees it: its drive, scaling and maximum
/// speed.
#[derive(Clone, Debug)]
pub struct AxisLimit {
    /// The axis' name.
    pub axis: String,
    /// Its drive's position in the chain.
    pub drive: usize,
    /// Units ⇄ counts.
    pub scaling: Scaling,
    /// `max.speed` (units/s).
    pub vmax: f64,
}

impl AxisLimit {
    /// Every real axis of a gantry configuration (the others have no drive whose record
    /// could be judged); the error names an axis whose scaling cannot be.
    pub fn of_config(config: &Config) -> Result<Vec<Self>, String> {
        config
            .axes
            .iter()
            .zip(&config.kernel_axes)
            .filter(|(a, _)| a.axis_type == gantry::config::AxisType::Real)
            .map(|(a, k)| {
                let scaling = a
                    .scaling()
                    .map_err(|(key, reason)| format!("axis {:?}: {key}: {reason}", a.name))?;
                Ok(Self {
                    axis: a.name.clone(),
                    drive: a.drive,
                    scaling,
                    vmax: k.max.vmax,
                })
            })
            .collect()
    }

    /// Its bound in cycles of `cycle_s` seconds.
    pub fn bound(&self, cycle_s: f64) -> AxisBound {
        AxisBound::new(&self.axis, self.drive, &self.scaling, self.vmax, cycle_s)
    }
}

/// What a run says about itself when its records are judged.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Conditions {
    /// Following-error faults were injected: they are not held against the master.
    pub injects_following_error: bool,
    /// The master's cycle was locked to SYNC0 all along: no setpoint may be missed or
    /// doubled.
    pub phase_locked: bool,
}

/// The records judged, axis by axis.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Verdict {
    /// Per axis, what its drive saw: `x: largest target step 1719 counts (bound 6554),
    /// 5120 targets, 0 faults, 0 following-error faults, setpoints missed 0, doubled 0`.
    pub summary: Vec<String>,
    /// Per axis that broke the invariant, how: `axis x (drive 0): target stepped …`.
    pub broken: Vec<String>,
}

impl Verdict {
    /// The invariant held on every axis.
    pub fn holds(&self) -> bool {
        self.broken.is_empty()
    }
}

/// Judges `records` (`records[i]`: the drive at chain position `i`, `None` for devices
/// that are no drive) against `bounds` under `conditions`. An axis whose drive kept no
/// record, or took no target at all, breaks it: a test that drives nothing asserts
/// nothing.
pub fn judge(
    records: &[Option<DriveRecord>],
    bounds: &[AxisBound],
    conditions: Conditions,
) -> Verdict {
    let mut verdict = Verdict::default();
    for b in bounds {
        let Some(Some(r)) = records.get(b.drive) else {
            verdict.broken.push(format!(
                "axis {} (drive {}): no drive record at that chain position",
                b.axis, b.drive
            ));
            continue;
        };
        verdict.summary.push(format!(
            "{}: largest target step {} counts (bound {}), {} targets, {} faults, \
             {} following-error faults, setpoints missed {}, doubled {}",
            b.axis,
            r.max_target_step_counts,
            b.max_step_counts,
            r.targets,
            r.faults,
            r.following_error_faults,
            r.sync_missed,
            r.sync_doubled
        ));
        let expect = Expectation {
            max_step_counts: b.max_step_counts,
            injects_following_error: conditions.injects_following_error,
            phase_locked: conditions.phase_locked,
        };
        if let Err(v) = r.check(&expect) {
            verdict
                .broken
                .push(format!("axis {} (drive {}): {v}; {r:?}", b.axis, b.drive));
        }
    }
    verdict
}

/// What `gantry run` on the in-process simulator does at exit with `bus.simulator_record`:
/// writes `records` to `path` ([`write_records`]) and tells `out` what each axis' drive saw
/// — an axis never driven says so; the others' figures against their bound, and any break
/// of the invariant. The run is judged as one whose phase lock may have slipped (a host
/// that is not real time, a bring-up): missed and doubled setpoints are shown, not held
/// against it.
pub fn report_at_exit(
    config: &Config,
    records: &[Option<DriveRecord>],
    path: &str,
    out: &mut dyn Write,
) {
    if let Err(e) = write_records(Path::new(path), records) {
        let _ = writeln!(out, "gantry: {e}");
        return;
    }
    let _ = writeln!(out, "gantry: drive records written to {path}");
    let bounds = match AxisBound::of_config(config) {
        Ok(b) => b,
        Err(e) => {
            let _ = writeln!(out, "gantry: drive records not judged: {e}");
            return;
        }
    };
    let (driven, idle): (Vec<_>, Vec<_>) = bounds.into_iter().partition(|b| {
        records
            .get(b.drive)
            .and_then(Option::as_ref)
            .is_some_and(|r| r.targets > 0)
    });
    let verdict = judge(records, &driven, Conditions::default());
    for line in verdict.summary {
        let _ = writeln!(out, "  {line}");
    }
    for b in idle {
        let _ = writeln!(out, "  {}: took no target (not driven)", b.axis);
    }
    for line in verdict.broken {
        let _ = writeln!(out, "gantry: drive invariant broken: {line}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::scaling::ScalingConfig;

    fn bound(axis: &str, drive: usize) -> AxisBound {
        let scaling = Scaling::new(ScalingConfig {
            counts_per_motor_rev: 1 << 17,
            motor_revs: 1,
            load_revs: 1,
            units_per_load_rev: 5.0,
            invert: false,
        })
        .unwrap();
        AxisBound::new(axis, drive, &scaling, 200.0, 1e-3)
    }

    #[test]
    fn a_step_beyond_vmax_t_names_the_axis_and_an_undriven_drive_counts_as_broken() {
        // 200 mm/s at 2^17 counts per 5 mm: 5242.88 counts per ms, so 5243 is the bound.
        assert_eq!(bound("x", 0).max_step_counts, 5243);
        let mut ok = DriveRecord::default();
        ok.target(0);
        ok.target(5243);
        let mut bad = ok;
        bad.target(5243 + 5244);
        let v = judge(&[Some(ok), None], &[bound("x", 0)], Conditions::default());
        assert!(v.holds(), "{v:?}");
        assert_eq!(
            v.summary,
            [
                "x: largest target step 5243 counts (bound 5243), 2 targets, 0 faults, \
              0 following-error faults, setpoints missed 0, doubled 0"
            ]
        );
        let v = judge(
            &[Some(ok), Some(bad), Some(DriveRecord::default())],
            &[bound("x", 0), bound("y", 1), bound("z", 2), bound("w", 3)],
            Conditions::default(),
        );
        assert_eq!(v.broken.len(), 3, "{v:?}");
        assert!(
            v.broken[0].starts_with(
                "axis y (drive 1): target stepped 5244 counts in one cycle at target #2"
            ),
            "{v:?}"
        );
        assert!(
            v.broken[1].starts_with("axis z (drive 2): took no target"),
            "{v:?}"
        );
        assert_eq!(
            v.broken[2],
            "axis w (drive 3): no drive record at that chain position"
        );
    }

    #[test]
    fn missed_setpoints_count_only_when_the_phase_lock_held() {
        let mut r = DriveRecord::default();
        r.target(0);
        r.missed(1);
        r.target(10);
        let free = judge(&[Some(r)], &[bound("x", 0)], Conditions::default());
        assert!(free.holds(), "{free:?}");
        let locked = Conditions {
            phase_locked: true,
            ..Conditions::default()
        };
        let v = judge(&[Some(r)], &[bound("x", 0)], locked);
        assert!(v.broken[0].contains("1 setpoint(s) missed"), "{v:?}");
    }

    #[test]
    fn the_bounds_of_the_example_configuration() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../deploy/examples/sim-4-axes.toml"
        );
        let config = Config::load(path).unwrap();
        let bounds = AxisBound::of_config(&config).unwrap();
        let names: Vec<_> = bounds.iter().map(|b| (b.axis.as_str(), b.drive)).collect();
        assert_eq!(names, [("x", 0), ("y", 1), ("z", 2), ("c", 3)]);
        // x: 250 mm/s at 2^17 counts per 5 mm, 1 ms: 6553.6 counts per cycle.
        assert_eq!(bounds[0].max_step_counts, 6554);
        // c: 720 °/s through 10:1 at 2^17 counts per motor turn: 2 621 440 counts/s,
        // 2621.44 per cycle.
        assert_eq!(bounds[3].max_step_counts, 2622);
    }
}
