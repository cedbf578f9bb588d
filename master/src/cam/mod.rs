//! Cam tables from files and from the control socket: CSV and TOML files, and lists of
//! `[master, slave]` pairs (JSON), made into [`gantry_kernel::cam::CamTable`]s. Every
//! error names the file and the line, or the point.
//!
//! **CSV** (`.csv`): one point a line, `master,slave`; blank lines and `#` comments
//! (whole lines or the rest of a line) are skipped; the first line may be a header, which
//! it is when its first field is not a number. The interpolation and the periodic flag
//! come from the configuration section that names the file.
//!
//! **TOML** (`.toml`):
//! ```toml
//! interpolation = "cubic"   # linear | cubic | quintic (5th-order, poly5); default cubic
//! periodic = true           # default false
//! points = [[0.0, 0.0], [90.0, 10.0], [180.0, 0.0]]   # [master, slave]
//! ```
//! The file's `interpolation` and `periodic` win over the defaults; if the caller gives
//! one too and it differs, that is an error ([`CamFileError::Conflict`]) rather than a
//! silent choice.
//!
//! What each interpolation does (and at the ends) is in [`gantry_kernel::cam`].

mod csv;
mod error;
mod toml_format;

use std::path::Path;

use gantry_kernel::cam::{CamError, CamPoint, CamTable, Interpolation};

pub use error::CamFileError;

/// The interpolation when neither the file nor the caller names one.
pub const DEFAULT_INTERPOLATION: Interpolation = Interpolation::Cubic;

/// Loads the cam table in `path`, in the format its extension names (`.csv` or `.toml`,
/// any case). `interpolation` and `periodic` are the caller's (the configuration section
/// naming the file): for CSV they are the table's (default cubic, not periodic); for TOML
/// they must agree with the file's where both are given.
pub fn load_cam_file(
    path: &Path,
    interpolation: Option<Interpolation>,
    periodic: Option<bool>,
) -> Result<CamTable, CamFileError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let parse = match extension.as_deref() {
        Some("csv") => csv::parse,
        Some("toml") => toml_format::parse,
        _ => {
            return Err(CamFileError::UnknownExtension {
                path: path.to_path_buf(),
            })
        }
    };
    let text = std::fs::read_to_string(path).map_err(|e| CamFileError::Read {
        path: path.to_path_buf(),
        source: e.into(),
    })?;
    parse(path, &text, interpolation, periodic)
}

/// A table from `[master, slave]` pairs (the control socket's JSON): default cubic, not
/// periodic. Errors name the points by their index in `points`.
pub fn cam_from_points(
    points: &[[f64; 2]],
    interpolation: Option<Interpolation>,
    periodic: Option<bool>,
) -> Result<CamTable, CamFileError> {
    let points = points
        .iter()
        .map(|&[master, slave]| CamPoint { master, slave })
        .collect();
    CamTable::new(
        points,
        interpolation.unwrap_or(DEFAULT_INTERPOLATION),
        periodic.unwrap_or(false),
    )
    .map_err(|source| CamFileError::Table {
        path: None,
        lines: Vec::new(),
        source,
    })
}

/// Builds the table from points read from `path`, where `lines[i]` is the line of point
/// `i`; a refusal names the lines of the points it is about.
fn build(
    path: &Path,
    points: Vec<CamPoint>,
    lines: &[usize],
    interpolation: Interpolation,
    periodic: bool,
) -> Result<CamTable, CamFileError> {
    CamTable::new(points, interpolation, periodic).map_err(|source| {
        let implicated: Vec<usize> = match source {
            CamError::NotFinite { index, .. } => vec![index],
            CamError::NotIncreasing { index, .. } => vec![index.saturating_sub(1), index],
            CamError::Degenerate { index, .. } => vec![index, index + 1],
            _ => Vec::new(),
        };
        CamFileError::Table {
            path: Some(path.to_path_buf()),
            lines: implicated
                .iter()
                .filter_map(|&i| lines.get(i).copied())
                .collect(),
            source,
        }
    })
}

/// 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text.get(..offset).unwrap_or("").matches('\n').count() + 1
}

#[cfg(test)]
mod tests;
