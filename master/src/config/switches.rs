//! `[axis.switches]`: where an axis' limit and reference switches come from, and whether
//! its drive's touch probe latches the reference edges and the index pulse.
//!
//! ```toml
//! [axis.switches]
//! negative_limit = "drive"                                  # 0x60FD bit 0
//! positive_limit = { from = "drive", normally_closed = true }
//! reference = "drive"                                       # 0x60FD bit 2
//! touch_probe = true                                        # default: with a reference
//! probe_source = { negative_limit = -1, positive_limit = -2 }  # the drive's 0x60D0 values
//! ```
//!
//! `probe_source` gives the drive's touch-probe source values (0x60D0, ETG.6010) that put
//! a probe on its negative and positive limit switch inputs — manufacturer-specific (the
//! standard's 1–4 are the probe inputs, 5/6 the zero impulse; drives use negative values
//! for their other inputs): see the drive's manual. The bring-up writes them to 0x60D0:1
//! and :2 and maps 0x60BD as well; MoveHome on a limit switch's edge then latches that
//! switch (probe 1 for the negative, probe 2 for the positive one). Without it that
//! MoveHome is refused.
//!
//! A drive reports each switch function active in 0x60FD (CiA 402: 1 = active) once it is
//! set up for its contacts; `normally_closed` is for a drive that reports the contact's
//! level instead. Switches on an I/O module of the bus are not read yet.

use gantry_drives::cia402::objects::{self, digital_inputs};
use gantry_drives::cia402::pdo::{PdoLayout, SdoWrite};
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
    /// The drive's 0x60D0 values for its limit switch inputs.
    pub probe_source: Option<ProbeSource>,
}

/// `probe_source = { negative_limit = N, positive_limit = P }`: the values of 0x60D0 that
/// select the drive's negative and positive limit switch inputs as a touch probe's source.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ProbeSource {
    /// For 0x60D0:1 (probe 1).
    pub negative_limit: i16,
    /// For 0x60D0:2 (probe 2).
    pub positive_limit: i16,
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

    /// The checked `probe_source`: the probe mapped, both limit switches the drive's,
    /// two different values, neither 0 (reserved in ETG.6010).
    pub fn probe_source(&self) -> Result<Option<ProbeSource>, (String, String)> {
        let Some(p) = self.probe_source else {
            return Ok(None);
        };
        let err = |why: &str| Err(("switches.probe_source".to_string(), why.to_string()));
        if !self.touch_probe() {
            return err("needs the touch probe (a reference switch, or touch_probe = true)");
        }
        if self.negative_limit.is_none() || self.positive_limit.is_none() {
            return err("needs negative_limit and positive_limit from the drive");
        }
        if p.negative_limit == 0 || p.positive_limit == 0 {
            return err("0 is reserved in 0x60D0 (ETG.6010); give the drive's values");
        }
        if p.negative_limit == p.positive_limit {
            return err("negative_limit and positive_limit name the same source");
        }
        Ok(Some(p))
    }

    /// The SDO downloads of the bring-up the switches need: 0x60D0:1 and :2 when
    /// `probe_source` is given.
    pub fn sdo_writes(&self) -> Result<Vec<SdoWrite>, (String, String)> {
        Ok(self
            .probe_source()?
            .map(|p| {
                [
                    (objects::TOUCH_PROBE_1_SOURCE, p.negative_limit),
                    (objects::TOUCH_PROBE_2_SOURCE, p.positive_limit),
                ]
                .map(|(o, v)| SdoWrite {
                    index: o.index,
                    sub: o.sub,
                    value: v.to_le_bytes().to_vec(),
                })
                .to_vec()
            })
            .unwrap_or_default())
    }

    /// `layout` with what the switches and the probe need: 0x60FD in the inputs; 0x60B8
    /// in the outputs and 0x60B9, 0x60BA, 0x60BB, 0x60BC in the inputs; 0x60BD too with
    /// `probe_source` (probe 2's negative edge, on the positive limit switch).
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
        if self.probe_source()?.is_some() {
            layout.inputs.push(objects::TOUCH_PROBE_POS2_NEG_VALUE);
        }
        Ok(())
    }
}
