//! `gantry profile`: the planned profile of one move as JSON, for sizing moves and for
//! checking the planner from outside. `--batch` reads one JSON request per line.

use std::io::{BufRead, Write};
use std::time::Instant;

use gantry_kernel::profile::{plan_position, KinematicState, Limits, Profile, RampType, Shape};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use gantry::error_chain::Chain;

/// One planning request (the `--batch` line format; the flags use the same names).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Request {
    /// Start position.
    #[serde(default)]
    pub from_pos: f64,
    /// Start velocity.
    #[serde(default)]
    pub from_vel: f64,
    /// Start acceleration.
    #[serde(default)]
    pub from_acc: f64,
    /// Target position.
    pub to_pos: f64,
    /// Maximum speed.
    pub vmax: f64,
    /// Maximum acceleration.
    pub amax: f64,
    /// Maximum deceleration.
    pub dmax: f64,
    /// Maximum jerk (S-curve only).
    #[serde(default)]
    pub jmax: Option<f64>,
    /// Ramp type name.
    #[serde(default = "default_ramp")]
    pub ramp: String,
}

fn default_ramp() -> String {
    "scurve".into()
}

/// One phase of the answer.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Phase {
    /// Start time (s).
    pub t0: f64,
    /// Duration (s).
    pub duration: f64,
    /// "jerk", "accel", "sine" or "sine2".
    pub shape: &'static str,
    /// Jerk of a jerk phase, acceleration of an accel phase, velocity change of a sine one.
    pub value: f64,
    /// Position at the start.
    pub p: f64,
    /// Velocity at the start.
    pub v: f64,
    /// Acceleration at the start.
    pub a: f64,
}

/// The answer.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Answer {
    /// Duration (s).
    pub duration_s: f64,
    /// Largest |v|.
    pub peak_v: f64,
    /// Largest |a|.
    pub peak_a: f64,
    /// Largest |j| (0 for ramps without jerk limit, which jump in acceleration).
    pub peak_j: f64,
    /// Time the planner took (ns).
    pub plan_ns: u64,
    /// The phases (omitted in batch mode).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phases: Option<Vec<Phase>>,
}

