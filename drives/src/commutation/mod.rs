//! Measuring a synchronous motor's commutation offset in the dynamic mode (seed 000 §5.2.6.1
//! 测量换向角, Jetter `MeasureCommutationOffset(DynamicMode)`): small motion, through only
//! what a drive exposes — an open-loop current vector it applies on command (amplitude,
//! electrical angle, in a manufacturer's mode: [`CommutationObjects`] names the drive's
//! objects, gantry-sim's mode −1 with 0x2102/0x2103 by default) and the position feedback
//! — never the motor's true offset.
//!
//! How: with the drive in its open-loop current-vector mode, the current is ramped up at
//! electrical angle 0 (the rotor's magnets turn to it), then the vector is turned slowly
//! through one electrical revolution forwards and one back. Each sample of (angle in effect,
//! position) gives an estimate of the offset, `position − angle · E / 2π` modulo `E` (the
//! counts of one electrical revolution, counts per motor revolution / pole pairs). Friction
//! makes the rotor lag the vector by the same angle in both directions, with opposite sign:
//! the circular mean of the forward estimates and that of the backward ones lie that lag
//! either side of the true offset, and their midpoint cancels it. The first quarter
//! revolution of each direction is left out (the rotor catching up). The result is written
//! to the drive's commutation offset (0x2100 on gantry-sim's servo), in the drive's units,
//! before the current is switched off.
//!
//! Sans-I/O: [`CommutationMeasurement::poll`] is told the time and the position actual value
//! and answers with the next [`Step`]: an object to write (by SDO; poll again once it is
//! written), nothing (poll again next cycle), or the outcome. The caller puts the drive into
//! the open-loop mode, enabled, before and hands it back to its cyclic mode afterwards; on an
//! error or a cancel it must switch the current off ([`CommutationMeasurement::abort`]).

use core::f64::consts::{PI, TAU};

use thiserror::Error;

use crate::cia402::objects::ObjectId;
use crate::cia402::procedure::{
    ModeSwitch, ProcedureFailure, ProcedureInputs, ProcedureOutputs, ProcedureStep, SdoAccess,
    SdoOutcome, Switching,
};
use crate::cia402::{ModeOfOperation, State};

pub mod objects;

pub use objects::{CommutationObjects, OffsetUnits, PolePairs};

/// How the measurement runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommutationConfig {
    /// Encoder counts per motor revolution (the axis' scaling).
    pub counts_per_rev: u32,
    /// The motor's pole pairs (read from the drive, 0x2101).
    pub pole_pairs: u32,
    /// Current of the vector, per mille of the rated torque's current (0x2102): enough to
    /// turn the rotor against its friction and load, small enough to be safe.
    pub current_per_mille: u16,
    /// Time to ramp the current up, and as long again to let the rotor settle (s).
    pub ramp_s: f64,
    /// Time for one electrical revolution each way (s).
    pub turn_s: f64,
    /// The drive's objects and open-loop mode.
    pub objects: CommutationObjects,
}

impl CommutationConfig {
    /// Defaults for a motor of `counts_per_rev` and `pole_pairs`: 30 % current, 0.5 s ramp,
    /// 2 s per electrical revolution.
    pub fn new(counts_per_rev: u32, pole_pairs: u32) -> Self {
        Self {
            counts_per_rev,
            pole_pairs,
            current_per_mille: 300,
            ramp_s: 0.5,
            turn_s: 2.0,
            objects: CommutationObjects::default(),
        }
    }

    /// Counts of one electrical revolution.
    pub fn counts_per_electrical_rev(&self) -> f64 {
        f64::from(self.counts_per_rev) / f64::from(self.pole_pairs.max(1))
    }

    /// Angle units of the drive's vector angle to an electrical revolution.
    fn angle_units(&self) -> f64 {
        f64::from(self.objects.angle_units)
    }
}

/// What to do next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Write `value` to `object` (by SDO), then poll again.
    Write(ObjectId, i64),
    /// Nothing now: poll again next cycle.
    Wait,
    /// The measurement is over: the offset was written to the drive and the current
    /// switched off.
    Done(CommutationOutcome),
}

/// What the measurement found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommutationOutcome {
    /// The commutation offset (counts, 0 ≤ offset < counts of an electrical revolution),
    /// written to 0x2100.
    pub offset_counts: i32,
    /// How far the rotor lagged the vector (electrical degrees): friction and load.
    pub lag_electrical_deg: f64,
    /// How far the rotor moved during the forward revolution from its first sample (counts;
    /// three quarters of an electrical revolution when it followed).
    pub travel_counts: i64,
}

