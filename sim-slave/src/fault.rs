//! Faults the simulated network can be told to have, as a wire and its devices fail in a
//! machine: frames lost, a cable pulled behind a slave (the slaves beyond it stop
//! answering; the last one still wired closes the loop, as a real ESC does on a lost link),
//! a slave that stops exchanging process data while it stays in OP (the working counter
//! comes back short).

/// The faults in force on a chain.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Faults {
    /// Frames still to lose (each lost frame decrements it).
    pub drop_frames: u32,
    /// The cable after slave `n - 1` is pulled: slaves `n..` are unreachable.
    pub cut_before: Option<usize>,
    /// Slave `n` passes every logical datagram on untouched: its application deactivated
    /// its SyncManagers (PDI control register 0x0807 bit 0, ESC datasheet section II), so
    /// an FMMU access to them is not performed and does not increment the working counter
    /// (ETG.1000.4 §5.4.2: the counter counts successful accesses only). Register accesses
    /// still work: the slave answers, in OP, and only the process data's working counter
    /// says something is wrong.
    pub no_process_data: Option<usize>,
    /// Replies still to lose after the slaves served their frame (each decrements it): a
    /// frame that did its work on the way out and was lost on the way back (a CRC error
    /// on the return path). The master sees no reply to accesses that happened — a
    /// mailbox write taken, a mailbox read that emptied it.
    pub drop_replies: u32,
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

    /// Whether the reply of a frame the slaves served is lost (and counts it).
    pub fn lose_reply(&mut self) -> bool {
        if self.drop_replies > 0 {
            self.drop_replies -= 1;
            true
        } else {
            false
        }
    }

    /// Whether slave `i` takes part in the process data (see [`Faults::no_process_data`]).
    pub fn exchanges_process_data(&self, i: usize) -> bool {
        self.no_process_data != Some(i)
    }

    /// How many of `n` slaves a frame reaches.
    pub fn reachable(&self, n: usize) -> usize {
        self.cut_before.map_or(n, |k| k.min(n))
    }
}
