//! The distributed-clocks (DC) unit of an ESC (ET1100/ET1200 datasheet section II,
//! registers 0x0900–0x09AF): a local clock with its own drift, the receive-time latches,
//! the system time (local time + offset) with the drift control loop that makes repeated
//! system-time writes converge, and the cyclic unit's SYNC0 pulses.
//!
//! Time comes from the chain: [`Arrival`] says when (chain time, ns) a frame passes this
//! slave's ports, and [`Clock`] turns chain time into this slave's local time.
//!
//! Model of the drift control loop (the datasheet describes what it measures, not its
//! exact filter): every write to 0x0910 gives `diff = local system time − (written value +
//! system time delay)`; its running mean (depth from 0x0934) goes to 0x092C as sign and
//! magnitude, and a PI controller turns it into a speed correction of the local clock:
//! the integral part (the "speed counter diff", 0x0932) follows the drift, the
//! proportional part removes the remaining offset. Both are bounded (a bounded slope,
//! as the ESC adds or skips single nanoseconds) and the integral only advances with
//! the local time that passed between two writes, so a burst of writes in no time does
//! not wind it up. The loop's bandwidth scales inversely with 0x0930 (speed counter
//! start), and a write there resets the loop, as on a real ESC.

use super::memory::Memory;
use super::registers::{
    DC_ACTIVATION, DC_ACTIVATION_STATUS, DC_RECEIVE_TIME_EPU, DC_RECEIVE_TIME_PORT0,
    DC_RECEIVE_TIME_PORT1, DC_SPEED_COUNTER_DIFF, DC_SPEED_COUNTER_START, DC_START_TIME_CYCLIC,
    DC_SYNC0_CYCLE_TIME, DC_SYNC0_STATUS, DC_SYSTEM_TIME, DC_SYSTEM_TIME_DELAY,
    DC_SYSTEM_TIME_DIFFERENCE, DC_SYSTEM_TIME_DIFF_FILTER_DEPTH, DC_SYSTEM_TIME_OFFSET,
};

/// Loop bandwidth (rad/s of local time) at the reset speed counter start 0x1000: the
/// loop is critically damped, so a drift step settles within about 5/ω (0.5 s).
const OMEGA_AT_DEFAULT_START: f64 = 10.0;
/// Reset value of 0x0930.
const DEFAULT_SPEED_COUNTER_START: f64 = 4096.0;
/// Bound of the integral (drift) correction: ±500 ppm.
const FREQ_MAX: f64 = 500e-6;
/// Bound of the proportional slew: ±500 ppm (the slope of an offset adjustment).
const SLEW_MAX: f64 = 500e-6;
/// Longest gap between two writes the integral accounts for: after a pause the loop
/// resumes instead of jumping.
const MAX_SAMPLE_GAP_S: f64 = 0.01;
/// 0x0932 scaling in this emulator: one unit is 0.1 ppm of speed correction.
const SPEED_DIFF_LSB: f64 = 1e-7;
/// Activation bits (0x0981).
const ACTIVATE_CYCLIC: u8 = 0x01;
const ACTIVATE_SYNC0: u8 = 0x02;

/// When a frame passes this slave, in chain time (ns).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Arrival {
    /// The frame's start at port 0 on its way from the master; the ECAT processing unit
    /// sees it at the same time.
    pub port0: u64,
    /// The frame coming back on port 1 from the slaves behind (None: port 1 closed).
    pub port1: Option<u64>,
}

/// A local clock: chain time in, local time out. It runs at `(1 + drift) × (1 + freq +
/// slew)` until the slew has made up the difference it was started for, then at `(1 +
/// drift) × (1 + freq)`. Local time is kept in `f64` nanoseconds (exact to well below
/// 1 ns for the first 100 days).
#[derive(Clone, Debug)]
pub struct Clock {
    drift: f64,
    freq: f64,
    slew: f64,
    /// Chain time the slew ends.
    slew_end: u64,
    base_chain: u64,
    base_local: f64,
}

