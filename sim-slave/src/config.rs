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
//! dc_drift_ppm = 30       # its distributed clock runs 30 ppm fast (default 0)
//!
//! [slave.al]              # its firmware's AL transition times (defaults 2, 10, 5 ms)
//! init_to_preop_ms = 2
//! preop_to_safeop_ms = 10
//! safeop_to_op_ms = 5
//!
//! [[slave]]
//! kind = "encoder"        # an incremental encoder module (like an EL5101), no CoE
//! counts_per_rev = 4096   # counts per shaft revolution
//! shaft_speed = 0.5       # rev/s the shaft turns by itself (default 0: it stands)
//!
//! [[slave]]
//! kind = "switches"       # 8 digital inputs (like an EL1008) read from switch cams
//! axis = 0                # chain index of the servo whose position moves the cams
//!
//! [[slave.cam]]           # a reference switch: input 0 high from 10000 to 12000 counts
//! input = 0
//! from = 10000
//! to = 12000
//!
//! [[slave.cam]]           # a positive limit switch, normally closed: input 1 drops
//! input = 1               # from 500000 counts on
//! from = 500000
//! to = 9223372036854775807
//! normally_closed = true
//! ```

use serde::Deserialize;
use thiserror::Error;

use crate::catalog::{self, EncoderOptions, ServoOptions, SwitchesOptions};
use crate::chain::SlaveChain;
use crate::esc::al::{Firmware, TransitionTimes};
use crate::plant::switches::{check_cams, CamError, SwitchCam};

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
        /// The motor's hidden commutation offset (counts), for commissioning to find.
        #[serde(default)]
        commutation_offset: i32,
        /// How fast its distributed clock's oscillator runs against true time (ppm;
        /// negative: slow). A real quartz is off by tens of ppm: the first DC slave's is
        /// the network's reference, which the master's cycle has to follow.
        #[serde(default)]
        dc_drift_ppm: f64,
        /// How long its firmware takes for each AL transition (`[slave.al]`).
        #[serde(default)]
        al: AlConfig,
    },
    /// An incremental encoder module.
    Encoder {
        /// Counts per shaft revolution.
        #[serde(default = "default_counts_per_rev")]
        counts_per_rev: u32,
        /// Speed at which the shaft turns by itself (rev/s).
        #[serde(default)]
        shaft_speed: f64,
        /// How long its firmware takes for each AL transition (`[slave.al]`).
        #[serde(default)]
        al: AlConfig,
    },
    /// A digital-input module whose inputs are switch cams on a servo's travel.
    Switches {
        /// Chain index of the servo.
        axis: usize,
        /// The cams (`[[slave.cam]]`).
        #[serde(rename = "cam", default)]
        cams: Vec<CamConfig>,
    },
}

/// One switch cam of a `switches` slave: the switch on `input` is actuated while the
/// servo's position actual value is in `from..=to` (counts).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct CamConfig {
    /// Input bit (0…7).
    pub input: u8,
    /// First actuated position (counts).
    pub from: i64,
    /// Last actuated position (counts).
    pub to: i64,
    /// A normally closed contact (limit switches).
    #[serde(default)]
    pub normally_closed: bool,
}

impl From<CamConfig> for SwitchCam {
    fn from(c: CamConfig) -> Self {
        SwitchCam {
            input: c.input,
            from: c.from,
            to: c.to,
            normally_closed: c.normally_closed,
        }
    }
}

fn default_counts_per_rev() -> u32 {
    4096
}

// AL transition times (`[slave.al]`).

/// How long a device's firmware takes for each upward AL transition (ms); what is not
/// given keeps the device's default (a servo: 2, 10 and 5 ms; an encoder module: 0). A
/// digital-input module has no firmware: its ESC mirrors AL control at once.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AlConfig {
    /// Init → PreOp.
    pub init_to_preop_ms: Option<f64>,
    /// PreOp → SafeOp.
    pub preop_to_safeop_ms: Option<f64>,
    /// SafeOp → Op.
    pub safeop_to_op_ms: Option<f64>,
}

/// Longest AL transition time accepted (ms): beyond, a master's state-transition timeout
/// (ethercrab: 5 s) has long given up.
const MAX_AL_TRANSITION_MS: f64 = 10_000.0;

