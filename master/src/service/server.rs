//! The control socket: a Unix domain socket (mode 0660) serving the JSON-lines protocol to
//! any number of clients, each in its own task. Requests become [`Controller`] calls;
//! replies are built from the latest snapshot. Nothing a client sends can reach the cycle
//! thread except as a well-formed request through the queue.

use std::collections::VecDeque;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::axis_fault::describe_fault;
use gantry_drives::cia402::error_code::describe;
use gantry_kernel::axis::command::{
    BufferMode, Command, CommandError, HaltMode, Jog, MoveDirection, MovePtp, PositioningMode,
    PowerCommand,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use serde_json::{json, Value};
use thiserror::Error;
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::{UnixListener, UnixStream};

use super::protocol::{
    self, CommissionKind, DriveHomeParams, HomeMethod, HomeMode, HomeParams, HomeSwitches,
    JogDirection, MoveMode, Request, SdoDirection, Word,
};
use crate::commission::{
    CommissionError, CommutationSettings, Procedure, ProcedureHandle, ProcedureOutcome, Reversing,
};
use crate::config::{AxisType, Config, DriveHomingSection};
use crate::error_chain::Chain;
use crate::persist::{Saved, StepSwitchNotGiven};
use crate::runtime::controller::{CommandHandle, ControlError, Controller};
use crate::runtime::procedure::DriveProcedure;
use crate::runtime::protocol::{Snapshot, TraceSample};
use crate::runtime::sdo::{SdoData, SdoError, SdoKind, SdoRequest, SDO_TIMEOUT_NS};
use gantry_drives::cia402::homing::{DriveHoming, DriveHomingParams};
use gantry_kernel::homing::{HomingMode, MoveHomeCall, SwitchConfig};

/// Trace samples kept for `trace` requests (60 s at 1 kHz).
const TRACE_KEEP: usize = 60_000;

/// What the server shares between client tasks.
pub struct ServerState {
    /// The cycle.
    pub controller: Controller,
    /// The configuration (axis units and defaults).
    pub config: Config,
    /// Whether the cycle runs in real time.
    pub real_time: bool,
    trace: Mutex<VecDeque<TraceSample>>,
    handles: Mutex<Vec<CommandHandle>>,
    /// Commissioning procedures started, by id.
    procedures: Mutex<Vec<(u64, ProcedureHandle)>>,
    /// Set when the service ends: recordings in progress answer with what they have.
    ending: tokio::sync::watch::Sender<bool>,
    /// Each axis' saved parameters (homing, PTP, position and commutation offsets).
    pub saved: Arc<Saved>,
}

impl ServerState {
    /// Shared state for a server that saves nothing to files: the axes' parameters are
    /// remembered while it runs (when the system gives the controller its saving thread).
    pub fn new(controller: Controller, config: Config, real_time: bool) -> Arc<Self> {
        let saved = Arc::new(Saved::none(&config));
        let controller = controller
            .clone()
            .saving_to(saved.clone())
            .unwrap_or(controller);
        Self::with_saved(controller, config, real_time, saved)
    }

    /// Shared state for a server that saves the axes' parameters in `saved`; `controller`
    /// saves into it ([`Controller::saving_to`]), so that what the requests leave out and
    /// what the axes accept are the same set, through the socket or not.
    pub fn with_saved(
        controller: Controller,
        config: Config,
        real_time: bool,
        saved: Arc<Saved>,
    ) -> Arc<Self> {
        Arc::new(Self {
            controller,
            config,
            real_time,
            trace: Mutex::new(VecDeque::with_capacity(TRACE_KEEP)),
            handles: Mutex::new(Vec::new()),
            procedures: Mutex::new(Vec::new()),
            ending: tokio::sync::watch::Sender::new(false),
            saved,
        })
    }

    /// The service is ending: every `trace` still recording replies now with the samples
    /// so far (marked incomplete), so a shutdown loses no recording. Returns once every
    /// client has its reply, or after `grace`.
    pub async fn end_recordings(&self, grace: Duration) {
        self.collect_trace();
        self.ending.send_replace(true);
        let end = tokio::time::Instant::now() + grace;
        // Each client holds a receiver while it reads or answers a request.
        while self.ending.receiver_count() > 0 && tokio::time::Instant::now() < end {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }

    /// Moves new trace samples from the cycle into the kept window (call every few ms).
    pub fn collect_trace(&self) {
        let mut new = Vec::new();
        self.controller.drain_trace(&mut new);
        let mut kept = self.trace.lock().unwrap_or_else(|p| p.into_inner());
        for s in new {
            if kept.len() == TRACE_KEEP {
                kept.pop_front();
            }
            kept.push_back(s);
        }
    }
}

/// Binds the socket at `path` (replacing a stale one), mode 0660.
pub fn bind(path: &Path) -> std::io::Result<UnixListener> {
    if path.exists() {
        // A socket left by a gantry that died; a live one would still answer.
        if std::os::unix::net::UnixStream::connect(path).is_ok() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AddrInUse,
                format!("{} is in use by a running gantry", path.display()),
            ));
        }
        std::fs::remove_file(path)?;
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let listener = UnixListener::bind(path)?;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o660))?;
    Ok(listener)
}

/// Serves clients until the task is dropped.
pub async fn serve(listener: UnixListener, state: Arc<ServerState>) {
    loop {
        let Ok((stream, _)) = listener.accept().await else {
            continue;
        };
        tokio::spawn(client(stream, state.clone()));
    }
}

