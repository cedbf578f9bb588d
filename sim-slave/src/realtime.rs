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

    /// Brings `chain` up to now (call before each frame, and when idle: without it the
    /// chain's time, and with it the devices' timers and the process-data watchdog,
    /// would stand still while the master is silent).
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

    #[test]
    fn the_watchdog_trips_when_the_master_is_silent_and_the_chain_catches_up() {
        use crate::catalog::encoder_description;
        use crate::esc::datagram::{Command, Datagram};
        use crate::esc::frame::{Frame, ETHERTYPE};
        use crate::esc::registers::{AL_CONTROL, AL_STATUS, SM0};
        use crate::slave::Slave;
        let frame = |ado: u16, data: &[u8]| {
            let mut buf = vec![0u8; 28 + data.len()];
            let mut f = Frame::new_unchecked(&mut buf[..]);
            f.set_ethertype(ETHERTYPE);
            f.set_ecat_header(12 + data.len());
            let mut d = Datagram::new_unchecked(f.payload_mut());
            d.set_command(Command::Apwr);
            d.set_ado(ado);
            d.set_len(data.len(), false, false);
            d.data_mut().copy_from_slice(data);
            buf
        };
        let mut chain = SlaveChain::new(vec![Slave::new(encoder_description(1))]);
        let clock = WallClock::start(&chain, Duration::from_millis(1));
        // Outputs on SM0 with the watchdog trigger (100 ms by default), up to Op.
        let mut steps = vec![frame(SM0, &[0x00, 0x10, 6, 0, 0x64, 0, 1, 0])];
        for state in [2u8, 4, 8] {
            steps.push(frame(AL_CONTROL, &[state, 0]));
        }
        steps.push(frame(0x1000, &[0; 6]));
        for mut f in steps {
            clock.catch_up(&mut chain);
            chain.process(&mut f).unwrap();
        }
        let status = |c: &SlaveChain| c.slaves()[0].memory().read_u16(AL_STATUS);
        assert_eq!(status(&chain), 0x08);
        // No frame for 150 ms, the chain brought to the host's time as a link does when
        // idle: out of Op with the error flagged, code 0x001B.
        std::thread::sleep(Duration::from_millis(150));
        clock.catch_up(&mut chain);
        assert_eq!(status(&chain), 0x14);
        assert_eq!(chain.slaves()[0].al_status_code().raw(), 0x001B);
    }
}
