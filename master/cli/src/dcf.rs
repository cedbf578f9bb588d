//! `gantry dcf --config FILE --axis X --out FILE`: the device configuration file (CiA
//! 306-1 §5) of what the bring-up configures on an axis' CANopen node — its EDS with
//! `[DeviceComissioning]` (node id, bit rate, the axis' name, the interface) and a
//! `ParameterValue` for every object the bring-up writes by SDO (PDO communication and
//! mapping, heartbeat producer time, cycle period, mode) — made offline from the
//! configuration, no bus needed. The EDS is the axis' `eds`; an axis without one whose
//! bus is `[bus] simulator` takes its simulated node's (what `gantry-sim eds` writes);
//! otherwise there is nothing to make a DCF of, and the error says so.

use std::path::Path;

use gantry::canopen::eds::EdsCheckError;
use gantry::config::{BusKind, Config, ConfigError};
use gantry_drives::canopen::eds::{write_dcf, Eds};
use thiserror::Error;

/// Why no DCF was written.
#[derive(Debug, Error)]
pub enum DcfCliError {
    /// The configuration.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Not a CANopen configuration.
    #[error("{config}: a DCF describes a CANopen node; this bus is kind = {kind:?}")]
    NotCanopen {
        /// The configuration.
        config: String,
        /// Its bus kind.
        kind: String,
    },
    /// No such axis.
    #[error("{config} has no axis {axis:?} (its axes: {known})")]
    NoAxis {
        /// The configuration.
        config: String,
        /// The name given.
        axis: String,
        /// Those there are.
        known: String,
    },
    /// No EDS to start from.
    #[error(
        "axis {axis:?} names no EDS (eds = \"drive.eds\" in its [[axis]]) and the bus is no \
         simulator: a DCF is the drive's EDS with the configured values"
    )]
    NoEds {
        /// The axis.
        axis: String,
    },
    /// The simulator's chain file.
    #[error("the simulated node's EDS: {0}")]
    Simulator(String),
    /// The configuration does not suit the EDS.
    #[error("axis {axis:?}: {source}")]
    Check {
        /// The axis.
        axis: String,
        /// Why.
        source: EdsCheckError,
    },
    /// The file could not be written.
    #[error("cannot write {path}")]
    Write {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

/// The EDS of axis `axis` of `config`: its own, or its simulated node's.
pub fn eds_for(config: &Config, axis: usize) -> Result<Eds, DcfCliError> {
    let a = config.axes.get(axis).ok_or_else(|| DcfCliError::NoAxis {
        config: config.path.clone(),
        axis: format!("#{axis}"),
        known: config
            .axes
            .iter()
            .map(|a| a.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
    })?;
    if let Some(eds) = config.eds_of(axis) {
        return Ok(eds.clone());
    }
    let (Some(sim), Some(node)) = (&config.bus.simulator, a.node) else {
        return Err(DcfCliError::NoEds {
            axis: a.name.clone(),
        });
    };
    let chain = gantry_sim::config::SimConfig::load(sim)
        .map_err(|e| DcfCliError::Simulator(e.to_string()))?;
    gantry_sim::canopen::eds::for_chain_node(&chain, node, &format!("node{node}.eds"))
        .map_err(|e| DcfCliError::Simulator(format!("{sim}: {e}")))
}

/// The DCF text of axis `axis_name` of the configuration at `config_path`.
pub fn dcf_text(config_path: &str, axis_name: &str, out_name: &str) -> Result<String, DcfCliError> {
    let config = Config::load(config_path)?;
    if config.bus.bus_kind() != BusKind::Canopen {
        return Err(DcfCliError::NotCanopen {
            config: config_path.into(),
            kind: config.bus.kind.clone(),
        });
    }
    let axis = config
        .axes
        .iter()
        .position(|a| a.name == axis_name)
        .ok_or_else(|| DcfCliError::NoAxis {
            config: config_path.into(),
            axis: axis_name.into(),
            known: config
                .axes
                .iter()
                .map(|a| a.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
        })?;
    let eds = eds_for(&config, axis)?;
    let mut dcf =
        gantry::canopen::eds::dcf(&config, axis, &eds).map_err(|source| DcfCliError::Check {
            axis: axis_name.into(),
            source,
        })?;
    dcf.file_info.file_name = out_name.to_string();
    dcf.file_info.modified_by = "gantry dcf".to_string();
    Ok(write_dcf(&dcf))
}

/// Writes the DCF of `axis` to `out`; the line to print.
pub fn run(config_path: &str, axis: &str, out: &Path) -> Result<String, DcfCliError> {
    let name = out
        .file_name()
        .map_or_else(|| "node.dcf".into(), |n| n.to_string_lossy().into_owned());
    let text = dcf_text(config_path, axis, &name)?;
    std::fs::write(out, text).map_err(|source| DcfCliError::Write {
        path: out.display().to_string(),
        source,
    })?;
    Ok(format!(
        "gantry: DCF of axis {axis:?} written to {}",
        out.display()
    ))
}
