//! Drive-side homing (CiA 402-2 homing mode, mode of operation 6), master side, sans I/O:
//! the sequence that writes a drive's homing objects, takes it out of CSP into homing
//! mode, starts it, follows its statusword and hands it back in CSP
//! ([`super::procedure`] is the hand-over).
//!
//! 1. SDO writes, in CSP still: 0x6098 homing method, 0x6099:01 speed during search for
//!    switch, 0x6099:02 speed during search for zero, 0x609A homing acceleration, 0x607C
//!    home offset. A drive that refuses one (a method it does not have: SDO abort
//!    0x06090030 value range) ends the sequence there, never having left CSP.
//! 2. Mode 6, by PDO or SDO, until 0x6061 shows it ([`ModeSwitch`]).
//! 3. Controlword bit 4 rises (homing operation start, CiA 402-2 §10.4.1) and stays set;
//!    the statusword decides (CiA 402-2 §10.4.2): bit 12 homing attained with bit 10
//!    target reached is done, bit 13 homing error failed, neither within the timeout
//!    failed naming what was missing. The first [`STALE_STEPS`] steps after the edge are
//!    not judged: the statusword they carry may predate it (a drive still showing the
//!    "attained" of an earlier homing).
//! 4. On an error, a timeout or a Stop: bit 8 halt, until bit 10 (the drive stands)
//!    or [`HALT_TIMEOUT_S`]. On a QuickStop: the power state machine's Quick stop
//!    (CiA 402-2 transition 11), so the drive brakes on its quick-stop ramp (0x6085, as
//!    its 0x605A says) rather than the homing acceleration, until its position stands
//!    still (or [`HALT_TIMEOUT_S`]); then it is enabled again — from Quick stop active,
//!    or from Switch on disabled where its option code took it there — before the
//!    hand-back.
//! 5. The position actual value still (within a count for [`SETTLE_STEPS`] steps, at most
//!    [`SETTLE_TIMEOUT_S`]): a drive reports "target reached" while its position loop
//!    still settles by a few counts, and the first CSP target after the hand-back is the
//!    position last read.
//! 6. Bits cleared, mode 8 (CSP) again until 0x6061 shows it; then the end.
//!
//! A drive with an absolute encoder that needs no homing is configured to skip it: the
//! sequence ends at once, done, without touching the drive (the master marks the axis
//! homed on the drive's own position).

use super::controlword::{HALT, MODE_SPECIFIC_4};
use super::objects::{self, ObjectId};
use super::procedure::{
    ModeSwitch, ProcedureFailure, ProcedureInputs, ProcedureOutputs, ProcedureStep, SdoAccess,
    SdoOutcome, Switching,
};
use super::statusword::{MODE_SPECIFIC_12, MODE_SPECIFIC_13, TARGET_REACHED};
use super::ModeOfOperation;

/// Statusword bit 12 in homing mode: homing attained.
pub const HOMING_ATTAINED: u16 = MODE_SPECIFIC_12;
/// Statusword bit 13 in homing mode: homing error.
pub const HOMING_ERROR: u16 = MODE_SPECIFIC_13;
/// Controlword bit 4 in homing mode: homing operation start.
pub const HOMING_START: u16 = MODE_SPECIFIC_4;

/// Steps after the start edge whose statusword is not judged (it may be older than the
/// edge: the process data's round trip is at most a few cycles on either bus).
pub const STALE_STEPS: u32 = 5;
/// How long a halted drive may take to stand (s).
pub const HALT_TIMEOUT_S: f64 = 5.0;
/// How long a drive may take to be enabled again after a quick stop (s).
pub const REENABLE_TIMEOUT_S: f64 = 1.0;
/// Steps in a row the position must stay within a count before the hand-back.
pub const SETTLE_STEPS: u32 = 3;
/// Longest wait for it (s): a drive that keeps creeping is handed back anyway.
pub const SETTLE_TIMEOUT_S: f64 = 1.0;