/// Why a request cannot be planned.
#[derive(Debug, Error)]
pub enum ProfileError {
    /// A field is missing, of the wrong type, or unknown.
    #[error("not a request")]
    Parse(#[source] serde_json::Error),
    /// A numeric field is not finite.
    #[error("{field} = {value} is not a finite number")]
    NotFinite {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A limit is not > 0.
    #[error("{field} = {value} must be > 0")]
    NotPositive {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// Unknown ramp type.
    #[error("ramp {0:?} is not one of scurve, trapezoid, sine, linear-sine")]
    Ramp(String),
    /// S-curve without jerk.
    #[error("jmax is required for the scurve ramp")]
    NoJerk,
    /// The planner failed.
    #[error("planning failed")]
    Plan(#[source] gantry_kernel::profile::PlanError),
}

/// Plans a request.
pub fn answer(req: &Request, with_phases: bool) -> Result<Answer, ProfileError> {
    for (field, value) in [
        ("from_pos", req.from_pos),
        ("from_vel", req.from_vel),
        ("from_acc", req.from_acc),
        ("to_pos", req.to_pos),
    ] {
        if !value.is_finite() {
            return Err(ProfileError::NotFinite { field, value });
        }
    }
    for (field, value) in [("vmax", req.vmax), ("amax", req.amax), ("dmax", req.dmax)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(ProfileError::NotPositive { field, value });
        }
    }
    let ramp =
        RampType::from_name(&req.ramp).ok_or_else(|| ProfileError::Ramp(req.ramp.clone()))?;
    let jmax = match (ramp, req.jmax) {
        (RampType::SCurve, None) => return Err(ProfileError::NoJerk),
        (_, Some(j)) if !(j.is_finite() && j > 0.0) => {
            return Err(ProfileError::NotPositive {
                field: "jmax",
                value: j,
            })
        }
        (RampType::SCurve, Some(j)) => j,
        (_, _) => f64::INFINITY,
    };
    let lim = Limits {
        vmax: req.vmax,
        amax: req.amax,
        dmax: req.dmax,
        jmax,
    };
    let start = KinematicState {
        p: req.from_pos,
        v: req.from_vel,
        a: req.from_acc,
        j: 0.0,
    };
    let t = Instant::now();
    let profile = plan_position(ramp, start, req.to_pos, 0.0, &lim).map_err(ProfileError::Plan)?;
    let plan_ns = t.elapsed().as_nanos() as u64;
    let peaks = profile.peaks();
    Ok(Answer {
        duration_s: profile.duration(),
        peak_v: peaks.v,
        peak_a: peaks.a,
        peak_j: peaks.j,
        plan_ns,
        phases: with_phases.then(|| phases(&profile)),
    })
}

fn phases(p: &Profile) -> Vec<Phase> {
    let mut t0 = 0.0;
    p.segments()
        .iter()
        .map(|s| {
            let (shape, value) = match s.shape {
                Shape::Jerk(j) => ("jerk", j),
                Shape::Accel(a) => ("accel", a),
                Shape::Sine { dv } => ("sine", dv),
                Shape::SineSquared { dv } => ("sine2", dv),
            };
            let start = s.sample(0.0);
            let ph = Phase {
                t0,
                duration: s.duration,
                shape,
                value,
                p: start.p,
                v: start.v,
                a: start.a,
            };
            t0 += s.duration;
            ph
        })
        .collect()
}

/// Runs `--batch`: one request per input line, one JSON answer (or `{"error": …}`) per
/// output line; a bad line never stops the batch.
pub fn batch(input: impl BufRead, mut output: impl Write) -> std::io::Result<()> {
    for (n, line) in input.lines().enumerate() {
        let line = line?;
        if line.trim().is_empty() {
            continue;
        }
        let result = serde_json::from_str::<Request>(&line)
            .map_err(ProfileError::Parse)
            .and_then(|r| answer(&r, false));
        let text = match result {
            Ok(a) => {
                serde_json::to_string(&a).unwrap_or_else(|e| error_json(n + 1, &e.to_string()))
            }
            Err(e) => error_json(n + 1, &Chain(&e).to_string()),
        };
        writeln!(output, "{text}")?;
    }
    output.flush()
}

fn error_json(line: usize, msg: &str) -> String {
    serde_json::json!({ "error": format!("line {line}: {msg}") }).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(ramp: &str) -> Request {
        Request {
            from_pos: 0.0,
            from_vel: 0.0,
            from_acc: 0.0,
            to_pos: 1.0,
            vmax: 1.0,
            amax: 1.0,
            dmax: 1.0,
            jmax: Some(1.0),
            ramp: ramp.into(),
        }
    }

    #[test]
    fn unit_s_curve_takes_3_1748_s() {
        let a = answer(&req("scurve"), true).unwrap();
        assert!((a.duration_s - 3.1748).abs() < 1e-4);
        assert!(a.phases.unwrap().iter().all(|p| p.shape == "jerk"));
    }

    #[test]
    fn errors_name_the_field() {
        let mut r = req("scurve");
        r.vmax = -1.0;
        assert_eq!(
            answer(&r, false).unwrap_err().to_string(),
            "vmax = -1 must be > 0"
        );
        let mut r = req("cubic");
        r.jmax = None;
        assert!(answer(&r, false).unwrap_err().to_string().contains("cubic"));
        let mut r = req("scurve");
        r.jmax = None;
        assert!(matches!(answer(&r, false), Err(ProfileError::NoJerk)));
    }

    #[test]
    fn batch_goes_on_after_a_bad_line() {
        let input = "{\"to_pos\":10,\"vmax\":2,\"amax\":1,\"dmax\":1,\"ramp\":\"trapezoid\"}\nnot json\n{\"to_pos\":1,\"vmax\":1,\"amax\":1,\"dmax\":1,\"jmax\":1}\n";
        let mut out = Vec::new();
        batch(input.as_bytes(), &mut out).unwrap();
        let lines: Vec<serde_json::Value> = String::from_utf8(out)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 3);
        assert!((lines[0]["duration_s"].as_f64().unwrap() - 7.0).abs() < 1e-9);
        assert!(lines[1]["error"].as_str().unwrap().starts_with("line 2:"));
        assert!((lines[2]["duration_s"].as_f64().unwrap() - 3.1748).abs() < 1e-4);
    }
}
