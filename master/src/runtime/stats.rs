//! What each cycle records: wake-up latency, compute time, bus round trip and overruns,
//! with the overrun policy (count, then stop the axes after N in a row).
//!
//! The work is split so that the cycle thread does O(1) per cycle: it counts cycles and
//! overruns (the policy needs them at once) and pushes each cycle's three durations into
//! a wait-free queue ([`CycleStats`]); the application drains the queue into its
//! histograms and computes the percentiles when it asks for them ([`FigureBook`]). A
//! percentile over 10 000 one-microsecond buckets is a scan of the whole histogram —
//! application work, not the cycle's.

use std::time::{Duration, Instant};

use super::clock::Wake;
use super::histogram::{Histogram, Summary};

/// Histogram range of every figure (1 µs buckets; longer samples count in the last).
const HISTOGRAM_US: usize = 10_000;
/// Durations the application's queue holds (at 4 kHz: 16 s without being drained).
pub const SAMPLE_QUEUE: usize = 1 << 16;
/// The application recomputes the percentiles at most this often (a status poll in a
/// tight loop must not rescan the histograms each time).
const SUMMARY_EVERY: Duration = Duration::from_millis(100);

/// The counters the cycle thread keeps (`Copy`: published in every snapshot).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CycleCounters {
    /// Cycles run.
    pub cycles: u64,
    /// Overruns since start.
    pub overruns: u64,
    /// Longest run of overruns in a row.
    pub worst_overrun_run: u32,
    /// Cycles whose durations the application's queue had no room for (it was not
    /// drained): missing from the percentiles, counted here.
    pub samples_dropped: u64,
}

/// The figures the application shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CycleFigures {
    /// Cycles run.
    pub cycles: u64,
    /// Wake-up latency.
    pub wake: Summary,
    /// Compute time (inputs, kernel, outputs).
    pub compute: Summary,
    /// Bus round trip.
    pub round_trip: Summary,
    /// Overruns since start.
    pub overruns: u64,
    /// Longest run of overruns in a row.
    pub worst_overrun_run: u32,
    /// Cycles missing from the percentiles (see [`CycleCounters::samples_dropped`]).
    pub samples_dropped: u64,
}

impl CycleFigures {
    /// Counters without percentiles (as the cycle thread publishes them).
    pub fn from_counters(c: CycleCounters) -> Self {
        Self {
            cycles: c.cycles,
            overruns: c.overruns,
            worst_overrun_run: c.worst_overrun_run,
            samples_dropped: c.samples_dropped,
            ..Self::default()
        }
    }
}

/// One cycle's durations (ns, saturated at u32::MAX ≈ 4.3 s).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CycleSample {
    /// Wake-up latency.
    pub wake_ns: u32,
    /// Compute time.
    pub compute_ns: u32,
    /// Bus round trip.
    pub round_trip_ns: u32,
}

fn saturate(ns: u64) -> u32 {
    u32::try_from(ns).unwrap_or(u32::MAX)
}

/// The cycle thread's side: counters, and the durations pushed to the application.
pub struct CycleStats {
    samples: rtrb::Producer<CycleSample>,
    counters: CycleCounters,
    in_a_row: u32,
}

impl CycleStats {
    /// The cycle's side and the application's end of the queue (allocates, once).
    pub fn new() -> (Self, rtrb::Consumer<CycleSample>) {
        let (tx, rx) = rtrb::RingBuffer::new(SAMPLE_QUEUE);
        (
            Self {
                samples: tx,
                counters: CycleCounters::default(),
                in_a_row: 0,
            },
            rx,
        )
    }

    /// Records one cycle (O(1), no allocation); returns the overruns in a row so far.
    pub fn record(&mut self, wake: Wake, compute_ns: u64, round_trip_ns: u64) -> u32 {
        let c = &mut self.counters;
        c.cycles += 1;
        let sample = CycleSample {
            wake_ns: saturate(wake.latency_ns),
            compute_ns: saturate(compute_ns),
            round_trip_ns: saturate(round_trip_ns),
        };
        if self.samples.push(sample).is_err() {
            c.samples_dropped += 1;
        }
        if wake.overrun {
            c.overruns += 1;
            self.in_a_row += 1;
            c.worst_overrun_run = c.worst_overrun_run.max(self.in_a_row);
        } else {
            self.in_a_row = 0;
        }
        self.in_a_row
    }

