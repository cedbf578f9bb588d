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

    /// Brings `chain` up to the time a frame arrived `age` ago (never back): frames that
    /// waited in the socket while this process was not scheduled are served at their
    /// arrival, with the SYNC0 edges between them where they were, so the drives judge the
    /// master's timing and not the simulator's own stall.
    pub fn catch_up_to_arrival(&self, chain: &mut SlaveChain, age: Duration) {
        let age_ns = u64::try_from(age.as_nanos()).unwrap_or(u64::MAX);
        chain.run_until(self.now_ns().saturating_sub(age_ns), self.period_ns);
    }

    /// How long until the applications' next period starts (to sleep at most that long).
    pub fn until_next_period(&self, chain: &SlaveChain) -> Duration {
        let next = (chain.now_ns() / self.period_ns + 1) * self.period_ns;
        Duration::from_nanos(next.saturating_sub(self.now_ns()))
    }
}

/// The largest gaps a real-time run left, in host time: between frames, and per slave
/// between writes of its process data (what restarts its process-data watchdog and, for a
/// drive, brings its next setpoint). A drive faults when this gap grows past its watchdog
/// or its own tolerance for missed setpoints, so a run reports it.
#[derive(Clone, Debug)]
pub struct Gaps {
    last_frame: Option<Instant>,
    largest_frame: Duration,
    /// Per slave: writes seen so far and when the last one came.
    last_write: Vec<(u64, Option<Instant>)>,
    largest_write: Vec<Duration>,
}

impl Gaps {
    /// Nothing seen yet, for a chain of `slaves` slaves (allocates, once).
    pub fn new(slaves: usize) -> Self {
        Self {
            last_frame: None,
            largest_frame: Duration::ZERO,
            last_write: vec![(0, None); slaves],
            largest_write: vec![Duration::ZERO; slaves],
        }
    }

    /// A frame passed `chain` at `now` (call after each one; allocates nothing).
    pub fn frame(&mut self, now: Instant, chain: &SlaveChain) {
        if let Some(last) = self.last_frame {
            self.largest_frame = self.largest_frame.max(now.saturating_duration_since(last));
        }
        self.last_frame = Some(now);
        let writes = chain.process_data_writes();
        for ((seen, at), (largest, &count)) in self
            .last_write
            .iter_mut()
            .zip(self.largest_write.iter_mut().zip(writes))
        {
            if count == *seen {
                continue;
            }
            if let Some(at) = *at {
                *largest = (*largest).max(now.saturating_duration_since(at));
            }
            *seen = count;
            *at = Some(now);
        }
    }

    /// The largest interval between two frames.
    pub fn largest_frame_gap(&self) -> Duration {
        self.largest_frame
    }

    /// Per slave, the largest interval between two writes of its process data (zero for
    /// a slave that never got two).
    pub fn largest_write_gaps(&self) -> &[Duration] {
        &self.largest_write
    }
}

impl std::fmt::Display for Gaps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "largest gap between frames {} µs; between process-data writes per slave [",
            self.largest_frame.as_micros()
        )?;
        for (i, g) in self.largest_write.iter().enumerate() {
            let sep = if i == 0 { "" } else { ", " };
            write!(f, "{sep}{}", g.as_micros())?;
        }
        f.write_str("] µs")
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

    /// Gaps are measured per slave between frames that wrote its process data; a slave
    /// that stopped taking process data keeps the gap from its last write open.
    #[test]
    fn gaps_are_the_largest_intervals_between_process_data_writes() {
        use crate::catalog::{self, ServoOptions};
        use crate::esc::datagram::{Command, Datagram};
        use crate::esc::frame::{Frame, ETHERTYPE};
        let servo = |serial| {
            catalog::servo(ServoOptions {
                serial,
                ..ServoOptions::default()
            })
        };
        let mut chain = SlaveChain::new(vec![servo(1), servo(2)]);
        // Fake the counts directly would test nothing; count real writes instead: the
        // chain counts a logical write only where an FMMU maps it, so map both slaves'
        // outputs by hand (FMMU 0 → SM2 at 0x1100, 1 byte each).
        for (pos, logical) in [(0u16, 0u32), (1, 1)] {
            for (ado, data) in [
                (0x0010u16, (0x1000 + pos).to_le_bytes().to_vec()),
                (0x0810, vec![0x00, 0x11, 1, 0, 0x64, 0, 1, 0]),
                (
                    0x0600,
                    [
                        logical.to_le_bytes().as_slice(),
                        &[1, 0, 0, 7, 0x00, 0x11, 0, 2, 1, 0, 0, 0],
                    ]
                    .concat(),
                ),
            ] {
                let mut f = frame(Command::Apwr, 0u16.wrapping_sub(pos), ado, &data);
                chain.process(&mut f).unwrap();
            }
        }
        fn frame(cmd: Command, adp: u16, ado: u16, data: &[u8]) -> Vec<u8> {
            let mut buf = vec![0u8; 28 + data.len()];
            let mut f = Frame::new_unchecked(&mut buf[..]);
            f.set_dst([0xff; 6]);
            f.set_src([0x10; 6]);
            f.set_ethertype(ETHERTYPE);
            f.set_ecat_header(12 + data.len());
            let mut d = Datagram::new_unchecked(f.payload_mut());
            d.set_command(cmd);
            d.set_adp(adp);
            d.set_ado(ado);
            d.set_len(data.len(), false, false);
            d.data_mut().copy_from_slice(data);
            buf
        }
        let lwr = |chain: &mut SlaveChain| {
            let mut f = frame(Command::Lwr, 0, 0, &[1, 2]);
            chain.process(&mut f).unwrap();
        };
        let mut gaps = Gaps::new(2);
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        lwr(&mut chain);
        gaps.frame(t0, &chain);
        assert_eq!(chain.process_data_writes(), [1, 1], "both mapped");
        lwr(&mut chain);
        gaps.frame(t0 + ms(1), &chain);
        // Slave 1 stops taking process data; frames still pass.
        chain.stop_process_data(Some(1));
        lwr(&mut chain);
        gaps.frame(t0 + ms(4), &chain);
        lwr(&mut chain);
        gaps.frame(t0 + ms(5), &chain);
        chain.stop_process_data(None);
        lwr(&mut chain);
        gaps.frame(t0 + ms(11), &chain);
        assert_eq!(gaps.largest_frame_gap(), ms(6));
        assert_eq!(gaps.largest_write_gaps(), [ms(6), ms(10)]);
        assert_eq!(
            gaps.to_string(),
            "largest gap between frames 6000 µs; between process-data writes per slave \
             [6000, 10000] µs"
        );
    }
}
