//! What is wrong with a cam file or a list of cam points: the file, the line (or the
//! point) and what.

use std::path::PathBuf;
use std::sync::Arc;

use gantry_kernel::cam::CamError;
use thiserror::Error;

/// A cam table that cannot be loaded. Messages say where (`file:line`); the cause, when
/// there is one, is the [`std::error::Error::source`] (shown by
/// [`crate::error_chain::Chain`]).
#[derive(Clone, Debug, Error)]
pub enum CamFileError {
    /// The file cannot be read.
    #[error("cannot read cam file {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why (shared: the error stays `Clone`).
        #[source]
        source: Arc<std::io::Error>,
    },
    /// Neither `.csv` nor `.toml`: the format is chosen by the extension.
    #[error("cam file {}: unknown format (the extension must be .csv or .toml)", path.display())]
    UnknownExtension {
        /// The file.
        path: PathBuf,
    },
    /// A CSV line without exactly two comma-separated columns.
    #[error("{}:{line}: expected 2 columns (master,slave), found {found}", path.display())]
    CsvColumns {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Columns on that line.
        found: usize,
    },
    /// A CSV field that is not a number (the first line may be a header only if its first
    /// field is not a number).
    #[error("{}:{line}: {column} {text:?} is not a number", path.display())]
    CsvNotANumber {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// "master" or "slave".
        column: &'static str,
        /// The field as written.
        text: String,
    },
    /// Malformed TOML, an unknown key, a missing `points` or a value of the wrong type.
    #[error("{}:{line}: {reason}", path.display())]
    Toml {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// The TOML layer's message.
        reason: String,
    },
    /// A TOML point that is not a pair `[master, slave]`.
    #[error("{}:{line}: points[{index}] has {found} numbers, expected [master, slave]", path.display())]
    TomlPointLength {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Index of the point in `points` (0-based).
        index: usize,
        /// Numbers in it.
        found: usize,
    },
    /// An `interpolation` that is not linear, cubic or quintic (5th-order, poly5).
    #[error(
        "{}:{line}: interpolation {name:?} is not one of linear, cubic, quintic (5th-order, poly5)",
        path.display()
    )]
    UnknownInterpolation {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// The name as written.
        name: String,
    },
    /// A TOML cam file sets `interpolation` or `periodic` and so does the configuration
    /// that names it, differently: which one was meant cannot be guessed.
    #[error(
        "{}:{line}: {key} = {in_file} in the cam file, but {from_caller} where the file is named",
        path.display()
    )]
    Conflict {
        /// The file.
        path: PathBuf,
        /// 1-based line of the key in the file.
        line: usize,
        /// `interpolation` or `periodic`.
        key: &'static str,
        /// The file's value.
        in_file: String,
        /// The caller's value.
        from_caller: String,
    },
    /// The points were read but are not a valid cam table (too few, not finite, master
    /// not increasing, …): the cause names the points by index (0-based, in the order
    /// given), `lines` the lines where they are written.
    #[error("{}: not a usable cam table", origin(path, lines))]
    Table {
        /// The file (`None`: points given directly, e.g. from the control socket's JSON).
        path: Option<PathBuf>,
        /// 1-based lines of the points the cause names (empty when it names none).
        lines: Vec<usize>,
        /// What is wrong with the points.
        #[source]
        source: CamError,
    },
}

/// `file:line`, `file: lines a and b`, `file` or `cam points`.
fn origin(path: &Option<PathBuf>, lines: &[usize]) -> String {
    let Some(path) = path else {
        return "cam points".into();
    };
    match lines {
        [] => path.display().to_string(),
        [l] => format!("{}:{l}", path.display()),
        [a, b] => format!("{}: lines {a} and {b}", path.display()),
        more => format!("{}: lines {more:?}", path.display()),
    }
}
