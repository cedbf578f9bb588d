//! `[[axis]]`: one axis — which drive, its mechanics and units, its limits and defaults.

use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::scaling::{Scaling, ScalingConfig};
use gantry_kernel::mechanics::{Direction, Mechanics, Modulo, MotionKind};
use gantry_kernel::profile::{Limits, RampType};
use gantry_kernel::{AxisConfig, AxisKind};
use serde::Deserialize;

/// `[[axis]]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisSection {
    /// Name used by commands (`gantry move x …`).
    pub name: String,
    /// What kind of axis (seed 000 §2, SPEC §1): `"real"` (default: a drive on the bus),
    /// `"simulated"` (configured like a real axis, no drive: actual = set), `"virtual"` (a
    /// set-value generator, no drive), `"external"` (an encoder module's input, never
    /// commanded) or `"shadow"` (mirrors the axis named by `source`). Not to be confused
    /// with `kind` (linear or rotary).
    #[serde(rename = "type", default)]
    pub axis_type: AxisType,
    /// Shadow axes: the name of the (non-shadow) axis it mirrors.
    #[serde(default)]
    pub source: Option<String>,
    /// External axes: the encoder module it reads (`[axis.encoder_input]`).
    #[serde(default)]
    pub encoder_input: Option<EncoderInputSection>,
    /// Position of its drive on the bus: on EtherCAT the slave's position in the chain
    /// (0 = next to the master), written in the file. On CANopen it is not written: the
    /// configuration sets it to the axis' own position in the file (axis `i` is on bus
    /// position `i`, the node its `node` names — each axis has a node of its own).
    #[serde(default = "drive_unset")]
    pub drive: usize,
    /// CANopen: the node id of the axis' drive (1..=127, one node per axis).
    #[serde(default)]
    pub node: Option<u8>,
    /// CANopen: the drive's electronic data sheet (CiA 306-1 EDS, as its vendor ships it),
    /// relative to the configuration file. At load the axis' PDO mapping and every SDO
    /// write of the bring-up are checked against it, so that what the drive would refuse
    /// with an SDO abort in the middle of the bring-up is refused at start in the EDS'
    /// words; `gantry sdo` takes each object's type from it; `gantry dcf` writes the DCF
    /// of what the bring-up configures. Refused on EtherCAT (a slave describes itself in
    /// its SII; an ESI is not read). Without it the drive's own aborts are the check.
    #[serde(default)]
    pub eds: Option<String>,
    /// `"linear"` or `"rotary"`.
    #[serde(default = "linear")]
    pub kind: String,
    /// Unit label for displays (`"mm"`, `"deg"`).
    #[serde(default = "mm")]
    pub units: String,
    /// Modulo period (rotary axes that wrap, e.g. 360).
    #[serde(default)]
    pub modulo: Option<f64>,
    /// `"both"`, `"positive"` or `"negative"`.
    #[serde(default = "both")]
    pub direction: String,
    /// `[min, max]` in units, active once homed.
    #[serde(default)]
    pub software_limits: Option<[f64; 2]>,
    /// Units ⇄ encoder counts (required for real and external axes; optional for simulated
    /// and virtual ones, which count nothing; refused for shadows, which are their
    /// source's). [`SCALING_UNSET`] when the file does not give it.
    #[serde(default = "scaling_unset")]
    pub scaling: ScalingSection,
    /// What the axis may ever be commanded (required but for external and shadow axes,
    /// which are never commanded). [`MAX_UNSET`] when the file does not give it.
    #[serde(default = "max_unset")]
    pub max: MaxSection,
    /// Dynamics of commands that leave them out (default: the maxima).
    #[serde(default)]
    pub defaults: DefaultsSection,
    /// Deceleration of a quick stop (default: max.deceleration).
    #[serde(default)]
    pub quick_stop_deceleration: Option<f64>,
    /// Absolute moves need a homed axis (default: yes, but for a virtual axis, which has
    /// no position to lose).
    #[serde(default)]
    pub homing_required: Option<bool>,
    /// When a move is Done: once the drive is in position (default), or as soon as the
    /// set value reaches the target.
    #[serde(default)]
    pub target_monitoring: TargetMonitoringSection,
    /// Process data layout the drive is mapped to: `"csp"` (with velocity, torque, error
    /// code) or `"csp-minimal"` (controlword/target, statusword/actual).
    #[serde(default = "csp")]
    pub pdo: String,
    /// Limit and reference switches and the touch probe (`[axis.switches]`).
    #[serde(default)]
    pub switches: super::switches::SwitchesSection,
    /// Homing done by the drive itself (`[axis.drive_homing]`).
    #[serde(default)]
    pub drive_homing: Option<super::drive_homing::DriveHomingSection>,
    /// Where its drive exposes the commutation measurement's objects and mode
    /// (`[axis.commutation]`; default gantry-sim's).
    #[serde(default)]
    pub commutation: super::commutation::CommutationSection,
    /// What the drive's position counts from: `"incremental"` (default: from where the
    /// drive was switched on) or `"absolute"` (a multi-turn absolute encoder: the same
    /// place reads the same after power-off). An absolute axis' position offset is saved
    /// whenever it is homed and restored at start (SPEC §1: restored, not homed).
    #[serde(default)]
    pub encoder: Encoder,
    /// An absolute axis is homed at start from its saved position offset (SPEC §1: "homed
    /// only when told so"). Refused for an incremental encoder.
    #[serde(default)]
    pub homed_at_start: bool,
    /// What the axis does when a master it follows (gear, cam, master-driven jog) asks
    /// more than its own speed, acceleration, deceleration or direction allow:
    /// `"errorstop"` (default: ErrorStop naming the quantity, braking from the last values
    /// within the limits) or `"warning"` (it follows on and its status says so).
    #[serde(default)]
    pub sync_limit: SyncLimit,
}

