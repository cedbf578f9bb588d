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
//! level instead.
//!
//! A switch may also be an input of a digital-input module on the bus. On EtherCAT:
//! `{ from = "module", slave = 1, input = 2, normally_closed = true }` — the module at
//! chain position 1, its input bit 2 (bit n of its input process data). On CANopen:
//! `{ from = "module", node = 9, input = 2 }` — the CiA 401 digital-input node 9, its
//! input bit 2 (bit `input % 8` of 0x6000:`input / 8 + 1`, read input 8-bit), brought up
//! with the drives and read from its TPDO1 at every SYNC ([`ModuleNode`]). Either way the
//! input is read every cycle and routed to the axis. A module input is a level sampled
//! once a cycle: the drive's touch probe cannot latch it, so homing runs that need the
//! reference switch's edge are refused for a module reference switch (the kernel's
//! `reference_edges_latched`).

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
    /// `{ from = "drive", normally_closed = true }`,
    /// `{ from = "module", slave = 1, input = 2, normally_closed = true }` (EtherCAT) or
    /// `{ from = "module", node = 9, input = 2 }` (CANopen).
    Wired {
        /// `"drive"` or `"module"`.
        from: String,
        /// The module's position on the bus (`"module"` on EtherCAT only).
        #[serde(default)]
        slave: Option<usize>,
        /// The module's CANopen node id (`"module"` on CANopen only).
        #[serde(default)]
        node: Option<u8>,
        /// The CANopen module's position on the bus (after the axes' drives), given by
        /// the configuration's check ([`SwitchesSection::place_modules`]).
        #[serde(skip)]
        position: Option<usize>,
        /// The module's input (bit of its input process data; `"module"` only).
        #[serde(default)]
        input: Option<u8>,
        /// The contact opens when actuated (the drive reports the contact's level; a
        /// module input always reads the level).
        #[serde(default)]
        normally_closed: bool,
    },
}

/// A switch read from an input of an I/O module on the bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ModuleInput {
    /// The module's position on the bus.
    pub slave: usize,
    /// Its input: bit `input % 8` of byte `input / 8` of its input process data.
    pub input: u8,
    /// Active when the input is low (a normally closed contact).
    pub normally_closed: bool,
}

impl ModuleInput {
    /// Whether the switch is active in the module's input bytes; `None` when the input is
    /// not in them.
    pub fn active(&self, inputs: &[u8]) -> Option<bool> {
        let byte = inputs.get(usize::from(self.input / 8))?;
        Some(
            (byte >> (self.input % 8)) & 1 == 1 && !self.normally_closed
                || (byte >> (self.input % 8)) & 1 == 0 && self.normally_closed,
        )
    }
}

/// Where a switch is read, resolved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Source {
    /// The drive's 0x60FD bit; `true`: read inverted.
    Drive(bool),
    /// An I/O module's input.
    Module(ModuleInput),
}

impl SwitchSource {
    fn resolve(&self, key: &str) -> Result<Source, (String, String)> {
        let (from, slave, node, position, input, normally_closed) = match self {
            SwitchSource::Named(from) => (from, None, None, None, None, false),
            SwitchSource::Wired {
                from,
                slave,
                node,
                position,
                input,
                normally_closed,
            } => (from, *slave, *node, *position, *input, *normally_closed),
        };
        let err = |why: String| Err((format!("switches.{key}"), why));
        match (from.as_str(), slave, node, input) {
            ("drive", None, None, None) => Ok(Source::Drive(normally_closed)),
            ("drive", _, _, _) => err(
                "slave and input are for from = \"module\" (node and input on CANopen); \
                 the drive's switches are its 0x60FD bits"
                    .into(),
            ),
            ("module", Some(_), Some(_), _) => err(
                "slave (an EtherCAT chain position) or node (a CANopen node id), not both".into(),
            ),
            ("module", Some(slave), None, Some(input)) => Ok(Source::Module(ModuleInput {
                slave,
                input,
                normally_closed,
            })),
            ("module", None, Some(node), Some(input)) => match position {
                Some(slave) => Ok(Source::Module(ModuleInput {
                    slave,
                    input,
                    normally_closed,
                })),
                None => err(format!(
                    "node = {node} names a CANopen node; on EtherCAT a module is named by \
                     its chain position (slave = N)"
                )),
            },
            ("module", _, _, _) => err(
                "a module input needs its module and input: { from = \"module\", slave = N, \
                 input = K } on EtherCAT, { from = \"module\", node = N, input = K } on \
                 CANopen"
                    .into(),
            ),
            (other, _, _, _) => err(format!(
                "{other:?}: \"drive\" (the drive's digital inputs 0x60FD) or \"module\" \
                 (an input of an I/O module on the bus)"
            )),
        }
    }
}