async fn client(stream: UnixStream, state: Arc<ServerState>) {
    let (read, mut write) = stream.into_split();
    let mut reader = BufReader::new(read);
    let max_line = protocol::max_line(state.controller.sdo_max_bytes());
    loop {
        let mut line = Vec::new();
        match (&mut reader)
            .take(max_line as u64 + 1)
            .read_until(b'\n', &mut line)
            .await
        {
            Ok(0) | Err(_) => return,
            Ok(_) => {}
        }
        // Held until this request's reply is written: a shutdown waits for it (see
        // `end_recordings`).
        let _in_progress = state.ending.subscribe();
        let reply = if line.len() > max_line {
            let reply = protocol::error(&format!("request longer than {max_line} bytes"));
            let _ = write.write_all(format!("{reply}\n").as_bytes()).await;
            return;
        } else {
            match std::str::from_utf8(&line) {
                Ok(text) if text.trim().is_empty() => continue,
                Ok(text) => match protocol::parse(text.trim()) {
                    Ok(request) => match handle(&state, request).await {
                        Ok(result) => protocol::ok(result),
                        Err(e) => protocol::error(&Chain(&e).to_string()),
                    },
                    Err(e) => protocol::error(&Chain(&e).to_string()),
                },
                Err(_) => protocol::error("request is not UTF-8"),
            }
        };
        if write
            .write_all(format!("{reply}\n").as_bytes())
            .await
            .is_err()
        {
            return;
        }
    }
}

fn status_name(s: CommandStatus, axes: &[String]) -> Value {
    match s {
        // `names_cause`: the text already says why the axis is in ErrorStop (a refusal
        // there), so a client need not add the axis' error to it.
        CommandStatus::Error(e) => json!({
            "status": "Error",
            "error": command_error_text(&e, axes),
            "names_cause": matches!(e, CommandError::InErrorStop { .. }),
        }),
        other => json!({ "status": format!("{other:?}") }),
    }
}

/// The index of the group called `name`.
fn group_index(state: &ServerState, name: &str) -> Result<usize, Refused> {
    state
        .config
        .groups
        .iter()
        .position(|g| g.name == name)
        .ok_or_else(|| Refused::NoGroup(name.to_string()))
}

/// How a move of group `g` joins its running move: what the request says, the group's
/// configured corner deviation where it says none.
fn group_junction(
    state: &ServerState,
    g: usize,
    buffer: protocol::BufferMode,
    transition: protocol::TransitionMode,
    corner_deviation: Option<f64>,
) -> Result<super::group::Junction, Refused> {
    let default = state
        .config
        .group_defaults
        .get(g)
        .copied()
        .unwrap_or_default();
    super::group::junction(
        buffer,
        transition,
        corner_deviation,
        default.corner_deviation,
    )
}

/// A command's error as the client reads it: a master named by the kernel's index is
/// named by its axis name too.
fn command_error_text(e: &CommandError, axes: &[String]) -> String {
    let text = e.to_string();
    let master = match *e {
        CommandError::BadMaster { master, .. }
        | CommandError::MasterNotAvailable { master, .. } => master,
        _ => return text,
    };
    match axes.get(master) {
        Some(name) => text.replacen(
            &format!("axis {master} "),
            &format!("axis {master} ({name}) "),
            1,
        ),
        None => text,
    }
}

/// An axis' fault as the status shows it, a lost master named.
fn fault_text(fault: &AxisFault, axes: &[String]) -> String {
    let text = describe_fault(fault);
    match *fault {
        AxisFault::MasterLost { master } => match axes.get(master) {
            Some(name) => text.replacen(
                &format!("axis {master} "),
                &format!("axis {master} ({name}) "),
                1,
            ),
            None => text,
        },
        _ => text,
    }
}

