//! Bringing a slave back to OP after it left (its watchdog expired while the cable was
//! out, or it refused a state): acknowledge the latched error, then request OP, as a
//! commissioning engineer does with "reset" in TwinCAT.
//!
//! A slave's firmware takes its time: it sees the AL control write, runs its checks and
//! only then writes AL status (ETG.1000.6 §6.4.1: the ESC latches AL control, the
//! application answers in AL status). A drive takes milliseconds from SafeOp to OP, so
//! the master polls the AL status until the slave is where it was asked to go or a
//! timeout passes — never once right after the request. The steps are a state machine,
//! [`Recovery`], that issues at most one register access at a time and takes its answer:
//! the cycle runs one access per cycle beside the process data, inside the cycle's reply
//! deadline, so a recovery never stretches a cycle (the slave's watchdog keeps getting
//! its process data meanwhile — and a drive goes to Op only once it has valid outputs).
//!
//! The error is acknowledged first, in the slave's current state (AL control = state |
//! acknowledge), and OP requested only once the error indicator is clear, as IgH's
//! master does: a slave that refuses OP sets the indicator again, so from then on the
//! indicator means "refused" and is reported at once with its AL status code, instead of
//! being mistaken for the old, not yet acknowledged error.

use std::ops::Deref;

use ethercrab::{SubDevice, SubDeviceRef};
use gantry_kernel::axis::command::CommandError;
use thiserror::Error;

/// AL control register (ETG.1000.4 §6.4.1, Table 34).
pub const AL_CONTROL: u16 = 0x0120;
/// AL status register (ETG.1000.4 Table 35), followed by a reserved word and the AL
/// status code at 0x0134: one 6-byte read gets both.
pub const AL_STATUS: u16 = 0x0130;
/// Bytes read from [`AL_STATUS`]: status, reserved, AL status code.
const AL_STATUS_AND_CODE_BYTES: usize = 6;
/// AL state PreOp in the AL control/status registers.
pub const AL_STATE_PREOP: u16 = 0x02;
/// AL state OP in the AL control/status registers.
pub const AL_STATE_OP: u16 = 0x08;
/// The state bits of AL control/status.
pub const AL_STATE_MASK: u16 = 0x0F;
/// AL control: acknowledge the error indicated in AL status; AL status: error indicator.
pub const AL_ERROR_ACK: u16 = 0x10;
/// How long a slave may take to acknowledge its error and reach OP: 10 s, longer than a
/// slave waits itself for what OP needs (the slave stack code's SafeOp→Op timeout, 9 s,
/// after which it refuses with a code), so that a slave that gives up says why before
/// the master does.
pub const RECOVERY_TIMEOUT_NS: u64 = 10_000_000_000;

/// Why a slave did not come back. `Copy`: the cycle thread records it without allocating.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum RecoveryError {
    /// The slave never answered (still unplugged, or switched off).
    #[error("slave {address:#06x} does not answer (cable, power?) after {waited_ms} ms")]
    NoAnswer {
        /// Station address.
        address: u16,
        /// How long the master tried.
        waited_ms: u64,
    },
    /// The slave refused a state: it set its error indicator again.
    #[error(
        "slave {address:#06x} refused {wanted}: AL status {status:#06x}, AL status code \
         {code:#06x} ({})",
        al_status_code_text(*code)
    )]
    Refused {
        /// Station address.
        address: u16,
        /// The state asked for.
        wanted: &'static str,
        /// AL status register.
        status: u16,
        /// AL status code (ETG.1000.6 Table 11).
        code: u16,
    },
    /// The slave answered but did not get there in time.
    #[error(
        "slave {address:#06x} did not {wanted} within {waited_ms} ms: AL status \
         {status:#06x}, AL status code {code:#06x} ({})",
        al_status_code_text(*code)
    )]
    TimedOut {
        /// Station address.
        address: u16,
        /// What it was asked to do.
        wanted: &'static str,
        /// How long the master waited.
        waited_ms: u64,
        /// Last AL status register read.
        status: u16,
        /// Last AL status code read.
        code: u16,
    },
}

