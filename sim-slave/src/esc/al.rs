//! The application-layer (AL) state machine of a slave (ETG.1000.6 §6.4.1): one function
//! from (AL status, AL control) to the new AL status, with the error indicator latched
//! until the master acknowledges it.

/// AL states (register 0x0120/0x0130 bits 0–3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AlState {
    /// 1: Init.
    Init,
    /// 2: Pre-operational.
    PreOp,
    /// 3: Bootstrap.
    Boot,
    /// 4: Safe-operational.
    SafeOp,
    /// 8: Operational.
    Op,
    /// Any other value (an invalid request).
    Unknown(u8),
}

impl AlState {
    /// Register value.
    pub const fn raw(self) -> u8 {
        match self {
            AlState::Init => 1,
            AlState::PreOp => 2,
            AlState::Boot => 3,
            AlState::SafeOp => 4,
            AlState::Op => 8,
            AlState::Unknown(v) => v,
        }
    }

    /// From bits 0–3 of AL control or status.
    pub const fn from_bits(v: u16) -> Self {
        match v & 0x0F {
            1 => AlState::Init,
            2 => AlState::PreOp,
            3 => AlState::Boot,
            4 => AlState::SafeOp,
            8 => AlState::Op,
            v => AlState::Unknown(v as u8),
        }
    }
}

/// AL status codes (ETG.1000.6 Table 11, the ones the emulation raises; decoding is total).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AlStatusCode {
    /// 0x0000 no error.
    NoError,
    /// 0x0011 invalid requested state change.
    InvalidStateChange,
    /// 0x0012 unknown requested state.
    UnknownState,
    /// 0x0013 bootstrap not supported.
    BootstrapNotSupported,
    /// 0x0016 invalid mailbox configuration (PreOp).
    InvalidMailboxConfigPreOp,
    /// 0x0017 invalid sync manager configuration.
    InvalidSyncManagerConfig,
    /// 0x001A synchronization error (too many SM events missed in a row).
    SyncError,
    /// 0x001B sync manager watchdog.
    SyncManagerWatchdog,
    /// 0x001D invalid output configuration.
    InvalidOutputConfig,
    /// 0x001E invalid input configuration.
    InvalidInputConfig,
    /// 0x002C fatal sync error (SYNC0 stopped in Op).
    FatalSyncError,
    /// 0x002D no sync error (no SYNC0 arrived while the device waited for it to go to Op).
    NoSyncError,
    /// 0x0030 invalid DC SYNC configuration.
    InvalidDcSyncConfig,
    /// Anything else.
    Other(u16),
}

impl AlStatusCode {
    /// Register value (0x0134).
    pub const fn raw(self) -> u16 {
        match self {
            Self::NoError => 0x0000,
            Self::InvalidStateChange => 0x0011,
            Self::UnknownState => 0x0012,
            Self::BootstrapNotSupported => 0x0013,
            Self::InvalidMailboxConfigPreOp => 0x0016,
            Self::InvalidSyncManagerConfig => 0x0017,
            Self::SyncError => 0x001A,
            Self::SyncManagerWatchdog => 0x001B,
            Self::InvalidOutputConfig => 0x001D,
            Self::InvalidInputConfig => 0x001E,
            Self::FatalSyncError => 0x002C,
            Self::NoSyncError => 0x002D,
            Self::InvalidDcSyncConfig => 0x0030,
            Self::Other(v) => v,
        }
    }

    /// From the register value.
    pub const fn from_raw(v: u16) -> Self {
        match v {
            0x0000 => Self::NoError,
            0x0011 => Self::InvalidStateChange,
            0x0012 => Self::UnknownState,
            0x0013 => Self::BootstrapNotSupported,
            0x0016 => Self::InvalidMailboxConfigPreOp,
            0x0017 => Self::InvalidSyncManagerConfig,
            0x001A => Self::SyncError,
            0x001B => Self::SyncManagerWatchdog,
            0x001D => Self::InvalidOutputConfig,
            0x001E => Self::InvalidInputConfig,
            0x002C => Self::FatalSyncError,
            0x002D => Self::NoSyncError,
            0x0030 => Self::InvalidDcSyncConfig,
            v => Self::Other(v),
        }
    }

    /// Text for users.
    pub const fn text(self) -> &'static str {
        match self {
            Self::NoError => "no error",
            Self::InvalidStateChange => "invalid requested state change",
            Self::UnknownState => "unknown requested state",
            Self::BootstrapNotSupported => "bootstrap not supported",
            Self::InvalidMailboxConfigPreOp => "invalid mailbox configuration (PreOp)",
            Self::InvalidSyncManagerConfig => "invalid sync manager configuration",
            Self::SyncError => "synchronization error",
            Self::SyncManagerWatchdog => "sync manager watchdog",
            Self::InvalidOutputConfig => "invalid output configuration",
            Self::InvalidInputConfig => "invalid input configuration",
            Self::FatalSyncError => "fatal sync error",
            Self::NoSyncError => "no sync error",
            Self::InvalidDcSyncConfig => "invalid DC SYNC configuration",
            Self::Other(_) => "unknown AL status code",
        }
    }
}

