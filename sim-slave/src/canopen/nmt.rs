//! The NMT slave state machine (CiA 301 §7.3.2.2, Figure 48): Initialisation, then the
//! boot-up message and Pre-operational; the master's commands move the node between
//! Pre-operational, Operational and Stopped, or reset it. What each state lets through is
//! CiA 301 Table 41: SDO, SYNC and EMCY in Pre-operational and Operational, PDOs only in
//! Operational, in Stopped nothing but NMT and error control (heartbeat).

use gantry_drives::canopen::heartbeat::NmtState;
use gantry_drives::canopen::nmt::NmtCommand;

/// The NMT state of a node (CiA 301 §7.3.2.2.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtSlaveState {
    /// Powered or reset, not yet booted: sends nothing until it has initialised.
    Initialisation,
    /// Booted: SDO, SYNC, EMCY, heartbeat; no PDO.
    PreOperational,
    /// Everything, PDOs included.
    Operational,
    /// Only NMT commands and heartbeat.
    Stopped,
}

/// What a command asks of the node beyond the state change.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtAction {
    /// Enter this state (may be the state it is in: CiA 301 lets a command repeat).
    Enter(NmtSlaveState),
    /// Reset application (0x2000–0x9FFF to power-on values) and communication, boot up.
    ResetNode,
    /// Reset the communication objects (0x1000–0x1FFF) to power-on values, boot up.
    ResetCommunication,
}

impl NmtSlaveState {
    /// The state byte a heartbeat carries (CiA 301 §7.2.8.3.2.2, Table 45).
    pub const fn heartbeat(self) -> NmtState {
        match self {
            Self::Initialisation => NmtState::BootUp,
            Self::PreOperational => NmtState::PreOperational,
            Self::Operational => NmtState::Operational,
            Self::Stopped => NmtState::Stopped,
        }
    }

    /// SDO served (Table 41: Pre-operational and Operational).
    pub const fn sdo_allowed(self) -> bool {
        matches!(self, Self::PreOperational | Self::Operational)
    }

    /// SYNC consumed and EMCY produced (Table 41: Pre-operational and Operational).
    pub const fn sync_emcy_allowed(self) -> bool {
        matches!(self, Self::PreOperational | Self::Operational)
    }

    /// PDOs received and sent (Table 41: Operational only).
    pub const fn pdo_allowed(self) -> bool {
        matches!(self, Self::Operational)
    }

    /// Heartbeat produced (Table 41: every state but Initialisation, which sends only
    /// the boot-up message when it ends).
    pub const fn heartbeat_allowed(self) -> bool {
        !matches!(self, Self::Initialisation)
    }

    /// What `command` does in this state (CiA 301 Figure 48: every command is accepted in
    /// Pre-operational, Operational and Stopped; in Initialisation the node does not
    /// listen yet, so nothing).
    pub const fn on_command(self, command: NmtCommand) -> Option<NmtAction> {
        if matches!(self, Self::Initialisation) {
            return None;
        }
        Some(match command {
            NmtCommand::Start => NmtAction::Enter(Self::Operational),
            NmtCommand::Stop => NmtAction::Enter(Self::Stopped),
            NmtCommand::EnterPreOperational => NmtAction::Enter(Self::PreOperational),
            NmtCommand::ResetNode => NmtAction::ResetNode,
            NmtCommand::ResetCommunication => NmtAction::ResetCommunication,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [NmtSlaveState; 4] = [
        NmtSlaveState::Initialisation,
        NmtSlaveState::PreOperational,
        NmtSlaveState::Operational,
        NmtSlaveState::Stopped,
    ];

    #[test]
    fn table_41_services_per_state() {
        let got: Vec<(bool, bool, bool, bool)> = ALL
            .iter()
            .map(|s| {
                (
                    s.sdo_allowed(),
                    s.sync_emcy_allowed(),
                    s.pdo_allowed(),
                    s.heartbeat_allowed(),
                )
            })
            .collect();
        assert_eq!(
            got,
            vec![
                (false, false, false, false),
                (true, true, false, true),
                (true, true, true, true),
                (false, false, false, true),
            ]
        );
    }

    #[test]
    fn figure_48_transitions() {
        use NmtCommand::*;
        use NmtSlaveState::*;
        for s in [PreOperational, Operational, Stopped] {
            assert_eq!(s.on_command(Start), Some(NmtAction::Enter(Operational)));
            assert_eq!(s.on_command(Stop), Some(NmtAction::Enter(Stopped)));
            assert_eq!(
                s.on_command(EnterPreOperational),
                Some(NmtAction::Enter(PreOperational))
            );
            assert_eq!(s.on_command(ResetNode), Some(NmtAction::ResetNode));
            assert_eq!(
                s.on_command(ResetCommunication),
                Some(NmtAction::ResetCommunication)
            );
        }
        assert_eq!(Initialisation.on_command(Start), None);
        assert_eq!(Stopped.heartbeat(), NmtState::Stopped);
        assert_eq!(Initialisation.heartbeat(), NmtState::BootUp);
    }
}
