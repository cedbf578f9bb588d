//! `gantry cam load|tables`: cam tables of a running gantry. `load` reads the file here
//! (CSV or TOML, as `[[cam]]` files; errors name its line) and sends the points, so the
//! service need not see the file; `tables` lists what the kernel's slots hold.

use std::io::Write;
use std::path::Path;

use gantry::cam::load_cam_file;
use gantry::service::protocol::Request;
use gantry_kernel::cam::Interpolation;
use serde_json::Value;

use crate::client::{Client, ClientError};

/// Why `gantry cam load` stopped before asking the service.
#[derive(Debug, thiserror::Error)]
pub enum CamCliError {
    /// The interpolation is none gantry knows.
    #[error("--interpolation {0:?} is none of linear, cubic, quintic")]
    Interpolation(String),
    /// The file is not a cam table.
    #[error(transparent)]
    File(#[from] gantry::cam::CamFileError),
    /// The service refused it, or the socket failed.
    #[error(transparent)]
    Client(#[from] ClientError),
}

/// The `cam_load` request for table `name` from `file`: its points, interpolation and
/// periodic flag as `load_cam_file` makes them (the caller's `interpolation` and
/// `periodic` must agree with a TOML file's own).
pub fn load_request(
    name: &str,
    file: &Path,
    interpolation: Option<&str>,
    periodic: Option<bool>,
) -> Result<Request, CamCliError> {
    let interpolation = interpolation
        .map(|s| Interpolation::from_name(s).ok_or_else(|| CamCliError::Interpolation(s.into())))
        .transpose()?;
    let table = load_cam_file(file, interpolation, periodic)?;
    Ok(Request::CamLoad {
        name: name.into(),
        file: None,
        points: Some(table.points().iter().map(|p| [p.master, p.slave]).collect()),
        interpolation: Some(table.interpolation().name().into()),
        periodic: Some(table.is_periodic()),
    })
}

/// Sends `request` (from [`load_request`]) and prints the table as loaded.
pub fn load(
    client: &mut Client,
    request: &Request,
    json_out: bool,
    out: &mut impl Write,
) -> Result<(), CamCliError> {
    let table = client.request(request)?;
    if json_out {
        writeln!(out, "{table}").map_err(ClientError::Output)?;
    } else {
        writeln!(out, "loaded {}", line(&table)).map_err(ClientError::Output)?;
    }
    Ok(())
}

/// Prints the cam tables loaded, one a line (or their JSON).
pub fn tables(
    client: &mut Client,
    json_out: bool,
    out: &mut impl Write,
) -> Result<(), CamCliError> {
    let reply = client.request(&Request::CamTables)?;
    let io = ClientError::Output;
    if json_out {
        writeln!(out, "{reply}").map_err(io)?;
        return Ok(());
    }
    let tables = reply["tables"].as_array().cloned().unwrap_or_default();
    if tables.is_empty() {
        writeln!(
            out,
            "no cam tables (`[[cam]]` in the configuration, `gantry cam load`)"
        )
        .map_err(io)?;
    }
    for t in &tables {
        writeln!(out, "{}", line(t)).map_err(io)?;
    }
    Ok(())
}

/// One table: `slot 1 knife: 25 points, quintic, not periodic, master 0..600, rise 400`.
fn line(t: &Value) -> String {
    let num = |v: &Value| v.as_f64().map_or("?".into(), |x| format!("{x}"));
    format!(
        "slot {} {}: {} points, {}, {}, master {}..{}, rise {}",
        t["slot"],
        t["name"].as_str().unwrap_or("?"),
        t["points"],
        t["interpolation"].as_str().unwrap_or("?"),
        if t["periodic"] == Value::Bool(true) {
            "periodic"
        } else {
            "not periodic"
        },
        num(&t["master_range"][0]),
        num(&t["master_range"][1]),
        num(&t["slave_rise"]),
    )
}
