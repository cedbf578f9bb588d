//! The TOML cam format: `interpolation`, `periodic` and `points = [[master, slave], …]`.

use std::path::Path;

use gantry_kernel::cam::{CamPoint, CamTable, Interpolation};
use serde::Deserialize;
use toml::Spanned;

use super::{build, line_of, CamFileError, DEFAULT_INTERPOLATION};

/// The file as written; spans give the line of each value for errors.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CamToml {
    interpolation: Option<Spanned<String>>,
    periodic: Option<Spanned<bool>>,
    /// `Vec`, not `[f64; 2]`: the toml crate (0.9) fills a fixed array from a longer
    /// TOML array without complaint, and a third number is a mistake to report.
    points: Vec<Spanned<Vec<f64>>>,
}

/// Parses `text` (the contents of `path`, named in errors) into a table.
pub(super) fn parse(
    path: &Path,
    text: &str,
    interpolation: Option<Interpolation>,
    periodic: Option<bool>,
) -> Result<CamTable, CamFileError> {
    let file: CamToml = toml::from_str(text).map_err(|e| CamFileError::Toml {
        path: path.to_path_buf(),
        line: line_of(text, e.span().map_or(0, |s| s.start)),
        reason: e.message().trim_end().to_string(),
    })?;
    let interpolation = match (file.interpolation, interpolation) {
        (None, caller) => caller.unwrap_or(DEFAULT_INTERPOLATION),
        (Some(name), caller) => {
            let line = line_of(text, name.span().start);
            let Some(in_file) = Interpolation::from_name(name.get_ref()) else {
                return Err(CamFileError::UnknownInterpolation {
                    path: path.to_path_buf(),
                    line,
                    name: name.into_inner(),
                });
            };
            match caller {
                Some(c) if c != in_file => {
                    return Err(CamFileError::Conflict {
                        path: path.to_path_buf(),
                        line,
                        key: "interpolation",
                        in_file: in_file.name().into(),
                        from_caller: c.name().into(),
                    })
                }
                _ => in_file,
            }
        }
    };
    let periodic = match (file.periodic, periodic) {
        (None, caller) => caller.unwrap_or(false),
        (Some(flag), Some(c)) if c != *flag.get_ref() => {
            return Err(CamFileError::Conflict {
                path: path.to_path_buf(),
                line: line_of(text, flag.span().start),
                key: "periodic",
                in_file: flag.get_ref().to_string(),
                from_caller: c.to_string(),
            })
        }
        (Some(flag), _) => flag.into_inner(),
    };
    let lines: Vec<usize> = file
        .points
        .iter()
        .map(|p| line_of(text, p.span().start))
        .collect();
    let mut points = Vec::with_capacity(file.points.len());
    for ((index, p), &line) in file.points.iter().enumerate().zip(&lines) {
        let [master, slave] = p.get_ref().as_slice() else {
            return Err(CamFileError::TomlPointLength {
                path: path.to_path_buf(),
                line,
                index,
                found: p.get_ref().len(),
            });
        };
        points.push(CamPoint {
            master: *master,
            slave: *slave,
        });
    }
    build(path, points, &lines, interpolation, periodic)
}
