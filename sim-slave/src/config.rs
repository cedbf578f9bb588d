//! The simulator's configuration: a TOML file that lists the chain, in wiring order.
//!
//! ```toml
//! # How often the devices' applications run (µs), in real time.
//! cycle_us = 1000
//!
//! [[slave]]
//! kind = "servo"          # a CiA-402 servo drive (CoE, CSP)
//! start_position = 0      # absolute encoder value at power-up, counts
//! bandwidth_hz = 200      # position loop bandwidth
//! ```

use serde::Deserialize;
use thiserror::Error;

use crate::catalog::{self, ServoOptions};
use crate::chain::SlaveChain;

/// A configuration that cannot be used, with where and why.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The TOML is malformed, has an unknown key or a value of the wrong type.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// 1-based line of the offending key or value.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A value is out of its range.
    #[error("{path}: {key}: {reason}")]
    Invalid {
        /// The file.
        path: String,
        /// The key, e.g. `slave[2].bandwidth_hz`.
        key: String,
        /// What is wrong.
        reason: String,
    },
}

/// The simulator's configuration.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// Period of the devices' applications (µs).
    #[serde(default = "default_cycle_us")]
    pub cycle_us: u32,
    /// The slaves, in wiring order.
    #[serde(rename = "slave", default)]
    pub slaves: Vec<SlaveConfig>,
}

fn default_cycle_us() -> u32 {
    1000
}

/// One slave of the chain.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum SlaveConfig {
    /// A CiA-402 servo drive.
    Servo {
        /// Absolute encoder value at power-up (counts).
        #[serde(default)]
        start_position: i32,
        /// Position loop bandwidth (Hz).
        #[serde(default = "default_bandwidth_hz")]
        bandwidth_hz: f64,
    },
}

fn default_bandwidth_hz() -> f64 {
    200.0
}

/// The line an error points at. For an unknown key inside a tagged table, TOML's span
/// covers the whole table; the line of the key itself is what the user needs.
fn error_line(text: &str, e: &toml::de::Error) -> usize {
    let start = e.span().map_or(0, |s| s.start);
    let line_of = |offset: usize| text.get(..offset).unwrap_or("").lines().count().max(1);
    let unknown = e
        .message()
        .strip_prefix("unknown field `")
        .and_then(|m| m.split('`').next());
    if let Some(key) = unknown {
        let mut offset = start;
        for line in text.get(start..).unwrap_or("").split_inclusive('\n') {
            let rest = line.trim_start().strip_prefix(key).unwrap_or("#");
            if rest.trim_start().starts_with('=') {
                return line_of(offset + 1);
            }
            offset += line.len();
        }
    }
    line_of(start)
}

impl SimConfig {
    /// Reads and checks `path`.
    pub fn load(path: &str) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.into(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses and checks `text`; `path` names it in errors.
    pub fn parse(text: &str, path: &str) -> Result<Self, ConfigError> {
        let config: SimConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.into(),
            line: error_line(text, &e),
            message: e.message().to_string(),
        })?;
        config.check(path)?;
        Ok(config)
    }

    fn check(&self, path: &str) -> Result<(), ConfigError> {
        let invalid = |key: String, reason: &str| ConfigError::Invalid {
            path: path.into(),
            key,
            reason: reason.into(),
        };
        if !(100..=100_000).contains(&self.cycle_us) {
            return Err(invalid("cycle_us".into(), "must be 100 to 100000 µs"));
        }
        if self.slaves.is_empty() {
            return Err(invalid("slave".into(), "the chain has no slave"));
        }
        for (i, s) in self.slaves.iter().enumerate() {
            match s {
                SlaveConfig::Servo { bandwidth_hz, .. } => {
                    if !(bandwidth_hz.is_finite() && *bandwidth_hz > 0.0 && *bandwidth_hz <= 5000.0)
                    {
                        return Err(invalid(
                            format!("slave[{i}].bandwidth_hz"),
                            "must be above 0 and at most 5000 Hz",
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// The chain this configuration describes.
    pub fn chain(&self) -> SlaveChain {
        SlaveChain::new(
            self.slaves
                .iter()
                .enumerate()
                .map(|(i, s)| match *s {
                    SlaveConfig::Servo {
                        start_position,
                        bandwidth_hz,
                    } => catalog::servo(ServoOptions {
                        serial: i as u32 + 1,
                        start_counts: start_position,
                        bandwidth_hz,
                    }),
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_a_chain_with_defaults() {
        let c = SimConfig::parse(
            "cycle_us = 500\n[[slave]]\nkind = \"servo\"\n[[slave]]\nkind = \"servo\"\nstart_position = -7\n",
            "sim.toml",
        )
        .unwrap();
        assert_eq!(c.cycle_us, 500);
        assert_eq!(
            c.slaves[1],
            SlaveConfig::Servo {
                start_position: -7,
                bandwidth_hz: 200.0
            }
        );
        assert_eq!(c.chain().slaves().len(), 2);
    }

    #[test]
    fn mistakes_name_file_line_and_key() {
        let e = |text: &str| SimConfig::parse(text, "sim.toml").unwrap_err().to_string();
        let unknown = e("[[slave]]\nkind = \"servo\"\nbandwith_hz = 3\n");
        assert!(unknown.starts_with("sim.toml:3:"), "{unknown}");
        assert!(unknown.contains("bandwith_hz"), "{unknown}");
        let kind = e("[[slave]]\nkind = \"robot\"\n");
        assert!(
            kind.starts_with("sim.toml:1:") || kind.starts_with("sim.toml:2:"),
            "{kind}"
        );
        assert!(kind.contains("robot"), "{kind}");
        let ty = e("cycle_us = \"fast\"\n[[slave]]\nkind = \"servo\"\n");
        assert!(ty.starts_with("sim.toml:1:"), "{ty}");
        assert_eq!(
            e("[[slave]]\nkind = \"servo\"\nbandwidth_hz = -1\n"),
            "sim.toml: slave[0].bandwidth_hz: must be above 0 and at most 5000 Hz"
        );
        assert_eq!(
            e("cycle_us = 1000\n"),
            "sim.toml: slave: the chain has no slave"
        );
    }
}