/// Why a measurement failed (the caller switches the current off).
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum CommutationError {
    /// The configuration cannot describe a motor.
    #[error("commutation: {what} must be at least 1, is {value}")]
    BadConfig {
        /// Which value.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// The rotor did not follow the vector through an electrical revolution.
    #[error(
        "commutation: the rotor moved {moved} counts where the current vector turned \
         {expected:.0} counts' worth ({pole_pairs} pole pairs): blocked, brake closed, too \
         little current, or wrong pole pairs / counts per revolution"
    )]
    NotFollowing {
        /// Counts moved.
        moved: i64,
        /// Counts expected.
        expected: f64,
        /// Pole pairs used.
        pole_pairs: u32,
    },
    /// The rotor lagged the vector by more than the measurement trusts.
    #[error(
        "commutation: the rotor lagged the current vector by {lag_deg:.1}° electrical (at most \
         {max_deg}°): raise the current or free the axis"
    )]
    TooMuchLag {
        /// Lag (electrical degrees).
        lag_deg: f64,
        /// The most allowed.
        max_deg: f64,
    },
}

/// Most lag the measurement trusts (electrical degrees): beyond it the rotor is near
/// stalling against its load and the two directions no longer mirror each other.
pub const MAX_LAG_DEG: f64 = 45.0;

/// Where the measurement is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Setting angle 0 and no current.
    Start,
    /// Ramping the current up and letting the rotor settle.
    Align,
    /// Turning the vector forwards through an electrical revolution.
    Forward,
    /// Turning it back.
    Backward,
    /// Writing the offset found.
    WriteOffset,
    /// Switching the current off.
    Release,
    /// Over.
    Done,
}

/// Circular sum of offset estimates (unit vectors of their electrical phase).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Circular {
    cos: f64,
    sin: f64,
    n: u32,
}

impl Circular {
    fn add(&mut self, phase: f64) {
        self.cos += phase.cos();
        self.sin += phase.sin();
        self.n += 1;
    }

    fn mean(&self) -> f64 {
        self.sin.atan2(self.cos)
    }
}

/// One commutation measurement (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommutationMeasurement {
    config: CommutationConfig,
    phase: Phase,
    /// Time the phase began (s); `None` until the first poll in it.
    since: Option<f64>,
    /// The angle (0x2103 units, unwrapped) and current last written.
    angle: i64,
    current: u16,
    /// Whether the angle and current of `Start` were written.
    started: u8,
    /// Unwrapped position: the first value seen, and the last (counts).
    origin: Option<i32>,
    position: i64,
    forward: Circular,
    backward: Circular,
    /// Position at the forward revolution's first sample (and the angle then), and at
    /// its end.
    forward_from: Option<i64>,
    forward_from_angle: i64,
    forward_to: i64,
    result: Option<CommutationOutcome>,
}

/// A wrapped difference turned into an angle in (−π, π].
fn wrap_pi(x: f64) -> f64 {
    let y = x.rem_euclid(TAU);
    if y > PI {
        y - TAU
    } else {
        y
    }
}

impl CommutationMeasurement {
    /// A measurement with `config`.
    pub fn new(config: CommutationConfig) -> Result<Self, CommutationError> {
        let checks = [
            ("counts per revolution", f64::from(config.counts_per_rev)),
            ("pole pairs", f64::from(config.pole_pairs)),
            ("current (per mille)", f64::from(config.current_per_mille)),
            ("turn time (ms)", config.turn_s * 1000.0),
        ];
        for (what, value) in checks {
            if value.is_nan() || value < 1.0 {
                return Err(CommutationError::BadConfig { what, value });
            }
        }
        if config.objects.angle_units < objects::MIN_ANGLE_UNITS {
            return Err(CommutationError::BadConfig {
                what: "angle units per electrical revolution (/ 360)",
                value: f64::from(config.objects.angle_units) / 360.0,
            });
        }
        if config.ramp_s.is_nan() || config.ramp_s < 0.0 {
            return Err(CommutationError::BadConfig {
                what: "ramp time (ms) + 1",
                value: config.ramp_s * 1000.0 + 1.0,
            });
        }
        Ok(Self {
            config,
            phase: Phase::Start,
            since: None,
            angle: 0,
            current: 0,
            started: 0,
            origin: None,
            position: 0,
            forward: Circular::default(),
            backward: Circular::default(),
            forward_from: None,
            forward_from_angle: 0,
            forward_to: 0,
            result: None,
        })
    }