/// Homing parameters in the drive's units (counts, counts/s, counts/s²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveHomingParams {
    /// 0x6098 homing method (CiA 402-2: 1…35, 37; negative: manufacturer-specific).
    pub method: i8,
    /// 0x6099:01 speed during search for switch.
    pub speed_switch: u32,
    /// 0x6099:02 speed during search for zero.
    pub speed_zero: u32,
    /// 0x609A homing acceleration.
    pub acceleration: u32,
    /// 0x607C home offset.
    pub home_offset: i32,
    /// How long the drive may take to report homing attained (s).
    pub timeout_s: f64,
    /// Skip drive homing (an absolute drive): end at once, done.
    pub skip: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Writing parameter `n` (`writing`: its access is on its way).
    Params {
        n: usize,
        writing: bool,
    },
    Enter(ModeSwitch),
    /// Bit 4 set at `since`, `steps` steps ago.
    Run {
        since: f64,
        steps: u32,
    },
    /// Halting since `since`, then leaving with `result`.
    Halt {
        since: f64,
        result: Result<(), ProcedureFailure>,
    },
    /// Quick stop since `since` (the position last seen, and for how many steps it has
    /// stood), then enabling again and leaving with `result`.
    QuickStop {
        since: f64,
        last: i32,
        still: u32,
        result: Result<(), ProcedureFailure>,
    },
    /// Enabling again after the quick stop, since `since`.
    Reenable {
        since: f64,
        result: Result<(), ProcedureFailure>,
    },
    /// Waiting for the position to stand still, then leaving with `result`.
    Settle {
        since: f64,
        last: i32,
        still: u32,
        result: Result<(), ProcedureFailure>,
    },
    Leave {
        switch: ModeSwitch,
        result: Result<(), ProcedureFailure>,
    },
    Ended,
}

/// The drive homing sequence of one drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveHoming {
    params: DriveHomingParams,
    phase: Phase,
    cancel: Option<&'static str>,
}

impl DriveHoming {
    /// A sequence with `params`.
    pub const fn new(params: DriveHomingParams) -> Self {
        Self {
            params,
            phase: Phase::Params {
                n: 0,
                writing: false,
            },
            cancel: None,
        }
    }

    /// The parameters.
    pub const fn params(&self) -> &DriveHomingParams {
        &self.params
    }

