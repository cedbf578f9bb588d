//! The cycle's clocks. [`CycleClock`]: absolute deadlines on CLOCK_MONOTONIC, so a late
//! wake-up does not shift every later cycle (relative sleeps drift by the sum of all
//! latencies). [`StepClock`]: no waiting at all, a simulated network's time moved one cycle
//! per cycle — the same engine loop in lockstep, for the demo and the tests.

use nix::sys::time::TimeSpec;
use nix::time::{clock_gettime, clock_nanosleep, ClockId, ClockNanosleepFlags};

/// Nanoseconds on CLOCK_MONOTONIC.
pub fn now_ns() -> u64 {
    clock_gettime(ClockId::CLOCK_MONOTONIC)
        .map(|t| t.tv_sec() as u64 * 1_000_000_000 + t.tv_nsec() as u64)
        .unwrap_or(0)
}

/// What a cycle keeps after its reply deadline for the rest of its work (publishing the
/// status, the trace) before the next deadline: at most a tenth of the period.
const REPLY_MARGIN_NS: u64 = 50_000;

/// How long after its start a cycle of `period_ns` waits for its bus' replies at most
/// ([`Wake::reply_by_ns`]): the period less the margin kept for the rest of its work. A
/// bus whose frames take longer than this every cycle cannot run at this period (the
/// CANopen bus-load check weighs its frames against it).
pub const fn reply_window_ns(period_ns: u64) -> u64 {
    let margin = if period_ns / 10 < REPLY_MARGIN_NS {
        period_ns / 10
    } else {
        REPLY_MARGIN_NS
    };
    period_ns - margin
}

/// Where the engine's cycles get their time from ([`crate::runtime::engine::Engine::cycle`]).
pub trait Clock {
    /// Waits for the next cycle's start; what the wait saw.
    fn wait(&mut self) -> Wake;
    /// Moves every later cycle start by `ns` (negative: earlier), to hold the cycle in
    /// phase with another clock (SYNC0). Callers keep `ns` small against the period.
    fn shift(&mut self, ns: i64);
}

impl Clock for CycleClock {
    fn wait(&mut self) -> Wake {
        CycleClock::wait(self)
    }

    fn shift(&mut self, ns: i64) {
        CycleClock::shift(self, ns);
    }
}

/// Lockstep: a cycle starts as soon as the last one ended, and each start moves a
/// simulated network's time on by one period (shifted as the engine asks) through
/// `advance`, which brings the network to the time it is given (ns on the network's
/// clock). Whatever the host does, the devices see a master exactly on time.
pub struct StepClock<F: FnMut(u64)> {
    period_ns: u64,
    next_ns: u64,
    advance: F,
}

impl<F: FnMut(u64)> StepClock<F> {
    /// Cycles every `period_ns` of network time from `start_ns` (the network's time now).
    pub fn new(period_ns: u64, start_ns: u64, advance: F) -> Self {
        Self {
            period_ns,
            next_ns: start_ns,
            advance,
        }
    }
}

impl<F: FnMut(u64)> std::fmt::Debug for StepClock<F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StepClock")
            .field("period_ns", &self.period_ns)
            .field("next_ns", &self.next_ns)
            .finish()
    }
}

impl<F: FnMut(u64)> Clock for StepClock<F> {
    /// Never late, never an overrun; the reply deadline is a period of host time away
    /// (a lockstep bus answers before the exchange looks).
    fn wait(&mut self) -> Wake {
        self.next_ns = self.next_ns.saturating_add(self.period_ns);
        (self.advance)(self.next_ns);
        let now = now_ns();
        Wake {
            deadline_ns: now,
            reply_by_ns: now + self.period_ns,
            latency_ns: 0,
            overrun: false,
            period_ns: self.period_ns,
        }
    }

    fn shift(&mut self, ns: i64) {
        self.next_ns = self.next_ns.saturating_add_signed(ns);
    }
}

/// Deadlines every `period_ns` from a start time.
#[derive(Clone, Copy, Debug)]
pub struct CycleClock {
    period_ns: u64,
    next_ns: u64,
}

/// What one wait for the next deadline saw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wake {
    /// The deadline.
    pub deadline_ns: u64,
    /// How long this cycle's bus exchange may wait for its reply: just before the next
    /// deadline, so a lost frame costs this cycle's inputs and not the next cycle's start.
    pub reply_by_ns: u64,
    /// How late the thread woke (0 if the deadline had already passed before sleeping:
    /// that is an overrun, not latency).
    pub latency_ns: u64,
    /// The previous cycle's work ran past this deadline.
    pub overrun: bool,
    /// The cycle time.
    pub period_ns: u64,
}

impl CycleClock {
    /// The first deadline is one period from now.
    pub fn start(period_ns: u64) -> Self {
        Self {
            period_ns,
            next_ns: now_ns() + period_ns,
        }
    }

    /// Moves every later deadline by `ns` (negative: earlier), to hold the cycle in phase
    /// with another clock (SYNC0). Callers keep `ns` small against the period.
    pub fn shift(&mut self, ns: i64) {
        self.next_ns = self.next_ns.saturating_add_signed(ns);
    }

    /// Sleeps until the next deadline. After an overrun the missed deadlines are skipped
    /// (the cycle keeps its phase) rather than run back to back.
    pub fn wait(&mut self) -> Wake {
        let deadline_ns = self.next_ns;
        let before = now_ns();
        let overrun = before > deadline_ns;
        if !overrun {
            let ts = TimeSpec::new(
                (deadline_ns / 1_000_000_000) as i64,
                (deadline_ns % 1_000_000_000) as i64,
            );
            // EINTR: we wake early and measure it as such; the next wait corrects.
            let _ = clock_nanosleep(
                ClockId::CLOCK_MONOTONIC,
                ClockNanosleepFlags::TIMER_ABSTIME,
                &ts,
            );
        }
        let woke = now_ns();
        self.next_ns += self.period_ns;
        if woke >= self.next_ns {
            let missed = (woke - self.next_ns) / self.period_ns + 1;
            self.next_ns += missed * self.period_ns;
        }
        Wake {
            deadline_ns,
            reply_by_ns: self.next_ns - self.period_ns + reply_window_ns(self.period_ns),
            period_ns: self.period_ns,
            latency_ns: if overrun {
                0
            } else {
                woke.saturating_sub(deadline_ns)
            },
            overrun,
        }
    }
}
