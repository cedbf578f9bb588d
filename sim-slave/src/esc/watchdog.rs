//! The process-data watchdog (ESC datasheet, registers 0x0400/0x0420/0x0440/0x0442): every
//! write into a SyncManager whose watchdog trigger is on restarts it; when the master stops
//! sending, it expires, and the application must leave Op (AL status code 0x001B) and,
//! for a drive, stop the motor.

use super::memory::Memory;
use super::registers::{
    SM0, WATCHDOG_COUNTER_PD, WATCHDOG_DIVIDER, WATCHDOG_STATUS_PD, WATCHDOG_TIME_PD,
};

/// SyncManager control bit 6: a write to this SyncManager triggers the watchdog.
const SM_WATCHDOG_TRIGGER: u8 = 0x40;
/// ESC clock period the divider counts (40 ns, 25 MHz).
const BASE_TICK_NS: u64 = 40;

/// The watchdog's state: when it was last triggered (chain time), so that it expires
/// when the network's time has passed, however the applications' periods fall.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProcessDataWatchdog {
    last_trigger_ns: u64,
    expired: bool,
}

impl ProcessDataWatchdog {
    /// The configured timeout, `None` when off (time 0).
    pub fn timeout_s(mem: &Memory) -> Option<f64> {
        Self::timeout_ns(mem).map(|ns| ns as f64 * 1e-9)
    }

    /// The configured timeout in ns, `None` when off (time 0): (divider + 2) × 40 ns per
    /// watchdog increment, times the watchdog time.
    pub fn timeout_ns(mem: &Memory) -> Option<u64> {
        let divider = u64::from(mem.read_u16(WATCHDOG_DIVIDER)) + 2;
        let time = u64::from(mem.read_u16(WATCHDOG_TIME_PD));
        (time != 0).then(|| divider * BASE_TICK_NS * time)
    }

    /// Whether any enabled SyncManager covering `[address, address + len)` triggers it.
    pub fn triggered_by(mem: &Memory, address: u16, len: usize) -> bool {
        Self::triggering_sync_managers(mem).any(|(start, length)| {
            (address as usize) < start + length && address as usize + len > start
        })
    }

    /// Whether it watches anything: an enabled SyncManager with its trigger on. Only a
    /// master's writes restart it (SyncManager control bit 6 is for ECAT-written
    /// SyncManagers), so a slave with no outputs — an input terminal — has nothing to
    /// watch and stays in Op while the master only reads it, as its stack supervises the
    /// watchdog only with process data outputs (ETG.1000.6 §6.4.1, ESC datasheet "Process
    /// Data Watchdog").
    pub fn watches(mem: &Memory) -> bool {
        Self::triggering_sync_managers(mem).next().is_some()
    }