    /// Where it is.
    pub const fn phase(&self) -> Phase {
        self.phase
    }

    /// How far it is, 0 to 1 (by time).
    pub fn progress(&self, now_s: f64) -> f64 {
        let c = &self.config;
        let total = 2.0 * c.ramp_s + 2.0 * c.turn_s;
        let t = self.since.map_or(0.0, |s| (now_s - s).max(0.0));
        let done = match self.phase {
            Phase::Start => 0.0,
            Phase::Align => t.min(2.0 * c.ramp_s),
            Phase::Forward => 2.0 * c.ramp_s + t.min(c.turn_s),
            Phase::Backward => 2.0 * c.ramp_s + c.turn_s + t.min(c.turn_s),
            Phase::WriteOffset | Phase::Release | Phase::Done => total,
        };
        if total > 0.0 {
            done / total
        } else {
            1.0
        }
    }

    /// The step that switches the current off (after an error or a cancel; the caller then
    /// disables the drive or hands it back).
    pub fn abort(&mut self) -> Step {
        self.phase = Phase::Done;
        Step::Write(self.config.objects.current, 0)
    }

    /// The next step at time `now_s` (s, any origin, not decreasing) with the drive's
    /// position actual value `position` (0x6064, it may wrap).
    pub fn poll(&mut self, now_s: f64, position: i32) -> Result<Step, CommutationError> {
        let origin = *self.origin.get_or_insert(position);
        // Unwrapped: the short way from the last value.
        let last = origin.wrapping_add(self.position as i32);
        self.position += i64::from(position.wrapping_sub(last));
        let c = self.config;
        let o = c.objects;
        let e = c.counts_per_electrical_rev();
        let units = c.angle_units();
        let full = i64::from(o.angle_units);
        match self.phase {
            Phase::Start => {
                self.started += 1;
                match self.started {
                    1 => return Ok(Step::Write(o.angle, 0)),
                    2 => return Ok(Step::Write(o.current, 0)),
                    _ => self.enter(Phase::Align, now_s),
                }
            }
            Phase::Align => {
                let t = self.elapsed(now_s);
                let share = if c.ramp_s > 0.0 {
                    (t / c.ramp_s).min(1.0)
                } else {
                    1.0
                };
                let want = (share * f64::from(c.current_per_mille)).round() as u16;
                if want != self.current {
                    self.current = want;
                    return Ok(Step::Write(o.current, i64::from(want)));
                }
                if t >= 2.0 * c.ramp_s {
                    self.enter(Phase::Forward, now_s);
                }
            }
            Phase::Forward | Phase::Backward => {
                let forward = self.phase == Phase::Forward;
                // The sample: the angle in effect (the last written) and where the rotor is.
                let angle = self.angle;
                let turned = if forward { angle } else { full - angle };
                if turned >= full / 4 {
                    // The position as the drive counts it (the phases repeat every
                    // revolution; a count that wrapped at 32 bits keeps them only when the
                    // counts per revolution divide 2³², as binary encoders' do).
                    let at = i64::from(origin) + self.position;
                    let estimate = at as f64 - angle as f64 / units * e;
                    let phase = TAU * estimate / e;
                    if forward {
                        if self.forward_from.is_none() {
                            self.forward_from = Some(self.position);
                            self.forward_from_angle = angle;
                        }
                        self.forward.add(phase);
                    } else {
                        self.backward.add(phase);
                    }
                }
                let t = self.elapsed(now_s);
                let share = (t / c.turn_s).min(1.0);
                let want = if forward {
                    (share * units).round() as i64
                } else {
                    full - (share * units).round() as i64
                };
                if want != self.angle {
                    self.angle = want;
                    let wire = want.rem_euclid(full);
                    return Ok(Step::Write(o.angle, wire));
                }
                if share >= 1.0 {
                    if forward {
                        self.forward_to = self.position;
                        self.enter(Phase::Backward, now_s);
                    } else {
                        let outcome = self.evaluate()?;
                        self.result = Some(outcome);
                        self.enter(Phase::WriteOffset, now_s);
                    }
                }
            }
            Phase::WriteOffset => {
                self.enter(Phase::Release, now_s);
                let offset = self.result.map_or(0, |r| r.offset_counts);
                let wire = o.offset_to_drive(i64::from(offset), e);
                return Ok(Step::Write(o.offset, wire));
            }
            Phase::Release => {
                self.phase = Phase::Done;
                self.current = 0;
                return Ok(Step::Write(o.current, 0));
            }
            Phase::Done => {}
        }
        Ok(match (self.phase, self.result) {
            (Phase::Done, Some(r)) => Step::Done(r),
            _ => Step::Wait,
        })
    }