impl Clock {
    /// A clock `drift_ppm` fast (negative: slow) that reads `local_at_zero` at chain time 0.
    pub fn new(drift_ppm: f64, local_at_zero: u64) -> Self {
        let drift = if drift_ppm.is_finite() {
            drift_ppm.clamp(-1e4, 1e4) * 1e-6
        } else {
            0.0
        };
        Self {
            drift,
            freq: 0.0,
            slew: 0.0,
            slew_end: 0,
            base_chain: 0,
            base_local: local_at_zero as f64,
        }
    }

    fn rate(&self, slewing: bool) -> f64 {
        let slew = if slewing { self.slew } else { 0.0 };
        (1.0 + self.drift) * (1.0 + self.freq + slew)
    }

    /// Local time at chain time `t`, with fractions.
    pub fn local_f(&self, t: u64) -> f64 {
        let split = self.slew_end.max(self.base_chain);
        let dt = |from: u64, to: u64| (to as i128 - from as i128) as f64;
        if t <= split {
            self.base_local + dt(self.base_chain, t) * self.rate(true)
        } else {
            self.base_local
                + dt(self.base_chain, split) * self.rate(true)
                + dt(split, t) * self.rate(false)
        }
    }

    /// Local time at chain time `t` (ns; the cast saturates, it cannot panic).
    pub fn local(&self, t: u64) -> u64 {
        self.local_f(t) as u64
    }

    /// The drift part of the speed correction (relative).
    pub fn correction(&self) -> f64 {
        self.freq
    }

    /// From chain time `t` on: speed correction `freq`, plus `slew` until `amount_ns` of
    /// difference are made up.
    fn adjust(&mut self, t: u64, freq: f64, slew: f64, amount_ns: f64) {
        self.base_local = self.local_f(t);
        self.base_chain = t;
        self.freq = freq;
        self.slew = slew;
        let duration = if slew == 0.0 {
            0.0
        } else {
            (amount_ns / slew).abs()
        };
        // The cast saturates.
        self.slew_end = t.saturating_add(duration as u64);
    }
}

/// Whether `[ado, ado + len)` and `[reg, reg + width)` overlap.
fn overlaps(ado: u16, len: usize, reg: u16, width: usize) -> bool {
    (ado as usize) < reg as usize + width && ado as usize + len > reg as usize
}

/// 0x092C encoding: bit 31 set when the local copy is smaller than the received time,
/// bits 30:0 the magnitude (saturated).
pub fn encode_difference(diff: i64) -> u32 {
    let magnitude = diff.unsigned_abs().min(0x7FFF_FFFF) as u32;
    if diff < 0 {
        magnitude | 0x8000_0000
    } else {
        magnitude
    }
}

/// The cyclic unit's SYNC0 generation.
#[derive(Clone, Debug, Default)]
struct Sync0 {
    active: bool,
    /// System time of the next pulse.
    next: u64,
    pulses: u64,
    last: Option<u64>,
}

/// The DC unit of one slave. Registers that only hold configuration (offset, delay,
/// cycle times, …) live in the ESC memory; this holds what changes with time.
#[derive(Clone, Debug)]
pub struct DcUnit {
    clock: Clock,
    /// Running mean of the system time difference (ns), what 0x092C shows.
    mean_diff: f64,
    /// Integral (drift) part of the speed correction.
    freq: f64,
    /// Local time of the previous system-time write since the last reset.
    last_sample: Option<f64>,
    sync0: Sync0,
}

impl DcUnit {
    /// A DC unit whose clock runs `drift_ppm` fast and reads `local_at_zero` at chain time 0.
    pub fn new(drift_ppm: f64, local_at_zero: u64) -> Self {
        Self {
            clock: Clock::new(drift_ppm, local_at_zero),
            mean_diff: 0.0,
            freq: 0.0,
            last_sample: None,
            sync0: Sync0::default(),
        }
    }

    /// The local clock.
    pub fn clock(&self) -> &Clock {
        &self.clock
    }

