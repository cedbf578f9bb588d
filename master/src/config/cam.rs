//! `[[cam]]`: cam tables loaded into the kernel's cam slots at start, one per section, in
//! file order (the first is slot 0). Axes cam on a table by its name (`gantry cam`).
//!
//! ```toml
//! [[cam]]
//! name = "knife"                      # unique, non-empty
//! file = "cams/flying_knife.csv"      # .csv or .toml, relative to this file
//! interpolation = "quintic"           # linear | cubic | quintic (default: the file's, else cubic)
//! periodic = false                    # default: the file's, else false
//! ```
//!
//! A TOML cam file may set `interpolation` and `periodic` itself; a section that sets them
//! too must agree ([`crate::cam::load_cam_file`] refuses a conflict rather than choose).

use std::path::Path;

use gantry_kernel::cam::{CamTable, Interpolation};
use gantry_kernel::kernel::CAM_SLOTS;
use serde::Deserialize;

/// `[[cam]]` as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CamSection {
    /// The table's name.
    pub name: String,
    /// Its file, relative to the configuration file.
    pub file: String,
    /// `linear`, `cubic` or `quintic`.
    #[serde(default)]
    pub interpolation: Option<String>,
    /// Whether the table repeats (the slave rises by the table's rise each period).
    #[serde(default)]
    pub periodic: Option<bool>,
}

/// A configured cam table: its name, the file it came from and the table, for slot
/// `slot` (its position among the `[[cam]]` sections).
#[derive(Clone, Debug)]
pub struct CamConfig {
    /// The table's name.
    pub name: String,
    /// Its file, as resolved (relative to the configuration file's directory).
    pub file: String,
    /// The kernel's cam slot.
    pub slot: usize,
    /// The table.
    pub table: CamTable,
}

impl CamSection {
    /// Checks the section and loads its file (`file` resolved against `config_path`);
    /// `others` are the sections before it. Errors name the key (below `cam[i].`) and why.
    pub fn load(
        &self,
        slot: usize,
        others: &[CamConfig],
        config_path: &str,
    ) -> Result<CamConfig, (String, String)> {
        if slot >= CAM_SLOTS {
            return Err((
                "name".into(),
                format!("{CAM_SLOTS} cam tables at most (the kernel's cam slots)"),
            ));
        }
        if self.name.trim().is_empty() {
            return Err(("name".into(), "is empty: name the table".into()));
        }
        if let Some(other) = others.iter().find(|c| c.name == self.name) {
            return Err((
                "name".into(),
                format!("{:?} is also cam[{}]", self.name, other.slot),
            ));
        }
        if self.file.trim().is_empty() {
            return Err((
                "file".into(),
                "is empty: name a .csv or .toml cam file".into(),
            ));
        }
        let interpolation = match &self.interpolation {
            None => None,
            Some(s) => Some(Interpolation::from_name(s).ok_or_else(|| {
                (
                    "interpolation".to_string(),
                    format!("{s:?} is none of linear, cubic, quintic"),
                )
            })?),
        };
        let file = super::relative_to(config_path, &self.file);
        let table = crate::cam::load_cam_file(Path::new(&file), interpolation, self.periodic)
            .map_err(|e| {
                (
                    "file".to_string(),
                    crate::error_chain::Chain(&e).to_string(),
                )
            })?;
        Ok(CamConfig {
            name: self.name.clone(),
            file,
            slot,
            table,
        })
    }
}