/// Why a well-formed request was refused (the reply's `error`).
#[derive(Debug, Error)]
pub enum Refused {
    /// The controller refused it (no such axis, the cycle not taking requests).
    #[error(transparent)]
    Control(#[from] ControlError),
    /// A number is not finite (JSON cannot carry one; a guard for
    /// `Duration::from_secs_f64`, which panics on them).
    #[error("{field} = {value} is not a finite number")]
    NotFinite {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A way round a modulo axis, asked of a linear one.
    #[error("mode \"{mode}\" is for a modulo axis; {axis} is not one (absolute or relative)")]
    NotModulo {
        /// The mode.
        mode: MoveMode,
        /// The axis.
        axis: String,
    },
    /// An axis the configuration does not have (the controller and the configuration
    /// disagree: a bug).
    #[error("axis {0:?} has no configuration")]
    NoConfig(String),
    /// A `home` request that asks for two homing runs.
    #[error(
        "home: MoveHome's params and step_switch both given; a homing run is one or the other"
    )]
    TwoHomings,
    /// A step-to-absolute-switch call without a parameter it needs.
    #[error(transparent)]
    StepSwitch(#[from] StepSwitchNotGiven),
    /// A drive homing parameter is missing or wrong.
    #[error("{key}: {reason}")]
    DriveHoming {
        /// The parameter (as the configuration names it).
        key: String,
        /// Why.
        reason: String,
    },
    /// A request that needs the axis' drive, for an axis without one.
    #[error("{axis} is a {axis_type} axis: it has no drive for {what}")]
    NoDrive {
        /// The axis.
        axis: String,
        /// Its type.
        axis_type: &'static str,
        /// What needed the drive.
        what: &'static str,
    },
    /// A synchronised-motion request whose fields do not go together.
    #[error("{0}")]
    Sync(&'static str),
    /// A group the configuration does not have.
    #[error("no group {0:?} (the configuration's [[group]] sections name them)")]
    NoGroup(String),
    /// A group move's operand is wrong.
    #[error("{field} = {value} {reason}")]
    GroupOperand {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        reason: &'static str,
    },
    /// A cam request names a table the service does not have.
    #[error("no cam table {0:?} (`gantry cam tables` lists them)")]
    NoCamTable(String),
    /// No such handle.
    #[error("no handle {0} (handles are per service run)")]
    NoHandle(u64),
    /// No such commissioning procedure.
    #[error("no procedure {0} (procedures are per service run)")]
    NoProcedure(u64),
    /// A commissioning procedure cannot start.
    #[error(transparent)]
    Commission(#[from] crate::commission::CommissionError),
    /// A procedure already runs on the axis.
    #[error(
        "{axis}: a {procedure} procedure is already running (`gantry stop {axis}` cancels it)"
    )]
    ProcedureRunning {
        /// The axis.
        axis: String,
        /// The procedure.
        procedure: &'static str,
    },
    /// `wait` ran out of time (the client polls on this text: "not final").
    #[error("handle {handle} not final after {timeout_s} s")]
    NotFinal {
        /// The handle.
        handle: u64,
        /// The time waited.
        timeout_s: f64,
    },
    /// An SDO request names its drive by neither or both of axis and drive.
    #[error("sdo: name the drive by its axis or by its bus position, one of the two")]
    SdoTarget,
    /// An SDO download's data is not hex bytes (its start, for the message).
    #[error("sdo: data {0:?} is not hex bytes (two digits a byte)")]
    SdoData(String),
    /// A download without data.
    #[error("sdo: a download needs data")]
    SdoNoData,
    /// The transfer failed.
    #[error(transparent)]
    Sdo(#[from] SdoError),
    /// The drive's EDS says the drive would refuse it (nothing was sent).
    #[error("sdo")]
    Eds(#[from] crate::canopen::eds::SdoEdsError),
    /// An `object` request for an object the drive's EDS does not have.
    #[error(transparent)]
    Object(crate::canopen::eds::SdoEdsError),
    /// A `cam_load` with neither or both of `file` and `points`.
    #[error("cam_load: give the table's file or its points, one of the two")]
    CamSource,
    /// An interpolation gantry does not know.
    #[error("cam_load: interpolation {0:?} is none of linear, cubic, quintic")]
    CamInterpolation(String),
    /// The cam file or the points are not a table.
    #[error(transparent)]
    CamFile(#[from] crate::cam::CamFileError),
    /// An axis beyond those the trace records.
    #[error(
        "only the first {} axes are traced",
        crate::runtime::protocol::TRACE_AXES
    )]
    NotTraced,
}

/// An SDO transfer, waited for in a blocking thread (the controller polls its outcome).
#[allow(clippy::too_many_arguments)]
async fn sdo(
    state: &ServerState,
    axis: Option<String>,
    drive: Option<usize>,
    direction: SdoDirection,
    index: u16,
    sub: u8,
    data: Option<String>,
    timeout_s: Option<f64>,
) -> Result<Value, Refused> {
    let ctl = &state.controller;
    let (drive, axis) = sdo_drive(state, axis, drive)?;
    let mut request = match (direction, data) {
        (SdoDirection::Upload, _) => SdoRequest::upload(drive, index, sub),
        (SdoDirection::Download, None) => return Err(Refused::SdoNoData),
        (SdoDirection::Download, Some(hex)) => {
            let bytes = from_hex(&hex).ok_or_else(|| {
                let start: String = hex.chars().take(40).collect();
                Refused::SdoData(if start.len() < hex.len() {
                    format!("{start}…")
                } else {
                    start
                })
            })?;
            SdoRequest::download(drive, index, sub, SdoData::from(bytes))
        }
    };
    // What the drive's EDS says it would refuse is refused here, before anything is sent.
    if let Some(eds) = axis.and_then(|i| state.config.eds_of(i)) {
        let len = match &request.kind {
            SdoKind::Upload => None,
            SdoKind::Download(d) => Some(d.len()),
        };
        crate::canopen::eds::check_sdo(eds, index, sub, len)?;
    }
    if let Some(t) = timeout_s {
        request.timeout_ns = (number("timeout_s", t)?.clamp(0.001, 60.0) * 1e9) as u64;
    }
    let timeout_ns = request.timeout_ns;
    let handle = ctl.sdo(request)?;
    // The bus times the drive's silence out itself, each answer anew: a transfer that
    // goes on may take as many answers as the object has segments. Bounded by that (a
    // cycle that stopped taking requests is reported then): for the largest object at
    // 7 bytes a segment, four cycles each, plus the drive's timeout and a margin.
    let cycle = Duration::from_micros(u64::from(state.config.bus.cycle_us));
    let segments = u32::try_from(ctl.sdo_max_bytes() / 7 + 16).unwrap_or(u32::MAX);
    let wait = Duration::from_nanos(timeout_ns.max(SDO_TIMEOUT_NS))
        + Duration::from_secs(2)
        + cycle.saturating_mul(4).saturating_mul(segments);
    let outcome = tokio::task::spawn_blocking(move || handle.wait(wait))
        .await
        .map_err(|_| Refused::Control(ControlError::Ended))??;
    let data = outcome?;
    Ok(json!({ "drive": drive, "data": to_hex(data.as_slice()) }))
}

/// A cam table as the socket shows it.
fn cam_json(c: &crate::runtime::cam::CamInfo) -> Value {
    json!({
        "name": c.name,
        "slot": c.slot,
        "points": c.points,
        "interpolation": c.interpolation.name(),
        "periodic": c.periodic,
        "master_range": [c.master_range.0, c.master_range.1],
        "slave_rise": c.slave_rise,
    })
}

/// `cam_load`: the table made from the file or the points, handed to the cycle thread
/// and waited for (in a blocking thread: the controller polls its outcome); the table as
/// loaded.
async fn cam_load(
    state: &ServerState,
    name: String,
    file: Option<String>,
    points: Option<Vec<[f64; 2]>>,
    interpolation: Option<String>,
    periodic: Option<bool>,
) -> Result<Value, Refused> {
    let interpolation = match interpolation {
        None => None,
        Some(s) => Some(
            gantry_kernel::cam::Interpolation::from_name(&s).ok_or(Refused::CamInterpolation(s))?,
        ),
    };
    let table = match (file, points) {
        (Some(file), None) => {
            crate::cam::load_cam_file(std::path::Path::new(&file), interpolation, periodic)?
        }
        (None, Some(points)) => crate::cam::cam_from_points(&points, interpolation, periodic)?,
        _ => return Err(Refused::CamSource),
    };
    let handle = state.controller.load_cam(&name, table)?;
    let slot = tokio::task::spawn_blocking(move || handle.wait(Duration::from_secs(5)))
        .await
        .map_err(|_| Refused::Control(ControlError::Ended))??;
    let info = state
        .controller
        .cam_tables()
        .into_iter()
        .find(|c| c.slot == slot)
        .ok_or(Refused::Control(ControlError::NoCam(name)))?;
    Ok(cam_json(&info))
}

/// Axis `a` and its configuration, when it has a drive for `what` to reach (a real
/// axis); another type is refused by name (a virtual axis has no drive to talk to).
fn drive_axis<'s>(
    state: &'s ServerState,
    a: &str,
    what: &'static str,
) -> Result<(usize, &'s crate::config::AxisSection), Refused> {
    let i = state.controller.axis(a)?;
    let section = state
        .config
        .axes
        .get(i)
        .ok_or_else(|| Refused::NoConfig(a.to_string()))?;
    if section.axis_type != AxisType::Real {
        return Err(Refused::NoDrive {
            axis: a.to_string(),
            axis_type: section.axis_type.name(),
            what,
        });
    }
    Ok((i, section))
}

/// The bus position of the drive an SDO request names, and the axis it drives (none
/// when a drive position is no axis').
fn sdo_drive(
    state: &ServerState,
    axis: Option<String>,
    drive: Option<usize>,
) -> Result<(usize, Option<usize>), Refused> {
    match (axis, drive) {
        (Some(a), None) => {
            let (i, section) = drive_axis(state, &a, "an SDO transfer")?;
            Ok((section.drive, Some(i)))
        }
        (None, Some(d)) => Ok((d, state.config.axes.iter().position(|c| c.drive == d))),
        _ => Err(Refused::SdoTarget),
    }
}

/// What the drive's EDS says of an object (`object` request): its type, access and
/// name, for `gantry sdo` to read and write it as its type; `eds: null` when the drive
/// has no EDS in the configuration.
fn object(
    state: &ServerState,
    axis: Option<String>,
    drive: Option<usize>,
    index: u16,
    sub: u8,
) -> Result<Value, Refused> {
    let (drive, axis) = sdo_drive(state, axis, drive)?;
    let Some((i, eds)) = axis.and_then(|i| Some((i, state.config.eds_of(i)?))) else {
        return Ok(json!({ "drive": drive, "eds": null }));
    };
    let e = eds.entry(index, sub).ok_or_else(|| {
        Refused::Object(crate::canopen::eds::SdoEdsError::NotInEds {
            index,
            sub,
            file: eds.file.clone(),
        })
    })?;
    Ok(json!({
        "drive": drive,
        "node": state.config.axes.get(i).and_then(|a| a.node),
        "eds": eds.file,
        "name": e.name,
        "type": e.data_type.name(),
        "access": e.access.as_str(),
        "pdo_mapping": e.pdo_mapping,
    }))
}

/// Bytes as hex, two lower-case digits each.
pub fn to_hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut text = String::with_capacity(2 * bytes.len());
    for b in bytes {
        for d in [b >> 4, b & 0x0F] {
            text.push(char::from(
                DIGITS.get(usize::from(d)).copied().unwrap_or(b'0'),
            ));
        }
    }
    text
}