    /// Local copy of the system time at chain time `t`: local time + offset (0x0920).
    pub fn system_time(&self, mem: &Memory, t: u64) -> u64 {
        self.clock
            .local(t)
            .wrapping_add(mem.read_u64(DC_SYSTEM_TIME_OFFSET))
    }

    /// SYNC0 pulses generated so far.
    pub fn sync0_pulses(&self) -> u64 {
        self.sync0.pulses
    }

    /// System time of the last SYNC0 pulse.
    pub fn last_sync0(&self) -> Option<u64> {
        self.sync0.last
    }

    /// Before a datagram at `ado` of `len` bytes is served: a read of the system time sees
    /// the time the frame passes the processing unit.
    pub fn before_access(&self, mem: &mut Memory, ado: u16, len: usize, at: &Arrival) {
        if overlaps(ado, len, DC_SYSTEM_TIME, 8) {
            let now = self.system_time(mem, at.port0);
            mem.pdi_write(DC_SYSTEM_TIME, &now.to_le_bytes());
        }
    }

    /// After a datagram wrote `[ado, ado + len)`: the side effects of DC register writes.
    pub fn after_write(&mut self, mem: &mut Memory, ado: u16, len: usize, at: &Arrival) {
        if overlaps(ado, len, DC_RECEIVE_TIME_PORT0, 1) {
            self.latch(mem, at);
        }
        // Only a write of the whole low word (32-bit ESCs) or both words is a sample.
        if ado == DC_SYSTEM_TIME && len >= 4 {
            self.sample(mem, at.port0, len >= 8);
        }
        if overlaps(ado, len, DC_SPEED_COUNTER_START, 2) {
            self.reset_loop(mem, at.port0);
        }
        if overlaps(ado, len, DC_ACTIVATION, 1) {
            self.on_activation(mem);
        }
        if self.sync0.active && overlaps(ado, len, DC_START_TIME_CYCLIC, 8) {
            // The start time is write-protected while the cyclic unit runs; it reads as
            // the next pulse.
            mem.pdi_write(DC_START_TIME_CYCLIC, &self.sync0.next.to_le_bytes());
        }
    }

    /// After a datagram read `[ado, ado + len)`: reading SYNC0 status acknowledges it
    /// (pulse length 0 is acknowledge mode).
    pub fn after_read(&mut self, mem: &mut Memory, ado: u16, len: usize) {
        if overlaps(ado, len, DC_SYNC0_STATUS, 1) {
            mem.pdi_write(DC_SYNC0_STATUS, &[0]);
        }
    }

    /// Runs the cyclic unit up to chain time `t`: every SYNC0 pulse whose system time has
    /// come is generated (counted; the status bit is set).
    pub fn advance(&mut self, mem: &mut Memory, t: u64) {
        if !self.sync0.active {
            return;
        }
        let now = self.system_time(mem, t);
        if now < self.sync0.next {
            return;
        }
        let cycle = u64::from(mem.read_u32(DC_SYNC0_CYCLE_TIME));
        match (now - self.sync0.next).checked_div(cycle) {
            Some(whole) => {
                let last = self.sync0.next.wrapping_add(whole.wrapping_mul(cycle));
                self.sync0.pulses = self.sync0.pulses.saturating_add(whole.saturating_add(1));
                self.sync0.last = Some(last);
                self.sync0.next = last.wrapping_add(cycle);
            }
            None => {
                // Cycle time 0: single shot.
                self.sync0.pulses = self.sync0.pulses.saturating_add(1);
                self.sync0.last = Some(self.sync0.next);
                self.sync0.active = false;
            }
        }
        mem.pdi_write(DC_ACTIVATION_STATUS, &[0]);
        mem.pdi_write(DC_SYNC0_STATUS, &[1]);
        mem.pdi_write(DC_START_TIME_CYCLIC, &self.sync0.next.to_le_bytes());
    }