impl AlConfig {
    /// The times, with `defaults` for what is not given.
    pub fn times(&self, defaults: TransitionTimes) -> TransitionTimes {
        let ns = |ms: Option<f64>, default: u64| ms.map_or(default, |ms| (ms * 1e6).round() as u64);
        TransitionTimes {
            init_to_preop_ns: ns(self.init_to_preop_ms, defaults.init_to_preop_ns),
            preop_to_safeop_ns: ns(self.preop_to_safeop_ms, defaults.preop_to_safeop_ns),
            safeop_to_op_ns: ns(self.safeop_to_op_ms, defaults.safeop_to_op_ns),
        }
    }

    /// The first key out of range, as `al.<key>`.
    fn invalid_key(&self) -> Option<&'static str> {
        [
            ("al.init_to_preop_ms", self.init_to_preop_ms),
            ("al.preop_to_safeop_ms", self.preop_to_safeop_ms),
            ("al.safeop_to_op_ms", self.safeop_to_op_ms),
        ]
        .into_iter()
        .find(|(_, v)| {
            v.is_some_and(|v| !(v.is_finite() && (0.0..=MAX_AL_TRANSITION_MS).contains(&v)))
        })
        .map(|(k, _)| k)
    }
}

/// Largest oscillator error of a simulated DC clock (ppm); real ones are within ±100.
const MAX_DC_DRIFT_PPM: f64 = 1000.0;