/// Hex digits as bytes (`None` unless an even number of hex digits).
pub fn from_hex(text: &str) -> Option<Vec<u8>> {
    let digits = text.as_bytes();
    if digits.len() % 2 != 0 || !digits.iter().all(u8::is_ascii_hexdigit) {
        return None;
    }
    digits
        .chunks(2)
        .map(|pair| u8::from_str_radix(std::str::from_utf8(pair).ok()?, 16).ok())
        .collect()
}

fn number(field: &'static str, value: f64) -> Result<f64, Refused> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Refused::NotFinite { field, value })
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Starts a commissioning procedure (`commission` request): one at a time per axis.
fn commission(
    state: &ServerState,
    a: String,
    kind: CommissionKind,
    (from, to, cycles, speed): (Option<f64>, Option<f64>, Option<u32>, Option<f64>),
    current: Option<u16>,
) -> Result<Value, Refused> {
    let i = state.controller.axis(&a)?;
    let section = state
        .config
        .axes
        .get(i)
        .ok_or_else(|| Refused::NoConfig(a.clone()))?;
    let missing = |operand: &'static str| {
        Refused::Commission(CommissionError::Operand {
            axis: a.clone(),
            procedure: "reversing",
            operand,
            reason: "is required".into(),
        })
    };
    if kind == CommissionKind::Commutation {
        drive_axis(state, &a, "a commutation measurement")?;
    }
    let procedure = match kind {
        CommissionKind::Commutation => Procedure::Commutation(CommutationSettings {
            drive: section.drive,
            counts_per_rev: section.scaling.counts_per_motor_rev,
            current_per_mille: current.or(section.commutation.current_per_mille),
            // Checked when the configuration was loaded.
            objects: section.commutation.objects().unwrap_or_default(),
        }),
        CommissionKind::Reversing => {
            let r = Reversing {
                from: from.ok_or_else(|| missing("--from"))?,
                to: to.ok_or_else(|| missing("--to"))?,
                cycles: cycles.ok_or_else(|| missing("--cycles"))?,
                speed,
                modulo: section.modulo,
            };
            r.check(&a)?;
            Procedure::Reversing(r)
        }
    };
    let mut procedures = lock(&state.procedures);
    if let Some((_, p)) = procedures
        .iter()
        .find(|(_, p)| p.axis() == i && p.outcome().is_none())
    {
        return Err(Refused::ProcedureRunning {
            axis: a,
            procedure: p.name(),
        });
    }
    let handle = crate::commission::start(&state.controller, i, procedure, state.saved.clone())?;
    let id = procedures.last().map_or(1, |(id, _)| id + 1);
    if procedures.len() >= 256 {
        procedures.remove(0);
    }
    procedures.push((id, handle));
    Ok(json!({ "procedure": id }))
}

