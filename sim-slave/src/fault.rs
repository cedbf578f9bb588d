//! Faults the simulated network can be told to have, as a wire and its devices fail in a
//! machine: frames lost, a cable pulled behind a slave (the slaves beyond it stop
//! answering; the last one still wired closes the loop, as a real ESC does on a lost link).

/// The faults in force on a chain.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Faults {
    /// Frames still to lose (each lost frame decrements it).
    pub drop_frames: u32,
    /// The cable after slave `n - 1` is pulled: slaves `n..` are unreachable.
    pub cut_before: Option<usize>,
}

impl Faults {
    /// Whether the next frame is lost (and counts it).
    pub fn lose_frame(&mut self) -> bool {
        if self.drop_frames > 0 {
            self.drop_frames -= 1;
            true
        } else {
            false
        }
    }

    /// How many of `n` slaves a frame reaches.
    pub fn reachable(&self, n: usize) -> usize {
        self.cut_before.map_or(n, |k| k.min(n))
    }
}
