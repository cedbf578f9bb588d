//! The client commands (`gantry status`, `move`, `jog`, …): one JSON line to the running
//! service's control socket, one line back, printed for people or (`--json`) for scripts.

use std::io::{BufRead, BufReader, IsTerminal, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use thiserror::Error;

use crate::plot::{self, Panel};
use gantry::service::protocol::{MoveMode, Request};
use gantry::trace::{Trace, TraceError};

/// Why a client command failed.
#[derive(Debug, Error)]
pub enum ClientError {
    /// The service is not there.
    #[error("cannot reach gantry at {path} (is `gantry run` running? --socket sets the path)")]
    Connect {
        /// Socket path.
        path: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The connection broke.
    #[error("control socket")]
    Io(#[source] std::io::Error),
    /// The request could not be written as JSON, or the reply is not JSON.
    #[error("control socket: {0}")]
    Json(&'static str, #[source] serde_json::Error),
    /// Writing the output failed.
    #[error("writing the output")]
    Output(#[source] std::io::Error),
    /// The trace could not be recorded or written.
    #[error(transparent)]
    Trace(#[from] TraceError),
    /// The SVG could not be written.
    #[error("cannot write {path}")]
    Write {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The service refused the request.
    #[error("{0}")]
    Refused(String),
    /// The command ended in error.
    #[error("{0}")]
    Failed(String),
    /// The command ended in error, and the text already says why the axis stopped (a
    /// refusal in ErrorStop names the axis' error).
    #[error("{0}")]
    Explained(String),
}

/// A connection to the service.
pub struct Client {
    writer: UnixStream,
    reader: BufReader<UnixStream>,
}

impl Client {
    /// Connects to the socket at `path`.
    pub fn connect(path: &Path) -> Result<Self, ClientError> {
        let connect_error = |source: std::io::Error| ClientError::Connect {
            path: path.display().to_string(),
            source,
        };
        let writer = UnixStream::connect(path).map_err(connect_error)?;
        let reader = BufReader::new(writer.try_clone().map_err(connect_error)?);
        Ok(Self { writer, reader })
    }

    /// Sends one request, returns the result or the service's error.
    pub fn request(&mut self, request: &Request) -> Result<Value, ClientError> {
        let line = request
            .to_line()
            .map_err(|e| ClientError::Json("request", e))?;
        writeln!(self.writer, "{line}").map_err(ClientError::Io)?;
        let mut line = String::new();
        self.reader.read_line(&mut line).map_err(ClientError::Io)?;
        let reply: Value =
            serde_json::from_str(&line).map_err(|e| ClientError::Json("reply", e))?;
        if reply["ok"] == json!(true) {
            Ok(reply["result"].clone())
        } else {
            Err(ClientError::Refused(
                reply["error"].as_str().unwrap_or("refused").to_string(),
            ))
        }
    }

    /// Waits until the cycle has taken command `handle` (its status is no longer Pending
    /// or Busy), at most `timeout`; an Error status is returned as the error.
    pub fn taken(&mut self, handle: u64, timeout: Duration) -> Result<(), ClientError> {
        let end = Instant::now() + timeout;
        loop {
            let s = self.request(&Request::Command { handle })?;
            match s["status"].as_str() {
                Some("Error") if s["names_cause"] == json!(true) => {
                    return Err(ClientError::Explained(
                        s["error"].as_str().unwrap_or("error").to_string(),
                    ))
                }
                Some("Error") => {
                    return Err(ClientError::Failed(
                        s["error"].as_str().unwrap_or("error").to_string(),
                    ))
                }
                Some("Pending" | "Busy") if Instant::now() < end => {
                    std::thread::sleep(Duration::from_millis(10));
                }
                _ => return Ok(()),
            }
        }
    }

    /// Waits for `handle` to be final; on a terminal, shows `progress` every 100 ms.
    pub fn wait(
        &mut self,
        handle: u64,
        timeout: Duration,
        mut progress: impl FnMut(&mut Self) -> Option<String>,
    ) -> Result<Value, ClientError> {
        let end = Instant::now() + timeout;
        let tty = std::io::stdout().is_terminal();
        loop {
            let s = self.request(&Request::Wait {
                handle,
                timeout_s: 0.1,
            });
            match s {
                Ok(status) => {
                    if tty {
                        print!("\r\x1b[K");
                    }
                    return match status["status"].as_str() {
                        Some("Done") => Ok(status),
                        Some("Error") if status["names_cause"] == json!(true) => {
                            Err(ClientError::Explained(
                                status["error"].as_str().unwrap_or("error").to_string(),
                            ))
                        }
                        Some("Error") => Err(ClientError::Failed(
                            status["error"].as_str().unwrap_or("error").to_string(),
                        )),
                        other => Err(ClientError::Failed(format!(
                            "ended {}",
                            other.unwrap_or("unknown")
                        ))),
                    };
                }
                Err(ClientError::Refused(e)) if e.contains("not final") => {}
                Err(e) => return Err(e),
            }
            if Instant::now() >= end {
                return Err(ClientError::Failed(format!(
                    "not done after {:.0} s (it goes on; `gantry status` shows it)",
                    timeout.as_secs_f64()
                )));
            }
            if tty {
                if let Some(line) = progress(self) {
                    print!("\r\x1b[K{line}");
                    let _ = std::io::stdout().flush();
                }
            }
        }
    }
}

/// The axis entry of a status reply.
fn axis_of<'a>(status: &'a Value, axis: &str) -> Option<&'a Value> {
    status["axes"]
        .as_array()?
        .iter()
        .find(|a| a["name"] == json!(axis))
}

/// What an axis follows, for the status table: "gear m in sync", "cam m catching up",
/// "jog m locked"; "-" for none; a limit exceeded (warning reaction) is flagged.
fn follows(sync: &Value) -> String {
    if sync.is_null() {
        return "-".into();
    }
    let kind = if sync["gearing"] == json!(true) {
        "gear"
    } else if sync["camming"] == json!(true) {
        "cam"
    } else if sync["jogging"] == json!(true) {
        "jog"
    } else {
        ""
    };
    let state = if kind == "jog" {
        if sync["jog_locked"] == json!(true) {
            "locked"
        } else {
            "waiting"
        }
    } else if sync["in_sync"] == json!(true) {
        "in sync"
    } else {
        "catching up"
    };
    let mut text = match sync["master"].as_str() {
        Some(m) => format!("{kind} {m} {state}"),
        None => String::new(),
    };
    if sync["limit_exceeded"] == json!(true) {
        text.push_str(" LIMIT");
    }
    if text.is_empty() {
        "-".into()
    } else {
        text
    }
}

/// The axis groups' table of `gantry status` (none without groups): state, axes, and
/// what the blends did — corners passed in motion, the last and largest deviation bound,
/// the last transit speed.
fn groups(s: &Value, out: &mut impl Write) -> Result<(), ClientError> {
    let Some(groups) = s["groups"].as_array().filter(|g| !g.is_empty()) else {
        return Ok(());
    };
    let io = ClientError::Output;
    writeln!(
        out,
        "{:<8} {:<15} {:<16} {:>6} {:>22} {:>10}",
        "group", "state", "axes", "blends", "corner dev. last/max", "transit"
    )
    .map_err(io)?;
    for g in groups {
        let axes: Vec<&str> = g["axes"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(Value::as_str)
            .collect();
        let num = |k: &str| g[k].as_f64().unwrap_or(0.0);
        writeln!(
            out,
            "{:<8} {:<15} {:<16} {:>6} {:>22} {:>10.3}",
            g["name"].as_str().unwrap_or("?"),
            g["state"].as_str().unwrap_or("-"),
            axes.join(","),
            g["blends"],
            format!(
                "{:.3} / {:.3}",
                num("last_corner_deviation"),
                num("max_corner_deviation")
            ),
            num("last_transit_speed")
        )
        .map_err(io)?;
    }
    Ok(())
}

/// `gantry status`.
pub fn status(
    client: &mut Client,
    json_out: bool,
    out: &mut impl Write,
) -> Result<(), ClientError> {
    let s = client.request(&Request::Status)?;
    let io = ClientError::Output;
    if json_out {
        writeln!(out, "{s}").map_err(io)?;
        return Ok(());
    }
    let f = |v: &Value| v.as_f64().map_or("-".into(), |x| format!("{x:.3}"));
    writeln!(
        out,
        "t = {:.3} s, {} cycles{}",
        s["time_s"].as_f64().unwrap_or(0.0),
        s["cycles"],
        if s["real_time"] == json!(true) {
            ""
        } else {
            " (not real time)"
        }
    )
    .map_err(io)?;
    writeln!(
        out,
        "{:<6} {:<9} {:<17} {:<20} {:>12} {:>12} {:>10} {:<5} {:<11} error",
        "axis", "type", "state", "follows", "position", "set", "velocity", "homed", "switches"
    )
    .map_err(io)?;
    for a in s["axes"].as_array().into_iter().flatten() {
        writeln!(
            out,
            "{:<6} {:<9} {:<17} {:<20} {:>12} {:>12} {:>10} {:<5} {:<11} {}",
            a["name"].as_str().unwrap_or("?"),
            a["type"].as_str().unwrap_or("real"),
            a["state"].as_str().unwrap_or("?"),
            follows(&a["sync"]),
            f(&a["position"]),
            f(&a["set_position"]),
            f(&a["velocity"]),
            if a["homed"] == json!(true) {
                "yes"
            } else {
                "no"
            },
            switches(&a["switches"]),
            a["error"].as_str().unwrap_or("")
        )
        .map_err(io)?;
    }
    writeln!(
        out,
        "{:<6} {:<6} {:<22} {:<10} fault",
        "axis", "drive", "drive state", "sw"
    )
    .map_err(io)?;
    for d in s["drives"].as_array().into_iter().flatten() {
        // A procedure the drive runs by itself shows where the fault would.
        let procedure = d["procedure"].is_object().then(|| {
            let p = &d["procedure"];
            format!(
                "{} method {}: {}",
                p["name"].as_str().unwrap_or("?"),
                p["method"],
                p["phase"].as_str().unwrap_or("?")
            )
        });
        let fault = d["bus_fault"]
            .as_str()
            .or(d["error_code"].as_str())
            .map(str::to_string)
            .or(procedure)
            .unwrap_or_default();
        writeln!(
            out,
            "{:<6} {:<6} {:<22} {:<10} {}",
            d["axis"].as_str().unwrap_or("?"),
            d["drive"].as_u64().map_or("?".into(), |n| n.to_string()),
            d["state"].as_str().unwrap_or("-"),
            d["statusword"].as_str().unwrap_or("-"),
            fault
        )
        .map_err(io)?;
    }
    can_nodes(&s, out)?;
    groups(&s, out)?;
    if s["overrun_stop"] == json!(true) {
        writeln!(
            out,
            "cycle: the axes were stopped after too many overruns in a row (rt.overrun_limit); reset them"
        )
        .map_err(io)?;
    }
    let c = &s["cycle"];
    let summary = |h: &Value| {
        let us = |key: &str| h[key].as_f64().unwrap_or(0.0);
        format!(
            "p50 {:.0} µs, p99 {:.0} µs, p99.9 {:.0} µs, max {:.0} µs",
            us("p50_us"),
            us("p99_us"),
            us("p999_us"),
            us("max_us")
        )
    };
    let figures = if c["wake"]["count"].as_u64().unwrap_or(0) == 0 {
        "cycle: no cycle recorded yet".to_string()
    } else {
        format!(
            "cycle: wake-up {}; compute {}; round trip {}; overruns {}",
            summary(&c["wake"]),
            summary(&c["compute"]),
            summary(&c["round_trip"]),
            c["overruns"]
        )
    };
    if s["drives"]
        .as_array()
        .is_some_and(|d| d.iter().any(|d| d["canopen"].is_object()))
    {
        // CANopen: what is lost is a drive's TPDOs in a cycle; there is no working
        // counter and no distributed clock.
        writeln!(
            out,
            "bus: CANopen, TPDO sets lost {} (a drive's TPDOs missing in a cycle; {} of \
             them in part)\n{figures}",
            s["bus"]["lost_frames"], s["bus"]["working_counter_errors"],
        )
        .map_err(io)?;
        return Ok(());
    }
    writeln!(
        out,
        "bus: lost frames {}, wrong working counters {}, {}\n{figures}",
        s["bus"]["lost_frames"],
        s["bus"]["working_counter_errors"],
        s["bus"]["dc"]["sync0_offset_us"]
            .as_f64()
            .map_or("no distributed clocks".into(), |us| {
                let held = s["bus"]["dc"]["target_us"]
                    .as_f64()
                    .map_or(", free-running".into(), |t| format!(", held at {t:.0} µs"));
                format!(
                    "distributed clocks: frames reach the reference {us:.0} µs into the SYNC0 period{held}"
                )
            }),
    )
    .map_err(io)?;
    Ok(())
}

/// On CANopen, the nodes as the bus sees them: node id, the NMT state of its last
/// heartbeat and how long ago it came (against the consumer time that stops its axes),
/// the exchanges whose TPDOs it missed.
fn can_nodes(s: &Value, out: &mut impl Write) -> Result<(), ClientError> {
    let io = ClientError::Output;
    let nodes: Vec<&Value> = s["drives"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|d| d["canopen"].is_object())
        .collect();
    if nodes.is_empty() {
        return Ok(());
    }
    writeln!(
        out,
        "{:<6} {:<5} {:<16} {:<22} lost TPDOs",
        "axis", "node", "NMT (heartbeat)", "last heartbeat"
    )
    .map_err(io)?;
    for d in nodes {
        let n = &d["canopen"];
        let limit = n["heartbeat_limit_ms"].as_u64().unwrap_or(0);
        let heard = n["heartbeat_ms_ago"]
            .as_u64()
            .map_or("-".into(), |ms| match limit {
                0 => format!("{ms} ms ago"),
                l => format!("{ms} ms ago (limit {l})"),
            });
        writeln!(
            out,
            "{:<6} {:<5} {:<16} {:<22} {} ({} in a row)",
            d["axis"].as_str().unwrap_or("?"),
            n["node"].as_u64().map_or("?".into(), |v| v.to_string()),
            n["nmt"].as_str().unwrap_or("none heard"),
            heard,
            n["lost_tpdos"],
            n["lost_in_a_row"]
        )
        .map_err(io)?;
    }
    Ok(())
}

/// Sends `request` for `axis` and, unless `no_wait`, waits for it with a progress line.
pub fn command(
    client: &mut Client,
    axis: &str,
    request: &Request,
    no_wait: bool,
    json_out: bool,
    out: &mut impl Write,
) -> Result<(), ClientError> {
    let io = ClientError::Output;
    let (target, relative) = match request {
        Request::Move { to, mode, .. } => (Some(*to), *mode == MoveMode::Relative),
        _ => (None, false),
    };
    let cmd = request.cmd();
    let request_is_move = matches!(
        request,
        Request::Move { .. } | Request::Home { .. } | Request::DriveHome { .. }
    );
    let sent = client.request(request)?;
    let handle = sent["handle"].as_u64().unwrap_or(0);
    // A homing run: which (the service says; a call without parameters repeats the axis'
    // last).
    let step_switch = sent["method"].as_str() == Some("step-to-switch");
    if no_wait {
        // Not waiting for the end, but for the cycle to take it: a refusal (no such
        // master, a loop, not allowed in this state) is this command's error.
        client.taken(handle, Duration::from_secs(5))?;
        if json_out {
            writeln!(out, "{}", json!({"handle": handle})).map_err(io)?;
        } else if cmd == "jog" {
            writeln!(
                out,
                "{axis}: jogging (handle {handle}); `gantry halt {axis}` stops it"
            )
            .map_err(io)?;
        } else if cmd == "gear" || cmd == "cam" {
            writeln!(
                out,
                "{axis}: following (handle {handle}); `gantry status` shows when it is in \
                 sync, `gantry {cmd} {axis} --out` ends it"
            )
            .map_err(io)?;
        } else {
            writeln!(out, "{axis}: started (handle {handle})").map_err(io)?;
        }
        return Ok(());
    }
    let start = client
        .request(&Request::Status)
        .ok()
        .and_then(|s| axis_of(&s, axis).and_then(|a| a["position"].as_f64()));
    let goal = match (target, start) {
        (Some(t), Some(p)) if relative => Some((p, p + t)),
        (Some(t), Some(p)) => Some((p, t)),
        _ => None,
    };
    // Moves may take long; power, halts and resets finish in seconds or not at all.
    let timeout = if request_is_move { 600 } else { 30 };
    let result = client.wait(handle, Duration::from_secs(timeout), |c| {
        let s = c.request(&Request::Status).ok()?;
        let a = axis_of(&s, axis)?;
        let p = a["position"].as_f64()?;
        let units = a["units"].as_str().unwrap_or("");
        Some(match goal {
            _ if cmd == "home" && step_switch => format!(
                "{axis} {p:10.3} {units} step-to-switch homing: {}",
                step_switch_phase(&a["homing"])
            ),
            _ if cmd == "home" => format!(
                "{axis} {p:10.3} {units} homing: {}",
                homing_phase(&a["homing"])
            ),
            _ if cmd == "drive_home" => format!(
                "{axis} {p:10.3} {units} drive homing: {}",
                drive_phase(&s, axis)
            ),
            Some((from, to)) if (to - from).abs() > 1e-9 => {
                let frac = ((p - from) / (to - from)).clamp(0.0, 1.0);
                let bar: String = (0..20)
                    .map(|i| if (i as f64) < frac * 20.0 { '#' } else { '-' })
                    .collect();
                format!(
                    "{axis} {p:10.3} {units} → {to:.3} {units} [{bar}] {:3.0}%",
                    frac * 100.0
                )
            }
            _ => format!(
                "{axis} {p:10.3} {units} ({})",
                a["state"].as_str().unwrap_or("?")
            ),
        })
    });
    let status = client.request(&Request::Status)?;
    let entry = axis_of(&status, axis);
    let position = entry.and_then(|a| a["position"].as_f64());
    // Where the command put the axis: the set position (a move's target when it is done;
    // with target monitoring off the actual may still be settling behind it).
    let set_position = entry.and_then(|a| a["set_position"].as_f64());
    match result {
        Ok(_) => {
            if json_out {
                writeln!(
                    out,
                    "{}",
                    json!({
                        "handle": handle,
                        "status": "Done",
                        "position": position,
                        "set_position": set_position,
                    })
                )
                .map_err(io)?;
            } else {
                let units = entry.and_then(|a| a["units"].as_str()).unwrap_or("");
                let set = set_position.or(position).unwrap_or(f64::NAN);
                let actual = position.unwrap_or(f64::NAN);
                let settling = if (actual - set).abs() >= 0.0005 {
                    format!(" (actual {actual:.3} {units})")
                } else {
                    String::new()
                };
                let state = entry.and_then(|a| a["state"].as_str()).unwrap_or("");
                let after = if cmd == "reset" {
                    after_reset(axis, state)
                } else {
                    String::new()
                };
                let outcome = if step_switch {
                    "homed by step-to-switch; stands at"
                } else {
                    outcome(cmd)
                };
                writeln!(out, "{axis}: {outcome} {set:.3} {units}{settling}{after}").map_err(io)?;
            }
            Ok(())
        }
        Err(ClientError::Explained(e)) => Err(ClientError::Failed(format!("{axis}: {e}"))),
        Err(e) => {
            // Say why, when the axis knows (a drive fault, the bus).
            let why = entry
                .and_then(|a| a["error"].as_str())
                .map(|r| format!(": {r}"))
                .unwrap_or_default();
            Err(ClientError::Failed(format!("{axis}: {e}{why}")))
        }
    }
}

/// What a reset left the axis in, in words (PLCopen MC_Reset: Standstill when its drive's
/// power is on, Disabled when it is off — see `Engine::reset`).
fn after_reset(axis: &str, state: &str) -> String {
    match state {
        "Standstill" => ", Standstill (its drive is powered)".into(),
        "Disabled" => format!(", Disabled (its drive's power is off: `gantry enable {axis}`)"),
        "" => String::new(),
        other => format!(", {other}"),
    }
}

/// What a finished command did, in words, before the position it left the axis at.
/// The active switches of an axis, in words ("-" when none is).
fn switches(sw: &Value) -> String {
    let active: Vec<&str> = [
        ("negative_limit", "neg"),
        ("positive_limit", "pos"),
        ("reference", "ref"),
    ]
    .into_iter()
    .filter(|(k, _)| sw[*k] == json!(true))
    .map(|(_, word)| word)
    .collect();
    if active.is_empty() {
        "-".into()
    } else {
        active.join(",")
    }
}

/// The phase a homing run is in, from its status bits (Jetter MoveHome: started, switch
/// found, reference found, reference set).
fn homing_phase(h: &Value) -> &'static str {
    let bit = |k: &str| h[k] == json!(true);
    if bit("reference_set") {
        "reference set"
    } else if bit("reference_found") {
        "reference found, going to the normal position"
    } else if bit("switch_found") {
        "switch found, searching the reference"
    } else if bit("started") {
        "searching the switch"
    } else {
        "starting"
    }
}

/// The phase a step-to-absolute-switch run is in, from its status bits (the cam's
/// crossing found is the switch and the reference at once).
fn step_switch_phase(h: &Value) -> &'static str {
    let bit = |k: &str| h[k] == json!(true);
    if bit("reference_set") {
        "reference set"
    } else if bit("reference_found") {
        "switch crossing found, stopping"
    } else if bit("started") {
        "searching the switch (reversing at the limit switches)"
    } else {
        "starting"
    }
}

/// What the axis' drive is doing in its procedure, from the status ("homing", "switching
/// back to CSP", …), with its method.
fn drive_phase(s: &Value, axis: &str) -> String {
    let drive = s["drives"]
        .as_array()
        .into_iter()
        .flatten()
        .find(|d| d["axis"].as_str() == Some(axis));
    match drive.map(|d| &d["procedure"]) {
        Some(p) if p.is_object() => format!(
            "method {}: {}",
            p["method"],
            p["phase"].as_str().unwrap_or("?")
        ),
        _ => "starting".into(),
    }
}

fn outcome(cmd: &str) -> &'static str {
    match cmd {
        "enable" => "enabled at",
        "disable" => "disabled at",
        "halt" => "halted at",
        "stop" => "stopped at",
        "release" => "released at",
        "set_position" => "position set to",
        "reset" => "reset at",
        "home" => "homed; stands at",
        "drive_home" => "homed by its drive; stands at",
        _ => "done at",
    }
}

/// `gantry trace`: records, then writes CSV or SVG (by the file's extension).
pub fn trace(
    client: &mut Client,
    axes: &[String],
    seconds: f64,
    path: &Path,
    xy: bool,
    out: &mut impl Write,
) -> Result<(), ClientError> {
    let r = client.request(&Request::Trace {
        axes: axes.to_vec(),
        seconds,
    })?;
    let columns: Vec<String> = r["columns"]
        .as_array()
        .into_iter()
        .flatten()
        .skip(1)
        .filter_map(|c| c.as_str().map(String::from))
        .collect();
    let rows = r["rows"].as_array().cloned().unwrap_or_default();
    let mut t = Trace::new(columns.clone(), rows.len().max(1));
    for row in &rows {
        let v: Vec<f64> = row
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(Value::as_f64)
            .collect();
        if let Some((time, values)) = v.split_first() {
            t.push(*time, values)?;
        }
    }
    let svg = path.extension().is_some_and(|e| e == "svg");
    if svg && xy {
        // Columns: x.set, x.actual, y.set, y.actual.
        let title = format!("{} / {}: set and actual path", axes[0], axes[1]);
        let doc = plot::xy_svg(&t, &title, &[(0, 2), (1, 3)]);
        std::fs::write(path, doc).map_err(|source| ClientError::Write {
            path: path.display().to_string(),
            source,
        })?;
    } else if svg {
        let doc = plot::svg(
            &t,
            &[Panel {
                title: "set and actual position".into(),
                channels: (0..columns.len()).collect(),
            }],
        );
        std::fs::write(path, doc).map_err(|source| ClientError::Write {
            path: path.display().to_string(),
            source,
        })?;
    } else {
        t.write_csv(path)?;
    }
    let cut_short = if r["complete"] == json!(false) {
        " (gantry stopped: the recording ends there)"
    } else {
        ""
    };
    writeln!(
        out,
        "trace: {} samples of {} to {}{cut_short}",
        rows.len(),
        axes.join(", "),
        path.display()
    )
    .map_err(ClientError::Output)?;
    Ok(())
}

/// `gantry commission AXIS …`: starts the procedure, shows its progress until it ends
/// (on a terminal), and prints its outcome. When `interrupted` turns true (Ctrl-C) the
/// axis is stopped (`stop`, which cancels the procedure: it switches the drive's current
/// off and leaves the axis stopped) and the procedure's end is waited for and reported.
pub fn commission(
    client: &mut Client,
    request: &Request,
    interrupted: &std::sync::atomic::AtomicBool,
    json_out: bool,
    out: &mut impl Write,
) -> Result<(), ClientError> {
    use std::sync::atomic::Ordering;
    let io = ClientError::Output;
    let axis = request.axis().unwrap_or_default().to_string();
    let started = client.request(request)?;
    let id = started["procedure"].as_u64().unwrap_or(0);
    let tty = std::io::stdout().is_terminal();
    let mut stopped = false;
    let end = loop {
        if interrupted.load(Ordering::Relaxed) && !stopped {
            stopped = true;
            if tty {
                print!("\r\x1b[K");
            }
            writeln!(out, "{axis}: stopping (Ctrl-C)").map_err(io)?;
            client.request(&Request::Stop { axis: axis.clone() })?;
        }
        let p = client.request(&Request::Procedure { id })?;
        if p["done"] == json!(true) {
            if tty {
                print!("\r\x1b[K");
            }
            break p;
        }
        if tty {
            let frac = p["progress"].as_f64().unwrap_or(0.0).clamp(0.0, 1.0);
            let bar: String = (0..20)
                .map(|i| if (i as f64) < frac * 20.0 { '#' } else { '-' })
                .collect();
            print!(
                "\r\x1b[K{axis} {} [{bar}] {:3.0}%  {}",
                p["procedure"].as_str().unwrap_or(""),
                frac * 100.0,
                p["phase"].as_str().unwrap_or("")
            );
            let _ = std::io::stdout().flush();
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    if json_out {
        writeln!(out, "{end}").map_err(io)?;
    }
    if end["ok"] != json!(true) {
        return Err(ClientError::Explained(
            end["error"].as_str().unwrap_or("failed").to_string(),
        ));
    }
    if !json_out {
        let r = &end["result"];
        let line = match end["procedure"].as_str() {
            Some("commutation") => format!(
                "{axis}: commutation offset {} counts written to the drive, {}; the axis is \
                 disabled (enable it to move)",
                r["offset_counts"],
                r["saved"].as_str().unwrap_or("not saved")
            ),
            _ => format!("{axis}: reversing done, {} cycles", r["cycles"]),
        };
        writeln!(out, "{line}").map_err(io)?;
    }
    Ok(())
}