/// `encoder` of `[[axis]]`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Encoder {
    /// Counts from where the drive was switched on.
    #[default]
    Incremental,
    /// Reads the same at the same place after a power-off (multi-turn absolute).
    Absolute,
}

/// `sync_limit` of `[[axis]]`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SyncLimit {
    /// ErrorStop.
    #[default]
    ErrorStop,
    /// Follow on, status bit set.
    Warning,
}

/// `drive` as read when the file does not give it.
pub const DRIVE_UNSET: usize = usize::MAX;

/// `scaling` as read when the file does not give it (no scaling has 0 counts per
/// revolution); replaced by [`UNIT_SCALING`] for the axis types that need none.
pub const SCALING_UNSET: ScalingSection = ScalingSection {
    counts_per_motor_rev: 0,
    motor_revs: 1,
    load_revs: 1,
    units_per_load_rev: 0.0,
    invert: false,
};

/// One count per unit: the scaling of an axis that counts nothing (simulated, virtual,
/// shadow axes without a `scaling`).
pub const UNIT_SCALING: ScalingSection = ScalingSection {
    counts_per_motor_rev: 1,
    motor_revs: 1,
    load_revs: 1,
    units_per_load_rev: 1.0,
    invert: false,
};

/// `max` as read when the file does not give it (no limit is 0).
pub const MAX_UNSET: MaxSection = MaxSection {
    speed: 0.0,
    acceleration: 0.0,
    deceleration: None,
    jerk: 0.0,
};

fn scaling_unset() -> ScalingSection {
    SCALING_UNSET
}
fn max_unset() -> MaxSection {
    MAX_UNSET
}

/// `type` of `[[axis]]` (seed 000 §2 "轴的类型").
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum AxisType {
    /// A drive on the bus (`drive`/`node`).
    #[default]
    Real,
    /// Configured like a real axis, no drive: the kernel sets actual = set.
    Simulated,
    /// No drive: a pure set-value generator (a master for gearing and camming).
    Virtual,
    /// An encoder module's counter (`[axis.encoder_input]`): never enabled or commanded.
    External,
    /// Mirrors the set and actual values of the axis named by `source`.
    Shadow,
}

impl AxisType {
    /// The name as written in the file (and shown by `gantry status`).
    pub const fn name(self) -> &'static str {
        match self {
            AxisType::Real => "real",
            AxisType::Simulated => "simulated",
            AxisType::Virtual => "virtual",
            AxisType::External => "external",
            AxisType::Shadow => "shadow",
        }
    }

    /// The kernel's kind (a shadow's source index is set by the caller).
    pub const fn kernel_kind(self, shadow_source: usize) -> AxisKind {
        match self {
            AxisType::Real => AxisKind::Real,
            AxisType::Simulated => AxisKind::Simulated,
            AxisType::Virtual => AxisKind::Virtual,
            AxisType::External => AxisKind::External,
            AxisType::Shadow => AxisKind::Shadow {
                source: shadow_source,
            },
        }
    }
}

/// Default of `freeze_timeout_ms`: ten 1 ms cycles without a new value from the module.
pub const DEFAULT_FREEZE_TIMEOUT_MS: f64 = 10.0;

