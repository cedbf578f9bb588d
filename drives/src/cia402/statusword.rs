//! 0x6041 Statusword: decoded by the mask/value pairs of CiA 402-2 Table 30, so every raw
//! value maps to exactly one state (bit 5 "quick stop" is *set* in normal operation).

use super::state::State;

/// A raw statusword.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Statusword(pub u16);

/// Bit 0: ready to switch on.
pub const READY_TO_SWITCH_ON: u16 = 1 << 0;
/// Bit 1: switched on.
pub const SWITCHED_ON: u16 = 1 << 1;
/// Bit 2: operation enabled.
pub const OPERATION_ENABLED: u16 = 1 << 2;
/// Bit 3: fault.
pub const FAULT: u16 = 1 << 3;
/// Bit 4: voltage enabled.
pub const VOLTAGE_ENABLED: u16 = 1 << 4;
/// Bit 5: quick stop (active low: 0 = quick stop active).
pub const QUICK_STOP: u16 = 1 << 5;
/// Bit 6: switch on disabled.
pub const SWITCH_ON_DISABLED: u16 = 1 << 6;
/// Bit 7: warning.
pub const WARNING: u16 = 1 << 7;
/// Bit 9: remote (the controlword is processed).
pub const REMOTE: u16 = 1 << 9;
/// Bit 10: target reached.
pub const TARGET_REACHED: u16 = 1 << 10;
/// Bit 11: internal limit active.
pub const INTERNAL_LIMIT_ACTIVE: u16 = 1 << 11;
/// Bit 12: mode specific (CSP/CSV/CST: drive follows the command value; HM: homing attained).
pub const MODE_SPECIFIC_12: u16 = 1 << 12;
/// Bit 13: mode specific (CSP: following error; HM: homing error).
pub const MODE_SPECIFIC_13: u16 = 1 << 13;

/// (mask, value, state) of CiA 402-2 Table 30.
pub const STATE_TABLE: [(u16, u16, State); 8] = [
    (0x4F, 0x00, State::NotReadyToSwitchOn),
    (0x4F, 0x40, State::SwitchOnDisabled),
    (0x6F, 0x21, State::ReadyToSwitchOn),
    (0x6F, 0x23, State::SwitchedOn),
    (0x6F, 0x27, State::OperationEnabled),
    (0x6F, 0x07, State::QuickStopActive),
    (0x4F, 0x0F, State::FaultReactionActive),
    (0x4F, 0x08, State::Fault),
];

impl Statusword {
    /// The state the statusword shows; `None` for bit patterns the standard does not
    /// define (a drive that sends one is misbehaving; the master reports it).
    pub fn state(self) -> Option<State> {
        STATE_TABLE
            .iter()
            .find(|(mask, value, _)| self.0 & mask == *value)
            .map(|&(_, _, s)| s)
    }

    /// The statusword a device in `state` reports (state bits only; `voltage` sets bit 4).
    pub fn of(state: State, voltage: bool) -> Self {
        let value = STATE_TABLE
            .iter()
            .find(|(_, _, s)| *s == state)
            .map(|&(_, v, _)| v)
            .unwrap_or(0);
        Self(value | if voltage { VOLTAGE_ENABLED } else { 0 })
    }

    /// Whether `bit` is set.
    pub const fn has(self, bit: u16) -> bool {
        self.0 & bit != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Typical statuswords: the state bits of Table 30 plus the bits a real drive sets
    /// beside them (4 voltage enabled, 9 remote, 10 target reached, 12 set-point
    /// acknowledge), which decoding must ignore.
    static FIXTURES: [(u16, State); 8] = [
        (0x0250, State::SwitchOnDisabled),
        (0x0231, State::ReadyToSwitchOn),
        (0x0233, State::SwitchedOn),
        (0x0637, State::OperationEnabled),
        (0x1637, State::OperationEnabled),
        (0x0217, State::QuickStopActive),
        (0x0218, State::Fault),
        (0x021F, State::FaultReactionActive),
    ];

    #[test]
    fn fixtures_decode_to_their_states() {
        for (raw, state) in FIXTURES {
            assert_eq!(Statusword(raw).state(), Some(state), "{raw:#06x}");
        }
    }

    #[test]
    fn bit_5_set_is_normal_operation_not_quick_stop() {
        // The ethercrab ds402 branch reads bit 5 as "quick stop active": wrong.
        assert_eq!(Statusword(0x0027).state(), Some(State::OperationEnabled));
        assert_eq!(Statusword(0x0007).state(), Some(State::QuickStopActive));
    }

    #[test]
    fn every_state_round_trips_and_decoding_is_unambiguous() {
        for &(_, _, s) in &STATE_TABLE {
            assert_eq!(Statusword::of(s, true).state(), Some(s));
            assert_eq!(Statusword::of(s, false).state(), Some(s));
        }
        // No raw value matches two rows.
        for raw in 0..=u16::MAX {
            let n = STATE_TABLE.iter().filter(|(m, v, _)| raw & m == *v).count();
            assert!(n <= 1, "{raw:#06x} matches {n} rows");
        }
    }
}