    /// A write to 0x0900: latch the local receive times of the ports and the processing
    /// unit.
    fn latch(&self, mem: &mut Memory, at: &Arrival) {
        let t0 = self.clock.local(at.port0);
        mem.pdi_write(DC_RECEIVE_TIME_PORT0, &(t0 as u32).to_le_bytes());
        mem.pdi_write(DC_RECEIVE_TIME_EPU, &t0.to_le_bytes());
        if let Some(t1) = at.port1 {
            let t1 = self.clock.local(t1);
            mem.pdi_write(DC_RECEIVE_TIME_PORT1, &(t1 as u32).to_le_bytes());
        }
    }

    /// A write to 0x0910 at chain time `t`: one sample of the drift control loop.
    fn sample(&mut self, mem: &mut Memory, t: u64, wide: bool) {
        let received = mem.read_u64(DC_SYSTEM_TIME);
        let delay = mem.read_u32(DC_SYSTEM_TIME_DELAY);
        let local = self.system_time(mem, t);
        let diff = if wide {
            local.wrapping_sub(received.wrapping_add(u64::from(delay))) as i64
        } else {
            i64::from((local as u32).wrapping_sub((received as u32).wrapping_add(delay)) as i32)
        };
        let depth = f64::from(mem.read_u16(DC_SYSTEM_TIME_DIFF_FILTER_DEPTH) & 0x0F);
        let local_now = self.clock.local_f(t);
        let gap_s = match self.last_sample {
            Some(before) => {
                self.mean_diff += (diff as f64 - self.mean_diff) / (1.0 + depth);
                ((local_now - before) * 1e-9).clamp(0.0, MAX_SAMPLE_GAP_S)
            }
            None => {
                self.mean_diff = diff as f64;
                0.0
            }
        };
        self.last_sample = Some(local_now);
        let start = f64::from(mem.read_u16(DC_SPEED_COUNTER_START)).clamp(128.0, 16383.0);
        let omega = OMEGA_AT_DEFAULT_START * DEFAULT_SPEED_COUNTER_START / start;
        let error_s = self.mean_diff * 1e-9;
        self.freq = (self.freq - omega * omega * error_s * gap_s).clamp(-FREQ_MAX, FREQ_MAX);
        let slew = (-2.0 * omega * error_s).clamp(-SLEW_MAX, SLEW_MAX);
        self.clock.adjust(t, self.freq, slew, self.mean_diff);
        let shown = encode_difference(self.mean_diff.round() as i64);
        mem.pdi_write(DC_SYSTEM_TIME_DIFFERENCE, &shown.to_le_bytes());
        let speed = (self.freq / SPEED_DIFF_LSB).round() as i16;
        mem.pdi_write(DC_SPEED_COUNTER_DIFF, &speed.to_le_bytes());
    }

    /// A write to 0x0930 resets the loop: difference and speed counter diff start over,
    /// the clock runs at its own speed again.
    fn reset_loop(&mut self, mem: &mut Memory, t: u64) {
        self.mean_diff = 0.0;
        self.freq = 0.0;
        self.last_sample = None;
        self.clock.adjust(t, 0.0, 0.0, 0.0);
        mem.pdi_write(DC_SYSTEM_TIME_DIFFERENCE, &[0; 4]);
        mem.pdi_write(DC_SPEED_COUNTER_DIFF, &[0; 2]);
    }

