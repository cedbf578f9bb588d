//! `gantry sdo upload|download`: an object's address (`INDEX:SUB`) and value as a user
//! types them, turned into the bytes of the transfer and back. Numbers are little-endian
//! on the wire (CiA 301 §7.1.2, ETG.1000.6 §5.6: the object dictionary's encoding), so a
//! value is written with exactly its type's width; a value that does not fit the type is
//! refused here, before anything reaches the drive. Without `--type`, a drive whose axis
//! names its EDS (`[[axis]] eds`) has each object read and written as the EDS' data type
//! says (the service answers an `object` request from the configuration, and refuses an
//! object the EDS does not have: "0x2001:00 is not in drive.eds"); a drive without an
//! EDS is read and written as raw hex bytes, as before. A large object (a recorder, a
//! parameter set) goes to or comes from a file as raw bytes (`--out`, `--file`).

use std::fmt;
use std::io::Write;
use std::path::PathBuf;
use std::str::FromStr;

use gantry::service::protocol::{Request, SdoDirection};
use gantry_drives::canopen::eds::{DataType, Value};
use serde_json::json;
use thiserror::Error;

use crate::client::{Client, ClientError};

/// The type a value is read or written as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoType {
    /// UNSIGNED8.
    U8,
    /// UNSIGNED16.
    U16,
    /// UNSIGNED32.
    U32,
    /// UNSIGNED64.
    U64,
    /// INTEGER8.
    I8,
    /// INTEGER16.
    I16,
    /// INTEGER32.
    I32,
    /// INTEGER64.
    I64,
    /// REAL32.
    F32,
    /// VISIBLE_STRING.
    String,
    /// Raw bytes, as hex digits.
    Hex,
}

/// Every type with its name on the command line.
const TYPES: &[(&str, SdoType)] = &[
    ("u8", SdoType::U8),
    ("u16", SdoType::U16),
    ("u32", SdoType::U32),
    ("u64", SdoType::U64),
    ("i8", SdoType::I8),
    ("i16", SdoType::I16),
    ("i32", SdoType::I32),
    ("i64", SdoType::I64),
    ("f32", SdoType::F32),
    ("string", SdoType::String),
    ("hex", SdoType::Hex),
];

impl FromStr for SdoType {
    type Err = String;

    fn from_str(word: &str) -> Result<Self, String> {
        TYPES
            .iter()
            .find(|(n, _)| *n == word)
            .map(|(_, t)| *t)
            .ok_or_else(|| {
                let names: Vec<&str> = TYPES.iter().map(|(n, _)| *n).collect();
                format!("type {word:?} is not one of {}", names.join(", "))
            })
    }
}

impl fmt::Display for SdoType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = TYPES
            .iter()
            .find(|(_, t)| t == self)
            .map_or("?", |(n, _)| n);
        f.write_str(name)
    }
}

/// Why what the user typed is not an SDO transfer.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum SdoInputError {
    /// The address is not `INDEX:SUB`.
    #[error(
        "object {0:?} is not INDEX:SUB (e.g. 0x6060:0 or 6060:00; index up to 0xFFFF, \
         sub-index up to 0xFF, in hex)"
    )]
    Address(String),
    /// The value does not fit the type.
    #[error("value {value:?} is not a {ty}{why}")]
    Value {
        /// What was typed.
        value: String,
        /// The type.
        ty: SdoType,
        /// More about it.
        why: &'static str,
    },
    /// The value does not fit the EDS' type.
    #[error("value {value:?} is not a {ty}, the object's type in its EDS ({why})")]
    EdsValue {
        /// What was typed.
        value: String,
        /// The type.
        ty: &'static str,
        /// Why.
        why: String,
    },
    /// The bytes read are not as long as the EDS' type.
    #[error(
        "the drive sent {got} bytes ({hex}), a {ty} (the object's type in its EDS) has \
         {want}; --type hex shows them raw"
    )]
    EdsWidth {
        /// The type.
        ty: &'static str,
        /// Its width.
        want: usize,
        /// Bytes received.
        got: usize,
        /// The bytes.
        hex: String,
    },
    /// The bytes read are not as long as the type.
    #[error("the drive sent {got} bytes ({hex}), a {ty} has {want}; --type hex shows them raw")]
    Width {
        /// The type asked for.
        ty: SdoType,
        /// Its width.
        want: usize,
        /// Bytes received.
        got: usize,
        /// The bytes.
        hex: String,
    },
}

