//! An axis group's configuration: its name and its axes, the logical axes A0..A3 in order
//! (Omron `_MC_GRP[].Kinematics`: "axis selection" assigns kernel axes to A0, A1, ... from
//! A0 on, without gaps).

use crate::axis::AxisKind;

/// At most four axes per group (Omron NJ: logical axes A0..A3; the move operands are
/// `ARRAY[0..3] OF LREAL`).
pub const MAX_GROUP_AXES: usize = 4;

/// Configuration of one axis group.
///
/// Modulo (rotary-mode) axes are allowed here: a linear move treats them as any axis. A
/// circular move refuses them at its start (Omron error 544A, "circular interpolation
/// started with an axis in rotary mode"), because an arc in a wrapped coordinate has no
/// meaning; that check belongs to MoveCircular2D, not to the group.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GroupConfig {
    /// Name (for messages and configuration).
    pub name: String,
    /// Kernel axis indices of the logical axes A0, A1, ... in order: 1 to
    /// [`MAX_GROUP_AXES`], distinct.
    pub axes: Vec<usize>,
}

impl GroupConfig {
    /// A group named `name` of the kernel axes `axes` (A0 first).
    pub fn new(name: &str, axes: &[usize]) -> Self {
        Self {
            name: name.to_owned(),
            axes: axes.to_vec(),
        }
    }

    /// The logical index (0 for A0) of kernel axis `axis` in this group.
    pub fn logical(&self, axis: usize) -> Option<usize> {
        self.axes.iter().position(|&a| a == axis)
    }

    /// Checks the group against the kernel's axes (`kinds[i]` is the kind of kernel axis
    /// `i`): 1 to 4 axes, each exists, none twice, each of a kind that takes motion.
    ///
    /// Only real, simulated and virtual axes take motion (Omron: "servo axis" and "virtual
    /// servo axis"); an external (encoder) or shadow axis has no set values a path could
    /// drive, so Omron refuses it with error 543D, "axis type not supported".
    pub fn validate(&self, kinds: &[AxisKind]) -> Result<(), GroupConfigError> {
        let group = || self.name.clone();
        if self.axes.is_empty() {
            return Err(GroupConfigError::NoAxes { group: group() });
        }
        if self.axes.len() > MAX_GROUP_AXES {
            return Err(GroupConfigError::TooManyAxes {
                group: group(),
                count: self.axes.len(),
            });
        }
        for (logical, &axis) in self.axes.iter().enumerate() {
            let Some(&kind) = kinds.get(axis) else {
                return Err(GroupConfigError::NoSuchAxis {
                    group: group(),
                    logical,
                    axis,
                    configured: kinds.len(),
                });
            };
            if let Some(first) = self.axes.iter().take(logical).position(|&a| a == axis) {
                return Err(GroupConfigError::DuplicateAxis {
                    group: group(),
                    axis,
                    first,
                    second: logical,
                });
            }
            if !kind.is_commandable() {
                return Err(GroupConfigError::AxisKindNotSupported {
                    group: group(),
                    logical,
                    axis,
                    kind: kind.name(),
                });
            }
        }
        Ok(())
    }
}

/// What is wrong with a group's configuration.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GroupConfigError {
    /// A group needs at least one axis.
    #[error("group {group}: no axes; a group has 1 to 4 axes (A0..A3)")]
    NoAxes {
        /// The group's name.
        group: String,
    },
    /// More axes than logical axes A0..A3.
    #[error("group {group}: {count} axes; a group has 1 to 4 axes (A0..A3)")]
    TooManyAxes {
        /// The group's name.
        group: String,
        /// How many were given.
        count: usize,
    },
    /// A logical axis names a kernel axis that is not configured.
    #[error("group {group}: A{logical} is axis {axis}, but only {configured} axes are configured")]
    NoSuchAxis {
        /// The group's name.
        group: String,
        /// The logical axis (0 for A0).
        logical: usize,
        /// The kernel axis index given.
        axis: usize,
        /// How many kernel axes exist.
        configured: usize,
    },
    /// One kernel axis assigned to two logical axes.
    #[error("group {group}: axis {axis} is both A{first} and A{second}")]
    DuplicateAxis {
        /// The group's name.
        group: String,
        /// The kernel axis.
        axis: usize,
        /// Its first logical axis.
        first: usize,
        /// Its second logical axis.
        second: usize,
    },
    /// An axis of a kind that takes no motion (Omron error 543D).
    #[error(
        "group {group}: A{logical} is axis {axis} of type {kind}; a group takes only real, \
         simulated and virtual axes (Omron 543D: axis type not supported)"
    )]
    AxisKindNotSupported {
        /// The group's name.
        group: String,
        /// The logical axis (0 for A0).
        logical: usize,
        /// The kernel axis.
        axis: usize,
        /// Its kind's name.
        kind: &'static str,
    },
}
