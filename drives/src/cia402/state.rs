//! The CiA 402 power state machine (CiA 402-2 Figure 43): one transition table used by
//! both sides — the simulated drive steps through it ([`DeviceStateMachine`]), the master
//! reads it backwards to choose the next controlword ([`next_command`]).

use super::controlword::{Command, Controlword};
use super::statusword::Statusword;

/// Power states of a CiA 402 drive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum State {
    /// Initialising; not yet ready.
    #[default]
    NotReadyToSwitchOn,
    /// Initialised, high voltage may be off.
    SwitchOnDisabled,
    /// Waiting for switch on.
    ReadyToSwitchOn,
    /// Power stage on, not enabled.
    SwitchedOn,
    /// Enabled: the drive follows its command values.
    OperationEnabled,
    /// Quick stop is braking (or done, with the drive still enabled).
    QuickStopActive,
    /// A fault was detected; the fault reaction is running.
    FaultReactionActive,
    /// Faulted; power stage off.
    Fault,
}

impl State {
    /// Name as CiA 402 writes it.
    pub const fn name(self) -> &'static str {
        match self {
            State::NotReadyToSwitchOn => "Not ready to switch on",
            State::SwitchOnDisabled => "Switch on disabled",
            State::ReadyToSwitchOn => "Ready to switch on",
            State::SwitchedOn => "Switched on",
            State::OperationEnabled => "Operation enabled",
            State::QuickStopActive => "Quick stop active",
            State::FaultReactionActive => "Fault reaction active",
            State::Fault => "Fault",
        }
    }
}

/// (transition number, from, command, to) of CiA 402-2 Figure 43 / Table 29 for the
/// transitions a controlword causes. Unlisted pairs leave the state unchanged. Transitions
/// 0, 1, 13 and 14 are the device's own (power-up, fault) and not in this table.
pub const TRANSITIONS: [(u8, State, Command, State); 15] = [
    (
        2,
        State::SwitchOnDisabled,
        Command::Shutdown,
        State::ReadyToSwitchOn,
    ),
    (
        3,
        State::ReadyToSwitchOn,
        Command::SwitchOn,
        State::SwitchedOn,
    ),
    // Many drives take "switch on + enable operation" (0x0F) straight from Ready to
    // switch on; it passes transition 3, and 4 follows on the next cycle.
    (
        3,
        State::ReadyToSwitchOn,
        Command::EnableOperation,
        State::SwitchedOn,
    ),
    (
        4,
        State::SwitchedOn,
        Command::EnableOperation,
        State::OperationEnabled,
    ),
    (
        5,
        State::OperationEnabled,
        Command::SwitchOn,
        State::SwitchedOn,
    ),
    (
        6,
        State::SwitchedOn,
        Command::Shutdown,
        State::ReadyToSwitchOn,
    ),
    (
        7,
        State::ReadyToSwitchOn,
        Command::DisableVoltage,
        State::SwitchOnDisabled,
    ),
    (
        7,
        State::ReadyToSwitchOn,
        Command::QuickStop,
        State::SwitchOnDisabled,
    ),
    (
        8,
        State::OperationEnabled,
        Command::Shutdown,
        State::ReadyToSwitchOn,
    ),
    (
        9,
        State::OperationEnabled,
        Command::DisableVoltage,
        State::SwitchOnDisabled,
    ),
    (
        10,
        State::SwitchedOn,
        Command::DisableVoltage,
        State::SwitchOnDisabled,
    ),
    (
        10,
        State::SwitchedOn,
        Command::QuickStop,
        State::SwitchOnDisabled,
    ),
    (
        11,
        State::OperationEnabled,
        Command::QuickStop,
        State::QuickStopActive,
    ),
    (
        12,
        State::QuickStopActive,
        Command::DisableVoltage,
        State::SwitchOnDisabled,
    ),
    (
        15,
        State::Fault,
        Command::FaultReset,
        State::SwitchOnDisabled,
    ),
];

/// The state a controlword command leads to from `from` (unchanged when the table has no
/// such transition).
pub fn transition(from: State, cmd: Command) -> State {
    TRANSITIONS
        .iter()
        .find(|(_, f, c, _)| *f == from && *c == cmd)
        .map(|&(_, _, _, to)| to)
        .unwrap_or(from)
}

