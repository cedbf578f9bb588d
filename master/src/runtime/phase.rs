//! Keeping the cycle in phase with SYNC0. With distributed clocks the drives take their
//! setpoints at SYNC0, on the reference clock's time; the cycle sleeps on the host's.
//! Two quartzes differ by tens of ppm, so a free-running cycle's frames walk through the
//! SYNC0 period (50 ppm: a whole 1 ms period in 20 s) and now and then arrive just as the
//! drives latch — a missed or doubled setpoint, then sync errors. So the cycle measures
//! where in the SYNC0 period each frame reaches the reference clock (ethercrab's
//! `cycle_start_offset`) and moves its own deadlines a little each cycle to hold that
//! point at a fixed offset, as TwinCAT and Codesys masters do.

/// Where in the SYNC0 period the frames should reach the reference clock: a quarter of
/// the period after SYNC0, so the inputs latched at SYNC0 are fresh and the outputs have
/// three quarters of a period of margin before the next SYNC0 takes them.
const TARGET_FRACTION: u64 = 4;
/// A cycle corrects this fraction of the error it measures: small enough that jitter in
/// the frame's own timing does not shake the cycle, large enough to follow any quartz
/// (the remaining error is drift per cycle × this, 0.8 µs at 100 ppm and 1 ms).
const GAIN_DIVISOR: i64 = 8;
/// At most this fraction of the period per cycle, so locking on from any phase is smooth.
const MAX_STEP_DIVISOR: i64 = 50;

/// The phase controller of one cycle time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PhaseLock {
    period_ns: i64,
    target_ns: i64,
}

impl PhaseLock {
    /// For a SYNC0 period (= the cycle time) of `period_ns`.
    pub fn new(period_ns: u64) -> Self {
        let period_ns = i64::try_from(period_ns).unwrap_or(i64::MAX).max(1);
        Self {
            period_ns,
            target_ns: period_ns / TARGET_FRACTION as i64,
        }
    }

    /// Where the frames should reach the reference clock (ns after SYNC0).
    pub fn target_ns(&self) -> u64 {
        self.target_ns as u64
    }

    /// How far the frame's arrival at `offset_ns` into the SYNC0 period is from the
    /// target, in −period/2 … period/2 (positive: too late).
    pub fn error_ns(&self, offset_ns: u64) -> i64 {
        let p = self.period_ns;
        let offset = i64::try_from(offset_ns).unwrap_or(0) % p;
        let e = (offset - self.target_ns).rem_euclid(p);
        if e > p / 2 {
            e - p
        } else {
            e
        }
    }

    /// Whether a frame that reached the reference clock `offset_ns` into the SYNC0 period
    /// is held: within an eighth of the period of the target, far from both SYNC0 edges.
    pub fn holds(&self, offset_ns: u64) -> bool {
        self.error_ns(offset_ns).unsigned_abs() <= (self.period_ns / 8) as u64
    }

    /// How far to move the next deadlines (ns; negative: earlier) after a frame reached
    /// the reference clock `offset_ns` into the SYNC0 period.
    pub fn correction_ns(&self, offset_ns: u64) -> i64 {
        let step = self.period_ns / MAX_STEP_DIVISOR;
        (-self.error_ns(offset_ns) / GAIN_DIVISOR).clamp(-step, step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_wrap_round_the_period() {
        let lock = PhaseLock::new(1_000_000);
        assert_eq!(lock.target_ns(), 250_000);
        assert_eq!(lock.error_ns(250_000), 0);
        assert_eq!(lock.error_ns(300_000), 50_000);
        assert_eq!(lock.error_ns(200_000), -50_000);
        // 900 µs is 350 µs early for the next target, not 650 µs late.
        assert_eq!(lock.error_ns(900_000), -350_000);
        assert_eq!(lock.error_ns(1_250_000), 0, "offsets beyond a period wrap");
    }

    #[test]
    fn corrections_are_proportional_and_bounded() {
        let lock = PhaseLock::new(1_000_000);
        assert_eq!(lock.correction_ns(250_000), 0);
        assert_eq!(lock.correction_ns(258_000), -1_000, "late: wake earlier");
        assert_eq!(lock.correction_ns(242_000), 1_000, "early: wake later");
        assert_eq!(lock.correction_ns(700_000), -20_000, "at most 2 % a cycle");
    }

    /// A cycle whose host clock is 100 ppm slow against the reference's locks on from
    /// anywhere in the period and stays within a microsecond of the target.
    #[test]
    fn a_drifting_cycle_locks_on_and_follows() {
        let lock = PhaseLock::new(1_000_000);
        // Each host period, the reference's time runs 100 ns further: the frames arrive
        // 100 ns later in the SYNC0 period each cycle unless corrected.
        let drift_per_cycle = 100;
        for start in [0u64, 130_000, 600_000, 999_000] {
            let mut phase = start as i64; // where the frames arrive
            for _ in 0..400 {
                let offset = phase.rem_euclid(1_000_000) as u64;
                phase += lock.correction_ns(offset) + drift_per_cycle;
            }
            let e = lock.error_ns(phase.rem_euclid(1_000_000) as u64);
            assert!(
                e.abs() <= 1_000,
                "from {start}: {e} ns off after 400 cycles"
            );
        }
    }
}