/// Highest shaft speed of an encoder (rev/s).
const MAX_SHAFT_SPEED: f64 = 1000.0;

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
                SlaveConfig::Servo {
                    bandwidth_hz,
                    dc_drift_ppm,
                    al,
                    ..
                } => {
                    if let Some(key) = al.invalid_key() {
                        return Err(invalid(
                            format!("slave[{i}].{key}"),
                            "must be 0 to 10000 ms",
                        ));
                    }
                    if !(bandwidth_hz.is_finite() && *bandwidth_hz > 0.0 && *bandwidth_hz <= 5000.0)
                    {
                        return Err(invalid(
                            format!("slave[{i}].bandwidth_hz"),
                            "must be above 0 and at most 5000 Hz",
                        ));
                    }
                    if !(dc_drift_ppm.is_finite() && dc_drift_ppm.abs() <= MAX_DC_DRIFT_PPM) {
                        return Err(invalid(
                            format!("slave[{i}].dc_drift_ppm"),
                            "must be -1000 to 1000 ppm",
                        ));
                    }
                }
                SlaveConfig::Encoder {
                    counts_per_rev,
                    shaft_speed,
                    al,
                } => {
                    if let Some(key) = al.invalid_key() {
                        return Err(invalid(
                            format!("slave[{i}].{key}"),
                            "must be 0 to 10000 ms",
                        ));
                    }
                    if *counts_per_rev == 0 {
                        return Err(invalid(
                            format!("slave[{i}].counts_per_rev"),
                            "must be at least 1",
                        ));
                    }
                    if !(shaft_speed.is_finite() && shaft_speed.abs() <= MAX_SHAFT_SPEED) {
                        return Err(invalid(
                            format!("slave[{i}].shaft_speed"),
                            "must be -1000 to 1000 rev/s",
                        ));
                    }
                }
                SlaveConfig::Switches { axis, cams } => {
                    match self.slaves.get(*axis) {
                        None => {
                            let n = self.slaves.len();
                            return Err(invalid(
                                format!("slave[{i}].axis"),
                                &format!("there is no slave {axis} (the chain has {n})"),
                            ));
                        }
                        Some(SlaveConfig::Servo { .. }) => {}
                        Some(_) => {
                            return Err(invalid(
                                format!("slave[{i}].axis"),
                                &format!("slave {axis} is not a servo"),
                            ));
                        }
                    }
                    let cams: Vec<SwitchCam> = cams.iter().map(|&c| c.into()).collect();
                    if let Err(e) = check_cams(&cams) {
                        let (cam, field, reason) = match e {
                            CamError::NoSuchInput { cam, .. } => {
                                (cam, "input", "must be 0 to 7".to_string())
                            }
                            CamError::EmptyRange { cam, from, to } => {
                                (cam, "from", format!("{from} is above to = {to}"))
                            }
                            CamError::InputTaken { cam, input, first } => (
                                cam,
                                "input",
                                format!("input {input} already has cam {first}"),
                            ),
                        };
                        return Err(invalid(format!("slave[{i}].cam[{cam}].{field}"), &reason));
                    }
                }
            }
        }
        Ok(())
    }

    /// The chain this configuration describes. Only a configuration built by hand, not
    /// one [`SimConfig::parse`] checked, can have cams that cannot be wired.
    pub fn chain(&self) -> Result<SlaveChain, CamError> {
        let slaves = self
            .slaves
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let serial = i as u32 + 1;
                Ok(match s {
                    SlaveConfig::Servo {
                        start_position,
                        bandwidth_hz,
                        commutation_offset,
                        dc_drift_ppm,
                        al,
                    } => catalog::servo(ServoOptions {
                        serial,
                        start_counts: *start_position,
                        bandwidth_hz: *bandwidth_hz,
                        commutation_offset: *commutation_offset,
                        firmware: Firmware {
                            times: al.times(TransitionTimes::SERVO),
                            ..Firmware::SERVO
                        },
                    })
                    .with_dc_drift_ppm(*dc_drift_ppm),
                    SlaveConfig::Encoder {
                        counts_per_rev,
                        shaft_speed,
                        al,
                    } => catalog::encoder(EncoderOptions {
                        serial,
                        counts_per_rev: *counts_per_rev,
                        shaft_speed_rev_s: *shaft_speed,
                    })
                    .with_firmware(Firmware {
                        times: al.times(TransitionTimes::INSTANT),
                        ..Firmware::SIMPLE
                    }),
                    SlaveConfig::Switches { axis, cams } => catalog::switches(SwitchesOptions {
                        serial,
                        axis: *axis,
                        cams: cams.iter().map(|&c| c.into()).collect(),
                    })?,
                })
            })
            .collect::<Result<Vec<_>, CamError>>()?;
        Ok(SlaveChain::new(slaves))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::DeviceModel;

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
                bandwidth_hz: 200.0,
                commutation_offset: 0,
                dc_drift_ppm: 0.0,
                al: AlConfig::default(),
            }
        );
        let chain = c.chain().unwrap();
        assert_eq!(chain.slaves().len(), 2);
        assert_eq!(chain.slaves()[0].firmware().times, TransitionTimes::SERVO);
    }

    #[test]
    fn al_transition_times_are_per_device_with_defaults() {
        let c = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\n[slave.al]\nsafeop_to_op_ms = 20\ninit_to_preop_ms = 0\n\
             [[slave]]\nkind = \"encoder\"\n[slave.al]\npreop_to_safeop_ms = 1.5\n\
             [[slave]]\nkind = \"servo\"\n",
            "sim.toml",
        )
        .unwrap();
        let chain = c.chain().unwrap();
        let times = |i: usize| chain.slaves()[i].firmware().times;
        assert_eq!(
            times(0),
            TransitionTimes {
                init_to_preop_ns: 0,
                preop_to_safeop_ns: 10_000_000,
                safeop_to_op_ns: 20_000_000,
            }
        );
        assert_eq!(
            times(1),
            TransitionTimes {
                preop_to_safeop_ns: 1_500_000,
                ..TransitionTimes::INSTANT
            }
        );
        assert_eq!(times(2), TransitionTimes::SERVO);
        assert!(chain.slaves()[0].firmware().op_needs_outputs);
        assert!(!chain.slaves()[1].firmware().op_needs_outputs);
        let e = |text: &str| SimConfig::parse(text, "sim.toml").unwrap_err().to_string();
        assert_eq!(
            e("[[slave]]\nkind = \"servo\"\n[slave.al]\nsafeop_to_op_ms = -1\n"),
            "sim.toml: slave[0].al.safeop_to_op_ms: must be 0 to 10000 ms"
        );
        let unknown = e("[[slave]]\nkind = \"servo\"\n[slave.al]\nsafeop_op_ms = 1\n");
        assert!(unknown.contains("safeop_op_ms"), "{unknown}");
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
            e("[[slave]]\nkind = \"servo\"\ndc_drift_ppm = 5000\n"),
            "sim.toml: slave[0].dc_drift_ppm: must be -1000 to 1000 ppm"
        );
        assert_eq!(
            e("cycle_us = 1000\n"),
            "sim.toml: slave: the chain has no slave"
        );
    }

    #[test]
    fn the_example_in_the_module_doc_parses() {
        let source = include_str!("config.rs");
        let example: String = source
            .lines()
            .skip_while(|l| !l.starts_with("//! ```toml"))
            .skip(1)
            .take_while(|l| !l.starts_with("//! ```"))
            .map(|l| format!("{}\n", l.trim_start_matches("//!").trim_start_matches(' ')))
            .collect();
        let c = SimConfig::parse(&example, "doc").unwrap();
        assert_eq!(c.slaves.len(), 3);
        assert_eq!(c.chain().unwrap().slaves().len(), 3);
    }

    #[test]
    fn parses_encoder_and_switches_with_cams() {
        let c = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\n\
             [[slave]]\nkind = \"encoder\"\ncounts_per_rev = 1024\nshaft_speed = -2.5\n\
             [[slave]]\nkind = \"switches\"\naxis = 0\n\
             [[slave.cam]]\ninput = 3\nfrom = -10\nto = 10\n\
             [[slave.cam]]\ninput = 4\nfrom = 100\nto = 200\nnormally_closed = true\n\
             [[slave]]\nkind = \"encoder\"\n",
            "sim.toml",
        )
        .unwrap();
        assert_eq!(
            c.slaves[1],
            SlaveConfig::Encoder {
                counts_per_rev: 1024,
                shaft_speed: -2.5,
                al: AlConfig::default(),
            }
        );
        assert_eq!(
            c.slaves[3],
            SlaveConfig::Encoder {
                counts_per_rev: 4096,
                shaft_speed: 0.0,
                al: AlConfig::default(),
            }
        );
        let SlaveConfig::Switches { axis, cams } = &c.slaves[2] else {
            panic!("{:?}", c.slaves[2]);
        };
        assert_eq!(*axis, 0);
        assert_eq!(
            cams[1],
            CamConfig {
                input: 4,
                from: 100,
                to: 200,
                normally_closed: true
            }
        );
        assert!(!cams[0].normally_closed);
        let chain = c.chain().unwrap();
        let d = |i: usize| chain.slaves()[i].device();
        assert!(
            matches!(d(1), DeviceModel::Encoder(e) if e.counts_per_rev == 1024 && e.shaft_speed_rev_s == -2.5)
        );
        assert!(matches!(d(2), DeviceModel::Switches(s) if s.axis == 0 && s.cams().len() == 2));
        assert_eq!(
            chain.slaves()[2].description().product_code,
            catalog::SWITCHES_PRODUCT
        );
    }

    #[test]
    fn encoder_and_switches_mistakes_name_the_key() {
        let e = |text: &str| SimConfig::parse(text, "sim.toml").unwrap_err().to_string();
        let servo = "[[slave]]\nkind = \"servo\"\n";
        let encoder = "[[slave]]\nkind = \"encoder\"\n";
        let switches = |axis: usize| format!("[[slave]]\nkind = \"switches\"\naxis = {axis}\n");
        let cam = |input: u8, from: i64, to: i64| {
            format!("[[slave.cam]]\ninput = {input}\nfrom = {from}\nto = {to}\n")
        };
        assert_eq!(
            e(&format!("{servo}{encoder}{}", switches(1))),
            "sim.toml: slave[2].axis: slave 1 is not a servo"
        );
        assert_eq!(
            e(&format!("{servo}{}", switches(5))),
            "sim.toml: slave[1].axis: there is no slave 5 (the chain has 2)"
        );
        assert_eq!(
            e(&format!("{servo}{}{}", switches(0), cam(8, 0, 1))),
            "sim.toml: slave[1].cam[0].input: must be 0 to 7"
        );
        assert_eq!(
            e(&format!(
                "{servo}{}{}{}",
                switches(0),
                cam(0, 0, 1),
                cam(1, 9, 2)
            )),
            "sim.toml: slave[1].cam[1].from: 9 is above to = 2"
        );
        assert_eq!(
            e(&format!(
                "{servo}{}{}{}",
                switches(0),
                cam(2, 0, 1),
                cam(2, 5, 6)
            )),
            "sim.toml: slave[1].cam[1].input: input 2 already has cam 0"
        );
        assert_eq!(
            e(&format!("{encoder}counts_per_rev = 0\n")),
            "sim.toml: slave[0].counts_per_rev: must be at least 1"
        );
        assert_eq!(
            e(&format!("{encoder}shaft_speed = 1e9\n")),
            "sim.toml: slave[0].shaft_speed: must be -1000 to 1000 rev/s"
        );
        // Serde's own checks: a missing axis, an unknown key in a cam (with its line).
        let missing = e(&format!("{servo}[[slave]]\nkind = \"switches\"\n"));
        assert!(missing.contains("axis"), "{missing}");
        let unknown = e(&format!(
            "{servo}{}[[slave.cam]]\ninput = 0\nfrom = 1\nto = 2\nclosed = true\n",
            switches(0)
        ));
        assert!(unknown.starts_with("sim.toml:10:"), "{unknown}");
        assert!(unknown.contains("closed"), "{unknown}");
    }
}
