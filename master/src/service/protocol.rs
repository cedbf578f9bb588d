//! The control protocol: JSON lines over a Unix socket, versioned. One request per line,
//! one reply per line:
//!
//! ```text
//! → {"v":1,"cmd":"move","axis":"x","to":100.0,"speed":50.0}
//! ← {"v":1,"ok":true,"result":{"handle":7}}
//! → {"v":1,"cmd":"wait","handle":7,"timeout_s":10}
//! ← {"v":1,"ok":true,"result":{"status":"Done"}}
//! → {"v":1,"cmd":"frobnicate"}
//! ← {"v":1,"ok":false,"error":"unknown variant `frobnicate`, expected one of …"}
//! ```
//!
//! Commands: `status`, `enable`, `disable`, `move`, `jog`, `halt`, `stop`, `release`,
//! `set_position`, `reset`, `command` (status of a handle), `wait`, `trace`, `shutdown`. A malformed or
//! hostile request gets an error reply; nothing of it reaches the cycle thread.

use serde::{Deserialize, Serialize};
use serde_json::Value;

/// The protocol version this gantry speaks.
pub const VERSION: u64 = 1;
/// Longest request line accepted.
pub const MAX_LINE: usize = 64 * 1024;

/// A request.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(tag = "cmd", rename_all = "snake_case", deny_unknown_fields)]
pub enum Request {
    /// Axes, drives, bus and cycle figures.
    Status,
    /// Power on.
    Enable {
        /// Axis name.
        axis: String,
    },
    /// Power off (stopping first).
    Disable {
        /// Axis name.
        axis: String,
    },
    /// A point-to-point move.
    Move {
        /// Axis name.
        axis: String,
        /// Target (absolute) or distance (relative), in the axis' units.
        to: f64,
        /// `"absolute"` (default; the shorter way on a modulo axis) or `"relative"`; on a
        /// modulo axis also `"positive"` / `"negative"` (the direction to go round).
        #[serde(default)]
        mode: Option<String>,
        /// Speed (units/s).
        #[serde(default)]
        speed: Option<f64>,
        /// Acceleration (units/s²).
        #[serde(default)]
        acceleration: Option<f64>,
        /// Deceleration (units/s²).
        #[serde(default)]
        deceleration: Option<f64>,
        /// Jerk (units/s³).
        #[serde(default)]
        jerk: Option<f64>,
        /// `"aborting"` (default), `"buffered"`, `"blending-low"`, `"blending-previous"`,
        /// `"blending-next"`, `"blending-high"`.
        #[serde(default)]
        buffer: Option<String>,
    },
    /// Jog until halted.
    Jog {
        /// Axis name.
        axis: String,
        /// `"+"` or `"-"`.
        direction: String,
        /// Speed (units/s).
        speed: f64,
    },
    /// Decelerate to a stop (the axis takes new moves at once).
    Halt {
        /// Axis name.
        axis: String,
    },
    /// Stop and lock the axis until released.
    Stop {
        /// Axis name.
        axis: String,
    },
    /// Release a stopped axis.
    Release {
        /// Axis name.
        axis: String,
    },
    /// Set the axis' position without moving (absolute: marks it homed).
    SetPosition {
        /// Axis name.
        axis: String,
        /// The position the axis is at now.
        position: f64,
    },
    /// Leave ErrorStop: the slave back to OP if needed, the drive's fault reset.
    Reset {
        /// Axis name.
        axis: String,
    },
    /// The status of a command handle.
    Command {
        /// The handle.
        handle: u64,
    },
    /// Waits until a handle's status is final (or the timeout).
    Wait {
        /// The handle.
        handle: u64,
        /// Seconds to wait at most.
        timeout_s: f64,
    },
    /// Set and actual positions of some axes over the next seconds.
    Trace {
        /// Axis names.
        axes: Vec<String>,
        /// Seconds to record (up to 60).
        seconds: f64,
    },
    /// Quick-stop, disable, take the bus down and end the service.
    Shutdown,
}

/// Parses one request line: the version first, then the command.
pub fn parse(line: &str) -> Result<Request, String> {
    let mut value: Value = serde_json::from_str(line).map_err(|e| format!("not JSON: {e}"))?;
    let obj = value.as_object_mut().ok_or("a request is a JSON object")?;
    match obj.remove("v").and_then(|v| v.as_u64()) {
        Some(VERSION) => {}
        Some(v) => {
            return Err(format!(
                "protocol version {v} is not supported (this gantry speaks {VERSION})"
            ))
        }
        None => return Err(format!("missing \"v\": the protocol version ({VERSION})")),
    }
    serde_json::from_value(value).map_err(|e| e.to_string())
}

/// A successful reply line.
pub fn ok(result: Value) -> String {
    serde_json::json!({"v": VERSION, "ok": true, "result": result}).to_string()
}

/// An error reply line.
pub fn error(message: &str) -> String {
    serde_json::json!({"v": VERSION, "ok": false, "error": message}).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_parse_and_mistakes_are_explained() {
        assert_eq!(
            parse(r#"{"v":1,"cmd":"move","axis":"x","to":5}"#).unwrap(),
            Request::Move {
                axis: "x".into(),
                to: 5.0,
                mode: None,
                speed: None,
                acceleration: None,
                deceleration: None,
                jerk: None,
                buffer: None
            }
        );
        assert_eq!(parse(r#"{"v":1,"cmd":"status"}"#).unwrap(), Request::Status);
        for (line, says) in [
            ("{", "not JSON"),
            ("[1]", "a JSON object"),
            (r#"{"cmd":"status"}"#, "missing \"v\""),
            (r#"{"v":2,"cmd":"status"}"#, "version 2 is not supported"),
            (r#"{"v":1,"cmd":"frob"}"#, "unknown variant `frob`"),
            (r#"{"v":1,"cmd":"move","axis":"x"}"#, "missing field `to`"),
            (
                r#"{"v":1,"cmd":"move","axis":"x","to":"far"}"#,
                "invalid type",
            ),
            (
                r#"{"v":1,"cmd":"halt","axis":"x","now":true}"#,
                "unknown field `now`",
            ),
        ] {
            let e = parse(line).unwrap_err();
            assert!(e.contains(says), "{line}: {e}");
        }
    }
}
