//! Why a parameter file could not be read or written; every error names the file.

use std::path::PathBuf;

use super::atomic::Step;
use super::envelope::Corruption;

/// A parameter file that could not be used or saved.
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    /// The state directory cannot be created or read.
    #[error("state directory {path}: {action}")]
    Directory {
        /// The directory.
        path: PathBuf,
        /// What failed.
        action: &'static str,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file exists but cannot be read.
    #[error("{path}: cannot read it")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is damaged, cut short, foreign or of another format: it is not used.
    #[error(
        "{path}: {problem}. gantry does not use a damaged parameter file. Move it away to \
         start without it (what it held goes back to the configured defaults; a commutation \
         offset must be measured again), or put back a good copy"
    )]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong with its bytes.
        problem: Corruption,
    },
    /// The envelope is whole but the content is not what this gantry writes.
    #[error(
        "{path}: its content is not valid: {reason}. gantry does not use it. Move it away to \
         start without it, or put back a good copy"
    )]
    Content {
        /// The file.
        path: PathBuf,
        /// What the TOML reader says.
        reason: String,
    },
    /// The file is another axis' (copied or renamed).
    #[error(
        "{path}: it holds the parameters of axis {found:?}, not of axis {expected:?}. gantry \
         does not use it. Move it away, or back to the name of its axis"
    )]
    WrongAxis {
        /// The file.
        path: PathBuf,
        /// The axis named inside.
        found: String,
        /// The axis the file name is for.
        expected: String,
    },
    /// Saving failed; the file keeps its previous content.
    #[error("{path}: cannot save the parameters ({}); the file keeps its previous content", step.describe())]
    Write {
        /// The file.
        path: PathBuf,
        /// The step that failed.
        step: Step,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The parameters cannot be written as TOML (a value TOML cannot hold).
    #[error("{path}: cannot write the parameters as TOML: {reason}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// What the TOML writer says.
        reason: String,
    },
}

impl PersistError {
    /// Whether the error is a damaged or unusable file (as opposed to the system refusing
    /// a read or a write).
    pub fn is_corrupt(&self) -> bool {
        matches!(
            self,
            Self::Corrupt { .. } | Self::Content { .. } | Self::WrongAxis { .. }
        )
    }
}
