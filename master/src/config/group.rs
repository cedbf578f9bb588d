//! `[[group]]`: axis groups (seed 004, PLCopen Part 4): up to four axes moved together
//! along one path, named in the order of their logical axes A0..A3.
//!
//! ```toml
//! [[group]]
//! name = "xy"            # unique, non-empty
//! axes = ["x", "y"]      # 1 to 4 axes that take motion (real, simulated, virtual)
//! corner_deviation = 0.5 # optional (units): how far a rounded corner may pass from
//!                        # the corner when a move asks for corner-superimposed and
//!                        # names no corner_deviation of its own
//! ```

use gantry_kernel::group::GroupConfig;
use gantry_kernel::AxisConfig;
use serde::Deserialize;

/// How many groups a configuration may have.
pub const MAX_GROUPS: usize = 16;

/// `[[group]]` as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GroupSection {
    /// The group's name.
    pub name: String,
    /// Its axes by name, A0 first.
    pub axes: Vec<String>,
    /// The corner deviation of a move that gives none (units; left out: the axes' limits
    /// alone decide).
    #[serde(default)]
    pub corner_deviation: Option<f64>,
}

/// What a group's moves take when a request leaves it out: the `[[group]]` keys that are
/// the service's, not the kernel's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupMoveDefaults {
    /// The corner deviation of a CornerSuperimposed move (units; infinite: the axes'
    /// limits alone decide).
    pub corner_deviation: f64,
}

impl Default for GroupMoveDefaults {
    fn default() -> Self {
        Self {
            corner_deviation: f64::INFINITY,
        }
    }
}

impl GroupSection {
    /// The kernel's group; `others` are the groups before it. Errors name the key (below
    /// `group[i].`) and why.
    pub fn resolve(
        &self,
        others: &[GroupConfig],
        axes: &[AxisConfig],
    ) -> Result<GroupConfig, (String, String)> {
        if others.len() >= MAX_GROUPS {
            return Err(("name".into(), format!("{MAX_GROUPS} groups at most")));
        }
        if self.name.trim().is_empty() {
            return Err(("name".into(), "is empty: name the group".into()));
        }
        if let Some(i) = others.iter().position(|g| g.name == self.name) {
            return Err(("name".into(), format!("{:?} is also group[{i}]", self.name)));
        }
        let mut indices = Vec::with_capacity(self.axes.len());
        for name in &self.axes {
            let i = axes.iter().position(|a| &a.name == name).ok_or_else(|| {
                (
                    "axes".to_string(),
                    format!("{name:?} is no [[axis]] of this file"),
                )
            })?;
            indices.push(i);
        }
        let cfg = GroupConfig::new(&self.name, &indices);
        let kinds: Vec<_> = axes.iter().map(|a| a.kind).collect();
        cfg.validate(&kinds)
            .map_err(|e| ("axes".to_string(), e.to_string()))?;
        Ok(cfg)
    }

    /// The defaults its moves take; errors name the key and the group.
    pub fn move_defaults(&self) -> Result<GroupMoveDefaults, (String, String)> {
        match self.corner_deviation {
            None => Ok(GroupMoveDefaults::default()),
            Some(d) if d.is_finite() && d > 0.0 => Ok(GroupMoveDefaults {
                corner_deviation: d,
            }),
            Some(d) => Err((
                "corner_deviation".into(),
                format!(
                    "group {:?}: {d} is not a corner deviation (a finite number of units > 0)",
                    self.name
                ),
            )),
        }
    }
}