    /// The counters so far.
    pub fn counters(&self) -> CycleCounters {
        self.counters
    }
}

/// The application's side: histograms of every duration the cycle recorded.
#[derive(Debug)]
pub struct FigureBook {
    samples: rtrb::Consumer<CycleSample>,
    wake: Histogram,
    compute: Histogram,
    round_trip: Histogram,
    summaries: Option<(Instant, [Summary; 3])>,
}

impl FigureBook {
    /// Histograms fed from the cycle's queue.
    pub fn new(samples: rtrb::Consumer<CycleSample>) -> Self {
        Self {
            samples,
            wake: Histogram::new(HISTOGRAM_US),
            compute: Histogram::new(HISTOGRAM_US),
            round_trip: Histogram::new(HISTOGRAM_US),
            summaries: None,
        }
    }

    /// Takes every duration waiting in the queue; true if there was any.
    pub fn drain(&mut self) -> bool {
        let mut any = false;
        while let Ok(s) = self.samples.pop() {
            self.wake.record(u64::from(s.wake_ns));
            self.compute.record(u64::from(s.compute_ns));
            self.round_trip.record(u64::from(s.round_trip_ns));
            any = true;
        }
        any
    }

    /// The figures: `counters` from the cycle, the percentiles of everything drained so
    /// far — recomputed when new samples came and the last computation is older than
    /// `SUMMARY_EVERY`, or when `fresh`.
    pub fn figures(&mut self, counters: CycleCounters, fresh: bool) -> CycleFigures {
        let new = self.drain();
        let stale = self
            .summaries
            .is_none_or(|(at, _)| new && at.elapsed() >= SUMMARY_EVERY);
        if fresh || stale {
            let s = [
                self.wake.summary(),
                self.compute.summary(),
                self.round_trip.summary(),
            ];
            self.summaries = Some((Instant::now(), s));
        }
        let [wake, compute, round_trip] = self.summaries.map(|(_, s)| s).unwrap_or_default();
        CycleFigures {
            wake,
            compute,
            round_trip,
            ..CycleFigures::from_counters(counters)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wake(latency_ns: u64, overrun: bool) -> Wake {
        Wake {
            deadline_ns: 0,
            reply_by_ns: 0,
            latency_ns,
            overrun,
            period_ns: 1_000_000,
        }
    }

    #[test]
    fn the_cycle_counts_and_the_application_computes_the_percentiles() {
        let (mut stats, rx) = CycleStats::new();
        let mut book = FigureBook::new(rx);
        for us in 1..=1000u64 {
            stats.record(wake(us * 1000 - 500, false), 2_000, 100_000);
        }
        assert_eq!(stats.record(wake(0, true), 2_000, 100_000), 1);
        assert_eq!(stats.record(wake(0, true), 2_000, 100_000), 2);
        stats.record(wake(10, false), 2_000, 100_000);
        let f = book.figures(stats.counters(), true);
        assert_eq!(f.cycles, 1003);
        assert_eq!((f.overruns, f.worst_overrun_run), (2, 2));
        assert_eq!(f.wake.count, 1003);
        assert_eq!(f.wake.p50_us, 499.0);
        assert_eq!(f.compute.p99_us, 2.0);
        assert_eq!(f.round_trip.max_us, 100.0);
        assert_eq!(f.samples_dropped, 0);
    }

    #[test]
    fn a_full_queue_drops_samples_and_says_so() {
        let (mut stats, rx) = CycleStats::new();
        for _ in 0..SAMPLE_QUEUE + 5 {
            stats.record(wake(1000, false), 0, 0);
        }
        let mut book = FigureBook::new(rx);
        let f = book.figures(stats.counters(), true);
        assert_eq!(f.samples_dropped, 5);
        assert_eq!(f.wake.count, SAMPLE_QUEUE as u64);
        assert_eq!(f.cycles, SAMPLE_QUEUE as u64 + 5);
    }
}
