//! `[service]`: how `gantry run` keeps its state.

use serde::Deserialize;

/// `[service]`.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ServiceSection {
    /// The state directory, where each axis' parameter file is kept (homing and PTP
    /// parameters, commutation offset, an absolute axis' position offset); relative to the
    /// configuration file. Default: systemd's `$STATE_DIRECTORY` (`StateDirectory=` of the
    /// unit); with neither, nothing is saved.
    #[serde(default)]
    pub state_dir: Option<String>,
}

impl ServiceSection {
    /// Checks the section: `(key, reason)` of the first mistake.
    pub fn check(&self) -> Result<(), (String, String)> {
        match &self.state_dir {
            Some(d) if d.trim().is_empty() => Err((
                "state_dir".into(),
                "is empty: name a directory, or leave the key out".into(),
            )),
            _ => Ok(()),
        }
    }
}