    /// `(start, length)` of every enabled SyncManager whose watchdog trigger is on.
    fn triggering_sync_managers(mem: &Memory) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..8u16).filter_map(|n| {
            let mut sm = [0u8; 8];
            if let Some(regs) = mem.raw(SM0 + 8 * n, 8) {
                sm.copy_from_slice(regs);
            }
            let (start, length) = (
                u16::from_le_bytes([sm[0], sm[1]]) as usize,
                u16::from_le_bytes([sm[2], sm[3]]) as usize,
            );
            let (control, enabled) = (sm[4], sm[6] & 0x01 != 0);
            (enabled && control & SM_WATCHDOG_TRIGGER != 0 && length > 0).then_some((start, length))
        })
    }

    /// A triggering write arrived at chain time `now`: restart.
    pub fn trigger(&mut self, mem: &mut Memory, now: u64) {
        self.last_trigger_ns = now;
        self.expired = false;
        mem.pdi_write(WATCHDOG_STATUS_PD, &1u16.to_le_bytes());
    }

    /// Stops it (the application left Op: nothing to watch).
    pub fn disarm(&mut self, mem: &mut Memory, now: u64) {
        self.trigger(mem, now);
    }

    /// The network's time is `now`; true exactly when it expires now (status cleared,
    /// counter incremented).
    pub fn check(&mut self, mem: &mut Memory, now: u64) -> bool {
        let Some(timeout) = Self::timeout_ns(mem) else {
            return false;
        };
        if !Self::watches(mem) {
            return false;
        }
        if self.expired || now.saturating_sub(self.last_trigger_ns) < timeout {
            return false;
        }
        self.expired = true;
        mem.pdi_write(WATCHDOG_STATUS_PD, &0u16.to_le_bytes());
        let count = mem
            .raw(WATCHDOG_COUNTER_PD, 1)
            .and_then(|b| b.first().copied());
        mem.pdi_write(WATCHDOG_COUNTER_PD, &[count.unwrap_or(0).saturating_add(1)]);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_timeout_is_100_ms_and_zero_turns_it_off() {
        let mut mem = Memory::new();
        let t = ProcessDataWatchdog::timeout_s(&mem).unwrap();
        assert!((t - 0.1).abs() < 1e-9, "{t}");
        mem.ecat_write(WATCHDOG_TIME_PD, &[0, 0]);
        assert_eq!(ProcessDataWatchdog::timeout_s(&mem), None);
    }

    #[test]
    fn expires_once_without_triggers_and_counts() {
        let mut mem = Memory::new();
        // SM2 at 0x1100, 6 bytes, control 0x64 (watchdog trigger), enabled: outputs to watch.
        mem.ecat_write(SM0 + 16, &[0x00, 0x11, 6, 0, 0x64, 0, 1, 0]);
        let mut wd = ProcessDataWatchdog::default();
        wd.trigger(&mut mem, 0);
        let fired: Vec<bool> = (1..=150u64)
            .map(|ms| wd.check(&mut mem, ms * 1_000_000))
            .collect();
        assert_eq!(fired.iter().filter(|f| **f).count(), 1);
        assert!(fired[99], "expires at 100 ms (2500 × 40 ns × 1000)");
        assert_eq!(mem.read_u16(WATCHDOG_STATUS_PD) & 1, 0);
        assert_eq!(mem.raw(WATCHDOG_COUNTER_PD, 1), Some(&[1u8][..]));
        wd.trigger(&mut mem, 200_000_000);
        assert_eq!(mem.read_u16(WATCHDOG_STATUS_PD) & 1, 1);
    }

    #[test]
    fn only_syncmanagers_with_the_trigger_bit_trigger() {
        let mut mem = Memory::new();
        // SM2 at 0x1100, 6 bytes, control 0x64 (watchdog trigger), enabled.
        mem.ecat_write(SM0 + 16, &[0x00, 0x11, 6, 0, 0x64, 0, 1, 0]);
        // SM3 at 0x1400, 6 bytes, control 0x20 (no trigger), enabled.
        mem.ecat_write(SM0 + 24, &[0x00, 0x14, 6, 0, 0x20, 0, 1, 0]);
        assert!(ProcessDataWatchdog::triggered_by(&mem, 0x1100, 6));
        assert!(ProcessDataWatchdog::triggered_by(&mem, 0x1105, 1));
        assert!(!ProcessDataWatchdog::triggered_by(&mem, 0x1106, 4));
        assert!(!ProcessDataWatchdog::triggered_by(&mem, 0x1400, 6));
    }

    #[test]
    fn a_slave_without_outputs_has_nothing_to_watch() {
        let mut mem = Memory::new();
        // An input terminal: SM3 at 0x1400, 6 bytes, control 0x20 (no trigger), enabled.
        mem.ecat_write(SM0 + 24, &[0x00, 0x14, 6, 0, 0x20, 0, 1, 0]);
        let mut wd = ProcessDataWatchdog::default();
        wd.trigger(&mut mem, 0);
        assert!(!ProcessDataWatchdog::watches(&mem));
        assert!((1..=1000u64).all(|ms| !wd.check(&mut mem, ms * 1_000_000)));
        // With an output SyncManager that triggers it, the same silence expires it.
        mem.ecat_write(SM0 + 16, &[0x00, 0x11, 6, 0, 0x64, 0, 1, 0]);
        assert!(ProcessDataWatchdog::watches(&mem));
        assert!((1001..=1200u64).any(|ms| wd.check(&mut mem, ms * 1_000_000)));
    }
}
