//! What each cycle records: wake-up latency, compute time, bus round trip and overruns,
//! with the overrun policy (count, then stop the axes after N in a row).

use super::clock::Wake;
use super::histogram::{Histogram, Summary};

/// The figures a snapshot carries (`Copy`: published without allocating).
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
}

/// Histograms and counters of the cycle.
#[derive(Clone, Debug)]
pub struct CycleStats {
    wake: Histogram,
    compute: Histogram,
    round_trip: Histogram,
    cycles: u64,
    overruns: u64,
    in_a_row: u32,
    worst: u32,
}

impl Default for CycleStats {
    fn default() -> Self {
        Self {
            wake: Histogram::new(10_000),
            compute: Histogram::new(10_000),
            round_trip: Histogram::new(10_000),
            cycles: 0,
            overruns: 0,
            in_a_row: 0,
            worst: 0,
        }
    }
}

impl CycleStats {
    /// Records one cycle; returns the overruns in a row so far.
    pub fn record(&mut self, wake: Wake, compute_ns: u64, round_trip_ns: u64) -> u32 {
        self.cycles += 1;
        self.wake.record(wake.latency_ns);
        self.compute.record(compute_ns);
        self.round_trip.record(round_trip_ns);
        if wake.overrun {
            self.overruns += 1;
            self.in_a_row += 1;
            self.worst = self.worst.max(self.in_a_row);
        } else {
            self.in_a_row = 0;
        }
        self.in_a_row
    }

    /// The figures so far.
    pub fn figures(&self) -> CycleFigures {
        CycleFigures {
            cycles: self.cycles,
            wake: self.wake.summary(),
            compute: self.compute.summary(),
            round_trip: self.round_trip.summary(),
            overruns: self.overruns,
            worst_overrun_run: self.worst,
        }
    }
}