    /// What it is doing, for the status ("writing 0x6098", "homing", "halting", …).
    pub const fn phase_name(&self) -> &'static str {
        match self.phase {
            Phase::Params { .. } => "writing the homing objects",
            Phase::Enter(_) => "switching to homing mode",
            Phase::Run { .. } => "homing",
            Phase::Halt { .. } => "halting",
            Phase::QuickStop { .. } => "quick stop",
            Phase::Reenable { .. } => "enabling after the quick stop",
            Phase::Settle { .. } => "waiting for the drive to stand",
            Phase::Leave { .. } => "switching back to CSP",
            Phase::Ended => "ended",
        }
    }

    /// Cancels the sequence (`by`: the command): the drive halts and is handed back.
    pub fn cancel(&mut self, by: &'static str) {
        self.cancel.get_or_insert(by);
    }

    /// The objects written, in order, with their values.
    fn writes(&self) -> [(ObjectId, i64); 5] {
        let p = &self.params;
        [
            (objects::HOMING_METHOD, i64::from(p.method)),
            (objects::HOMING_SPEED_SWITCH, i64::from(p.speed_switch)),
            (objects::HOMING_SPEED_ZERO, i64::from(p.speed_zero)),
            (objects::HOMING_ACCELERATION, i64::from(p.acceleration)),
            (objects::HOME_OFFSET, i64::from(p.home_offset)),
        ]
    }

    /// One cycle.
    pub fn step(&mut self, io: &ProcedureInputs) -> ProcedureStep {
        let homing = ProcedureOutputs::idle(ModeOfOperation::Homing);
        if self.params.skip {
            self.phase = Phase::Ended;
            return end(Ok(()));
        }
        // A cancel while the drive is in CSP ends at once; later it halts first.
        if let Some(by) = self.cancel {
            let failure = ProcedureFailure::Cancelled { by };
            match self.phase {
                Phase::Params { writing: false, .. } => {
                    self.phase = Phase::Ended;
                    return end(Err(failure));
                }
                Phase::Enter(_) | Phase::Run { .. } if by == "QuickStop" => {
                    self.phase = Phase::QuickStop {
                        since: io.now_s,
                        last: io.position,
                        still: 0,
                        result: Err(failure),
                    };
                }
                Phase::Enter(_) | Phase::Run { .. } => {
                    self.phase = Phase::Halt {
                        since: io.now_s,
                        result: Err(failure),
                    };
                }
                _ => {}
            }
        }
        match self.phase {
            Phase::Params { n, writing } => {
                let writes = self.writes();
                if writing {
                    let Some(outcome) = io.sdo else {
                        return ProcedureStep::hold(None);
                    };
                    let (object, value) = writes
                        .get(n)
                        .copied()
                        .unwrap_or((objects::HOMING_METHOD, 0));
                    match outcome {
                        SdoOutcome::Done(_) => {}
                        SdoOutcome::Aborted(code) => {
                            self.phase = Phase::Ended;
                            return end(Err(ProcedureFailure::Refused {
                                object,
                                value,
                                code,
                            }));
                        }
                        SdoOutcome::Failed(what) => {
                            self.phase = Phase::Ended;
                            return end(Err(ProcedureFailure::Sdo { object, what }));
                        }
                    }
                    if let Some(c) = self.cancel {
                        self.phase = Phase::Ended;
                        return end(Err(ProcedureFailure::Cancelled { by: c }));
                    }
                    self.phase = Phase::Params {
                        n: n + 1,
                        writing: false,
                    };
                    return self.step(&without_sdo(io));
                }
                match writes.get(n) {
                    Some(&(object, value)) => {
                        self.phase = Phase::Params { n, writing: true };
                        ProcedureStep {
                            outputs: None,
                            sdo: Some(SdoAccess {
                                object,
                                write: Some(value),
                            }),
                            end: None,
                        }
                    }
                    None => {
                        self.phase = Phase::Enter(ModeSwitch::to(ModeOfOperation::Homing));
                        self.step(&without_sdo(io))
                    }
                }
            }
            Phase::Enter(mut switch) => match switch.step(io, 0) {
                Switching::Pending(step) => {
                    self.phase = Phase::Enter(switch);
                    step
                }
                Switching::Done => {
                    self.phase = Phase::Run {
                        since: io.now_s,
                        steps: 0,
                    };
                    ProcedureStep::hold(Some(homing.with(HOMING_START)))
                }
                Switching::Failed(f) => self.leave(io, Err(f)),
            },
            Phase::Run { since, steps } => {
                let steps = steps.saturating_add(1);
                self.phase = Phase::Run { since, steps };
                let sw = io.statusword.0;
                if steps > STALE_STEPS {
                    if sw & HOMING_ERROR != 0 {
                        let f = ProcedureFailure::DriveReports {
                            what: "a homing error (statusword bit 13)",
                        };
                        return self.halt(io, Err(f));
                    }
                    if sw & HOMING_ATTAINED != 0 && sw & TARGET_REACHED != 0 {
                        return self.leave(io, Ok(()));
                    }
                }
                if io.now_s - since > self.params.timeout_s {
                    let missing = if sw & HOMING_ATTAINED != 0 {
                        "target reached"
                    } else {
                        "homing attained"
                    };
                    let f = ProcedureFailure::NotReported {
                        missing,
                        timeout_s: self.params.timeout_s,
                    };
                    return self.halt(io, Err(f));
                }
                ProcedureStep::hold(Some(homing.with(HOMING_START)))
            }
            Phase::Halt { since, result } => {
                // Bit 10 with halt set: the drive stands (CiA 402-2 §10.4.2).
                let stands = io.statusword.0 & TARGET_REACHED != 0;
                if (stands && io.now_s - since > 0.0) || io.now_s - since > HALT_TIMEOUT_S {
                    return self.leave(io, result);
                }
                ProcedureStep::hold(Some(homing.with(HOMING_START | HALT)))
            }
            Phase::QuickStop {
                since,
                last,
                still,
                result,
            } => {
                let still = steps_still(io, last, still);
                if still >= SETTLE_STEPS || io.now_s - since > HALT_TIMEOUT_S {
                    self.phase = Phase::Reenable {
                        since: io.now_s,
                        result,
                    };
                    return ProcedureStep::hold(Some(homing));
                }
                self.phase = Phase::QuickStop {
                    since,
                    last: io.position,
                    still,
                    result,
                };
                ProcedureStep::hold(Some(homing.quick_stopping()))
            }
            Phase::Reenable { since, result } => {
                let enabled = io.statusword.state() == Some(super::State::OperationEnabled);
                if enabled && io.now_s - since > 0.0 {
                    return self.leave(io, result);
                }
                if io.now_s - since > REENABLE_TIMEOUT_S {
                    // Handed back anyway: the axis finds its drive not enabled.
                    return self.leave(
                        io,
                        result.and(Err(ProcedureFailure::NotReported {
                            missing: "Operation enabled after the quick stop",
                            timeout_s: REENABLE_TIMEOUT_S,
                        })),
                    );
                }
                ProcedureStep::hold(Some(homing))
            }
            Phase::Settle {
                since,
                last,
                still,
                result,
            } => {
                let still = steps_still(io, last, still);
                if still >= SETTLE_STEPS || io.now_s - since > SETTLE_TIMEOUT_S {
                    self.phase = Phase::Leave {
                        switch: ModeSwitch::to(ModeOfOperation::CyclicSyncPosition),
                        result,
                    };
                    return self.step(&without_sdo(io));
                }
                self.phase = Phase::Settle {
                    since,
                    last: io.position,
                    still,
                    result,
                };
                ProcedureStep::hold(Some(ProcedureOutputs::idle(ModeOfOperation::Homing)))
            }
            Phase::Leave { mut switch, result } => match switch.step(io, 0) {
                Switching::Pending(step) => {
                    self.phase = Phase::Leave { switch, result };
                    step
                }
                Switching::Done => {
                    self.phase = Phase::Ended;
                    end(result)
                }
                // The first failure is the one to report; a drive that does not return
                // to CSP is reported when there was none.
                Switching::Failed(f) => {
                    self.phase = Phase::Ended;
                    end(result.and(Err(f)))
                }
            },
            Phase::Ended => ProcedureStep::hold(None),
        }
    }

    fn halt(
        &mut self,
        io: &ProcedureInputs,
        result: Result<(), ProcedureFailure>,
    ) -> ProcedureStep {
        self.phase = Phase::Halt {
            since: io.now_s,
            result,
        };
        ProcedureStep::hold(Some(
            ProcedureOutputs::idle(ModeOfOperation::Homing).with(HOMING_START | HALT),
        ))
    }

    fn leave(
        &mut self,
        io: &ProcedureInputs,
        result: Result<(), ProcedureFailure>,
    ) -> ProcedureStep {
        self.phase = Phase::Settle {
            since: io.now_s,
            last: io.position,
            still: 0,
            result,
        };
        ProcedureStep::hold(Some(ProcedureOutputs::idle(ModeOfOperation::Homing)))
    }
}