/// How a transfer's value is read and written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Typing {
    /// As the user's `--type`.
    Given(SdoType),
    /// As the entry's data type in the drive's EDS, on node `node` (for `$NODEID`).
    Eds {
        /// The CiA 301 type.
        ty: DataType,
        /// The drive's node id.
        node: u8,
    },
}

impl fmt::Display for Typing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Given(t) => t.fmt(f),
            Self::Eds { ty, .. } => f.write_str(ty.name()),
        }
    }
}

impl Typing {
    /// The bytes of `value`.
    pub fn encode(self, value: &str) -> Result<Vec<u8>, SdoInputError> {
        match self {
            Self::Given(t) => encode(t, value),
            Self::Eds { ty, node } => encode_eds(ty, node, value),
        }
    }

    /// `bytes` for people.
    pub fn decode(self, bytes: &[u8]) -> Result<String, SdoInputError> {
        match self {
            Self::Given(t) => decode(t, bytes),
            Self::Eds { ty, .. } => decode_eds(ty, bytes),
        }
    }
}

/// The bytes of `value` as an entry of CiA 301 type `ty` on node `node` (integers as
/// `--type` takes them: decimal or 0x… hex, within the type's range; other types as
/// an EDS writes them: reals, strings, octets as hex digits).
pub fn encode_eds(ty: DataType, node: u8, value: &str) -> Result<Vec<u8>, SdoInputError> {
    let bad = |why: String| SdoInputError::EdsValue {
        value: value.to_string(),
        ty: ty.name(),
        why,
    };
    let parsed = if ty.is_integer() {
        integer(value.trim())
            .map(Value::Integer)
            .ok_or_else(|| bad("a whole number, or 0x… hex".into()))?
    } else {
        Value::parse(value, ty)
            .map_err(|e| bad(e.to_string()))?
            .ok_or_else(|| bad("no value given".into()))?
    };
    if let Value::Real(f) = parsed {
        if !f.is_finite() {
            return Err(bad("a finite number".into()));
        }
    }
    parsed.to_le_bytes(ty, node).map_err(|e| bad(e.to_string()))
}

/// `bytes` read as an entry of CiA 301 type `ty`, for people (integers in decimal).
pub fn decode_eds(ty: DataType, bytes: &[u8]) -> Result<String, SdoInputError> {
    let value = Value::from_le_bytes(bytes, ty).map_err(|_| SdoInputError::EdsWidth {
        ty: ty.name(),
        want: ty.bytes().unwrap_or(0),
        got: bytes.len(),
        hex: gantry::service::server::to_hex(bytes),
    })?;
    Ok(match value {
        Value::Integer(n) => n.to_string(),
        Value::Real(f) if ty == DataType::Real32 => (f as f32).to_string(),
        Value::Real(f) => f.to_string(),
        // A VISIBLE_STRING may end in NULs (CiA 301 §7.1.6.3 pads with them).
        Value::Text(t) => t.trim_end_matches('\0').to_string(),
        Value::Octets(b) => gantry::service::server::to_hex(&b),
        other => other.to_eds(ty),
    })
}

/// Reads `INDEX:SUB`: both hexadecimal, with or without `0x`.
pub fn parse_address(text: &str) -> Result<(u16, u8), SdoInputError> {
    let bad = || SdoInputError::Address(text.to_string());
    let (index, sub) = text.split_once(':').ok_or_else(bad)?;
    fn hex(s: &str) -> Option<&str> {
        let s = s.trim();
        let s = s
            .strip_prefix("0x")
            .or_else(|| s.strip_prefix("0X"))
            .unwrap_or(s);
        (!s.is_empty() && s.bytes().all(|b| b.is_ascii_hexdigit())).then_some(s)
    }
    let index = u16::from_str_radix(hex(index).ok_or_else(bad)?, 16).map_err(|_| bad())?;
    let sub = u8::from_str_radix(hex(sub).ok_or_else(bad)?, 16).map_err(|_| bad())?;
    Ok((index, sub))
}