/// A procedure's progress and outcome, as the `procedure` request replies.
fn procedure_json(state: &ServerState, p: &ProcedureHandle) -> Value {
    let progress = p.progress();
    let axis = state.controller.axes().get(p.axis()).cloned();
    let mut v = json!({
        "axis": axis,
        "procedure": p.name(),
        "phase": progress.phase,
        "progress": progress.fraction,
        "done": false,
    });
    match p.outcome() {
        None => {}
        Some(Ok(outcome)) => {
            v["done"] = json!(true);
            v["ok"] = json!(true);
            v["result"] = match outcome {
                ProcedureOutcome::Commutation { offset_counts } => json!({
                    "offset_counts": offset_counts,
                    "saved": p.saved(),
                }),
                ProcedureOutcome::Reversing { cycles } => json!({ "cycles": cycles }),
            };
        }
        Some(Err(e)) => {
            v["done"] = json!(true);
            v["ok"] = json!(false);
            v["cancelled"] = json!(matches!(*e, CommissionError::Cancelled { .. }));
            v["error"] = json!(Chain(&*e).to_string());
        }
    }
    v
}

async fn handle(state: &ServerState, request: Request) -> Result<Value, Refused> {
    let ctl = &state.controller;
    let axis = |name: &str| ctl.axis(name);
    let sent = |h: Result<CommandHandle, ControlError>| -> Result<Value, Refused> {
        let h = h?;
        let id = h.id();
        let mut handles = state.handles.lock().unwrap_or_else(|p| p.into_inner());
        if handles.len() >= 4096 {
            handles.remove(0);
        }
        handles.push(h);
        Ok(json!({ "handle": id }))
    };
    match request {
        Request::Status => Ok(status_json(state, &ctl.snapshot())),
        Request::Enable { axis: a } => {
            sent(ctl.command(axis(&a)?, Command::Power(PowerCommand::Enable)))
        }
        Request::Disable { axis: a } => {
            sent(ctl.command(axis(&a)?, Command::Power(PowerCommand::Disable)))
        }
        Request::Move {
            axis: a,
            to,
            mode,
            speed,
            acceleration,
            deceleration,
            jerk,
            buffer,
        } => {
            let i = axis(&a)?;
            let modulo = state
                .config
                .kernel_axes
                .get(i)
                .is_some_and(|c| c.mechanics.modulo.is_some());
            let mode = match (mode, modulo) {
                (MoveMode::Absolute, false) => PositioningMode::AbsNormal,
                // On a modulo axis "absolute" takes the shorter way round.
                (MoveMode::Absolute | MoveMode::Shortest, true) => PositioningMode::AbsModuloAuto,
                (MoveMode::Positive, true) => PositioningMode::AbsModuloPos,
                (MoveMode::Negative, true) => PositioningMode::AbsModuloNeg,
                (MoveMode::Relative, _) => PositioningMode::RelTarget,
                (MoveMode::Shortest | MoveMode::Positive | MoveMode::Negative, false) => {
                    return Err(Refused::NotModulo { mode, axis: a })
                }
            };
            let mut m = MovePtp::new(mode, number("to", to)?).buffered(buffer.into());
            // What the move leaves out: the saved dynamics of the last moves (Jetter's
            // rule, across restarts; the controller fills them in and saves what the
            // axis takes), then the axis' own.
            m.speed = speed;
            m.acceleration = acceleration;
            m.deceleration = deceleration;
            m.jerk = jerk;
            sent(ctl.command(i, Command::MovePtp(m)))
        }
        Request::Jog {
            axis: a,
            direction,
            speed,
            master,
            lock,
            lock_position,
        } => {
            let i = axis(&a)?;
            let d = state
                .config
                .kernel_axes
                .get(i)
                .map(|c| c.defaults)
                .ok_or(Refused::NoConfig(a))?;
            let cmd = match master {
                Some(m) => super::sync::master_jog(
                    axis(&m)?,
                    direction,
                    speed,
                    lock,
                    lock_position,
                    super::sync::catch_up(Some(d.acceleration), Some(d.deceleration), None)?,
                )?,
                None if lock.is_some() || lock_position.is_some() => {
                    return Err(Refused::Sync(
                        "lock and lock_position are for a jog with a master",
                    ))
                }
                None => Command::Jog(Jog::new(
                    direction.into(),
                    number("speed", speed)?,
                    d.acceleration,
                    d.deceleration,
                )),
            };
            sent(ctl.command(i, cmd))
        }
        Request::Gear {
            axis: a,
            master,
            numerator,
            denominator,
            source,
            acceleration,
            deceleration,
            jerk,
            master_sync_position,
            slave_sync_position,
            master_start_distance,
        } => {
            let i = axis(&a)?;
            let gear = super::sync::GearRequest {
                master: axis(&master)?,
                numerator,
                denominator,
                source,
                catch_up: super::sync::catch_up(acceleration, deceleration, jerk)?,
                master_sync_position,
                slave_sync_position,
                master_start_distance,
            };
            sent(ctl.command(i, gear.command()?))
        }
        Request::GearOut { axis: a } => sent(ctl.command(axis(&a)?, Command::GearOut)),
        Request::Group { group, op } => {
            let g = group_index(state, &group)?;
            sent(ctl.group_command(g, super::group::group_op(op)))
        }
        Request::MoveLinear {
            group,
            to,
            velocity,
            acceleration,
            deceleration,
            jerk,
            relative,
            buffer,
            transition,
            corner_deviation,
        } => {
            let g = group_index(state, &group)?;
            let axes = state.config.groups.get(g).map_or(0, |c| c.axes.len());
            let d = super::group::dynamics(velocity, acceleration, deceleration, jerk)?;
            let j = group_junction(state, g, buffer, transition, corner_deviation)?;
            let cmd = super::group::move_linear(&to, axes, d, relative, j)?;
            sent(ctl.group_command(g, cmd))
        }
        Request::MoveCircular {
            group,
            mode,
            aux,
            end,
            direction,
            axes,
            velocity,
            acceleration,
            deceleration,
            jerk,
            relative,
            buffer,
            transition,
            corner_deviation,
        } => {
            let g = group_index(state, &group)?;
            for (field, p) in [("aux", aux), ("end", end)] {
                for v in p {
                    number(field, v)?;
                }
            }
            let d = super::group::dynamics(velocity, acceleration, deceleration, jerk)?;
            let j = group_junction(state, g, buffer, transition, corner_deviation)?;
            let cmd = super::group::move_circular(
                mode,
                aux,
                end,
                direction,
                axes.unwrap_or([0, 1]),
                d,
                relative,
                j,
            );
            sent(ctl.group_command(g, cmd))
        }
        Request::Cam {
            axis: a,
            master,
            table,
            periodic,
            start,
            source,
            master_offset,
            slave_offset,
            master_scaling,
            slave_scaling,
            acceleration,
            deceleration,
            jerk,
        } => {
            let i = axis(&a)?;
            let slot = ctl.cam_slot(&table).ok_or(Refused::NoCamTable(table))?;
            let cam = super::sync::CamRequest {
                master: axis(&master)?,
                table: slot,
                periodic,
                start,
                source,
                placement: [master_offset, slave_offset, master_scaling, slave_scaling],
                catch_up: super::sync::catch_up(acceleration, deceleration, jerk)?,
            };
            sent(ctl.command(i, cam.command()?))
        }
        Request::CamOut { axis: a } => sent(ctl.command(axis(&a)?, Command::CamOut)),
        Request::Halt { axis: a } => sent(ctl.command(
            axis(&a)?,
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: None,
            },
        )),
        Request::Stop { axis: a } => {
            let i = axis(&a)?;
            // A commissioning procedure on the axis is cancelled too (it switches its
            // drive's current off and ends); the Stop is this one. A commutation
            // measurement runs with the axis Disabled (its drive enabled by the procedure):
            // there the stop is a power off, which ends the lending as a Stop would.
            let procedures = lock(&state.procedures);
            let running: Vec<&ProcedureHandle> = procedures
                .iter()
                .map(|(_, p)| p)
                .filter(|p| p.axis() == i && p.outcome().is_none())
                .collect();
            let disabled = ctl
                .snapshot()
                .axes
                .get(i)
                .is_some_and(|a| a.state == AxisState::Disabled);
            let command = if !running.is_empty() && disabled {
                Command::Power(PowerCommand::Disable)
            } else {
                Command::Stop { deceleration: None }
            };
            let stop = ctl.command(i, command);
            for p in running {
                p.cancel_stopped();
            }
            drop(procedures);
            sent(stop)
        }
        Request::Commission {
            axis: a,
            procedure,
            from,
            to,
            cycles,
            speed,
            current,
        } => commission(state, a, procedure, (from, to, cycles, speed), current),
        Request::Procedure { id } => {
            let procedures = lock(&state.procedures);
            let (_, p) = procedures
                .iter()
                .find(|(i, _)| *i == id)
                .ok_or(Refused::NoProcedure(id))?;
            Ok(procedure_json(state, p))
        }
        Request::Release { axis: a } => sent(ctl.command(axis(&a)?, Command::Release)),
        Request::SetPosition { axis: a, position } => sent(ctl.command(
            axis(&a)?,
            Command::SetPosition {
                position: number("position", position)?,
                relative: false,
            },
        )),
        Request::Reset { axis: a } => sent(ctl.reset(axis(&a)?)),
        // The kernel checks every operand (finite, > 0 where it must be) and says which.
        // What the call leaves out are the saved parameters (seed 000 §6.3.2, across
        // restarts: the controller fills MoveHome's in and saves what the axis takes); a
        // call that names no homing run repeats the axis' last.
        Request::Home {
            axis: a,
            params,
            step_switch,
        } => {
            let i = axis(&a)?;
            let method = match (&params, &step_switch) {
                (Some(_), Some(_)) => return Err(Refused::TwoHomings),
                (Some(_), None) => HomeMethod::MoveHome,
                (None, Some(_)) => HomeMethod::StepToSwitch,
                (None, None) => state.saved.home_method(i),
            };
            let command = match method {
                HomeMethod::MoveHome => {
                    Command::MoveHome(MoveHomeCall::from(params.unwrap_or_default()))
                }
                HomeMethod::StepToSwitch => Command::StepAbsoluteSwitch(
                    state
                        .saved
                        .step_switch_run(i, &step_switch.unwrap_or_default())?,
                ),
            };
            let mut reply = sent(ctl.command(i, command))?;
            reply["method"] = json!(method.name());
            Ok(reply)
        }
        Request::DriveHome { axis: a, params } => {
            let (i, cfg) = drive_axis(state, &a, "homing by the drive")?;
            let params = drive_home_params(cfg, &params)?;
            sent(ctl.drive_procedure(i, DriveProcedure::Homing(DriveHoming::new(params))))
        }
        Request::Sdo {
            axis: a,
            drive,
            direction,
            index,
            sub,
            data,
            timeout_s,
        } => sdo(state, a, drive, direction, index, sub, data, timeout_s).await,
        Request::Object {
            axis: a,
            drive,
            index,
            sub,
        } => object(state, a, drive, index, sub),
        Request::CamLoad {
            name,
            file,
            points,
            interpolation,
            periodic,
        } => cam_load(state, name, file, points, interpolation, periodic).await,
        Request::CamTables => Ok(json!({
            "tables": ctl.cam_tables().iter().map(cam_json).collect::<Vec<_>>()
        })),
        Request::Command { handle } => {
            let h = find(state, handle)?;
            let axes = ctl.axes();
            Ok(h.status()
                .map_or(json!({"status": "Pending"}), |s| status_name(s, axes)))
        }
        Request::Wait { handle, timeout_s } => {
            let h = find(state, handle)?;
            let timeout =
                Duration::from_secs_f64(number("timeout_s", timeout_s)?.clamp(0.0, 3600.0));
            match tokio::time::timeout(timeout, h.done()).await {
                Ok(s) => Ok(status_name(s, ctl.axes())),
                Err(_) => Err(Refused::NotFinal { handle, timeout_s }),
            }
        }
        Request::Trace { axes, seconds } => {
            let idx: Vec<usize> = axes.iter().map(|a| axis(a)).collect::<Result<_, _>>()?;
            if idx
                .iter()
                .any(|&i| i >= crate::runtime::protocol::TRACE_AXES)
            {
                return Err(Refused::NotTraced);
            }
            let seconds = number("seconds", seconds)?.clamp(0.0, 60.0);
            let start = ctl.snapshot().time_s;
            let mut ending = state.ending.subscribe();
            let complete = tokio::select! {
                _ = tokio::time::sleep(Duration::from_secs_f64(seconds)) => true,
                _ = ending.wait_for(|e| *e) => false,
            };
            state.collect_trace();
            let kept = state.trace.lock().unwrap_or_else(|p| p.into_inner());
            let rows: Vec<Value> = kept
                .iter()
                .filter(|s| s.time_s >= start)
                .map(|s| {
                    let mut row = vec![json!(s.time_s)];
                    for &i in &idx {
                        row.push(json!(s.set[i]));
                        row.push(json!(s.actual[i]));
                    }
                    Value::Array(row)
                })
                .collect();
            let columns: Vec<String> = std::iter::once("time_s".to_string())
                .chain(
                    axes.iter()
                        .flat_map(|a| [format!("{a}.set"), format!("{a}.actual")]),
                )
                .collect();
            Ok(json!({"columns": columns, "rows": rows, "complete": complete}))
        }
        Request::Shutdown => {
            ctl.shutdown()?;
            Ok(json!({"shutting_down": true}))
        }
    }
}

