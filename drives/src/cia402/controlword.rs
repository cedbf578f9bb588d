//! 0x6040 Controlword: the device-control commands of CiA 402-2 Table 28, both ways —
//! the master encodes a [`Command`], the (simulated) device decodes a raw value.

/// Bit 0: switch on.
pub const SWITCH_ON: u16 = 1 << 0;
/// Bit 1: enable voltage.
pub const ENABLE_VOLTAGE: u16 = 1 << 1;
/// Bit 2: quick stop (active low).
pub const QUICK_STOP: u16 = 1 << 2;
/// Bit 3: enable operation.
pub const ENABLE_OPERATION: u16 = 1 << 3;
/// Bit 4: mode specific (HM: homing operation start; PP: new set-point).
pub const MODE_SPECIFIC_4: u16 = 1 << 4;
/// Bit 7: fault reset (acts on the rising edge).
pub const FAULT_RESET: u16 = 1 << 7;
/// Bit 8: halt.
pub const HALT: u16 = 1 << 8;

/// A device-control command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// Shutdown (transitions 2, 6, 8).
    Shutdown,
    /// Switch on (transition 3); also "disable operation" (transition 5).
    SwitchOn,
    /// Disable voltage (transitions 7, 9, 10, 12).
    DisableVoltage,
    /// Quick stop (transitions 7, 10, 11).
    QuickStop,
    /// Enable operation (transitions 4, 16; from Ready to switch on: 3 then 4).
    EnableOperation,
    /// Fault reset (transition 15), on the rising edge of bit 7.
    FaultReset,
}

/// A raw controlword.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Controlword(pub u16);

impl Controlword {
    /// The controlword of a command (bits 0–3 and 7; other bits zero).
    pub const fn of(cmd: Command) -> Self {
        Self(match cmd {
            Command::Shutdown => ENABLE_VOLTAGE | QUICK_STOP,
            Command::SwitchOn => ENABLE_VOLTAGE | QUICK_STOP | SWITCH_ON,
            Command::DisableVoltage => 0,
            Command::QuickStop => ENABLE_VOLTAGE,
            Command::EnableOperation => ENABLE_VOLTAGE | QUICK_STOP | SWITCH_ON | ENABLE_OPERATION,
            Command::FaultReset => FAULT_RESET,
        })
    }

    /// The command a device reads from this controlword, given the previous one (fault
    /// reset acts on the 0→1 edge of bit 7). Decoding follows Table 28's priority: a
    /// fault-reset edge first, then bit 1 (disable voltage), bit 2 (quick stop), bits 0/3.
    pub const fn command(self, previous: Controlword) -> Command {
        let cw = self.0;
        if cw & FAULT_RESET != 0 && previous.0 & FAULT_RESET == 0 {
            return Command::FaultReset;
        }
        if cw & ENABLE_VOLTAGE == 0 {
            Command::DisableVoltage
        } else if cw & QUICK_STOP == 0 {
            Command::QuickStop
        } else if cw & SWITCH_ON == 0 {
            Command::Shutdown
        } else if cw & ENABLE_OPERATION == 0 {
            Command::SwitchOn
        } else {
            Command::EnableOperation
        }
    }

    /// Whether `bit` is set.
    pub const fn has(self, bit: u16) -> bool {
        self.0 & bit != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_round_trip_through_the_wire_value() {
        let none = Controlword(0);
        for cmd in [
            Command::Shutdown,
            Command::SwitchOn,
            Command::DisableVoltage,
            Command::QuickStop,
            Command::EnableOperation,
            Command::FaultReset,
        ] {
            assert_eq!(Controlword::of(cmd).command(none), cmd, "{cmd:?}");
        }
    }

    #[test]
    fn table_28_values() {
        assert_eq!(Controlword::of(Command::Shutdown).0, 0x06);
        assert_eq!(Controlword::of(Command::SwitchOn).0, 0x07);
        assert_eq!(Controlword::of(Command::EnableOperation).0, 0x0F);
        assert_eq!(Controlword::of(Command::QuickStop).0, 0x02);
        assert_eq!(Controlword::of(Command::DisableVoltage).0, 0x00);
        assert_eq!(Controlword::of(Command::FaultReset).0, 0x80);
    }

    #[test]
    fn fault_reset_needs_a_rising_edge() {
        let held = Controlword(0x80);
        assert_eq!(held.command(Controlword(0x80)), Command::DisableVoltage);
        assert_eq!(held.command(Controlword(0x00)), Command::FaultReset);
        // Mode-specific and halt bits do not change the command.
        assert_eq!(
            Controlword(0x011F).command(Controlword(0)),
            Command::EnableOperation
        );
    }
}