/// A number as typed: decimal, or hexadecimal with `0x` (negative with `-`).
fn integer(text: &str) -> Option<i128> {
    let (negative, digits) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text),
    };
    let magnitude = match digits
        .strip_prefix("0x")
        .or_else(|| digits.strip_prefix("0X"))
    {
        Some(hex) => i128::from_str_radix(hex, 16).ok()?,
        None if digits.bytes().all(|b| b.is_ascii_digit()) && !digits.is_empty() => {
            digits.parse().ok()?
        }
        None => return None,
    };
    Some(if negative { -magnitude } else { magnitude })
}

/// The bytes of `value` as `ty`.
pub fn encode(ty: SdoType, value: &str) -> Result<Vec<u8>, SdoInputError> {
    let bad = |why: &'static str| SdoInputError::Value {
        value: value.to_string(),
        ty,
        why,
    };
    let int = |min: i128, max: i128| {
        let n = integer(value.trim()).ok_or_else(|| bad(" (a whole number, or 0x… hex)"))?;
        if n < min || n > max {
            return Err(bad(" (out of its range)"));
        }
        Ok(n)
    };
    Ok(match ty {
        SdoType::U8 => vec![int(0, u8::MAX.into())? as u8],
        SdoType::U16 => (int(0, u16::MAX.into())? as u16).to_le_bytes().to_vec(),
        SdoType::U32 => (int(0, u32::MAX.into())? as u32).to_le_bytes().to_vec(),
        SdoType::U64 => (int(0, u64::MAX.into())? as u64).to_le_bytes().to_vec(),
        SdoType::I8 => (int(i8::MIN.into(), i8::MAX.into())? as i8)
            .to_le_bytes()
            .to_vec(),
        SdoType::I16 => (int(i16::MIN.into(), i16::MAX.into())? as i16)
            .to_le_bytes()
            .to_vec(),
        SdoType::I32 => (int(i32::MIN.into(), i32::MAX.into())? as i32)
            .to_le_bytes()
            .to_vec(),
        SdoType::I64 => (int(i64::MIN.into(), i64::MAX.into())? as i64)
            .to_le_bytes()
            .to_vec(),
        SdoType::F32 => {
            let f: f32 = value.trim().parse().map_err(|_| bad(" (a number)"))?;
            if !f.is_finite() {
                return Err(bad(" (a finite number)"));
            }
            f.to_le_bytes().to_vec()
        }
        SdoType::String => value.as_bytes().to_vec(),
        SdoType::Hex => {
            let digits: String = value.chars().filter(|c| !c.is_whitespace()).collect();
            gantry::service::server::from_hex(&digits)
                .ok_or_else(|| bad(" (pairs of hex digits, e.g. 0a1b)"))?
        }
    })
}

/// `bytes` read as `ty`, for people.
pub fn decode(ty: SdoType, bytes: &[u8]) -> Result<String, SdoInputError> {
    let width = |want: usize| {
        if bytes.len() == want {
            Ok(())
        } else {
            Err(SdoInputError::Width {
                ty,
                want,
                got: bytes.len(),
                hex: gantry::service::server::to_hex(bytes),
            })
        }
    };
    let le = |n: usize| {
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(&bytes[..n]);
        u64::from_le_bytes(b)
    };
    Ok(match ty {
        SdoType::U8 => width(1).map(|_| le(1).to_string())?,
        SdoType::U16 => width(2).map(|_| le(2).to_string())?,
        SdoType::U32 => width(4).map(|_| le(4).to_string())?,
        SdoType::U64 => width(8).map(|_| le(8).to_string())?,
        SdoType::I8 => width(1).map(|_| (le(1) as u8 as i8).to_string())?,
        SdoType::I16 => width(2).map(|_| (le(2) as u16 as i16).to_string())?,
        SdoType::I32 => width(4).map(|_| (le(4) as u32 as i32).to_string())?,
        SdoType::I64 => width(8).map(|_| (le(8) as i64).to_string())?,
        SdoType::F32 => width(4).map(|_| f32::from_bits(le(4) as u32).to_string())?,
        // A VISIBLE_STRING may end in NULs (CiA 301 §7.1.6.3 pads with them).
        SdoType::String => String::from_utf8_lossy(bytes)
            .trim_end_matches('\0')
            .to_string(),
        SdoType::Hex => gantry::service::server::to_hex(bytes),
    })
}