    fn enter(&mut self, phase: Phase, now_s: f64) {
        self.phase = phase;
        self.since = Some(now_s);
    }

    fn elapsed(&mut self, now_s: f64) -> f64 {
        (now_s - *self.since.get_or_insert(now_s)).max(0.0)
    }

    /// The offset from the two directions' circular means, checked.
    fn evaluate(&self) -> Result<CommutationOutcome, CommutationError> {
        let c = &self.config;
        let e = c.counts_per_electrical_rev();
        let travel = self.forward_to - self.forward_from.unwrap_or(self.forward_to);
        // From the first sample to the end of the revolution (the samples start a quarter
        // in: a rotor that stood opposite the vector at the start, where the pull is nil,
        // has swung round to it by then), within a tenth of a revolution.
        let units = c.angle_units();
        let expected = (units - self.forward_from_angle as f64) / units * e;
        if self.forward.n == 0
            || self.backward.n == 0
            || ((travel as f64) - expected).abs() > 0.1 * e
        {
            return Err(CommutationError::NotFollowing {
                moved: travel,
                expected,
                pole_pairs: c.pole_pairs,
            });
        }
        let f = self.forward.mean();
        let b = self.backward.mean();
        // The rotor lags behind the vector: forwards its estimate lies the lag below the
        // true offset, backwards as far above.
        let lag = wrap_pi(b - f) / 2.0;
        let lag_deg = lag.to_degrees();
        if lag_deg.abs() > MAX_LAG_DEG {
            return Err(CommutationError::TooMuchLag {
                lag_deg,
                max_deg: MAX_LAG_DEG,
            });
        }
        let phase = (f + lag).rem_euclid(TAU);
        let mut offset = (phase / TAU * e).round();
        if offset >= e.floor() {
            offset = 0.0;
        }
        Ok(CommutationOutcome {
            offset_counts: offset as i32,
            lag_electrical_deg: lag_deg,
            travel_counts: travel,
        })
    }
}

/// The measurement as a procedure the master's cycle thread runs on a drive lent to it
/// (`crate::cia402::procedure`): the vector's current set to 0 (SDO), the open-loop mode
/// ([`CommutationObjects::mode`]) switched to and shown, the drive
/// enabled in it (the channel enables it: the axis may be lent from Disabled, so that a
/// drive of unknown commutation never holds a closed loop), then the measurement's writes
/// one by one by SDO on the position of the process data; it ends with the current off,
/// still in the open-loop mode: handed back, the drive is disabled by its Disabled axis,
/// and the master sets 0x6060 back to CSP then (see `gantry::commission::commutation`).
/// A failure or a cancel switches the current off first too.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommutationProcedure {
    measurement: CommutationMeasurement,
    step: ProcedureStage,
    switch: ModeSwitch,
    /// The access on its way (its outcome comes in the next inputs).
    awaiting: Option<SdoAccess>,
    /// Why it will end in failure, once the current is off.
    failure: Option<ProcedureFailure>,
    /// When the measurement's clock started (s).
    t0: Option<f64>,
    /// When the drive was told to enable (s).
    enabling_since: Option<f64>,
}

/// Where a [`CommutationProcedure`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ProcedureStage {
    /// Current 0 before anything is energised.
    ZeroCurrent,
    /// Switching to the open-loop mode.
    ToOpenLoop,
    /// Waiting for Operation enabled.
    Enabling,
    /// Measuring.
    Measuring,
    /// Switching the current off (after a failure or a cancel).
    CurrentOff,
    /// Over.
    Ended,
}

/// How long the drive may take to reach Operation enabled (s).
const ENABLE_TIMEOUT_S: f64 = 1.0;