/// Inputs of a CiA 401 module's TPDO1 at most: 8 groups of 8 (0x6000:01–08, one 8-byte
/// PDO).
pub const MODULE_NODE_INPUTS: u8 = 64;

/// A CANopen digital-input module (CiA 401) the switches of the axes read: brought up
/// with the drives, on its own bus position after theirs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ModuleNode {
    /// Its node id.
    pub node: u8,
    /// Its position on the bus (the cycle reads its inputs there).
    pub position: usize,
    /// The 8-bit input groups its TPDO1 carries (0x6000:01..=groups): enough for the
    /// highest input an axis reads.
    pub groups: u8,
    /// The axes that read it.
    pub axes: Vec<String>,
}

/// A CANopen module switch as written: the switch, the node and the input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeSwitch {
    /// `negative_limit`, `positive_limit` or `reference`.
    pub key: &'static str,
    /// `slave = N` was given (an EtherCAT chain position).
    pub slave: Option<usize>,
    /// `node = N`.
    pub node: Option<u8>,
    /// `input = K`.
    pub input: Option<u8>,
    /// The bus position a CANopen module was placed on
    /// ([`SwitchesSection::place_modules`]).
    pub position: Option<usize>,
}

impl SwitchesSection {
    /// The module switches as written (`from = "module"`), for the bus' own checks.
    pub fn module_switches(&self) -> Vec<NodeSwitch> {
        [
            ("negative_limit", &self.negative_limit),
            ("positive_limit", &self.positive_limit),
            ("reference", &self.reference),
        ]
        .into_iter()
        .filter_map(|(key, source)| match source {
            Some(SwitchSource::Wired {
                from,
                slave,
                node,
                input,
                position,
                ..
            }) if from == "module" => Some(NodeSwitch {
                key,
                slave: *slave,
                node: *node,
                input: *input,
                position: *position,
            }),
            _ => None,
        })
        .collect()
    }

    /// Places each CANopen module switch (`node = N`) on its module's bus position.
    pub fn place_modules(&mut self, position: impl Fn(u8) -> usize) {
        for source in [
            &mut self.negative_limit,
            &mut self.positive_limit,
            &mut self.reference,
        ]
        .into_iter()
        .flatten()
        {
            if let SwitchSource::Wired {
                from,
                node: Some(node),
                position: at,
                ..
            } = source
            {
                if from == "module" {
                    *at = Some(position(*node));
                }
            }
        }
    }

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
                if let Source::Drive(inverted) = s.resolve(key)? {
                    w.used |= bit;
                    if inverted {
                        w.inverted |= bit;
                    }
                }
            }
        }
        Ok(w)
    }

    /// The switches read from I/O modules: negative limit, positive limit, reference.
    pub fn module_inputs(&self) -> Result<[Option<ModuleInput>; 3], (String, String)> {
        let mut out = [None; 3];
        for (slot, (key, source)) in out.iter_mut().zip([
            ("negative_limit", &self.negative_limit),
            ("positive_limit", &self.positive_limit),
            ("reference", &self.reference),
        ]) {
            if let Some(Source::Module(m)) = source.as_ref().map(|s| s.resolve(key)).transpose()? {
                *slot = Some(m);
            }
        }
        Ok(out)
    }

    /// Whether the drive's touch probe latches the reference switch's edges: the probe
    /// mapped and the reference switch not a module's.
    pub fn reference_latched(&self) -> Result<bool, (String, String)> {
        let [_, _, reference] = self.module_inputs()?;
        Ok(self.touch_probe() && reference.is_none())
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
        let [neg, pos, _] = self.module_inputs()?;
        if self.negative_limit.is_none()
            || self.positive_limit.is_none()
            || neg.is_some()
            || pos.is_some()
        {
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