/// What the master wants of a drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// Operation enabled (the axis follows set values).
    Enabled,
    /// Switch on disabled (power stage off).
    Disabled,
    /// Quick stop: brake with the drive's quick-stop ramp.
    QuickStop,
}

impl Target {
    /// The states that fulfil the target, the preferred first: quick stop is reached
    /// from Operation enabled (transition 11); from anywhere else the drive is not enabled
    /// to be stopped, it is switched off.
    const fn goals(self) -> &'static [State] {
        match self {
            Target::Enabled => &[State::OperationEnabled],
            Target::Disabled => &[State::SwitchOnDisabled],
            Target::QuickStop => &[State::QuickStopActive, State::SwitchOnDisabled],
        }
    }
}

/// Every state, in declaration order (the search below indexes by it).
const ALL_STATES: [State; 8] = [
    State::NotReadyToSwitchOn,
    State::SwitchOnDisabled,
    State::ReadyToSwitchOn,
    State::SwitchedOn,
    State::OperationEnabled,
    State::QuickStopActive,
    State::FaultReactionActive,
    State::Fault,
];

/// The controlword command that moves a drive in `state` one step towards `target`, read
/// from [`TRANSITIONS`]: the first command of a shortest path to one of the target's
/// states (at equal length the preferred state, then table order). In a target state it
/// is the command that leads into that state (which holds it there); with no path — a
/// fault reaction still running, a fault that may not be reset — it is Disable voltage,
/// the drive's state of rest. `reset` allows a fault reset; that needs a rising edge of
/// bit 7, so when the last controlword already had it set the reset waits a cycle.
pub fn next_command(state: State, target: Target, reset: bool, last: Controlword) -> Command {
    let goals = target.goals();
    let may_reset = reset && !last.has(super::controlword::FAULT_RESET);
    let usable = |cmd: Command| cmd != Command::FaultReset || may_reset;
    if goals.contains(&state) {
        return TRANSITIONS
            .iter()
            .find(|&&(_, _, _, to)| to == state)
            .map_or(Command::DisableVoltage, |&(_, _, cmd, _)| cmd);
    }
    // Breadth first over the 8 states (sets as bit masks): for each state reached, the
    // first command taken from `state` on the way to it.
    let bit = |s: State| 1u8 << (s as u8);
    let mut first: [Option<Command>; ALL_STATES.len()] = [None; ALL_STATES.len()];
    let (mut seen, mut frontier) = (bit(state), bit(state));
    while frontier != 0 {
        let mut next = 0u8;
        for &(_, from, cmd, to) in &TRANSITIONS {
            if frontier & bit(from) == 0 || seen & bit(to) != 0 || !usable(cmd) {
                continue;
            }
            let via = if from == state {
                Some(cmd)
            } else {
                first.get(from as usize).copied().flatten()
            };
            if let Some(slot) = first.get_mut(to as usize) {
                *slot = via;
            }
            seen |= bit(to);
            next |= bit(to);
        }
        // The preferred goal this layer reached, if any.
        for &goal in goals {
            if next & bit(goal) != 0 {
                if let Some(cmd) = first.get(goal as usize).copied().flatten() {
                    return cmd;
                }
            }
        }
        frontier = next;
    }
    Command::DisableVoltage
}

/// The device side: a drive's state, stepped by controlwords and faults. Used by the
/// simulated drives; the master never owns one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceStateMachine {
    state: State,
    last: Controlword,
}

impl DeviceStateMachine {
    /// A drive that has finished initialising (transitions 0 and 1 done).
    pub fn ready() -> Self {
        Self {
            state: State::SwitchOnDisabled,
            last: Controlword(0),
        }
    }

    /// Current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// Takes a controlword; returns the new state.
    pub fn control(&mut self, cw: Controlword) -> State {
        let cmd = cw.command(self.last);
        self.last = cw;
        self.state = transition(self.state, cmd);
        self.state
    }

    /// A fault occurred (transition 13).
    pub fn fault(&mut self) {
        if self.state != State::Fault {
            self.state = State::FaultReactionActive;
        }
    }

    /// The fault reaction finished (transition 14).
    pub fn fault_reaction_done(&mut self) {
        if self.state == State::FaultReactionActive {
            self.state = State::Fault;
        }
    }