impl RecoveryError {
    /// The error as the axis' reset reports it (the kernel's `Copy` error type).
    pub fn command_error(&self) -> CommandError {
        let (address, problem, al_status, al_status_code) = match *self {
            RecoveryError::NoAnswer { address, .. } => {
                (address, "it does not answer (cable, power?)", 0, 0)
            }
            RecoveryError::Refused {
                address,
                status,
                code,
                ..
            } => (address, "it refused", status, code),
            RecoveryError::TimedOut {
                address,
                status,
                code,
                ..
            } => (address, "it did not get there in time", status, code),
        };
        CommandError::SlaveNotOperational {
            address,
            problem,
            al_status,
            al_status_code,
            code_text: al_status_code_text(al_status_code),
        }
    }
}

/// The text of an AL status code (ETG.1000.6 Table 11).
pub const fn al_status_code_text(code: u16) -> &'static str {
    match code {
        0x0000 => "no error",
        0x0001 => "unspecified error",
        0x0002 => "no memory",
        0x0003 => "invalid device setup",
        0x0011 => "invalid requested state change",
        0x0012 => "unknown requested state",
        0x0013 => "bootstrap not supported",
        0x0014 => "no valid firmware",
        0x0015 | 0x0016 => "invalid mailbox configuration",
        0x0017 => "invalid sync manager configuration",
        0x0018 => "no valid inputs available",
        0x0019 => "no valid outputs",
        0x001A => "synchronization error",
        0x001B => "sync manager watchdog",
        0x001C => "invalid sync manager types",
        0x001D => "invalid output configuration",
        0x001E => "invalid input configuration",
        0x001F => "invalid watchdog configuration",
        0x0020 => "slave needs cold start",
        0x0021 => "slave needs INIT",
        0x0022 => "slave needs PREOP",
        0x0023 => "slave needs SAFEOP",
        0x0024 => "invalid input mapping",
        0x0025 => "invalid output mapping",
        0x0026 => "inconsistent settings",
        0x0027 => "free run not supported",
        0x0028 => "sync mode not supported",
        0x0029 => "free run needs 3-buffer mode",
        0x002A => "background watchdog",
        0x002B => "no valid inputs and outputs",
        0x002C => "fatal sync error",
        0x002D => "no sync error",
        0x0030 => "invalid DC SYNC configuration",
        0x0031 => "invalid DC latch configuration",
        0x0032 => "PLL error",
        0x0033 => "DC sync IO error",
        0x0034 => "DC sync timeout",
        0x0035 => "DC invalid sync cycle time",
        0x0036 => "DC SYNC0 cycle time",
        0x0037 => "DC SYNC1 cycle time",
        0x0041..=0x004F => "mailbox protocol error",
        0x0050 => "EEPROM no access",
        0x0051 => "EEPROM error",
        0x0060 => "slave restarted locally",
        0x8000..=0xFFFF => "vendor specific (see the device's manual)",
        _ => "reserved code",
    }
}

/// What recovery did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Recovered {
    /// The slave was in OP already.
    WasInOp,
    /// Its error was acknowledged and it is back in OP.
    BackInOp,
}

/// The one register access a [`Recovery`] wants next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RegisterAccess {
    /// Read AL status and AL status code (FPRD 0x0130, 6 bytes).
    ReadAlStatus,
    /// Write AL control (FPWR 0x0120).
    WriteAlControl(u16),
}

/// What the slave answered to a [`RegisterAccess`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    /// AL status and AL status code.
    AlStatus {
        /// AL status register.
        status: u16,
        /// AL status code.
        code: u16,
    },
    /// The write was taken (working counter 1).
    Written,
    /// No answer: the frame was lost, timed out, or came back with working counter 0.
    None,
}

