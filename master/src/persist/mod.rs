//! What gantry keeps of its axes between runs (issue 13 §4, SPEC §4–§5): one parameter
//! file per axis in a state directory — the commutation offset, the homing parameters,
//! the last point-to-point dynamics, an absolute axis' position offset ([`params`]) —,
//! each written atomically and durably ([`atomic`]: temporary file, fsync, rename, fsync
//! of the directory) in a checked envelope ([`envelope`]: format line, CRC-32), so that a
//! crash or `kill -9` during a save leaves the old or the new file whole, and a damaged
//! file is found at start and named ([`error::PersistError`]), never silently used.
//!
//! What the axes accept is saved whichever way the command came ([`saver`]: the control
//! socket and programs on the controller API alike).
//!
//! The directory ([`state_dir`]): `[service] state_dir` in the configuration, else
//! systemd's `$STATE_DIRECTORY` (`StateDirectory=gantry` in `deploy/gantry.service` makes
//! it `/var/lib/gantry`); with neither nothing is saved, and gantry says so at start.

pub mod atomic;
pub mod checksum;
pub mod envelope;
pub mod error;
pub mod params;
pub mod saved;
pub mod saver;
pub mod store;

pub use error::PersistError;
pub use params::{AxisParams, PositionOffset, PtpParams, ScalingStamp};
pub use saved::{Saved, StartPosition, StepSwitchNotGiven};
pub use store::Store;

use std::path::PathBuf;

/// The environment variable systemd sets to the unit's `StateDirectory=` (absolute
/// paths, separated by colons when the unit names several).
pub const STATE_DIRECTORY_ENV: &str = "STATE_DIRECTORY";

/// Where the state directory came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateDirSource {
    /// `[service] state_dir` in the configuration.
    Config,
    /// systemd's `$STATE_DIRECTORY`.
    Systemd,
}

impl StateDirSource {
    /// For messages.
    pub const fn describe(self) -> &'static str {
        match self {
            Self::Config => "[service] state_dir",
            Self::Systemd => "$STATE_DIRECTORY (systemd's StateDirectory=)",
        }
    }
}

/// The state directory: `configured` (`[service] state_dir`, already resolved against
/// the configuration file's folder) if given, else the first path of `$STATE_DIRECTORY`
/// (`env` is its value), else none.
pub fn state_dir(
    configured: Option<&str>,
    env: Option<&std::ffi::OsStr>,
) -> Option<(PathBuf, StateDirSource)> {
    if let Some(dir) = configured {
        return Some((PathBuf::from(dir), StateDirSource::Config));
    }
    let env = env?.to_str()?;
    let first = env.split(':').next().filter(|d| !d.is_empty())?;
    Some((PathBuf::from(first), StateDirSource::Systemd))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::OsStr;

    #[test]
    fn the_configuration_wins_over_systemd_and_none_is_none() {
        assert_eq!(
            state_dir(Some("/srv/g"), Some(OsStr::new("/var/lib/gantry"))),
            Some((PathBuf::from("/srv/g"), StateDirSource::Config))
        );
        assert_eq!(
            state_dir(None, Some(OsStr::new("/var/lib/gantry:/var/lib/other"))),
            Some((PathBuf::from("/var/lib/gantry"), StateDirSource::Systemd))
        );
        assert_eq!(state_dir(None, Some(OsStr::new(""))), None);
        assert_eq!(state_dir(None, None), None);
    }
}