    /// The statusword to report.
    pub fn statusword(&self) -> Statusword {
        Statusword::of(self.state, self.state != State::SwitchOnDisabled)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STATES: [State; 8] = ALL_STATES;

    /// The rules as they were written out by hand before the master read the table: the
    /// search must choose the same command everywhere.
    fn written_out(state: State, target: Target, reset: bool, last: Controlword) -> Command {
        use State as S;
        match (state, target) {
            (S::Fault, _) if reset && !last.has(crate::cia402::controlword::FAULT_RESET) => {
                Command::FaultReset
            }
            (S::Fault | S::FaultReactionActive | S::NotReadyToSwitchOn, _) => {
                Command::DisableVoltage
            }
            (_, Target::Disabled) => Command::DisableVoltage,
            (S::OperationEnabled | S::QuickStopActive, Target::QuickStop) => Command::QuickStop,
            (_, Target::QuickStop) => Command::DisableVoltage,
            (S::SwitchOnDisabled, Target::Enabled) => Command::Shutdown,
            (S::ReadyToSwitchOn, Target::Enabled) => Command::SwitchOn,
            (S::SwitchedOn | S::OperationEnabled, Target::Enabled) => Command::EnableOperation,
            (S::QuickStopActive, Target::Enabled) => Command::DisableVoltage,
        }
    }

    #[test]
    fn the_table_read_backwards_gives_the_written_out_rules() {
        for state in STATES {
            for target in [Target::Enabled, Target::Disabled, Target::QuickStop] {
                for reset in [false, true] {
                    for last in [Controlword(0), Controlword(0x80)] {
                        assert_eq!(
                            next_command(state, target, reset, last),
                            written_out(state, target, reset, last),
                            "{state:?} → {target:?}, reset {reset}, last {last:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn every_table_row_is_taken_by_the_device() {
        for &(n, from, cmd, to) in &TRANSITIONS {
            let mut d = DeviceStateMachine {
                state: from,
                last: Controlword(0),
            };
            assert_eq!(d.control(Controlword::of(cmd)), to, "transition {n}");
        }
    }

    #[test]
    fn transition_2_3_4_shutdown_switch_on_enable() {
        let mut d = DeviceStateMachine::ready();
        d.control(Controlword(0x06));
        d.control(Controlword(0x07));
        assert_eq!(d.control(Controlword(0x0F)), State::OperationEnabled);
        assert_eq!(d.statusword().state(), Some(State::OperationEnabled));
    }

    #[test]
    fn master_reaches_every_target_from_every_state() {
        for start in STATES {
            for target in [Target::Enabled, Target::Disabled, Target::QuickStop] {
                let mut d = DeviceStateMachine {
                    state: start,
                    last: Controlword(0),
                };
                let mut last = Controlword(0);
                for _ in 0..10 {
                    // The device finishes its own work: initialisation, fault reaction.
                    if d.state == State::NotReadyToSwitchOn {
                        d.state = State::SwitchOnDisabled;
                    }
                    d.fault_reaction_done();
                    let seen = d.statusword().state().unwrap();
                    let cmd = next_command(seen, target, true, last);
                    last = Controlword::of(cmd);
                    d.control(last);
                }
                let want = match target {
                    Target::Enabled => State::OperationEnabled,
                    Target::Disabled => State::SwitchOnDisabled,
                    Target::QuickStop => match start {
                        State::OperationEnabled | State::QuickStopActive => State::QuickStopActive,
                        _ => State::SwitchOnDisabled,
                    },
                };
                assert_eq!(d.state, want, "from {start:?} to {target:?}");
            }
        }
    }

    #[test]
    fn a_fault_needs_a_reset_edge_to_clear() {
        let mut d = DeviceStateMachine::ready();
        for cw in [0x06, 0x07, 0x0F] {
            d.control(Controlword(cw));
        }
        d.fault();
        assert_eq!(d.state(), State::FaultReactionActive);
        d.fault_reaction_done();
        assert_eq!(d.statusword().state(), Some(State::Fault));
        // Holding bit 7 high does not reset; the edge does.
        assert_eq!(d.control(Controlword(0x80)), State::SwitchOnDisabled);
        let mut d2 = DeviceStateMachine {
            state: State::Fault,
            last: Controlword(0x80),
        };
        assert_eq!(d2.control(Controlword(0x80)), State::Fault);
        assert_eq!(
            next_command(State::Fault, Target::Enabled, true, Controlword(0x80)),
            Command::DisableVoltage
        );
        assert_eq!(
            next_command(State::Fault, Target::Enabled, false, Controlword(0)),
            Command::DisableVoltage
        );
    }
}