/// The drive a transfer goes to: an axis' or a bus position.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    /// The drive of this axis.
    Axis(String),
    /// The drive at this position on the bus.
    Drive(usize),
    /// The CANopen drive with this node id (resolved through the service's status).
    Node(u8),
}

/// How to read and write `index`:`sub` of the drive: `ty` when given, else the type
/// the drive's EDS gives it (the service refuses an object the EDS does not have), else
/// raw hex.
pub fn typing(
    client: &mut Client,
    axis: Option<String>,
    drive: Option<usize>,
    index: u16,
    sub: u8,
    ty: Option<SdoType>,
) -> Result<Typing, SdoCliError> {
    if let Some(t) = ty {
        return Ok(Typing::Given(t));
    }
    let reply = client.request(&Request::Object {
        axis,
        drive,
        index,
        sub,
    })?;
    Ok(match reply["type"].as_str().and_then(DataType::from_name) {
        Some(ty) => Typing::Eds {
            ty,
            node: reply["node"]
                .as_u64()
                .and_then(|n| u8::try_from(n).ok())
                .unwrap_or(0),
        },
        None => Typing::Given(SdoType::Hex),
    })
}

/// A file a transfer's raw bytes go to or come from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum File {
    /// An upload's bytes are written here.
    Out(PathBuf),
    /// A download's bytes are read from here.
    In(PathBuf),
}

/// A transfer as typed on the command line.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer<'a> {
    /// Which drive.
    pub target: Target,
    /// `INDEX:SUB`.
    pub address: &'a str,
    /// The value to write; `None` reads.
    pub value: Option<&'a str>,
    /// How the value is typed (`None`: as the drive's EDS types the object, raw hex
    /// for a drive without an EDS).
    pub ty: Option<SdoType>,
    /// Seconds the drive may take (`None`: the service's default).
    pub timeout_s: Option<f64>,
    /// The raw bytes to a file (upload) or from one (download, instead of `value`).
    pub file: Option<File>,
}

/// Runs `gantry sdo upload` (no value) or `download`: prints the value read (as its
/// type), or nothing for a write; with `json_out`, one object.
pub fn run(
    client: &mut Client,
    transfer: &Transfer<'_>,
    json_out: bool,
    out: &mut dyn Write,
) -> Result<(), SdoCliError> {
    let (index, sub) = parse_address(transfer.address)?;
    let (axis, drive) = match &transfer.target {
        Target::Axis(a) => (Some(a.clone()), None),
        Target::Drive(d) => (None, Some(*d)),
        Target::Node(n) => (None, Some(drive_of_node(client, *n)?)),
    };
    // A file holds raw bytes, whatever the object's type.
    let ty = match &transfer.file {
        Some(_) => Typing::Given(SdoType::Hex),
        None => typing(client, axis.clone(), drive, index, sub, transfer.ty)?,
    };
    let data = match &transfer.file {
        Some(File::In(path)) => Some(std::fs::read(path).map_err(|source| SdoCliError::File {
            path: path.display().to_string(),
            source,
        })?),
        _ => transfer.value.map(|v| ty.encode(v)).transpose()?,
    };
    let direction = if data.is_some() {
        SdoDirection::Download
    } else {
        SdoDirection::Upload
    };
    let request = Request::Sdo {
        axis,
        drive,
        direction,
        index,
        sub,
        data: data.as_deref().map(gantry::service::server::to_hex),
        timeout_s: transfer.timeout_s,
    };
    let reply = client.request(&request)?;
    let hex = reply["data"].as_str().unwrap_or_default();
    let bytes = gantry::service::server::from_hex(hex).unwrap_or_default();
    let print = |out: &mut dyn Write, text: String| {
        writeln!(out, "{text}").map_err(|e| SdoCliError::Client(ClientError::Output(e)))
    };
    match (&transfer.file, data.as_deref()) {
        (Some(File::Out(path)), _) => {
            std::fs::write(path, &bytes).map_err(|source| SdoCliError::File {
                path: path.display().to_string(),
                source,
            })?;
            let path = path.display().to_string();
            let n = bytes.len();
            return print(
                out,
                if json_out {
                    json!({"index": index, "sub": sub, "bytes": n, "out": path}).to_string()
                } else {
                    format!("{n} bytes to {path}")
                },
            );
        }
        (Some(File::In(_)), Some(written)) => {
            let n = written.len();
            return match json_out {
                true => print(
                    out,
                    json!({"index": index, "sub": sub, "bytes": n}).to_string(),
                ),
                false => Ok(()),
            };
        }
        _ => {}
    }
    match (direction, json_out) {
        (SdoDirection::Upload, false) => print(out, ty.decode(&bytes)?),
        (SdoDirection::Upload, true) => {
            let value = ty.decode(&bytes).ok();
            print(
                out,
                json!({"index": index, "sub": sub, "data": hex, "type": ty.to_string(), "value": value})
                    .to_string(),
            )
        }
        (SdoDirection::Download, false) => Ok(()),
        (SdoDirection::Download, true) => print(
            out,
            json!({"index": index, "sub": sub, "written": to_hex_or_empty(data.as_deref())})
                .to_string(),
        ),
    }
}

