//! A chain on the wall clock: the network's time (DC clocks, SYNC0) follows the host's
//! monotonic clock to the nanosecond at every frame, and the devices' applications run
//! once per period of it. Used wherever the simulator runs in real time: `gantry-sim
//! --interface`, and gantry's in-process simulator (`gantry run`, the demo's bus).

use std::time::{Duration, Instant};

use crate::chain::SlaveChain;

/// Ties a chain's time to the host's.
#[derive(Clone, Copy, Debug)]
pub struct WallClock {
    origin: Instant,
    origin_ns: u64,
    period_ns: u64,
}

impl WallClock {
    /// From now on `chain`'s time follows the host's, starting where it is; the
    /// applications run every `period`.
    pub fn start(chain: &SlaveChain, period: Duration) -> Self {
        Self {
            origin: Instant::now(),
            origin_ns: chain.now_ns(),
            period_ns: u64::try_from(period.as_nanos()).unwrap_or(u64::MAX).max(1),
        }
    }

    /// The network's time now (ns).
    pub fn now_ns(&self) -> u64 {
        let elapsed = u64::try_from(self.origin.elapsed().as_nanos()).unwrap_or(u64::MAX);
        self.origin_ns.saturating_add(elapsed)
    }

    /// Brings `chain` up to now (call before each frame, and when idle).
    pub fn catch_up(&self, chain: &mut SlaveChain) {
        chain.run_until(self.now_ns(), self.period_ns);
    }

    /// How long until the applications' next period starts (to sleep at most that long).
    pub fn until_next_period(&self, chain: &SlaveChain) -> Duration {
        let next = (chain.now_ns() / self.period_ns + 1) * self.period_ns;
        Duration::from_nanos(next.saturating_sub(self.now_ns()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_network_time_follows_the_host_between_periods() {
        let mut chain = SlaveChain::new(Vec::new());
        let clock = WallClock::start(&chain, Duration::from_millis(50));
        std::thread::sleep(Duration::from_millis(3));
        clock.catch_up(&mut chain);
        let t = chain.now_ns();
        // Not rounded to the 50 ms period: the clocks are where the host is.
        assert!((3_000_000..50_000_000).contains(&t), "{t} ns");
        assert!(clock.until_next_period(&chain) <= Duration::from_millis(47));
    }
}