/// The axis' `[axis.drive_homing]` with the request's values in place of its own, in the
/// drive's counts; what is missing or wrong is refused by its key.
fn drive_home_params(
    cfg: &crate::config::AxisSection,
    p: &DriveHomeParams,
) -> Result<DriveHomingParams, Refused> {
    let base = cfg.drive_homing;
    let missing = |key: &'static str| Refused::DriveHoming {
        key: key.into(),
        reason: format!(
            "not given, and axis {:?} has no [axis.drive_homing] to take it from",
            cfg.name
        ),
    };
    let section = DriveHomingSection {
        method: p
            .method
            .or(base.map(|b| b.method))
            .ok_or_else(|| missing("method"))?,
        speed_switch: p
            .speed_switch
            .or(base.map(|b| b.speed_switch))
            .ok_or_else(|| missing("speed_switch"))?,
        speed_zero: p
            .speed_zero
            .or(base.map(|b| b.speed_zero))
            .ok_or_else(|| missing("speed_zero"))?,
        acceleration: p
            .acceleration
            .or(base.map(|b| b.acceleration))
            .ok_or_else(|| missing("acceleration"))?,
        home_offset: p.home_offset.or(base.map(|b| b.home_offset)).unwrap_or(0.0),
        timeout: p
            .timeout_s
            .or(base.map(|b| b.timeout))
            .unwrap_or(crate::config::DRIVE_HOMING_TIMEOUT_S),
        skip: p.skip.or(base.map(|b| b.skip)).unwrap_or(false),
    };
    let scaling = cfg
        .scaling()
        .map_err(|(key, reason)| Refused::DriveHoming { key, reason })?;
    section
        .params(&scaling, cfg.max.speed)
        .map_err(|(key, reason)| Refused::DriveHoming { key, reason })
}