fn to_hex_or_empty(data: Option<&[u8]>) -> String {
    data.map(gantry::service::server::to_hex)
        .unwrap_or_default()
}

/// Why `gantry sdo` failed.
#[derive(Debug, Error)]
pub enum SdoCliError {
    /// What was typed.
    #[error(transparent)]
    Input(#[from] SdoInputError),
    /// The service, the bus or the drive.
    #[error(transparent)]
    Client(#[from] ClientError),
    /// The file of `--out` or `--file`.
    #[error("{path}")]
    File {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// `--node N` names no CANopen node of the running bus.
    #[error("--node {node}: no such CANopen node on this bus ({nodes})")]
    NoNode {
        /// The node asked for.
        node: u8,
        /// The bus' nodes, or why there are none.
        nodes: String,
    },
}

/// The bus position of the CANopen drive with node id `node`, from the service's status.
fn drive_of_node(client: &mut Client, node: u8) -> Result<usize, SdoCliError> {
    let status = client.request(&Request::Status)?;
    let drives: Vec<(u64, u64)> = status["drives"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|d| Some((d["canopen"]["node"].as_u64()?, d["drive"].as_u64()?)))
        .collect();
    if let Some((_, drive)) = drives.iter().find(|(n, _)| *n == u64::from(node)) {
        return Ok(*drive as usize);
    }
    let nodes = if drives.is_empty() {
        "it is not a CANopen bus: use --axis or --drive".to_string()
    } else {
        let ids: Vec<String> = drives.iter().map(|(n, _)| n.to_string()).collect();
        format!("its nodes: {}", ids.join(", "))
    };
    Err(SdoCliError::NoNode { node, nodes })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_are_hex_index_colon_hex_sub() {
        assert_eq!(parse_address("0x6060:0"), Ok((0x6060, 0)));
        assert_eq!(parse_address("6060:00"), Ok((0x6060, 0)));
        assert_eq!(parse_address("1018:0A"), Ok((0x1018, 0x0A)));
        for bad in [
            "6060",
            "6060:",
            ":1",
            "0x10000:0",
            "6060:100",
            "60g0:0",
            "0x:0",
            "-1:0",
        ] {
            assert_eq!(
                parse_address(bad),
                Err(SdoInputError::Address(bad.into())),
                "{bad}"
            );
        }
    }

    #[test]
    fn values_take_their_types_width_little_endian() {
        assert_eq!(encode(SdoType::U8, "8"), Ok(vec![8]));
        assert_eq!(encode(SdoType::U16, "0x1234"), Ok(vec![0x34, 0x12]));
        assert_eq!(encode(SdoType::I8, "-1"), Ok(vec![0xFF]));
        assert_eq!(encode(SdoType::I32, "-2"), Ok(vec![0xFE, 0xFF, 0xFF, 0xFF]));
        assert_eq!(encode(SdoType::U64, "1"), Ok(vec![1, 0, 0, 0, 0, 0, 0, 0]));
        assert_eq!(
            encode(SdoType::F32, "1.5"),
            Ok(1.5f32.to_le_bytes().to_vec())
        );
        assert_eq!(encode(SdoType::String, "ab"), Ok(b"ab".to_vec()));
        assert_eq!(encode(SdoType::Hex, "0a 1B"), Ok(vec![0x0A, 0x1B]));
    }

    #[test]
    fn a_value_that_does_not_fit_its_type_is_refused_saying_so() {
        for (ty, value, says) in [
            (
                SdoType::U8,
                "256",
                "value \"256\" is not a u8 (out of its range)",
            ),
            (
                SdoType::U8,
                "-1",
                "value \"-1\" is not a u8 (out of its range)",
            ),
            (SdoType::I8, "128", "is not a i8 (out of its range)"),
            (
                SdoType::U16,
                "12.5",
                "is not a u16 (a whole number, or 0x… hex)",
            ),
            (SdoType::U32, "ten", "is not a u32"),
            (SdoType::F32, "nan", "is not a f32 (a finite number)"),
            (SdoType::Hex, "abc", "is not a hex (pairs of hex digits"),
        ] {
            let e = encode(ty, value).unwrap_err().to_string();
            assert!(e.contains(says), "{ty} {value}: {e}");
        }
    }

    #[test]
    fn values_take_the_eds_type_of_their_object() {
        use DataType::*;
        let eds = |ty, v: &str| Typing::Eds { ty, node: 5 }.encode(v);
        assert_eq!(eds(Integer32, "-2"), Ok(vec![0xFE, 0xFF, 0xFF, 0xFF]));
        assert_eq!(eds(Unsigned16, "0x1234"), Ok(vec![0x34, 0x12]));
        assert_eq!(eds(Unsigned24, "0x010203"), Ok(vec![3, 2, 1]));
        assert_eq!(eds(Real32, "1.5"), Ok(1.5f32.to_le_bytes().to_vec()));
        assert_eq!(eds(VisibleString, "SX400"), Ok(b"SX400".to_vec()));
        assert_eq!(eds(OctetString, "0a1B"), Ok(vec![0x0A, 0x1B]));
        for (ty, v, says) in [
            (
                Unsigned8,
                "256",
                "value \"256\" is not a UNSIGNED8, the object's type in its EDS",
            ),
            (Integer8, "12.5", "(a whole number, or 0x… hex)"),
            (Real32, "nan", "(a finite number)"),
            (OctetString, "abc", "is not a OCTET_STRING"),
        ] {
            let e = eds(ty, v).unwrap_err().to_string();
            assert!(e.contains(says), "{ty:?} {v}: {e}");
        }
        let read = |ty, b: &[u8]| Typing::Eds { ty, node: 5 }.decode(b);
        assert_eq!(read(Integer16, &[0xFE, 0xFF]).unwrap(), "-2");
        assert_eq!(read(Unsigned32, &[0x92, 0x01, 2, 0]).unwrap(), "131474");
        assert_eq!(read(Real32, &1.5f32.to_le_bytes()).unwrap(), "1.5");
        assert_eq!(read(VisibleString, b"SX400\0").unwrap(), "SX400");
        assert_eq!(
            read(Integer32, &[1, 2]).unwrap_err().to_string(),
            "the drive sent 2 bytes (0102), a INTEGER32 (the object's type in its EDS) has 4; \
             --type hex shows them raw"
        );
        // A given --type wins over the EDS.
        assert_eq!(Typing::Given(SdoType::U8).encode("8"), Ok(vec![8]));
        assert_eq!(
            Typing::Eds {
                ty: Integer32,
                node: 5
            }
            .to_string(),
            "INTEGER32"
        );
    }

    #[test]
    fn bytes_read_as_a_type_must_have_its_width() {
        assert_eq!(decode(SdoType::I16, &[0xFE, 0xFF]).unwrap(), "-2");
        assert_eq!(decode(SdoType::U32, &[1, 0, 0, 0]).unwrap(), "1");
        assert_eq!(decode(SdoType::String, b"gantry\0\0").unwrap(), "gantry");
        assert_eq!(decode(SdoType::Hex, &[0xAB]).unwrap(), "ab");
        assert_eq!(
            decode(SdoType::U16, &[1, 2, 3]).unwrap_err().to_string(),
            "the drive sent 3 bytes (010203), a u16 has 2; --type hex shows them raw"
        );
    }
}
