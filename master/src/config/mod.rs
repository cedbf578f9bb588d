//! The configuration file: one TOML file with the bus, the cycle, the real-time settings
//! and the axes. Every mistake stops start-up with the file, the line, the key and the
//! reason (`gantry.toml:14: axis[1].max.speed: must be a finite number > 0`).
//!
//! See `deploy/examples/*.toml` for commented examples.

mod axis;
mod bus;
mod cam;
mod commutation;
mod drive_homing;
mod error;
mod group;
mod service;
mod switches;

pub use axis::{
    AxisSection, AxisType, DefaultsSection, Encoder, EncoderInputSection, MaxSection,
    ScalingSection, DEFAULT_FREEZE_TIMEOUT_MS, DRIVE_UNSET, MAX_UNSET, SCALING_UNSET, UNIT_SCALING,
};
pub use bus::{
    BusKind, BusSection, FaultsSection, RtSection, CIA_102_BITRATES, DEFAULT_HEARTBEAT_MS,
    DEFAULT_MASTER_NODE,
};
pub use cam::{CamConfig, CamSection};
pub use commutation::CommutationSection;
pub use drive_homing::{DriveHomingSection, DEFAULT_TIMEOUT_S as DRIVE_HOMING_TIMEOUT_S};
pub use error::ConfigError;
pub use group::{GroupMoveDefaults, GroupSection, MAX_GROUPS};
pub use service::ServiceSection;
pub use switches::{
    ModuleInput, ModuleNode, NodeSwitch, ProbeSource, SwitchSource, SwitchesSection,
    MODULE_NODE_INPUTS,
};

use std::path::Path;
use std::sync::Arc;

use gantry_drives::canopen::eds::Eds;
use gantry_kernel::AxisConfig;
use serde::Deserialize;
use toml::Spanned;

/// The whole file as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    bus: Spanned<BusSection>,
    #[serde(default)]
    rt: RtSection,
    #[serde(default)]
    service: ServiceSection,
    #[serde(rename = "axis", default)]
    axes: Vec<Spanned<AxisSection>>,
    #[serde(rename = "cam", default)]
    cams: Vec<Spanned<CamSection>>,
    #[serde(rename = "group", default)]
    groups: Vec<Spanned<group::GroupSection>>,
}

/// A checked configuration.
#[derive(Clone, Debug)]
pub struct Config {
    /// Where it was read from.
    pub path: String,
    /// The bus.
    pub bus: BusSection,
    /// Real-time settings.
    pub rt: RtSection,
    /// How the service keeps its state (`[service]`).
    pub service: ServiceSection,
    /// The axes, in order.
    pub axes: Vec<AxisSection>,
    /// The kernel's view of each axis.
    pub kernel_axes: Vec<AxisConfig>,
    /// Each axis' EDS as read from its `eds` file (CANopen), in axis order.
    pub eds: Vec<Option<Arc<Eds>>>,
    /// The cam tables (`[[cam]]`), loaded; the `i`-th goes into the kernel's cam slot `i`.
    pub cams: Vec<CamConfig>,
    /// The axis groups (`[[group]]`), in file order (the kernel's group indices).
    pub groups: Vec<gantry_kernel::group::GroupConfig>,
    /// What each group's moves take when a request leaves it out, in the order of
    /// `groups` (the keys the kernel's group configuration does not have).
    pub group_defaults: Vec<GroupMoveDefaults>,
}

impl Config {
    /// The CANopen digital-input modules (CiA 401) the axes' switches read, by bus
    /// position (after the drives'); none on EtherCAT.
    pub fn module_nodes(&self) -> Vec<ModuleNode> {
        let mut out: Vec<ModuleNode> = Vec::new();
        if self.bus.bus_kind() != BusKind::Canopen {
            return out;
        }
        for a in &self.axes {
            for m in a.switches.module_switches() {
                let (Some(node), Some(input), Some(position)) = (m.node, m.input, m.position)
                else {
                    continue;
                };
                let groups = input / 8 + 1;
                match out.iter_mut().find(|n| n.node == node) {
                    Some(n) => {
                        n.groups = n.groups.max(groups);
                        if !n.axes.contains(&a.name) {
                            n.axes.push(a.name.clone());
                        }
                    }
                    None => out.push(ModuleNode {
                        node,
                        position,
                        groups,
                        axes: vec![a.name.clone()],
                    }),
                }
            }
        }
        out.sort_by_key(|n| n.position);
        out
    }

    /// The indices of the axes that have a drive (type "real"), in file order: on CANopen
    /// the `k`-th of them is on bus position `k`.
    pub fn drive_axes(&self) -> Vec<usize> {
        (0..self.axes.len())
            .filter(|&i| {
                self.axes
                    .get(i)
                    .is_some_and(|a| a.axis_type == AxisType::Real)
            })
            .collect()
    }