    /// A write to 0x0981: cyclic operation with SYNC0 starts at the start time (0x0990);
    /// clearing either bit stops it.
    fn on_activation(&mut self, mem: &mut Memory) {
        let bits = mem.read_u16(DC_ACTIVATION) as u8;
        let on = bits & (ACTIVATE_CYCLIC | ACTIVATE_SYNC0) == ACTIVATE_CYCLIC | ACTIVATE_SYNC0;
        if on && !self.sync0.active {
            self.sync0.active = true;
            self.sync0.next = mem.read_u64(DC_START_TIME_CYCLIC);
            // Bit 0: first SYNC0 pulse pending.
            mem.pdi_write(DC_ACTIVATION_STATUS, &[1]);
        } else if !on {
            self.sync0.active = false;
            mem.pdi_write(DC_ACTIVATION_STATUS, &[0]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bytes(mem: &Memory, at: u16, n: usize) -> Vec<u8> {
        let mut b = vec![0u8; n];
        assert!(mem.ecat_read(at, &mut b, false));
        b
    }

    /// The master's write of `data` at `ado`, as the chain would serve it.
    fn write(dc: &mut DcUnit, mem: &mut Memory, ado: u16, data: &[u8], at: &Arrival) {
        dc.before_access(mem, ado, data.len(), at);
        assert!(mem.ecat_write(ado, data));
        dc.after_write(mem, ado, data.len(), at);
    }

    fn read(dc: &mut DcUnit, mem: &mut Memory, ado: u16, n: usize, at: &Arrival) -> Vec<u8> {
        dc.before_access(mem, ado, n, at);
        let b = bytes(mem, ado, n);
        dc.after_read(mem, ado, n);
        b
    }

    fn at(t: u64) -> Arrival {
        Arrival {
            port0: t,
            port1: None,
        }
    }

    #[test]
    fn the_clock_drifts_by_its_ppm() {
        let c = Clock::new(50.0, 7);
        assert_eq!(c.local(1_000_000_000), 1_000_050_007);
        let c = Clock::new(-30.0, 0);
        assert_eq!(c.local(1_000_000_000), 999_970_000);
        assert_eq!(Clock::new(f64::NAN, 3).local(10), 13, "no drift from junk");
    }

    #[test]
    fn a_write_to_0x0900_latches_local_receive_times() {
        let mut mem = Memory::new();
        let mut dc = DcUnit::new(0.0, 0x1_0000_1000);
        let arrival = Arrival {
            port0: 0x0500,
            port1: Some(0x0A00),
        };
        // Written data is not stored (read-only) but latches.
        write(&mut dc, &mut mem, 0x0900, &[0xFF; 4], &arrival);
        assert_eq!(
            bytes(&mem, 0x0900, 16),
            [
                0x00, 0x15, 0x00, 0x00, // port 0: low 32 bits of 0x1_0000_1500
                0x00, 0x1A, 0x00, 0x00, // port 1
                0, 0, 0, 0, 0, 0, 0, 0, // ports 2 and 3: closed
            ]
        );
        assert_eq!(
            bytes(&mem, 0x0918, 8),
            [0x00, 0x15, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00]
        );
        // A write elsewhere latches nothing.
        write(&mut dc, &mut mem, 0x0904, &[0; 4], &at(0x0F00));
        assert_eq!(bytes(&mem, 0x0900, 2), [0x00, 0x15]);
    }

    #[test]
    fn system_time_is_local_time_plus_offset() {
        let mut mem = Memory::new();
        let mut dc = DcUnit::new(0.0, 1000);
        write(
            &mut dc,
            &mut mem,
            0x0920,
            &0x0102_0304_0000_0000u64.to_le_bytes(),
            &at(0),
        );
        assert_eq!(
            read(&mut dc, &mut mem, 0x0910, 8, &at(24)),
            [0x00, 0x04, 0x00, 0x00, 0x04, 0x03, 0x02, 0x01]
        );
        // A 32-bit read sees the low word.
        assert_eq!(
            read(&mut dc, &mut mem, 0x0910, 4, &at(25)),
            [0x01, 0x04, 0, 0]
        );
    }

    #[test]
    fn a_system_time_write_stores_the_difference_as_sign_and_magnitude() {
        let mut mem = Memory::new();
        let mut dc = DcUnit::new(0.0, 10_000);
        write(&mut dc, &mut mem, 0x0934, &[0], &at(0)); // no averaging
        write(&mut dc, &mut mem, 0x0928, &200u32.to_le_bytes(), &at(0));
        // Local system time 10_000; received 10_100 + delay 200: local is 300 behind.
        write(&mut dc, &mut mem, 0x0910, &10_100u64.to_le_bytes(), &at(0));
        assert_eq!(bytes(&mem, 0x092C, 4), [0x2C, 0x01, 0x00, 0x80]);
        // 32-bit write: only the low words count (the high word differs wildly).
        let received = 0xDEAD_0000_0000_0000u64 | (10_000 - 200 - 5);
        write(
            &mut dc,
            &mut mem,
            0x0910,
            &received.to_le_bytes()[..4],
            &at(0),
        );
        assert_eq!(bytes(&mem, 0x092C, 4), [0x05, 0x00, 0x00, 0x00]);
        assert_eq!(encode_difference(i64::MIN), 0xFFFF_FFFF);
        assert_eq!(encode_difference(i64::MAX), 0x7FFF_FFFF);
    }

    #[test]
    fn writes_in_no_time_do_not_wind_up_the_drift_correction() {
        let mut mem = Memory::new();
        let mut dc = DcUnit::new(0.0, 0);
        for _ in 0..10_000 {
            write(&mut dc, &mut mem, 0x0910, &1_000u64.to_le_bytes(), &at(0));
        }
        assert_eq!(bytes(&mem, 0x0932, 2), [0, 0]);
        assert_eq!(dc.clock().correction(), 0.0);
        // The slew makes up the 1000 ns (at 2ω × 1 µs = 20 ppm, in 50 ms), then stops.
        let before = dc.system_time(&mem, 0);
        assert_eq!(dc.system_time(&mem, 10_000_000) - before, 10_000_200);
        let made_up = dc.system_time(&mem, 100_000_000) - before;
        assert!(made_up.abs_diff(100_001_000) <= 1, "{made_up}");
    }

    #[test]
    fn writing_speed_counter_start_resets_the_loop() {
        let mut mem = Memory::new();
        let mut dc = DcUnit::new(0.0, 0);
        write(&mut dc, &mut mem, 0x0910, &1_000u64.to_le_bytes(), &at(0));
        write(
            &mut dc,
            &mut mem,
            0x0910,
            &1_000u64.to_le_bytes(),
            &at(1_000_000),
        );
        assert_ne!(bytes(&mem, 0x092C, 4), [0; 4]);
        assert_ne!(bytes(&mem, 0x0932, 2), [0; 2]);
        write(
            &mut dc,
            &mut mem,
            0x0930,
            &0x1000u16.to_le_bytes(),
            &at(1_000_000),
        );
        assert_eq!(bytes(&mem, 0x092C, 6), [0, 0, 0, 0, 0x00, 0x10]);
        assert_eq!(bytes(&mem, 0x0932, 4), [0, 0, 0x04, 0x0C], "depths keep");
    }

    /// A follower fed the reference's system time every millisecond (as FRMW does)
    /// settles on it whatever the two drifts.
    #[test]
    fn repeated_writes_converge_on_the_reference() {
        for (ref_ppm, ppm) in [(50.0, -30.0), (-100.0, 100.0), (0.0, 10.0)] {
            let (mut rmem, mut mem) = (Memory::new(), Memory::new());
            let mut reference = DcUnit::new(ref_ppm, 5_000_000);
            let mut follower = DcUnit::new(ppm, 123);
            let offset = 5_000_000u64 - 123;
            write(
                &mut follower,
                &mut mem,
                0x0920,
                &offset.to_le_bytes(),
                &at(0),
            );
            write(&mut follower, &mut mem, 0x0934, &[0], &at(0));
            let mut worst_late = 0i64;
            for cycle in 0..3000u64 {
                let t = cycle * 1_000_000;
                let now = read(&mut reference, &mut rmem, 0x0910, 8, &at(t));
                write(&mut follower, &mut mem, 0x0910, &now, &at(t));
                let diff =
                    follower.system_time(&mem, t) as i64 - reference.system_time(&rmem, t) as i64;
                if cycle >= 2000 {
                    worst_late = worst_late.max(diff.abs());
                }
            }
            assert!(
                worst_late <= 2,
                "{ref_ppm}/{ppm}: {worst_late} ns after 2 s"
            );
            let speed = i16::from_le_bytes([bytes(&mem, 0x0932, 2)[0], bytes(&mem, 0x0932, 2)[1]]);
            let expected = ((1.0 + ref_ppm * 1e-6) / (1.0 + ppm * 1e-6) - 1.0) / SPEED_DIFF_LSB;
            assert!(
                (f64::from(speed) - expected).abs() <= 2.0,
                "speed counter diff {speed}, drift {expected}"
            );
        }
    }

    #[test]
    fn sync0_pulses_start_at_the_start_time_and_repeat_every_cycle() {
        let mut mem = Memory::new();
        let mut dc = DcUnit::new(0.0, 0);
        write(
            &mut dc,
            &mut mem,
            0x0990,
            &1_000_000u64.to_le_bytes(),
            &at(0),
        );
        write(&mut dc, &mut mem, 0x09A0, &250_000u32.to_le_bytes(), &at(0));
        write(&mut dc, &mut mem, 0x0981, &[0x03], &at(0));
        assert_eq!(bytes(&mem, 0x0984, 1), [0x01], "first pulse pending");
        dc.advance(&mut mem, 999_999);
        assert_eq!((dc.sync0_pulses(), bytes(&mem, 0x098E, 1)[0]), (0, 0));
        dc.advance(&mut mem, 1_000_000);
        assert_eq!(dc.sync0_pulses(), 1);
        assert_eq!(dc.last_sync0(), Some(1_000_000));
        assert_eq!(bytes(&mem, 0x0984, 1), [0x00]);
        assert_eq!(
            bytes(&mem, 0x0990, 8),
            1_250_000u64.to_le_bytes(),
            "reads the next pulse"
        );
        // Write-protected while running.
        write(&mut dc, &mut mem, 0x0990, &[0; 8], &at(1_000_000));
        assert_eq!(bytes(&mem, 0x0990, 8), 1_250_000u64.to_le_bytes());
        assert_eq!(read(&mut dc, &mut mem, 0x098E, 1, &at(1_000_000)), [0x01]);
        assert_eq!(bytes(&mem, 0x098E, 1), [0x00], "reading acknowledges");
        dc.advance(&mut mem, 2_100_000);
        assert_eq!(dc.sync0_pulses(), 5);
        assert_eq!(dc.last_sync0(), Some(2_000_000));
        write(&mut dc, &mut mem, 0x0981, &[0x00], &at(2_100_000));
        dc.advance(&mut mem, 9_000_000);
        assert_eq!(dc.sync0_pulses(), 5, "stopped");
        // Cycle time 0: single shot.
        write(&mut dc, &mut mem, 0x09A0, &[0; 4], &at(9_000_000));
        write(
            &mut dc,
            &mut mem,
            0x0990,
            &9_500_000u64.to_le_bytes(),
            &at(9_000_000),
        );
        write(&mut dc, &mut mem, 0x0981, &[0x03], &at(9_000_000));
        dc.advance(&mut mem, 20_000_000);
        dc.advance(&mut mem, 30_000_000);
        assert_eq!(dc.sync0_pulses(), 6);
    }

    #[test]
    fn any_access_is_panic_free() {
        let mut mem = Memory::new();
        let mut dc = DcUnit::new(1e9, u64::MAX);
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let ado = 0x0900 + (x % 0xB0) as u16;
            let len = (x >> 16) as usize % 12;
            let t = x >> 20;
            let arrival = Arrival {
                port0: t,
                port1: Some(x),
            };
            let data = x.to_le_bytes();
            mem.pdi_write(0x0910, &data);
            mem.pdi_write(0x0928, &data[..4]);
            mem.pdi_write(0x09A0, &data[4..]);
            dc.before_access(&mut mem, ado, len, &arrival);
            dc.after_write(&mut mem, ado, len, &arrival);
            dc.after_read(&mut mem, ado, len);
            dc.advance(&mut mem, t);
        }
    }
}