fn default_freeze_timeout_ms() -> f64 {
    DEFAULT_FREEZE_TIMEOUT_MS
}

/// `[axis.encoder_input]` of an external axis: the encoder module (an EL5101-like
/// incremental encoder terminal: 0x6000 status, 0x6000:11 counter value u32) it reads.
/// Its counts become units through the axis' `scaling` (`counts_per_motor_rev` = the
/// encoder's counts per revolution) and wrap at the axis' `modulo`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EncoderInputSection {
    /// EtherCAT position of the encoder module in the chain (0 = next to the master).
    pub slave: usize,
    /// The axis is lost when the module's TxPDO toggle (0x6000:10) has not changed for
    /// this long (ms, > 0; default [`DEFAULT_FREEZE_TIMEOUT_MS`], at least one cycle).
    #[serde(default = "default_freeze_timeout_ms")]
    pub freeze_timeout_ms: f64,
}

fn drive_unset() -> usize {
    DRIVE_UNSET
}
fn linear() -> String {
    "linear".into()
}
fn mm() -> String {
    "mm".into()
}
fn both() -> String {
    "both".into()
}
fn csp() -> String {
    "csp".into()
}

/// `[axis.scaling]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScalingSection {
    /// Encoder counts per motor revolution.
    pub counts_per_motor_rev: u32,
    /// Gear: motor revolutions …
    #[serde(default = "one")]
    pub motor_revs: u32,
    /// … per load revolutions.
    #[serde(default = "one")]
    pub load_revs: u32,
    /// Units per load revolution (5 for a 5 mm ball screw, 360 for degrees).
    pub units_per_load_rev: f64,
    /// The motor turns the other way round.
    #[serde(default)]
    pub invert: bool,
}

fn one() -> u32 {
    1
}

/// `[axis.max]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MaxSection {
    /// Units/s.
    pub speed: f64,
    /// Units/s².
    pub acceleration: f64,
    /// Units/s² (default: acceleration).
    #[serde(default)]
    pub deceleration: Option<f64>,
    /// Units/s³.
    pub jerk: f64,
}

/// `[axis.defaults]`.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DefaultsSection {
    /// Units/s.
    pub speed: Option<f64>,
    /// Units/s².
    pub acceleration: Option<f64>,
    /// Units/s².
    pub deceleration: Option<f64>,
    /// Units/s³.
    pub jerk: Option<f64>,
    /// `"scurve"`, `"trapezoid"`, `"sine"`, `"linear-sine"`.
    pub ramp: Option<String>,
    /// In-position window (units).
    pub target_window: Option<f64>,
}

/// `[axis.target_monitoring]`: a positioning move is Done once the actual position has
/// stayed inside the target window (`defaults.target_window`, or the move's own) for
/// `dwell_s` after the set value reached the target; `timeout_s` after that without it, the
/// move fails and the axis goes to ErrorStop (TwinCAT's target position monitoring).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TargetMonitoringSection {
    /// Default true.
    pub enabled: Option<bool>,
    /// Seconds the actual must stay in the window (default 0.02).
    pub dwell_s: Option<f64>,
    /// Seconds after the set value reached the target before the move fails (default 5).
    pub timeout_s: Option<f64>,
}

