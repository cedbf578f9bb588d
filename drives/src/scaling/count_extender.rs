//! A drive's wrapping position counter, extended to 64 bits.

use super::ScalingError;

/// Extends a wrapping drive position counter (32 bits by default; encoder modules often
/// count 16 or 24) to 64 bits: the drive counts from −2³¹ to 2³¹−1 and wraps, the master
/// keeps the full count. Consecutive values must differ by less than half the counter
/// range (at 2³¹ counts that is ~2·10⁹ counts per cycle, never reached).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CountExtender {
    last: Option<i32>,
    total: i64,
    /// A value set by [`CountExtender::rebase`] before the first raw value.
    pending: Option<i64>,
    /// `32 − width`: shifting the raw difference up and back sign-extends it.
    shift: u32,
}

impl Default for CountExtender {
    fn default() -> Self {
        Self::new()
    }
}

impl CountExtender {
    /// An extender for a full 32-bit counter.
    pub const fn new() -> Self {
        Self {
            last: None,
            total: 0,
            pending: None,
            shift: 0,
        }
    }

    /// An extender for a counter of `bits` bits (2..=32) that wraps from `2^bits − 1` to 0.
    pub fn with_width(bits: u32) -> Result<Self, ScalingError> {
        if !(2..=32).contains(&bits) {
            return Err(ScalingError::BadCounterWidth { bits });
        }
        Ok(Self {
            shift: 32 - bits,
            ..Self::new()
        })
    }

    /// Takes the next raw counter value; returns the extended count. The first value (and
    /// the first after [`CountExtender::reset`]) is taken as is. Saturates at the `i64`
    /// range rather than wrapping.
    pub fn update(&mut self, raw: i32) -> i64 {
        match self.last {
            None => self.total = self.pending.take().unwrap_or(i64::from(raw)),
            Some(prev) => {
                let d = raw.wrapping_sub(prev).wrapping_shl(self.shift) >> self.shift;
                self.total = self.total.saturating_add(i64::from(d));
            }
        }
        self.last = Some(raw);
        self.total
    }

    /// The extended count so far, `None` before the first value.
    pub fn value(&self) -> Option<i64> {
        self.last.map(|_| self.total)
    }

    /// Makes the current raw value stand for `total` (restoring a stored absolute position
    /// at power-up, or after homing); takes effect at once if a value has been seen, else
    /// at the next one.
    pub fn rebase(&mut self, total: i64) {
        if self.last.is_some() {
            self.total = total;
        } else {
            self.pending = Some(total);
        }
    }

    /// Forgets the last raw value and any pending rebase (bus restart): the next raw value
    /// is taken as is.
    pub fn reset(&mut self) {
        self.last = None;
        self.pending = None;
    }
}