    /// The axis whose drive is at bus position `drive`, and its index.
    pub fn axis_on_drive(&self, drive: usize) -> Option<(usize, &AxisSection)> {
        self.axes
            .iter()
            .enumerate()
            .find(|(_, a)| a.axis_type == AxisType::Real && a.drive == drive)
    }

    /// The EDS of axis `axis`, when it names one.
    pub fn eds_of(&self, axis: usize) -> Option<&Eds> {
        self.eds.get(axis).and_then(|e| e.as_deref())
    }

    /// Reads and checks `path`.
    pub fn load(path: &str) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError::Read {
            path: path.into(),
            source: e.into(),
        })?;
        let mut config = Self::parse(&text, path)?;
        // Files named in the configuration are relative to it.
        let dir = std::path::Path::new(path)
            .parent()
            .unwrap_or(std::path::Path::new(""));
        for file in [
            &mut config.bus.simulator,
            &mut config.bus.simulator_record,
            &mut config.bus.pcap,
            &mut config.service.state_dir,
        ]
        .into_iter()
        .flatten()
        {
            if std::path::Path::new(file.as_str()).is_relative() {
                *file = dir.join(&*file).display().to_string();
            }
        }
        Ok(config)
    }

    /// Parses and checks `text`; `path` names it in errors.
    pub fn parse(text: &str, path: &str) -> Result<Self, ConfigError> {
        let file: File =
            toml::from_str(text).map_err(|e| ConfigError::from_toml(path, text, &e))?;
        let at = |span: std::ops::Range<usize>, key: String, reason: String| {
            ConfigError::invalid(path, text, span, key, reason)
        };
        let bus_span = file.bus.span();
        let bus = file.bus.into_inner();
        bus.check()
            .map_err(|(key, reason)| at(bus_span.clone(), format!("bus.{key}"), reason))?;
        file.rt
            .check()
            .map_err(|(key, reason)| at(0..0, format!("rt.{key}"), reason))?;
        file.service
            .check()
            .map_err(|(key, reason)| at(0..0, format!("service.{key}"), reason))?;
        if file.axes.is_empty() {
            return Err(at(0..0, "axis".into(), "no axis is configured".into()));
        }
        let mut axes = Vec::with_capacity(file.axes.len());
        let mut kernel_axes = Vec::with_capacity(file.axes.len());
        let mut eds = Vec::with_capacity(file.axes.len());
        let mut spans = Vec::with_capacity(file.axes.len());
        let kind = bus.bus_kind();
        // CANopen I/O modules the switches name: node, the axis and key that named it
        // first, its span.
        let mut module_nodes: Vec<(u8, usize, String, std::ops::Range<usize>)> = Vec::new();
        // On CANopen the drives are the real axes' nodes, at bus positions 0.., the I/O
        // modules after them.
        let real_axes = file
            .axes
            .iter()
            .filter(|a| a.get_ref().axis_type == AxisType::Real)
            .count();
        for (i, spanned) in file.axes.into_iter().enumerate() {
            let span = spanned.span();
            let mut a = spanned.into_inner();
            let key = |k: &str| format!("axis[{i}].{k}");
            a.check_type(bus.cycle_us)
                .map_err(|(k, reason)| at(span.clone(), key(&k), reason))?;
            let real = a.axis_type == AxisType::Real;
            if a.axis_type == AxisType::External {
                if kind == BusKind::Canopen {
                    return Err(at(
                        span,
                        key("type"),
                        "an external axis reads an EtherCAT encoder module \
                         ([axis.encoder_input] slave = N); CANopen encoders are not supported"
                            .into(),
                    ));
                }
                let slave = a.encoder_input.map_or(0, |e| e.slave);
                if let Some(other) = axes.iter().position(|b: &AxisSection| {
                    b.drive == slave || b.encoder_input.is_some_and(|e| e.slave == slave)
                }) {
                    return Err(at(
                        span,
                        key("encoder_input.slave"),
                        format!("slave {slave} is also axis[{other}]'s"),
                    ));
                }
            }
            match (kind, a.drive, a.node) {
                _ if !real => {}
                (BusKind::Ethercat, DRIVE_UNSET, _) => {
                    return Err(at(
                        span,
                        key("drive"),
                        "missing: the position of the axis' drive in the chain (0 = next to \
                         the master)"
                            .into(),
                    ))
                }
                (BusKind::Ethercat, _, Some(_)) => {
                    return Err(at(
                        span,
                        key("node"),
                        "is a CANopen node id; on EtherCAT an axis names its drive's \
                         position (drive = N)"
                            .into(),
                    ))
                }
                (BusKind::Ethercat, _, None) => {}
                (BusKind::Canopen, DRIVE_UNSET, None) => {
                    return Err(at(
                        span,
                        key("node"),
                        "missing: the CANopen node id of the axis' drive (1..=127)".into(),
                    ))
                }
                (BusKind::Canopen, DRIVE_UNSET, Some(node)) => {
                    if !(1..=127).contains(&node) {
                        return Err(at(
                            span,
                            key("node"),
                            format!(
                                "{node} is outside 1..=127 (CiA 301: a 7-bit node id, 0 \
                                 addresses every node)"
                            ),
                        ));
                    }
                    if let Some(other) = axes.iter().position(|b: &AxisSection| b.node == a.node) {
                        return Err(at(
                            span,
                            key("node"),
                            format!("node {node} is also axis[{other}]'s"),
                        ));
                    }
                    if node == bus.master_node() {
                        return Err(at(
                            span,
                            key("node"),
                            format!(
                                "node {node} is gantry's own (bus.master_node, its \
                                 heartbeat's): give the drive another id or gantry another \
                                 master_node"
                            ),
                        ));
                    }
                    // Bus position: the axis' rank among the real axes (see
                    // `AxisSection::drive`).
                    a.drive = axes
                        .iter()
                        .filter(|b: &&AxisSection| b.axis_type == AxisType::Real)
                        .count();
                }
                (BusKind::Canopen, _, _) => {
                    return Err(at(
                        span,
                        key("drive"),
                        "on CANopen an axis names its drive by node id (node = N), not by \
                         drive position"
                            .into(),
                    ))
                }
            }
            if let Some(other) = axes.iter().position(|b: &AxisSection| b.name == a.name) {
                return Err(at(
                    span,
                    key("name"),
                    format!("{:?} is also axis[{other}]", a.name),
                ));
            }
            if let Some(other) = axes.iter().position(|b: &AxisSection| {
                real && (b.drive == a.drive || b.encoder_input.is_some_and(|e| e.slave == a.drive))
            }) {
                return Err(at(
                    span,
                    key("drive"),
                    format!("drive {} is also axis[{other}]'s", a.drive),
                ));
            }
            // Switches on I/O modules: an EtherCAT chain position or a CANopen node, each
            // bus' own; a CANopen module placed on its bus position after the drives.
            for m in a.switches.module_switches() {
                let sw = key(&format!("switches.{}", m.key));
                match (kind, m.slave, m.node) {
                    (BusKind::Ethercat, _, Some(node)) => {
                        return Err(at(
                            span,
                            sw,
                            format!(
                                "node = {node} is a CANopen node id; on EtherCAT a module is \
                                 named by its chain position (slave = N)"
                            ),
                        ))
                    }
                    (BusKind::Canopen, Some(_), None) => {
                        return Err(at(
                            span,
                            sw,
                            "slave is an EtherCAT chain position; on CANopen a module is named \
                             by its node id (node = N, a CiA 401 digital-input node)"
                                .into(),
                        ))
                    }
                    (BusKind::Canopen, None, Some(node)) => {
                        if !(1..=127).contains(&node) {
                            return Err(at(
                                span,
                                sw,
                                format!("node {node} is outside 1..=127 (CiA 301)"),
                            ));
                        }
                        if node == bus.master_node() {
                            return Err(at(
                                span,
                                sw,
                                format!(
                                    "node {node} is gantry's own (bus.master_node): give the \
                                     module another id"
                                ),
                            ));
                        }
                        if let Some(input) = m.input.filter(|i| *i >= MODULE_NODE_INPUTS) {
                            return Err(at(
                                span,
                                sw,
                                format!(
                                    "input {input}: a CiA 401 module's TPDO1 carries inputs \
                                     0..={} (0x6000:01–08, 8 inputs each)",
                                    MODULE_NODE_INPUTS - 1
                                ),
                            ));
                        }
                        if !module_nodes.iter().any(|(n, ..)| *n == node) {
                            module_nodes.push((node, i, sw, span.clone()));
                        }
                    }
                    _ => {}
                }
            }
            if kind == BusKind::Canopen {
                let n_axes = real_axes;
                let nodes: Vec<u8> = module_nodes.iter().map(|(n, ..)| *n).collect();
                a.switches.place_modules(|node| {
                    n_axes + nodes.iter().position(|n| *n == node).unwrap_or(nodes.len())
                });
            }
            let k = a
                .kernel_config()
                .map_err(|(k, reason)| at(span.clone(), key(&k), reason))?;
            let sheet = match (&a.eds, kind) {
                (None, _) => None,
                (Some(_), BusKind::Ethercat) => {
                    return Err(at(
                        span,
                        key("eds"),
                        "is a CANopen device's EDS (CiA 306, kind = \"canopen\"); an \
                         EtherCAT slave describes itself in its SII and gantry reads no ESI"
                            .into(),
                    ))
                }
                (Some(file), BusKind::Canopen) => {
                    // Relative to the configuration file, as its other files are.
                    let resolved = relative_to(path, file);
                    let sheet = gantry_drives::canopen::eds::load(Path::new(&resolved))
                        .map_err(|e| at(span.clone(), key("eds"), e.to_string()))?;
                    a.eds = Some(resolved);
                    Some(Arc::new(sheet))
                }
            };
            eds.push(sheet);
            spans.push(span);
            kernel_axes.push(k);
            axes.push(a);
        }
        // A shadow's source: a non-shadow axis of the file, by name; the shadow takes its
        // mechanics, limits and units (seed 000 §5.6: it inherits the source's settings).
        for (i, span) in spans.iter().enumerate() {
            let Some(a) = axes.get(i).filter(|a| a.axis_type == AxisType::Shadow) else {
                continue;
            };
            let wanted = a.source.clone().unwrap_or_default();
            let source = axes
                .iter()
                .position(|b| b.name == wanted)
                .filter(|&s| axes.get(s).is_some_and(|b| b.axis_type != AxisType::Shadow))
                .ok_or_else(|| {
                    at(
                        span.clone(),
                        format!("axis[{i}].source"),
                        format!(
                            "{wanted:?} is not a non-shadow axis of this file (a shadow mirrors \
                             a real, simulated, virtual or external axis)"
                        ),
                    )
                })?;
            let name = a.name.clone();
            let units = axes
                .get(source)
                .map(|b| (b.units.clone(), b.kind.clone(), b.modulo));
            if let (Some(k), Some(src)) = (kernel_axes.get(source).cloned(), kernel_axes.get_mut(i))
            {
                *src = AxisConfig {
                    name,
                    kind: gantry_kernel::AxisKind::Shadow { source },
                    homing_required: false,
                    ..k
                };
            }
            if let (Some((units, mkind, modulo)), Some(a)) = (units, axes.get_mut(i)) {
                a.units = units;
                a.kind = mkind;
                a.modulo = modulo;
            }
        }
        // A module is a node of its own: not an axis' drive.
        for (node, axis, sw, span) in &module_nodes {
            if let Some(other) = axes.iter().position(|b| b.node == Some(*node)) {
                return Err(at(
                    span.clone(),
                    sw.clone(),
                    format!(
                        "node {node} is axis[{other}]'s drive (axis[{axis}] reads it as an I/O \
                         module): a CiA 401 module is a node of its own"
                    ),
                ));
            }
        }
        let mut cams: Vec<CamConfig> = Vec::with_capacity(file.cams.len());
        for (i, spanned) in file.cams.into_iter().enumerate() {
            let span = spanned.span();
            let cam = spanned
                .into_inner()
                .load(i, &cams, path)
                .map_err(|(k, reason)| at(span, format!("cam[{i}].{k}"), reason))?;
            cams.push(cam);
        }
        let mut groups = Vec::with_capacity(file.groups.len());
        let mut group_defaults = Vec::with_capacity(file.groups.len());
        for (i, spanned) in file.groups.into_iter().enumerate() {
            let span = spanned.span();
            let section = spanned.into_inner();
            let g = section
                .resolve(&groups, &kernel_axes)
                .and_then(|g| Ok((g, section.move_defaults()?)))
                .map_err(|(k, reason)| at(span, format!("group[{i}].{k}"), reason))?;
            groups.push(g.0);
            group_defaults.push(g.1);
        }
        let config = Self {
            path: path.into(),
            bus,
            rt: file.rt,
            service: file.service,
            axes,
            kernel_axes,
            eds,
            cams,
            groups,
            group_defaults,
        };
        if kind == BusKind::Canopen {
            // The cycle's frames must fit the bit rate (issue 12 §2: refused with the figure).
            crate::canopen::load::BusLoad::of_config(&config)
                .and_then(|load| load.check())
                .map_err(|e| at(bus_span.clone(), "bus.bitrate".into(), e.to_string()))?;
            // What each drive would refuse, refused now in its EDS' words.
            for (i, span) in spans.into_iter().enumerate() {
                crate::canopen::eds::check(&config, i)
                    .map_err(|e| at(span, format!("axis[{i}].eds"), e.to_string()))?;
            }
        }
        Ok(config)
    }
}

/// `file` as named in the configuration at `config_path`: relative to its directory.
fn relative_to(config_path: &str, file: &str) -> String {
    if Path::new(file).is_relative() {
        let dir = Path::new(config_path).parent().unwrap_or(Path::new(""));
        dir.join(file).display().to_string()
    } else {
        file.to_string()
    }
}

#[cfg(test)]
mod tests;