/// Bit 4 of AL status: error indicator; of AL control: error acknowledge.
pub const ERROR_BIT: u16 = 0x10;

/// How long a device's firmware takes to complete each upward transition once the master
/// requested it (chain time, ns). Until then AL status shows the old state: a slave
/// reports a state when it is in it (ETG.1000.6 §6.4.1), and starting mailbox, input and
/// output handlers takes a drive's firmware milliseconds. Downward transitions and error
/// acknowledges are taken at once (the firmware stops its handlers in the AL event).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TransitionTimes {
    /// Init → PreOp (and Init → Boot): the mailbox handler starts.
    pub init_to_preop_ns: u64,
    /// PreOp → SafeOp: the mapping is checked and the input handler starts.
    pub preop_to_safeop_ns: u64,
    /// SafeOp → Op: the output handler starts.
    pub safeop_to_op_ns: u64,
}

impl TransitionTimes {
    /// A servo drive's firmware: 2 ms, 10 ms, 5 ms.
    pub const SERVO: Self = Self {
        init_to_preop_ns: 2_000_000,
        preop_to_safeop_ns: 10_000_000,
        safeop_to_op_ns: 5_000_000,
    };
    /// An I/O terminal with no firmware to run: at once.
    pub const INSTANT: Self = Self {
        init_to_preop_ns: 0,
        preop_to_safeop_ns: 0,
        safeop_to_op_ns: 0,
    };

    /// How long `from` → `to` takes.
    pub const fn of(&self, from: AlState, to: AlState) -> u64 {
        match (from, to) {
            (AlState::Init, AlState::PreOp | AlState::Boot) => self.init_to_preop_ns,
            (AlState::PreOp, AlState::SafeOp) => self.preop_to_safeop_ns,
            (AlState::SafeOp, AlState::Op) => self.safeop_to_op_ns,
            _ => 0,
        }
    }
}

/// How long a device in SafeOp waits, once Op was requested, for what it needs to go
/// there (valid outputs, SYNC0 in DC mode) before it refuses: the slave stack code's
/// SAFEOP2OPTIMEOUT (9 s, the ESI default `SafeopOpTimeout`, less the 50 ms it keeps to
/// answer before the master gives up).
pub const SAFEOP_OP_TIMEOUT_NS: u64 = 8_950_000_000;

/// What the firmware behind an ESC requires of a transition, besides the standard's rules.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Firmware {
    /// How long each upward transition takes.
    pub times: TransitionTimes,
    /// SafeOp → Op waits for the outputs: the output SyncManager's buffer completed at
    /// least once since SafeOp (a drive must not enable on undefined outputs; ETG.1000.6
    /// §6.4.1 "valid outputs", the slave stack code's OP_PD_REQUIRED). On timeout: 0x001B.
    pub op_needs_outputs: bool,
    /// The device runs only synchronised to SYNC0 (PreOp → SafeOp without SYNC0 active:
    /// 0x0030).
    pub requires_dc: bool,
    /// 0x10F1:02 sync error counter limit: the SM event missed counter (0x1C32:0B) goes
    /// up by 3 for a SYNC0 without new outputs and down by 1 for each output buffer; at
    /// the limit the device leaves Op with 0x001A (ETG.1020; the slave stack code's
    /// default 4: two SYNC0 periods in a row without outputs).
    pub sync_error_limit: u16,
    /// How long the firmware takes to answer a mailbox request (ns): a real slave's
    /// application picks the request up in its own loop and answers milliseconds later,
    /// so a master must poll SM1 until its answer is there, not read it at once. 0: in
    /// the frame that brought the request.
    pub mailbox_response_ns: u64,
}

/// The slave stack code's default 0x10F1:02.
pub const DEFAULT_SYNC_ERROR_LIMIT: u16 = 4;

impl Firmware {
    /// A CiA-402 servo drive.
    pub const SERVO: Self = Self {
        times: TransitionTimes::SERVO,
        op_needs_outputs: true,
        requires_dc: false,
        sync_error_limit: DEFAULT_SYNC_ERROR_LIMIT,
        mailbox_response_ns: 0,
    };
    /// An I/O module without checks of its own beyond the standard's.
    pub const SIMPLE: Self = Self {
        times: TransitionTimes::INSTANT,
        op_needs_outputs: false,
        requires_dc: false,
        sync_error_limit: DEFAULT_SYNC_ERROR_LIMIT,
        mailbox_response_ns: 0,
    };
}