impl AxisSection {
    /// The rules of the axis' `type` that need no bus (seed 000 §2): what each type must
    /// have and may not have, as `(key, reason)`; fills in the scaling and the maxima the
    /// type does not need. `cycle_us` is the bus' cycle time (a freeze timeout shorter
    /// than a cycle would lose every encoder). A real axis' drive is checked by the bus'
    /// rules (see `Config::parse`).
    pub fn check_type(&mut self, cycle_us: u32) -> Result<(), (String, String)> {
        let t = self.axis_type;
        let name = t.name();
        let refuse = |key: &str, why: &str| Err((key.to_string(), format!("a {name} axis {why}")));
        if t != AxisType::Real {
            if self.drive != DRIVE_UNSET {
                return refuse("drive", "has no drive; remove drive");
            }
            if self.node.is_some() {
                return refuse("node", "has no drive; remove node");
            }
            if self.eds.is_some() {
                return refuse("eds", "has no drive; remove eds");
            }
            if self.drive_homing.is_some() {
                return refuse(
                    "drive_homing",
                    "has no drive to home; remove [axis.drive_homing]",
                );
            }
            if self.switches != super::switches::SwitchesSection::default() {
                return refuse(
                    "switches",
                    "reads no switches (they are read from a drive or an I/O module for a \
                     real axis); remove [axis.switches]",
                );
            }
        }
        if t != AxisType::Shadow && self.source.is_some() {
            return refuse(
                "source",
                "mirrors nothing (only a shadow axis has a source)",
            );
        }
        if t != AxisType::External && self.encoder_input.is_some() {
            return refuse(
                "encoder_input",
                "reads no encoder module (only an external axis has [axis.encoder_input])",
            );
        }
        let scaling_given = self.scaling != SCALING_UNSET;
        let max_given = self.max != MAX_UNSET;
        match t {
            AxisType::Real | AxisType::External if !scaling_given => {
                return Err((
                    "scaling".into(),
                    format!(
                        "missing: a {name} axis counts encoder counts (scaling = {{ \
                         counts_per_motor_rev = N, units_per_load_rev = X }})"
                    ),
                ))
            }
            AxisType::Simulated | AxisType::Virtual if !scaling_given => {
                self.scaling = UNIT_SCALING;
            }
            _ => {}
        }
        match t {
            AxisType::Real | AxisType::Simulated | AxisType::Virtual if !max_given => {
                return Err((
                    "max".into(),
                    format!(
                        "missing: what a {name} axis may be commanded (max = {{ speed = V, \
                         acceleration = A, jerk = J }})"
                    ),
                ))
            }
            _ => {}
        }
        match t {
            AxisType::External => {
                let Some(e) = self.encoder_input else {
                    return Err((
                        "encoder_input".into(),
                        "missing: the encoder module an external axis reads \
                         ([axis.encoder_input] slave = N, its EtherCAT position)"
                            .into(),
                    ));
                };
                let ms = e.freeze_timeout_ms;
                if !(ms.is_finite() && ms > 0.0) {
                    return Err((
                        "encoder_input.freeze_timeout_ms".into(),
                        format!(
                            "{ms} is not a time > 0 (ms without a new value from the module \
                             before the axis is lost)"
                        ),
                    ));
                }
                if ms * 1000.0 < f64::from(cycle_us) {
                    return Err((
                        "encoder_input.freeze_timeout_ms".into(),
                        format!(
                            "{ms} ms is shorter than the bus cycle ({cycle_us} µs): the module \
                             cannot toggle faster than the master reads it"
                        ),
                    ));
                }
            }
            AxisType::Shadow => {
                if self.source.is_none() {
                    return Err((
                        "source".into(),
                        "missing: the name of the axis a shadow axis mirrors".into(),
                    ));
                }
                for (key, given) in [
                    ("scaling", scaling_given),
                    ("max", max_given),
                    ("modulo", self.modulo.is_some()),
                    ("software_limits", self.software_limits.is_some()),
                ] {
                    if given {
                        return refuse(
                            key,
                            &format!("takes its {key} from its source; remove {key}"),
                        );
                    }
                }
                self.scaling = UNIT_SCALING;
            }
            _ => {}
        }
        Ok(())
    }

    /// The scaling (checked).
    pub fn scaling(&self) -> Result<Scaling, (String, String)> {
        let s = self.scaling;
        Scaling::new(ScalingConfig {
            counts_per_motor_rev: s.counts_per_motor_rev,
            motor_revs: s.motor_revs,
            load_revs: s.load_revs,
            units_per_load_rev: s.units_per_load_rev,
            invert: s.invert,
        })
        .map_err(|e| ("scaling".into(), e.to_string()))
    }

    /// The PDO layout named by `pdo`, with what `[axis.switches]` needs added.
    pub fn pdo_layout(&self) -> Result<PdoLayout, (String, String)> {
        let mut layout = match self.pdo.as_str() {
            "csp" => PdoLayout::csp(),
            "csp-minimal" => PdoLayout::csp_minimal(),
            other => {
                return Err((
                    "pdo".into(),
                    format!("{other:?} is not a layout (\"csp\", \"csp-minimal\")"),
                ))
            }
        };
        self.switches.extend(&mut layout)?;
        Ok(layout)
    }

    /// The drive homing parameters of `[axis.drive_homing]` in the drive's counts, if
    /// the axis has them.
    pub fn drive_homing_params(
        &self,
    ) -> Result<Option<gantry_drives::cia402::homing::DriveHomingParams>, (String, String)> {
        self.drive_homing
            .map(|d| d.params(&self.scaling()?, self.max.speed))
            .transpose()
    }

