//! A trace of named channels sampled over time (set/actual values per axis), kept in
//! memory and written as CSV.

use std::io::Write;
use std::path::Path;

use thiserror::Error;

/// Errors of recording or writing a trace.
#[derive(Debug, Error)]
pub enum TraceError {
    /// A sample had the wrong number of values.
    #[error("trace sample has {got} values, the trace has {expected} channels")]
    Width {
        /// Channels of the trace.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// Writing the file failed.
    #[error("cannot write trace file {path}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

/// Samples of named channels over time.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    channels: Vec<String>,
    times: Vec<f64>,
    values: Vec<f64>,
}

impl Trace {
    /// An empty trace with these channel names, room for `capacity` samples.
    pub fn new(channels: Vec<String>, capacity: usize) -> Self {
        Self {
            times: Vec::with_capacity(capacity),
            values: Vec::with_capacity(capacity * channels.len()),
            channels,
        }
    }

    /// Appends one sample at time `t_s`.
    pub fn push(&mut self, t_s: f64, values: &[f64]) -> Result<(), TraceError> {
        if values.len() != self.channels.len() {
            return Err(TraceError::Width {
                expected: self.channels.len(),
                got: values.len(),
            });
        }
        self.times.push(t_s);
        self.values.extend_from_slice(values);
        Ok(())
    }

    /// Channel names.
    pub fn channels(&self) -> &[String] {
        &self.channels
    }

    /// Sample times (s).
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Whether the trace has no samples.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The values of channel `c`, one per sample.
    pub fn column(&self, c: usize) -> impl Iterator<Item = f64> + '_ {
        let w = self.channels.len().max(1);
        self.values.iter().skip(c).step_by(w).copied()
    }

    /// Writes `time_s,<channels…>` and one line per sample.
    pub fn write_csv(&self, path: &Path) -> Result<(), TraceError> {
        let io = |source| TraceError::Io {
            path: path.display().to_string(),
            source,
        };
        let mut out = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
        write!(out, "time_s").map_err(io)?;
        for c in &self.channels {
            write!(out, ",{c}").map_err(io)?;
        }
        writeln!(out).map_err(io)?;
        let w = self.channels.len();
        for (i, t) in self.times.iter().enumerate() {
            write!(out, "{t}").map_err(io)?;
            for v in self.values.iter().skip(i * w).take(w) {
                write!(out, ",{v}").map_err(io)?;
            }
            writeln!(out).map_err(io)?;
        }
        out.flush().map_err(io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_round_trips_values() {
        let mut t = Trace::new(vec!["x.p".into(), "x.v".into()], 4);
        t.push(0.0, &[1.5, -2.0]).unwrap();
        t.push(0.001, &[1.25e-7, 3.0]).unwrap();
        assert!(t.push(0.002, &[1.0]).is_err());
        let dir = std::env::temp_dir().join(format!("gantry-trace-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        t.write_csv(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("time_s,x.p,x.v"));
        let row: Vec<f64> = lines
            .nth(1)
            .unwrap()
            .split(',')
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(row, vec![0.001, 1.25e-7, 3.0]);
        assert_eq!(t.column(1).collect::<Vec<_>>(), vec![-2.0, 3.0]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
