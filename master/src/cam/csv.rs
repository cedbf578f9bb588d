//! The CSV cam format: `master,slave` a line, an optional header, `#` comments.

use std::path::Path;

use gantry_kernel::cam::{CamPoint, CamTable, Interpolation};

use super::{build, CamFileError, DEFAULT_INTERPOLATION};

/// Parses `text` (the contents of `path`, named in errors) into a table.
pub(super) fn parse(
    path: &Path,
    text: &str,
    interpolation: Option<Interpolation>,
    periodic: Option<bool>,
) -> Result<CamTable, CamFileError> {
    let mut points = Vec::new();
    let mut lines = Vec::new();
    let mut first = true;
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let fields: Vec<&str> = content.split(',').map(str::trim).collect();
        let is_first = std::mem::replace(&mut first, false);
        // A header is a first line that does not start with a number.
        if is_first && fields.first().is_some_and(|f| f.parse::<f64>().is_err()) {
            continue;
        }
        let [master, slave] = fields.as_slice() else {
            return Err(CamFileError::CsvColumns {
                path: path.to_path_buf(),
                line,
                found: fields.len(),
            });
        };
        let number = |text: &str, column| {
            text.parse::<f64>()
                .map_err(|_| CamFileError::CsvNotANumber {
                    path: path.to_path_buf(),
                    line,
                    column,
                    text: text.to_string(),
                })
        };
        points.push(CamPoint {
            master: number(master, "master")?,
            slave: number(slave, "slave")?,
        });
        lines.push(line);
    }
    build(
        path,
        points,
        &lines,
        interpolation.unwrap_or(DEFAULT_INTERPOLATION),
        periodic.unwrap_or(false),
    )
}