    /// The kernel's configuration of this axis (checked by the kernel's own rules).
    pub fn kernel_config(&self) -> Result<AxisConfig, (String, String)> {
        if self.homed_at_start && self.encoder != Encoder::Absolute {
            return Err((
                "homed_at_start".into(),
                "needs an absolute encoder (encoder = \"absolute\"): an incremental \
                 encoder's position is lost when the drive is switched off, so a saved \
                 offset would home the axis at the wrong place"
                    .into(),
            ));
        }
        self.scaling()?;
        self.pdo_layout()?;
        self.drive_homing_params()?;
        self.commutation.objects()?;
        // A shadow's source index is set by `Config::parse`, which knows the other axes.
        let mut c = AxisConfig::new(&self.name, self.axis_type.kernel_kind(usize::MAX));
        let kind = match self.kind.as_str() {
            "linear" => MotionKind::Linear,
            "rotary" => MotionKind::Rotary,
            other => {
                return Err((
                    "kind".into(),
                    format!("{other:?} is not \"linear\" or \"rotary\""),
                ))
            }
        };
        let direction = match self.direction.as_str() {
            "both" => Direction::Both,
            "positive" => Direction::PositiveOnly,
            "negative" => Direction::NegativeOnly,
            other => {
                return Err((
                    "direction".into(),
                    format!("{other:?} is not \"both\", \"positive\" or \"negative\""),
                ))
            }
        };
        let modulo = self
            .modulo
            .map(Modulo::try_new)
            .transpose()
            .map_err(|e| ("modulo".to_string(), e.to_string()))?;
        c.mechanics = Mechanics {
            kind,
            modulo,
            direction,
            software_limits: self.software_limits.map(|[a, b]| (a, b)),
        };
        // External and shadow axes are never commanded: without `max`, the kernel's own.
        if self.max != MAX_UNSET {
            c.max = Limits {
                vmax: self.max.speed,
                amax: self.max.acceleration,
                dmax: self.max.deceleration.unwrap_or(self.max.acceleration),
                jmax: self.max.jerk,
            };
        }
        let d = &self.defaults;
        c.defaults.speed = d.speed.unwrap_or(c.max.vmax);
        c.defaults.acceleration = d.acceleration.unwrap_or(c.max.amax);
        c.defaults.deceleration = d.deceleration.unwrap_or(c.max.dmax);
        c.defaults.jerk = d.jerk.unwrap_or(c.max.jmax);
        if let Some(ramp) = &d.ramp {
            c.defaults.ramp = RampType::from_name(ramp).ok_or_else(|| {
                (
                    "defaults.ramp".to_string(),
                    format!("{ramp:?} is not scurve, trapezoid, sine or linear-sine"),
                )
            })?;
        }
        if let Some(w) = d.target_window {
            c.defaults.target_window = w;
        }
        c.quick_stop_deceleration = self.quick_stop_deceleration.unwrap_or(c.max.dmax);
        // Unless given, the kernel's default for the kind (a virtual axis needs no homing).
        c.homing_required = self.homing_required.unwrap_or(c.homing_required);
        c.limit_edges_latched = self.switches.probe_source()?.is_some();
        c.reference_edges_latched = self.switches.reference_latched()?;
        let tm = self.target_monitoring;
        c.target_monitoring.enabled = tm.enabled.unwrap_or(c.target_monitoring.enabled);
        c.target_monitoring.dwell_s = tm.dwell_s.unwrap_or(c.target_monitoring.dwell_s);
        c.target_monitoring.timeout_s = tm.timeout_s.unwrap_or(c.target_monitoring.timeout_s);
        c.sync_limit_reaction = match self.sync_limit {
            SyncLimit::ErrorStop => gantry_kernel::axis::SyncLimitReaction::ErrorStop,
            SyncLimit::Warning => gantry_kernel::axis::SyncLimitReaction::Warning,
        };
        c.validate().map_err(|e| {
            use gantry_kernel::axis::ConfigError as K;
            match &e {
                K::NotPositive { field, .. } | K::AboveMax { field, .. } => {
                    (field.to_string(), kernel_reason(&e))
                }
                K::TargetMonitoring { .. } => ("target_monitoring".into(), kernel_reason(&e)),
                _ => ("mechanics".into(), kernel_reason(&e)),
            }
        })?;
        Ok(c)
    }
}

/// The kernel's message without its "axis NAME: " prefix (the key says which axis).
fn kernel_reason(e: &gantry_kernel::axis::ConfigError) -> String {
    let text = e.to_string();
    text.split_once(": ")
        .map_or(text.clone(), |(_, rest)| rest.to_string())
}