impl Answer {
    /// Decodes the 6 bytes read from [`AL_STATUS`].
    pub fn from_al_status_bytes(bytes: [u8; AL_STATUS_AND_CODE_BYTES]) -> Self {
        let [s0, s1, _, _, c0, c1] = bytes;
        Answer::AlStatus {
            status: u16::from_le_bytes([s0, s1]),
            code: u16::from_le_bytes([c0, c1]),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// Where is the slave?
    Check,
    /// Acknowledge its error in this state.
    Acknowledge(u16),
    /// Wait until the error indicator is clear.
    AwaitAcknowledge,
    /// Ask for OP.
    RequestOp,
    /// Wait until it is in OP.
    AwaitOp,
    /// Finished.
    Done(Result<Recovered, RecoveryError>),
}

/// Brings one slave back to OP, one register access at a time (see the module doc). No
/// allocation, no clock of its own: the caller passes the time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Recovery {
    address: u16,
    step: Step,
    started_ns: u64,
    timeout_ns: u64,
    /// The last AL status and code read.
    last: Option<(u16, u16)>,
}

impl Recovery {
    /// A recovery of the slave at station `address`, started at `now_ns`, that gives up
    /// `timeout_ns` later.
    pub fn new(address: u16, now_ns: u64, timeout_ns: u64) -> Self {
        Self {
            address,
            step: Step::Check,
            started_ns: now_ns,
            timeout_ns,
            last: None,
        }
    }

    /// The slave's station address.
    pub fn address(&self) -> u16 {
        self.address
    }

    /// The access to run next; `None` once finished.
    pub fn next_access(&self) -> Option<RegisterAccess> {
        match self.step {
            Step::Check | Step::AwaitAcknowledge | Step::AwaitOp => {
                Some(RegisterAccess::ReadAlStatus)
            }
            Step::Acknowledge(state) => Some(RegisterAccess::WriteAlControl(state | AL_ERROR_ACK)),
            Step::RequestOp => Some(RegisterAccess::WriteAlControl(AL_STATE_OP)),
            Step::Done(_) => None,
        }
    }

    /// The outcome, once finished.
    pub fn outcome(&self) -> Option<Result<Recovered, RecoveryError>> {
        match self.step {
            Step::Done(r) => Some(r),
            _ => None,
        }
    }

