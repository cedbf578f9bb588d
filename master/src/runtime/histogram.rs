//! A fixed histogram of durations in 1 µs buckets: recording never allocates, so the RT
//! thread can keep one per figure (wake-up latency, compute, bus round trip).

/// Summary of a histogram, in µs.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Samples.
    pub count: u64,
    /// Median.
    pub p50_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// 99.9th percentile.
    pub p999_us: f64,
    /// Largest sample.
    pub max_us: f64,
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "p50 {:.0} µs, p99 {:.0} µs, p99.9 {:.0} µs, max {:.0} µs ({} samples)",
            self.p50_us, self.p99_us, self.p999_us, self.max_us, self.count
        )
    }
}

/// Durations up to `buckets` µs in 1 µs steps; longer ones land in the last bucket
/// (their exact maximum is kept).
#[derive(Clone, Debug)]
pub struct Histogram {
    counts: Vec<u64>,
    count: u64,
    max_ns: u64,
}

impl Histogram {
    /// A histogram of 1 µs buckets up to `max_us`.
    pub fn new(max_us: usize) -> Self {
        Self {
            counts: vec![0; max_us.max(1)],
            count: 0,
            max_ns: 0,
        }
    }

    /// Records one duration.
    pub fn record(&mut self, ns: u64) {
        let last = self.counts.len() - 1;
        let bucket = ((ns / 1000) as usize).min(last);
        if let Some(c) = self.counts.get_mut(bucket) {
            *c += 1;
        }
        self.count += 1;
        self.max_ns = self.max_ns.max(ns);
    }

    /// The `q` quantile (0..=1) in µs: the upper edge of its bucket, capped at the max.
    pub fn quantile_us(&self, q: f64) -> f64 {
        if self.count == 0 {
            return 0.0;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.count as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return ((i + 1) as f64).min(self.max_ns as f64 / 1000.0);
            }
        }
        self.max_ns as f64 / 1000.0
    }

    /// p50, p99, p99.9 and max.
    pub fn summary(&self) -> Summary {
        Summary {
            count: self.count,
            p50_us: self.quantile_us(0.5),
            p99_us: self.quantile_us(0.99),
            p999_us: self.quantile_us(0.999),
            max_us: self.max_ns as f64 / 1000.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_a_known_distribution() {
        let mut h = Histogram::new(1000);
        for us in 1..=1000u64 {
            h.record(us * 1000 - 500);
        }
        h.record(5_000_000); // 5 ms: beyond the range, kept as max
        let s = h.summary();
        assert_eq!(s.count, 1001);
        assert_eq!(s.p50_us, 501.0);
        assert_eq!(s.p99_us, 991.0);
        assert_eq!(s.max_us, 5000.0);
        assert_eq!(Histogram::new(10).summary(), Summary::default());
    }
}