impl CommutationProcedure {
    /// A procedure running `measurement`.
    pub fn new(measurement: CommutationMeasurement) -> Self {
        Self {
            measurement,
            step: ProcedureStage::ZeroCurrent,
            switch: ModeSwitch::to(ModeOfOperation::Other(measurement.config.objects.mode)),
            awaiting: None,
            failure: None,
            t0: None,
            enabling_since: None,
        }
    }

    /// What it is doing, in words.
    pub const fn phase_name(&self) -> &'static str {
        match self.step {
            ProcedureStage::ZeroCurrent | ProcedureStage::ToOpenLoop => {
                "switching to the open-loop current mode"
            }
            ProcedureStage::Enabling => "enabling the drive",
            ProcedureStage::Measuring => match self.measurement.phase() {
                Phase::Start | Phase::Align => "aligning the rotor with the current vector",
                Phase::Forward => "turning the current vector forwards",
                Phase::Backward => "turning the current vector back",
                Phase::WriteOffset => "writing the offset",
                Phase::Release | Phase::Done => "switching the current off",
            },
            ProcedureStage::CurrentOff => "switching the current off",
            ProcedureStage::Ended => "ended",
        }
    }

    /// How far the measurement is, 0 to 1.
    pub fn progress(&self, now_s: f64) -> f64 {
        self.measurement.progress(now_s - self.t0.unwrap_or(now_s))
    }

    /// Cancels it (a Stop or QuickStop of the axis): the current off, then the end.
    pub fn cancel(&mut self, by: &'static str) {
        if self.failure.is_none() && self.step != ProcedureStage::Ended {
            self.failure = Some(ProcedureFailure::Cancelled { by });
        }
    }

    fn outputs(&self) -> Option<ProcedureOutputs> {
        Some(ProcedureOutputs::idle(ModeOfOperation::Other(
            self.measurement.config.objects.mode,
        )))
    }

    /// The vector's current object.
    fn current(&self) -> ObjectId {
        self.measurement.config.objects.current
    }

    fn access(&mut self, object: ObjectId, value: i64) -> ProcedureStep {
        let a = SdoAccess {
            object,
            write: Some(value),
        };
        self.awaiting = Some(a);
        ProcedureStep {
            outputs: self.outputs(),
            sdo: Some(a),
            end: None,
        }
    }

    fn end(&mut self, result: Result<(), ProcedureFailure>) -> ProcedureStep {
        self.step = ProcedureStage::Ended;
        ProcedureStep {
            outputs: self.outputs(),
            sdo: None,
            end: Some(result),
        }
    }

    /// One cycle (see `crate::cia402::procedure`).
    pub fn step(&mut self, io: &ProcedureInputs) -> ProcedureStep {
        // The outcome of the write on its way.
        if let Some(a) = self.awaiting {
            let Some(outcome) = io.sdo else {
                return ProcedureStep::hold(self.outputs());
            };
            self.awaiting = None;
            let failed = match outcome {
                SdoOutcome::Done(_) => None,
                SdoOutcome::Aborted(code) => Some(ProcedureFailure::Refused {
                    object: a.object,
                    value: a.write.unwrap_or(0),
                    code,
                }),
                SdoOutcome::Failed(what) => Some(ProcedureFailure::Sdo {
                    object: a.object,
                    what,
                }),
            };
            if let Some(f) = failed {
                if self.step == ProcedureStage::CurrentOff {
                    // The current could not be switched off: the hand-back disables it.
                    return self.end(Err(self.failure.unwrap_or(f)));
                }
                self.failure.get_or_insert(f);
            }
            if self.step == ProcedureStage::CurrentOff {
                let f = self
                    .failure
                    .unwrap_or(ProcedureFailure::Cancelled { by: "a failure" });
                return self.end(Err(f));
            }
        }
        if self.failure.is_some() && self.step != ProcedureStage::CurrentOff {
            self.step = ProcedureStage::CurrentOff;
            return self.access(self.current(), 0);
        }
        match self.step {
            ProcedureStage::ZeroCurrent => {
                self.step = ProcedureStage::ToOpenLoop;
                self.access(self.current(), 0)
            }
            ProcedureStage::ToOpenLoop => match self.switch.step(io, 0) {
                Switching::Pending(s) => s,
                Switching::Done => {
                    self.step = ProcedureStage::Enabling;
                    self.enabling_since = Some(io.now_s);
                    ProcedureStep::hold(self.outputs())
                }
                Switching::Failed(f) => {
                    self.failure = Some(f);
                    self.step = ProcedureStage::CurrentOff;
                    self.access(self.current(), 0)
                }
            },
            ProcedureStage::Enabling => {
                if io.statusword.state() == Some(State::OperationEnabled) {
                    self.step = ProcedureStage::Measuring;
                    self.t0 = Some(io.now_s);
                } else if io.now_s - self.enabling_since.unwrap_or(io.now_s) > ENABLE_TIMEOUT_S {
                    self.failure = Some(ProcedureFailure::NotReported {
                        missing: "Operation enabled in the open-loop current mode",
                        timeout_s: ENABLE_TIMEOUT_S,
                    });
                    self.step = ProcedureStage::CurrentOff;
                    return self.access(self.current(), 0);
                }
                ProcedureStep::hold(self.outputs())
            }
            ProcedureStage::Measuring => {
                let t = io.now_s - self.t0.unwrap_or(io.now_s);
                match self.measurement.poll(t, io.position) {
                    Ok(Step::Write(o, v)) => self.access(o, v),
                    Ok(Step::Wait) => ProcedureStep::hold(self.outputs()),
                    Ok(Step::Done(_)) => self.end(Ok(())),
                    Err(e) => {
                        self.failure = Some(ProcedureFailure::DriveReports {
                            what: match e {
                                CommutationError::NotFollowing { .. } => {
                                    "a rotor that did not follow the current vector"
                                }
                                CommutationError::TooMuchLag { .. } => {
                                    "a rotor lagging the current vector too far"
                                }
                                CommutationError::BadConfig { .. } => "a configuration error",
                            },
                        });
                        self.step = ProcedureStage::CurrentOff;
                        self.access(self.current(), 0)
                    }
                }
            }
            ProcedureStage::CurrentOff | ProcedureStage::Ended => {
                ProcedureStep::hold(self.outputs())
            }
        }
    }
}