impl From<protocol::BufferMode> for BufferMode {
    fn from(b: protocol::BufferMode) -> Self {
        match b {
            protocol::BufferMode::Aborting => Self::Aborting,
            protocol::BufferMode::Buffered => Self::Buffered,
            protocol::BufferMode::BlendingLow => Self::BlendingLow,
            protocol::BufferMode::BlendingPrevious => Self::BlendingPrevious,
            protocol::BufferMode::BlendingNext => Self::BlendingNext,
            protocol::BufferMode::BlendingHigh => Self::BlendingHigh,
        }
    }
}

impl From<JogDirection> for MoveDirection {
    fn from(d: JogDirection) -> Self {
        match d {
            JogDirection::Positive => Self::Positive,
            JogDirection::Negative => Self::Negative,
        }
    }
}

impl From<HomeSwitches> for SwitchConfig {
    fn from(s: HomeSwitches) -> Self {
        match s {
            HomeSwitches::None => Self::NoSwitch,
            HomeSwitches::RefAndLimit => Self::RefAndLimitSwitch,
            HomeSwitches::Ref => Self::RefSwitch,
            HomeSwitches::Limit => Self::LimitSwitch,
        }
    }
}

impl From<HomeMode> for HomingMode {
    fn from(m: HomeMode) -> Self {
        match m {
            HomeMode::Edge => Self::SwitchingEdge1Phase,
            HomeMode::Edge2 => Self::SwitchingEdge2Phase,
            HomeMode::ZeroPulse => Self::ZeroPulse1Phase,
            HomeMode::ZeroPulse2 => Self::ZeroPulse2Phase,
        }
    }
}

impl From<HomeParams> for MoveHomeCall {
    fn from(p: HomeParams) -> Self {
        Self {
            direction: p.direction.map(Into::into),
            switch_config: p.switches.map(Into::into),
            mode: p.mode.map(Into::into),
            acceleration: p.acceleration,
            jerk: p.jerk,
            speed_switch_search: p.speed_switch,
            max_distance_switch_search: p.max_distance_switch,
            speed_reference_search: p.speed_reference,
            max_distance_reference_search: p.max_distance_reference,
            reference_offset: p.reference_offset,
            normal_position: p.normal_position,
        }
    }
}

fn find(state: &ServerState, id: u64) -> Result<CommandHandle, Refused> {
    state
        .handles
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .iter()
        .find(|h| h.id() == id)
        .cloned()
        .ok_or(Refused::NoHandle(id))
}

/// A follower's relation to its master (`null` when it follows none and no bit is set).
fn sync_json(axes: &[String], s: &gantry_kernel::axis::status::AxisStatus) -> Value {
    let b = &s.bits;
    if s.master.is_none() && !b.sync_limit_exceeded {
        return Value::Null;
    }
    json!({
        "master": s.master.and_then(|m| axes.get(m)),
        "gearing": b.gearing,
        "camming": b.camming,
        "jogging": b.jogging,
        "in_sync": b.in_sync,
        "jog_locked": b.jog_locked,
        "end_of_profile": b.end_of_profile,
        "limit_exceeded": b.sync_limit_exceeded,
    })
}

