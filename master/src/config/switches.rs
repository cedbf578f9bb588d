//! `[axis.switches]`: where an axis' limit and reference switches come from, and whether
//! its drive's touch probe latches the reference edges and the index pulse.
//!
//! ```toml
//! [axis.switches]
//! negative_limit = "drive"                                  # 0x60FD bit 0
//! positive_limit = { from = "drive", normally_closed = true }
//! reference = "drive"                                       # 0x60FD bit 2
//! touch_probe = true                                        # default: with a reference
//! ```
//!
//! A drive reports each switch function active in 0x60FD (CiA 402: 1 = active) once it is
//! set up for its contacts; `normally_closed` is for a drive that reports the contact's
//! level instead. Switches on an I/O module of the bus are not read yet.

use gantry_drives::cia402::objects::{self, digital_inputs};
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::csp::probe::SwitchWiring;
use serde::Deserialize;

/// `[axis.switches]`.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct SwitchesSection {
    /// The negative hardware limit switch.
    pub negative_limit: Option<SwitchSource>,
    /// The positive hardware limit switch.
    pub positive_limit: Option<SwitchSource>,
    /// The reference (home) switch.
    pub reference: Option<SwitchSource>,
    /// Map the drive's touch probe (0x60B8–0x60BC) so that homing takes the reference
    /// edges and the index pulse from its latches. Default: on when the reference switch
    /// is the drive's.
    pub touch_probe: Option<bool>,
}

/// Where one switch is read.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum SwitchSource {
    /// `"drive"`: its bit of the drive's 0x60FD.
    Named(String),
    /// `{ from = "drive", normally_closed = true }`.
    Wired {
        /// `"drive"`.
        from: String,
        /// The drive reports the contact's level and the contact opens when actuated.
        #[serde(default)]
        normally_closed: bool,
    },
}

impl SwitchSource {
    fn resolve(&self, key: &str) -> Result<bool, (String, String)> {
        let (from, normally_closed) = match self {
            SwitchSource::Named(from) => (from, false),
            SwitchSource::Wired {
                from,
                normally_closed,
            } => (from, *normally_closed),
        };
        if from != "drive" {
            return Err((
                format!("switches.{key}"),
                format!(
                    "{from:?}: only \"drive\" (the drive's digital inputs 0x60FD) is read; \
                     switches on an I/O module are not supported yet"
                ),
            ));
        }
        Ok(normally_closed)
    }
}

impl SwitchesSection {
    /// Which 0x60FD bits are switches and which read inverted.
    pub fn wiring(&self) -> Result<SwitchWiring, (String, String)> {
        let mut w = SwitchWiring::default();
        for (key, source, bit) in [
            (
                "negative_limit",
                &self.negative_limit,
                digital_inputs::NEGATIVE_LIMIT,
            ),
            (
                "positive_limit",
                &self.positive_limit,
                digital_inputs::POSITIVE_LIMIT,
            ),
            ("reference", &self.reference, digital_inputs::HOME_SWITCH),
        ] {
            if let Some(s) = source {
                w.used |= bit;
                if s.resolve(key)? {
                    w.inverted |= bit;
                }
            }
        }
        Ok(w)
    }

    /// Whether the touch probe is mapped.
    pub fn touch_probe(&self) -> bool {
        self.touch_probe.unwrap_or(self.reference.is_some())
    }

    /// `layout` with what the switches and the probe need: 0x60FD in the inputs; 0x60B8
    /// in the outputs and 0x60B9, 0x60BA, 0x60BB, 0x60BC in the inputs.
    pub fn extend(&self, layout: &mut PdoLayout) -> Result<(), (String, String)> {
        if self.wiring()?.used != 0 {
            layout.inputs.push(objects::DIGITAL_INPUTS);
        }
        if self.touch_probe() {
            layout.outputs.push(objects::TOUCH_PROBE_FUNCTION);
            layout.inputs.extend([
                objects::TOUCH_PROBE_STATUS,
                objects::TOUCH_PROBE_POS1_POS_VALUE,
                objects::TOUCH_PROBE_POS1_NEG_VALUE,
                objects::TOUCH_PROBE_POS2_POS_VALUE,
            ]);
        }
        Ok(())
    }
}