/// The electrical angle (degrees, in (−180, 180]) by which offset `a` misses offset `b`
/// (counts) on a motor of `counts_per_rev` and `pole_pairs`: how a measured offset is
/// judged against another.
pub fn electrical_error_deg(a: i64, b: i64, counts_per_rev: u32, pole_pairs: u32) -> f64 {
    let e = f64::from(counts_per_rev) / f64::from(pole_pairs.max(1));
    wrap_pi(TAU * (a - b) as f64 / e).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia402::objects as od;

    #[test]
    fn a_bad_configuration_is_named() {
        let mut c = CommutationConfig::new(1 << 17, 0);
        assert_eq!(
            CommutationMeasurement::new(c).unwrap_err().to_string(),
            "commutation: pole pairs must be at least 1, is 0"
        );
        c.pole_pairs = 4;
        c.turn_s = f64::NAN;
        assert!(matches!(
            CommutationMeasurement::new(c),
            Err(CommutationError::BadConfig {
                what: "turn time (ms)",
                ..
            })
        ));
    }

    #[test]
    fn electrical_error_wraps_at_half_a_revolution() {
        // 1000 counts, 4 pole pairs: 250 counts to an electrical revolution.
        assert!((electrical_error_deg(10, 0, 1000, 4) - 14.4).abs() < 1e-9);
        assert!((electrical_error_deg(0, 10, 1000, 4) + 14.4).abs() < 1e-9);
        assert!((electrical_error_deg(245, 0, 1000, 4) + 7.2).abs() < 1e-9);
        assert!((electrical_error_deg(250 * 7 + 1, 0, 1000, 4) - 1.44).abs() < 1e-9);
    }

    /// Runs a measurement with `objects` on an ideal rotor that sits `lag` (rad) behind
    /// the vector in the direction it turns: the outcome, and every write but the angle's.
    fn measure_ideal_rotor(
        objects: CommutationObjects,
        (cpr, pp, offset): (u32, u32, f64),
        lag: f64,
    ) -> (CommutationOutcome, Vec<(ObjectId, i64)>) {
        let e = f64::from(cpr) / f64::from(pp);
        let full = i64::from(objects.angle_units);
        let mut config = CommutationConfig::new(cpr, pp);
        config.objects = objects;
        let mut m = CommutationMeasurement::new(config).unwrap();
        let (mut angle, mut last_angle, mut current) = (0i64, 0i64, 0i64);
        let mut writes = Vec::new();
        let mut t = 0.0;
        let outcome = loop {
            // Rotor: aligned with the vector, lagging in the direction it last turned.
            let dir = (angle - last_angle).signum() as f64;
            let rotor = angle as f64 / full as f64 * TAU - dir * lag;
            let position = (offset + rotor / TAU * e).round() as i32;
            match m.poll(t, position).unwrap() {
                Step::Write(o, v) if o == objects.angle => {
                    assert!((0..full).contains(&v));
                    // Unwrapped by the short way, as the rotor turns.
                    let d = (v - angle.rem_euclid(full) + full / 2).rem_euclid(full) - full / 2;
                    if d != 0 {
                        last_angle = angle;
                    }
                    angle += d;
                }
                Step::Write(o, v) => {
                    if o == objects.current {
                        current = v;
                    }
                    writes.push((o, v));
                }
                Step::Wait => t += 0.001,
                Step::Done(r) => break r,
            }
            assert!(t < 10.0, "runs out");
        };
        assert_eq!(current, 0, "the current is off at the end");
        (outcome, writes)
    }

    /// The measurement finds the offset and the lag exactly, and writes what it promises.
    #[test]
    fn a_rotor_lagging_by_friction_is_measured_without_the_lag() {
        let (cpr, pp, offset) = (1u32 << 17, 5u32, 12_345.0f64);
        let e = f64::from(cpr) / f64::from(pp);
        let objects = CommutationObjects::default();
        let (outcome, writes) = measure_ideal_rotor(objects, (cpr, pp, offset), 10f64.to_radians());
        assert!(
            (outcome.lag_electrical_deg - 10.0).abs() < 0.1,
            "{outcome:?}"
        );
        let miss = electrical_error_deg(i64::from(outcome.offset_counts), offset as i64, cpr, pp);
        assert!(miss.abs() < 0.05, "{miss}° {outcome:?}");
        assert!(writes.contains(&(od::COMMUTATION_OFFSET, i64::from(outcome.offset_counts))));
        // From a quarter in to the end, lagging at both.
        let travel = e * 0.75;
        assert!(
            (outcome.travel_counts as f64 - travel).abs() < 2.0,
            "{outcome:?}"
        );
    }

    /// Another maker's objects: the vector's angle in tenths of a degree, the offset in
    /// 16-bit units of an electrical revolution, at indices of its own. Every write goes
    /// to those objects, in those units.
    #[test]
    fn another_drive_s_objects_and_units_are_written() {
        let at = |index| ObjectId {
            index,
            ..od::COMMUTATION_OFFSET
        };
        let objects = CommutationObjects {
            mode: -3,
            offset: ObjectId {
                kind: crate::cia402::objects::DataType::U16,
                ..at(0x3010)
            },
            offset_units: OffsetUnits::PerElectricalRev(65536),
            pole_pairs: PolePairs::Fixed(4),
            current: at(0x3012),
            angle: at(0x3013),
            angle_units: 3600,
        };
        let (cpr, pp, offset) = (10_000u32, 4u32, 1_234.0f64);
        let (outcome, writes) = measure_ideal_rotor(objects, (cpr, pp, offset), 0.2);
        let miss = electrical_error_deg(i64::from(outcome.offset_counts), offset as i64, cpr, pp);
        assert!(miss.abs() < 0.2, "{miss}° {outcome:?}");
        // 1234 counts of 2500 to an electrical revolution, in 65536ths.
        let wire = (f64::from(outcome.offset_counts) / 2500.0 * 65536.0).round() as i64;
        assert!(writes.contains(&(objects.offset, wire)), "{writes:?}");
        assert!(
            writes
                .iter()
                .all(|(o, _)| [0x3010, 0x3012].contains(&o.index)),
            "{writes:?}"
        );
    }

    #[test]
    fn a_rotor_that_does_not_move_is_reported() {
        let mut m = CommutationMeasurement::new(CommutationConfig::new(1 << 17, 5)).unwrap();
        let mut t = 0.0;
        let err = loop {
            match m.poll(t, 777) {
                Ok(Step::Wait) => t += 0.001,
                Ok(Step::Write(..)) => {}
                Ok(Step::Done(r)) => panic!("{r:?}"),
                Err(e) => break e,
            }
        };
        assert!(
            matches!(err, CommutationError::NotFollowing { moved: 0, .. }),
            "{err}"
        );
        assert_eq!(m.abort(), Step::Write(od::COMMUTATION_CURRENT, 0));
    }
}