impl Default for Firmware {
    fn default() -> Self {
        Self::SIMPLE
    }
}

/// What the AL state machine decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AlOutcome {
    /// New AL status register value.
    pub status: u16,
    /// New AL status code.
    pub code: AlStatusCode,
}

/// Whether the standard allows going from `from` to `to` directly.
pub const fn allowed(from: AlState, to: AlState) -> bool {
    use AlState::*;
    matches!(
        (from, to),
        (Init, Init | PreOp | Boot)
            | (PreOp, Init | PreOp | SafeOp)
            | (SafeOp, Init | PreOp | SafeOp | Op)
            | (Op, Init | PreOp | SafeOp | Op)
            | (Boot, Init | Boot)
    )
}

/// Applies an AL control write. `check(from, to)` is the device's own check of an upward
/// transition (SyncManager and PDO configuration); `supports_boot` whether bootstrap is.
///
/// While the error indicator is set, only a request with the acknowledge bit clears it;
/// requests without it leave status and code unchanged. A refused transition keeps the
/// current state and sets the error indicator and code.
pub fn on_control(
    status: u16,
    code: AlStatusCode,
    control: u16,
    supports_boot: bool,
    check: impl Fn(AlState, AlState) -> Result<(), AlStatusCode>,
) -> AlOutcome {
    let current = AlState::from_bits(status);
    let requested = AlState::from_bits(control);
    let error = status & ERROR_BIT != 0;
    let ack = control & ERROR_BIT != 0;
    if error && !ack {
        // Latched until acknowledged; downward requests are still obeyed (to Init).
        if requested == AlState::Init {
            return AlOutcome {
                status: u16::from(AlState::Init.raw()) | ERROR_BIT,
                code,
            };
        }
        return AlOutcome { status, code };
    }
    let refuse = |code: AlStatusCode| AlOutcome {
        status: u16::from(current.raw()) | ERROR_BIT,
        code,
    };
    if let AlState::Unknown(_) = requested {
        return refuse(AlStatusCode::UnknownState);
    }
    if requested == AlState::Boot && !supports_boot {
        return refuse(AlStatusCode::BootstrapNotSupported);
    }
    if !allowed(current, requested) {
        return refuse(AlStatusCode::InvalidStateChange);
    }
    if let Err(c) = check(current, requested) {
        return refuse(c);
    }
    AlOutcome {
        status: u16::from(requested.raw()),
        code: AlStatusCode::NoError,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use AlState::*;

    fn ok(_: AlState, _: AlState) -> Result<(), AlStatusCode> {
        Ok(())
    }

    fn go(status: u16, control: u16) -> AlOutcome {
        on_control(status, AlStatusCode::NoError, control, false, ok)
    }

    #[test]
    fn ip_ps_so_and_back() {
        assert_eq!(go(1, 2).status, 2);
        assert_eq!(go(2, 4).status, 4);
        assert_eq!(go(4, 8).status, 8);
        assert_eq!(go(8, 4).status, 4);
        assert_eq!(go(8, 1).status, 1);
    }

    #[test]
    fn skipping_states_upwards_is_an_invalid_state_change() {
        for (from, to) in [(1u16, 4u16), (1, 8), (2, 8)] {
            let o = go(from, to);
            assert_eq!(o.status, from | ERROR_BIT, "{from}->{to}");
            assert_eq!(o.code, AlStatusCode::InvalidStateChange);
        }
        assert_eq!(go(1, 5).code, AlStatusCode::UnknownState);
        assert_eq!(go(1, 3).code, AlStatusCode::BootstrapNotSupported);
    }

    #[test]
    fn device_checks_refuse_with_their_code_and_the_error_latches() {
        let bad_outputs = |from: AlState, to: AlState| {
            if (from, to) == (PreOp, SafeOp) {
                Err(AlStatusCode::InvalidOutputConfig)
            } else {
                Ok(())
            }
        };
        let o = on_control(2, AlStatusCode::NoError, 4, false, bad_outputs);
        assert_eq!(
            (o.status, o.code),
            (2 | ERROR_BIT, AlStatusCode::InvalidOutputConfig)
        );
        // Without acknowledge nothing changes, even a valid request.
        let o2 = on_control(o.status, o.code, 2, false, ok);
        assert_eq!(o2, o);
        // Acknowledge + request clears it.
        let o3 = on_control(o.status, o.code, 2 | ERROR_BIT, false, ok);
        assert_eq!((o3.status, o3.code), (2, AlStatusCode::NoError));
    }

    #[test]
    fn codes_round_trip_and_have_text() {
        for v in 0..=0x40u16 {
            assert_eq!(AlStatusCode::from_raw(v).raw(), v);
        }
        assert_eq!(
            AlStatusCode::from_raw(0x1D).text(),
            "invalid output configuration"
        );
    }
}