/// Steps in a row the position has stood within a count of `last` (`still` before).
fn steps_still(io: &ProcedureInputs, last: i32, still: u32) -> u32 {
    if (i64::from(io.position) - i64::from(last)).abs() <= 1 {
        still + 1
    } else {
        0
    }
}

fn end(result: Result<(), ProcedureFailure>) -> ProcedureStep {
    ProcedureStep {
        outputs: None,
        sdo: None,
        end: Some(result),
    }
}

/// The same inputs with the SDO outcome taken (a phase that follows in the same step
/// must not take its predecessor's outcome for its own).
fn without_sdo(io: &ProcedureInputs) -> ProcedureInputs {
    ProcedureInputs { sdo: None, ..*io }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia402::Statusword;

    fn params() -> DriveHomingParams {
        DriveHomingParams {
            method: 19,
            speed_switch: 1000,
            speed_zero: 100,
            acceleration: 10_000,
            home_offset: -7,
            timeout_s: 1.0,
            skip: false,
        }
    }

    fn io(sw: u16, display: i8, t: f64, sdo: Option<SdoOutcome>) -> ProcedureInputs {
        ProcedureInputs {
            statusword: Statusword(sw),
            mode_display: Some(display),
            mode_mapped: true,
            position: 0,
            now_s: t,
            sdo,
        }
    }

    /// The objects go by SDO in order while the drive stays in CSP; a statusword that
    /// still shows an earlier homing's "attained" right after the start edge is not
    /// taken; the real one is, and the drive is handed back in CSP.
    #[test]
    fn writes_the_objects_starts_and_ignores_a_stale_attained() {
        let mut h = DriveHoming::new(params());
        let mut written = Vec::new();
        let mut step = h.step(&io(0x0237, 8, 0.0, None));
        while let Some(a) = step.sdo {
            assert_eq!(step.outputs, None, "still CSP while writing");
            written.push((a.object.index, a.object.sub, a.write));
            step = h.step(&io(0x0237, 8, 0.0, Some(SdoOutcome::Done(0))));
        }
        assert_eq!(
            written,
            [
                (0x6098, 0, Some(19)),
                (0x6099, 1, Some(1000)),
                (0x6099, 2, Some(100)),
                (0x609A, 0, Some(10_000)),
                (0x607C, 0, Some(-7)),
            ]
        );
        // Mode 6 by PDO; bit 4 once the display shows it.
        assert_eq!(step.outputs.map(|o| o.mode), Some(ModeOfOperation::Homing));
        let step = h.step(&io(0x0237, 6, 0.01, None));
        assert_eq!(step.outputs.map(|o| o.mode_bits), Some(HOMING_START));
        let stale = 0x0237 | HOMING_ATTAINED | TARGET_REACHED;
        for k in 0..STALE_STEPS {
            let step = h.step(&io(stale, 6, 0.02 + f64::from(k) * 0.001, None));
            assert_eq!(step.end, None, "step {k}: a stale statusword");
        }
        assert_eq!(h.phase_name(), "homing");
        // Attained now; the position stands: settle, then CSP, then the end.
        let mut end = None;
        for k in 0..20 {
            let display = if k < 5 { 6 } else { 8 };
            let step = h.step(&io(stale, display, 0.1 + f64::from(k) * 0.001, None));
            if step.end.is_some() {
                end = step.end;
                break;
            }
        }
        assert_eq!(end, Some(Ok(())));
    }

    #[test]
    fn the_timeout_names_what_was_missing_and_a_refused_method_ends_in_csp() {
        let mut h = DriveHoming::new(params());
        let step = h.step(&io(0x0237, 8, 0.0, None));
        assert!(step.sdo.is_some());
        let step = h.step(&io(0x0237, 8, 0.0, Some(SdoOutcome::Aborted(0x0609_0030))));
        assert_eq!(
            step.end,
            Some(Err(ProcedureFailure::Refused {
                object: objects::HOMING_METHOD,
                value: 19,
                code: 0x0609_0030
            }))
        );
        assert_eq!(step.outputs, None, "never left CSP");
        let mut h = DriveHoming::new(params());
        let mut step = h.step(&io(0x0237, 8, 0.0, None));
        while step.sdo.is_some() {
            step = h.step(&io(0x0237, 8, 0.0, Some(SdoOutcome::Done(0))));
        }
        let mut t = 0.0;
        let mut end = None;
        while t < 10.0 {
            t += 0.01;
            // In homing mode, "in progress" forever; halted, it stands (bit 10).
            let halted = h.phase_name() == "halting";
            let sw = 0x0237 | if halted { TARGET_REACHED } else { 0 };
            let display = if matches!(h.phase_name(), "switching back to CSP") {
                8
            } else {
                6
            };
            let step = h.step(&io(sw, display, t, None));
            if let Some(e) = step.end {
                end = Some(e);
                break;
            }
        }
        assert_eq!(
            end,
            Some(Err(ProcedureFailure::NotReported {
                missing: "homing attained",
                timeout_s: 1.0
            }))
        );
        assert!(t > 1.0 && t < 1.5, "{t}");
    }

    /// QuickStop while the drive homes: the Quick stop command (not the halt bit) until
    /// the position stands, then enabled again (the statusword still shows Quick stop
    /// active: 0x0217), and handed back in CSP, cancelled by QuickStop. A Stop halts.
    #[test]
    fn a_quick_stop_uses_the_drive_s_quick_stop_and_enables_it_again() {
        let running = |h: &mut DriveHoming| {
            let mut step = h.step(&io(0x0237, 8, 0.0, None));
            while step.sdo.is_some() {
                step = h.step(&io(0x0237, 8, 0.0, Some(SdoOutcome::Done(0))));
            }
            let step = h.step(&io(0x0237, 6, 0.01, None));
            assert_eq!(step.outputs.map(|o| o.mode_bits), Some(HOMING_START));
        };
        let mut h = DriveHoming::new(params());
        running(&mut h);
        h.cancel("Stop");
        let step = h.step(&io(0x0237, 6, 0.02, None));
        let out = step.outputs.unwrap();
        assert!(out.mode_bits & HALT != 0 && !out.quick_stop, "a Stop halts");

        let mut h = DriveHoming::new(params());
        running(&mut h);
        h.cancel("QuickStop");
        // Braking: the position still changes.
        for k in 0..10 {
            let mut i = io(0x0217, 6, 0.02 + f64::from(k) * 0.001, None);
            i.position = 100 * k;
            let out = h.step(&i).outputs.unwrap();
            assert!(out.quick_stop && out.mode_bits == 0, "{k}: {out:?}");
        }
        assert_eq!(h.phase_name(), "quick stop");
        // Standing (in Quick stop active): enabled again, then back to CSP.
        let mut end = None;
        for k in 0..40 {
            let mut i = io(0x0217, 6, 0.04 + f64::from(k) * 0.001, None);
            i.position = 900;
            if h.phase_name() != "quick stop" {
                // The channel's Enable operation took it back to Operation enabled.
                i.statusword = Statusword(0x0237);
            }
            if h.phase_name() == "switching back to CSP" {
                i.mode_display = Some(8);
            }
            let step = h.step(&i);
            if let Some(e) = step.end {
                end = Some(e);
                break;
            }
            if h.phase_name() != "quick stop" {
                assert!(!step.outputs.is_some_and(|o| o.quick_stop), "{k}");
            }
        }
        assert_eq!(
            end,
            Some(Err(ProcedureFailure::Cancelled { by: "QuickStop" }))
        );
    }
}