/// The `status` reply.
pub fn status_json(state: &ServerState, snap: &Snapshot) -> Value {
    let axes: Vec<Value> = state
        .config
        .axes
        .iter()
        .zip(&snap.axes)
        .map(|(cfg, s)| {
            json!({
                "name": cfg.name,
                "type": cfg.axis_type.name(),
                "units": cfg.units,
                "state": s.state.name(),
                "position": s.actual_position,
                "set_position": s.set.p,
                "position_offset": s.position_offset,
                "velocity": s.set.v,
                "homed": s.bits.homed,
                "moving": s.bits.moving,
                "homing": {
                    "started": s.homing.started,
                    "switch_found": s.homing.switch_found,
                    "reference_found": s.homing.reference_found,
                    "reference_set": s.homing.reference_set,
                },
                "switches": {
                    "negative_limit": s.switches.negative_limit,
                    "positive_limit": s.switches.positive_limit,
                    "reference": s.switches.reference,
                },
                "error": s.error.as_ref().map(|f| fault_text(f, state.controller.axes())),
                "sync": sync_json(state.controller.axes(), s),
                "coordinated": s.bits.coordinated,
            })
        })
        .collect();
    // Axes with something on the bus: a real axis' drive, an external axis' encoder module
    // (its bus position; its state and statusword are a drive's, so none).
    let drives: Vec<Value> = state
        .config
        .axes
        .iter()
        .zip(&snap.drives)
        .filter_map(|(cfg, d)| {
            let position = match (cfg.axis_type, cfg.encoder_input) {
                (AxisType::Real, _) => cfg.drive,
                (AxisType::External, Some(e)) => e.slave,
                _ => return None,
            };
            Some((cfg, d, position))
        })
        .map(|(cfg, d, position)| {
            json!({
                "axis": cfg.name,
                "drive": position,
                "state": d.state.map(|s| s.name()),
                "statusword": format!("{:#06x}", d.statusword),
                "error_code": d.error_code.filter(|c| *c != 0).map(|c| format!("{c:#06x}: {}", describe(c))),
                "bus_fault": d.bus_fault.map(|f| f.to_string()),
                "mode": d.mode_display,
                "procedure": d.procedure.map(|p| json!({
                    "name": p.name,
                    "method": p.method,
                    "phase": p.phase,
                })),
                "canopen": d.can_node.map(|n| json!({
                    "node": n.node,
                    "nmt": n.nmt,
                    "heartbeat_ms_ago": n.heard_ms_ago,
                    "heartbeat_limit_ms": n.heartbeat_limit_ms,
                    "lost_tpdos": n.lost_tpdos,
                    "lost_in_a_row": n.lost_in_a_row,
                })),
            })
        })
        .collect();
    let groups: Vec<Value> = state
        .config
        .groups
        .iter()
        .zip(snap.groups.iter().zip(&snap.group_corners))
        .map(|(g, (s, c))| {
            json!({
                "name": g.name,
                "axes": g.axes.iter().filter_map(|&i| state.config.axes.get(i).map(|a| &a.name)).collect::<Vec<_>>(),
                "state": s.map(|s| s.name()),
                // What its blended junctions did (all 0 before the first).
                "blends": c.blends,
                "last_corner_deviation": c.last_deviation,
                "max_corner_deviation": c.max_deviation,
                "last_transit_speed": c.last_transit_speed,
            })
        })
        .collect();
    json!({
        "time_s": snap.time_s,
        "cycles": snap.cycle,
        "groups": groups,
        "real_time": state.real_time,
        "state_dir": state.saved.store().map(|s| s.dir().display().to_string()),
        "ended": snap.ended,
        "overrun_stop": snap.overrun_stop,
        "axes": axes,
        "drives": drives,
        "bus": {
            "lost_frames": snap.lost_frames,
            "working_counter_errors": snap.working_counter_errors,
            "dc": snap.dc_offset_ns.map(|ns| json!({
                "sync0_offset_us": ns as f64 / 1000.0,
                "target_us": snap.dc_target_ns.map(|t| t as f64 / 1000.0),
            })),
        },
        "cycle": snap.figures,
    })
}

/// The default socket path: `$XDG_RUNTIME_DIR/gantry.sock`, else `/tmp/gantry-UID.sock`.
pub fn default_socket() -> PathBuf {
    std::env::var_os("XDG_RUNTIME_DIR")
        .map(|d| PathBuf::from(d).join("gantry.sock"))
        .unwrap_or_else(|| {
            // SAFETY: getuid has no failure mode.
            let uid = unsafe { libc::getuid() };
            PathBuf::from(format!("/tmp/gantry-{uid}.sock"))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_master_named_by_index_is_named_by_its_axis_name_too() {
        let axes: Vec<String> = ["x", "y", "z", "e"].iter().map(|s| s.to_string()).collect();
        assert_eq!(
            fault_text(&AxisFault::MasterLost { master: 3 }, &axes),
            "master axis 3 (e) became unavailable (its encoder or drive failed)"
        );
        let e = CommandError::BadMaster {
            command: "GearIn",
            master: 0,
            why: "it follows this axis: the relations would go round in a loop",
        };
        assert_eq!(
            command_error_text(&e, &axes),
            "GearIn: axis 0 (x) cannot be this axis' master (it follows this axis: the \
             relations would go round in a loop)"
        );
        // An index the service does not know stays as the kernel wrote it.
        let e = CommandError::MasterNotAvailable {
            command: "CamIn",
            master: 9,
        };
        assert_eq!(command_error_text(&e, &axes), e.to_string());
        assert_eq!(
            fault_text(&AxisFault::Encoder { code: 0x8130 }, &axes),
            "encoder input failed 0x8130: the module's values stopped changing (TxPDO Toggle \
             frozen)"
        );
    }
}
