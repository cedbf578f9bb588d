//! Directions the mechanics may move in.

use core::fmt;

/// Directions the mechanics may move in (seed 000 §3.3, §3.4, §3.7, §3.8): a conveyor or
/// a ratchet may only turn one way. Allowed on normal axes too.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Both directions.
    #[default]
    Both,
    /// Positive direction only.
    PositiveOnly,
    /// Negative direction only.
    NegativeOnly,
}

impl Direction {
    /// The name used in messages and configuration files.
    pub const fn name(self) -> &'static str {
        match self {
            Direction::Both => "both",
            Direction::PositiveOnly => "positive only",
            Direction::NegativeOnly => "negative only",
        }
    }

    /// Whether a move by `delta` (units, signed) is allowed; a zero move always is. NaN
    /// is refused on one-way axes.
    pub fn allows(self, delta: f64) -> bool {
        match self {
            Direction::Both => true,
            Direction::PositiveOnly => delta >= 0.0,
            Direction::NegativeOnly => delta <= 0.0,
        }
    }
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