    /// Takes the answer to [`Recovery::next_access`], received at `now_ns`.
    pub fn on_answer(&mut self, answer: Answer, now_ns: u64) {
        let waited_ns = now_ns.saturating_sub(self.started_ns);
        if let Answer::AlStatus { status, code } = answer {
            self.last = Some((status, code));
        }
        self.step = match (self.step, answer) {
            (Step::Done(r), _) => Step::Done(r),
            (step, Answer::None) => step,
            (Step::Check, Answer::AlStatus { status, .. }) => {
                if status & AL_ERROR_ACK != 0 {
                    Step::Acknowledge(status & AL_STATE_MASK)
                } else if status & AL_STATE_MASK == AL_STATE_OP {
                    Step::Done(Ok(Recovered::WasInOp))
                } else {
                    Step::RequestOp
                }
            }
            (Step::Acknowledge(_), Answer::Written) => Step::AwaitAcknowledge,
            (Step::AwaitAcknowledge, Answer::AlStatus { status, .. }) => {
                if status & AL_ERROR_ACK != 0 {
                    Step::AwaitAcknowledge
                } else if status & AL_STATE_MASK == AL_STATE_OP {
                    Step::Done(Ok(Recovered::BackInOp))
                } else {
                    Step::RequestOp
                }
            }
            (Step::RequestOp, Answer::Written) => Step::AwaitOp,
            (Step::AwaitOp, Answer::AlStatus { status, code }) => {
                if status & AL_ERROR_ACK != 0 {
                    Step::Done(Err(RecoveryError::Refused {
                        address: self.address,
                        wanted: "OP",
                        status,
                        code,
                    }))
                } else if status & AL_STATE_MASK == AL_STATE_OP {
                    Step::Done(Ok(Recovered::BackInOp))
                } else {
                    Step::AwaitOp
                }
            }
            // An answer that does not fit the access (cannot happen with a correct
            // caller): ask again.
            (step, _) => step,
        };
        if self.step.is_done() || waited_ns < self.timeout_ns {
            return;
        }
        let waited_ms = waited_ns / 1_000_000;
        let wanted = match self.step {
            Step::Check | Step::Acknowledge(_) | Step::AwaitAcknowledge => "acknowledge its error",
            _ => "reach OP",
        };
        self.step = Step::Done(Err(match self.last {
            None => RecoveryError::NoAnswer {
                address: self.address,
                waited_ms,
            },
            Some((status, code)) => RecoveryError::TimedOut {
                address: self.address,
                wanted,
                waited_ms,
                status,
                code,
            },
        }));
    }
}

impl Step {
    fn is_done(&self) -> bool {
        matches!(self, Step::Done(_))
    }
}

/// Runs `access` on `sd`: one register round trip.
pub async fn access<S>(sd: &SubDeviceRef<'_, S>, access: RegisterAccess) -> Answer
where
    S: Deref<Target = SubDevice>,
{
    match access {
        RegisterAccess::ReadAlStatus => sd
            .register_read::<[u8; AL_STATUS_AND_CODE_BYTES]>(AL_STATUS)
            .await
            .map_or(Answer::None, Answer::from_al_status_bytes),
        RegisterAccess::WriteAlControl(value) => sd
            .register_write(AL_CONTROL, value)
            .await
            .map_or(Answer::None, |_| Answer::Written),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slave as the datasheet describes it, reduced to its AL registers: it latches AL
    /// control and answers in AL status `delay_polls` reads later (its firmware's time),
    /// refusing OP with `refuse_op` if given.
    struct SlowSlave {
        status: u16,
        code: u16,
        pending: Option<(u16, u32)>,
        delay_polls: u32,
        refuse_op: Option<u16>,
        online: bool,
    }

    impl SlowSlave {
        fn in_safe_op_with_error(delay_polls: u32) -> Self {
            Self {
                status: 0x14,
                code: 0x001B,
                pending: None,
                delay_polls,
                refuse_op: None,
                online: true,
            }
        }

        fn serve(&mut self, access: RegisterAccess) -> Answer {
            if !self.online {
                return Answer::None;
            }
            match access {
                RegisterAccess::WriteAlControl(c) => {
                    self.pending = Some((c, self.delay_polls));
                    Answer::Written
                }
                RegisterAccess::ReadAlStatus => {
                    if let Some((control, left)) = self.pending {
                        if left == 0 {
                            self.pending = None;
                            self.apply(control);
                        } else {
                            self.pending = Some((control, left - 1));
                        }
                    }
                    Answer::AlStatus {
                        status: self.status,
                        code: self.code,
                    }
                }
            }
        }

        fn apply(&mut self, control: u16) {
            let error = self.status & AL_ERROR_ACK != 0;
            if error && control & AL_ERROR_ACK == 0 {
                return;
            }
            let wanted = control & AL_STATE_MASK;
            match (wanted, self.refuse_op) {
                (AL_STATE_OP, Some(code)) => {
                    self.status = (self.status & AL_STATE_MASK) | AL_ERROR_ACK;
                    self.code = code;
                }
                _ => {
                    self.status = wanted;
                    self.code = 0;
                }
            }
        }
    }

    /// Runs a recovery against `slave`, one access per 1 ms cycle; returns the outcome
    /// and the cycles it took.
    fn run(slave: &mut SlowSlave, timeout_ns: u64) -> (Result<Recovered, RecoveryError>, u32) {
        let mut r = Recovery::new(0x1002, 0, timeout_ns);
        for cycle in 1..100_000u32 {
            let access = r.next_access().expect("not finished");
            let answer = slave.serve(access);
            r.on_answer(answer, u64::from(cycle) * 1_000_000);
            if let Some(outcome) = r.outcome() {
                assert_eq!(r.next_access(), None);
                return (outcome, cycle);
            }
        }
        panic!("never finished");
    }

    #[test]
    fn an_instant_slave_is_back_in_five_accesses() {
        let mut slave = SlowSlave::in_safe_op_with_error(0);
        // Read (SafeOp + error), acknowledge, read (SafeOp), request OP, read (OP).
        assert_eq!(
            run(&mut slave, RECOVERY_TIMEOUT_NS),
            (Ok(Recovered::BackInOp), 5)
        );
        assert_eq!(slave.status, AL_STATE_OP);
    }

    #[test]
    fn a_slave_in_op_costs_one_read() {
        let mut slave = SlowSlave::in_safe_op_with_error(0);
        slave.status = AL_STATE_OP;
        assert_eq!(
            run(&mut slave, RECOVERY_TIMEOUT_NS),
            (Ok(Recovered::WasInOp), 1)
        );
    }

    /// The bug this replaces: a slave still on its way to OP was called "refused". A
    /// slave that takes 10 ms for each transition is polled until it is there.
    #[test]
    fn a_slow_slave_is_polled_until_it_is_in_op() {
        let mut slave = SlowSlave::in_safe_op_with_error(10);
        let (outcome, cycles) = run(&mut slave, RECOVERY_TIMEOUT_NS);
        assert_eq!(outcome, Ok(Recovered::BackInOp));
        // Two transitions of 10 polls each, plus the first read and two writes.
        assert_eq!(cycles, 1 + 1 + 11 + 1 + 11);
    }

    #[test]
    fn a_refusal_is_reported_with_its_code_as_text() {
        let mut slave = SlowSlave::in_safe_op_with_error(3);
        slave.refuse_op = Some(0x001D);
        let (outcome, _) = run(&mut slave, RECOVERY_TIMEOUT_NS);
        let e = outcome.unwrap_err();
        assert_eq!(
            e.to_string(),
            "slave 0x1002 refused OP: AL status 0x0014, AL status code 0x001d (invalid \
             output configuration)"
        );
        assert_eq!(
            e.command_error().to_string(),
            "Reset: bus slave 0x1002 is not back in operation: it refused (AL status 0x0014, \
             AL status code 0x001d: invalid output configuration)"
        );
    }

    #[test]
    fn a_slave_too_slow_times_out_with_its_last_status_and_code() {
        let mut slave = SlowSlave::in_safe_op_with_error(500);
        let (outcome, cycles) = run(&mut slave, 100_000_000);
        assert_eq!(cycles, 100, "gave up at the timeout");
        assert_eq!(
            outcome.unwrap_err().to_string(),
            "slave 0x1002 did not acknowledge its error within 100 ms: AL status 0x0014, \
             AL status code 0x001b (sync manager watchdog)"
        );
    }

    #[test]
    fn a_silent_slave_is_retried_until_the_timeout() {
        let mut slave = SlowSlave::in_safe_op_with_error(0);
        slave.online = false;
        let (outcome, cycles) = run(&mut slave, 50_000_000);
        assert_eq!(cycles, 50);
        assert_eq!(
            outcome.unwrap_err().to_string(),
            "slave 0x1002 does not answer (cable, power?) after 50 ms"
        );
        // Lost answers in between only delay it.
        let mut slave = SlowSlave::in_safe_op_with_error(2);
        let mut r = Recovery::new(0x1002, 0, RECOVERY_TIMEOUT_NS);
        let mut t = 0;
        while r.outcome().is_none() {
            t += 1_000_000;
            let access = r.next_access().unwrap();
            let answer = if t % 3_000_000 == 0 {
                Answer::None
            } else {
                slave.serve(access)
            };
            r.on_answer(answer, t);
        }
        assert_eq!(r.outcome(), Some(Ok(Recovered::BackInOp)));
    }

    #[test]
    fn al_status_bytes_decode_status_and_code() {
        assert_eq!(
            Answer::from_al_status_bytes([0x14, 0x00, 0xAA, 0xBB, 0x1B, 0x00]),
            Answer::AlStatus {
                status: 0x14,
                code: 0x001B
            }
        );
        assert_eq!(al_status_code_text(0x001B), "sync manager watchdog");
        assert_eq!(
            al_status_code_text(0x8001),
            "vendor specific (see the device's manual)"
        );
    }
}
