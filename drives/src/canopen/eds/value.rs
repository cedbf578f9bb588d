//! Values of `DefaultValue=`, `ParameterValue=`, `LowLimit=` and `HighLimit=` (CiA 306-1
//! §4.6.3, §4.1 "entry value interpretation"): integers in decimal, hexadecimal (`0x`)
//! or octal (leading `0`), optionally relative to the node id (`$NODEID+0x180`, the
//! COB-IDs of the predefined connection set); reals; strings; octet strings as hex.

use thiserror::Error;

use super::data_type::DataType;

/// One value of an entry, as the file states it.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// An integer (BOOLEAN as 0/1; a signed type's value, its sign applied).
    Integer(i128),
    /// `$NODEID` plus this offset: the value on a node is its id plus the offset.
    NodeRelative(i128),
    /// A REAL32 or REAL64.
    Real(f64),
    /// A VISIBLE_STRING, UNICODE_STRING, DOMAIN (a file name or data) or time value,
    /// kept as written.
    Text(String),
    /// An OCTET_STRING's bytes (written as hex digits).
    Octets(Vec<u8>),
}

/// A value that does not suit its entry.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum ValueError {
    /// Not a number.
    #[error("{text:?} is not a number")]
    NotANumber {
        /// As written.
        text: String,
    },
    /// Out of the type's range.
    #[error("{text} does not fit {ty}")]
    OutOfRange {
        /// As written.
        text: String,
        /// The entry's type.
        ty: DataType,
    },
    /// `$NODEID` where the type cannot hold a node id.
    #[error("{text}: $NODEID in a {ty}")]
    NodeIdInNonInteger {
        /// As written.
        text: String,
        /// The entry's type.
        ty: DataType,
    },
    /// Not hex digit pairs.
    #[error("{text:?} is not an OCTET_STRING in hex digits")]
    NotOctets {
        /// As written.
        text: String,
    },
    /// Bytes of the wrong length for the type.
    #[error("{len} bytes for a {ty}")]
    Length {
        /// Bytes given.
        len: usize,
        /// The type.
        ty: DataType,
    },
}

/// Parses an unsigned or signed integer: decimal, `0x` hexadecimal, or octal with a
/// leading `0` (CiA 306-1 §4.1), with an optional sign.
pub fn parse_integer(text: &str) -> Option<i128> {
    let t = text.trim();
    let (negative, t) = match t.strip_prefix('-') {
        Some(rest) => (true, rest.trim_start()),
        None => (false, t.strip_prefix('+').unwrap_or(t).trim_start()),
    };
    let magnitude = if let Some(hex) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        if hex.is_empty() || hex.starts_with(['+', '-']) {
            return None;
        }
        i128::from_str_radix(hex, 16).ok()?
    } else if t.len() > 1 && t.starts_with('0') {
        let oct = t.get(1..)?;
        if oct.starts_with(['+', '-']) {
            return None;
        }
        i128::from_str_radix(oct, 8).ok()?
    } else {
        if t.starts_with(['+', '-']) {
            return None;
        }
        t.parse::<i128>().ok()?
    };
    Some(if negative { -magnitude } else { magnitude })
}

/// Whether `text` mentions `$NODEID` (any case), and the rest of the expression:
/// `$NODEID`, `$NODEID+N`, `$NODEID-N`, `N+$NODEID`.
fn split_node_id(text: &str) -> Option<Result<i128, ()>> {
    let upper = text.to_ascii_uppercase();
    let at = upper.find("$NODEID")?;
    let before = text.get(..at).unwrap_or("").trim();
    let after = text.get(at + "$NODEID".len()..).unwrap_or("").trim();
    let offset = match (before.is_empty(), after.is_empty()) {
        (true, true) => Some(0),
        (true, false) => {
            if let Some(rest) = after.strip_prefix('+') {
                parse_integer(rest.trim_start()).filter(|_| !rest.trim_start().starts_with('-'))
            } else if let Some(rest) = after.strip_prefix('-') {
                parse_integer(rest.trim_start())
                    .filter(|_| !rest.trim_start().starts_with(['+', '-']))
                    .map(|v| -v)
            } else {
                None
            }
        }
        (false, true) => before
            .strip_suffix('+')
            .and_then(|n| parse_integer(n.trim_end())),
        (false, false) => None,
    };
    Some(offset.ok_or(()))
}

/// Node ids a `$NODEID` value may be evaluated for (CiA 301 §7.2.1: 1..=127).
const NODE_IDS: (i128, i128) = (1, 127);

/// Converts an integer as written to the value of `ty`: a signed type's value may be
/// written as its two's-complement bit pattern in hex (`0xFFFF` for an INTEGER16 −1,
/// as vendors write it).
fn fit_integer(v: i128, ty: DataType, text: &str, hex: bool) -> Result<i128, ValueError> {
    let range = || ValueError::OutOfRange {
        text: text.trim().to_string(),
        ty,
    };
    let (lo, hi) = ty.integer_range().ok_or_else(range)?;
    if (lo..=hi).contains(&v) {
        return Ok(v);
    }
    if hex && ty.is_signed() && v > hi {
        let bits = ty.bits().unwrap_or(64);
        if v < (1i128 << bits) {
            return Ok(v - (1i128 << bits));
        }
    }
    Err(range())
}

impl Value {
    /// Parses `text` as a value of `ty`; `Ok(None)` when empty (CiA 306: no value given).
    pub fn parse(text: &str, ty: DataType) -> Result<Option<Self>, ValueError> {
        let t = text.trim();
        if t.is_empty() {
            return Ok(None);
        }
        if ty.is_integer() {
            if let Some(offset) = split_node_id(t) {
                let offset = offset.map_err(|()| ValueError::NotANumber {
                    text: t.to_string(),
                })?;
                let (lo, hi) = ty.integer_range().unwrap_or((0, 0));
                if offset + NODE_IDS.0 < lo || offset + NODE_IDS.1 > hi {
                    return Err(ValueError::OutOfRange {
                        text: t.to_string(),
                        ty,
                    });
                }
                return Ok(Some(Self::NodeRelative(offset)));
            }
            let v = parse_integer(t).ok_or_else(|| ValueError::NotANumber {
                text: t.to_string(),
            })?;
            let hex = t
                .trim_start_matches(['+', '-'])
                .trim_start()
                .starts_with("0x")
                || t.trim_start_matches(['+', '-'])
                    .trim_start()
                    .starts_with("0X");
            return fit_integer(v, ty, t, hex).map(|v| Some(Self::Integer(v)));
        }
        if t.to_ascii_uppercase().contains("$NODEID") {
            return Err(ValueError::NodeIdInNonInteger {
                text: t.to_string(),
                ty,
            });
        }
        match ty {
            DataType::Real32 | DataType::Real64 => {
                let v = t.parse::<f64>().map_err(|_| ValueError::NotANumber {
                    text: t.to_string(),
                })?;
                if ty == DataType::Real32 && v.is_finite() && v.abs() > f64::from(f32::MAX) {
                    return Err(ValueError::OutOfRange {
                        text: t.to_string(),
                        ty,
                    });
                }
                Ok(Some(Self::Real(v)))
            }
            DataType::OctetString => {
                let digits: String = t.chars().filter(|c| !c.is_whitespace()).collect();
                let digits = digits
                    .strip_prefix("0x")
                    .or_else(|| digits.strip_prefix("0X"))
                    .unwrap_or(&digits);
                if digits.len() % 2 != 0 || !digits.chars().all(|c| c.is_ascii_hexdigit()) {
                    return Err(ValueError::NotOctets {
                        text: t.to_string(),
                    });
                }
                let bytes = (0..digits.len() / 2)
                    .filter_map(|i| {
                        digits
                            .get(2 * i..2 * i + 2)
                            .and_then(|d| u8::from_str_radix(d, 16).ok())
                    })
                    .collect();
                Ok(Some(Self::Octets(bytes)))
            }
            _ => Ok(Some(Self::Text(t.to_string()))),
        }
    }

    /// The integer this value has on node `node` (`$NODEID` resolved); `None` for a
    /// value that is no integer.
    pub fn integer_on(&self, node: u8) -> Option<i128> {
        match self {
            Self::Integer(v) => Some(*v),
            Self::NodeRelative(offset) => Some(offset + i128::from(node)),
            _ => None,
        }
    }

    /// The value as an EDS writes it for an entry of `ty` (unsigned integers in hex,
    /// signed in decimal).
    pub fn to_eds(&self, ty: DataType) -> String {
        match self {
            Self::Integer(v) if ty.is_signed() || ty == DataType::Boolean || *v < 0 => {
                v.to_string()
            }
            Self::Integer(v) => format!("0x{v:X}"),
            Self::NodeRelative(0) => "$NODEID".to_string(),
            Self::NodeRelative(o) if *o < 0 => format!("$NODEID-0x{:X}", o.unsigned_abs()),
            Self::NodeRelative(o) => format!("$NODEID+0x{o:X}"),
            Self::Real(v) => format!("{v:?}"),
            Self::Text(s) => s.clone(),
            Self::Octets(b) => b.iter().map(|x| format!("{x:02X}")).collect(),
        }
    }

    /// The value's bytes as an SDO carries them for `ty` on node `node` (little-endian
    /// integers and reals, strings as they are).
    pub fn to_le_bytes(&self, ty: DataType, node: u8) -> Result<Vec<u8>, ValueError> {
        let text = || self.to_eds(ty);
        if let Some(v) = self.integer_on(node) {
            let v = fit_integer(v, ty, &text(), false)?;
            let n = ty.bytes().unwrap_or(0);
            return Ok(v.to_le_bytes().get(..n).unwrap_or(&[]).to_vec());
        }
        match (self, ty) {
            (Self::Real(v), DataType::Real32) => Ok((*v as f32).to_le_bytes().to_vec()),
            (Self::Real(v), DataType::Real64) => Ok(v.to_le_bytes().to_vec()),
            (Self::Octets(b), _) => Ok(b.clone()),
            (Self::Text(s), _) if ty.bits().is_none() => Ok(s.as_bytes().to_vec()),
            _ => Err(ValueError::OutOfRange { text: text(), ty }),
        }
    }

    /// The value of `ty` that `bytes` (little-endian, as uploaded or downloaded) hold.
    pub fn from_le_bytes(bytes: &[u8], ty: DataType) -> Result<Self, ValueError> {
        let len_error = || ValueError::Length {
            len: bytes.len(),
            ty,
        };
        if let Some((_, _)) = ty.integer_range() {
            let n = ty.bytes().unwrap_or(0);
            if bytes.len() != n || n > 8 {
                return Err(len_error());
            }
            let mut le = [0u8; 16];
            for (d, s) in le.iter_mut().zip(bytes) {
                *d = *s;
            }
            let raw = i128::from_le_bytes(le);
            let bits = ty.bits().unwrap_or(8);
            let v = if ty.is_signed() && raw >= 1i128 << (bits - 1) {
                raw - (1i128 << bits)
            } else {
                raw
            };
            return Ok(Self::Integer(v));
        }
        match ty {
            DataType::Real32 => {
                let b: [u8; 4] = bytes.try_into().map_err(|_| len_error())?;
                Ok(Self::Real(f64::from(f32::from_le_bytes(b))))
            }
            DataType::Real64 => {
                let b: [u8; 8] = bytes.try_into().map_err(|_| len_error())?;
                Ok(Self::Real(f64::from_le_bytes(b)))
            }
            DataType::VisibleString | DataType::UnicodeString | DataType::Domain => {
                Ok(Self::Text(String::from_utf8_lossy(bytes).into_owned()))
            }
            _ => Ok(Self::Octets(bytes.to_vec())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use DataType::*;

    fn p(text: &str, ty: DataType) -> Result<Option<Value>, ValueError> {
        Value::parse(text, ty)
    }

    #[test]
    fn integers_in_the_three_bases_of_cia_306() {
        assert_eq!(p("42", Unsigned8), Ok(Some(Value::Integer(42))));
        assert_eq!(p("0x2A", Unsigned8), Ok(Some(Value::Integer(42))));
        assert_eq!(p("052", Unsigned8), Ok(Some(Value::Integer(42))));
        assert_eq!(p("0", Unsigned8), Ok(Some(Value::Integer(0))));
        assert_eq!(p("-5", Integer16), Ok(Some(Value::Integer(-5))));
        assert_eq!(p("", Unsigned8), Ok(None));
        assert!(matches!(
            p("0x100", Unsigned8),
            Err(ValueError::OutOfRange { .. })
        ));
        assert!(matches!(
            p("-1", Unsigned32),
            Err(ValueError::OutOfRange { .. })
        ));
        assert!(matches!(
            p("08", Unsigned8),
            Err(ValueError::NotANumber { .. })
        ));
        assert!(matches!(
            p("0x", Unsigned8),
            Err(ValueError::NotANumber { .. })
        ));
        assert!(matches!(
            p("--1", Integer8),
            Err(ValueError::NotANumber { .. })
        ));
        assert_eq!(
            p("2", Boolean),
            Err(ValueError::OutOfRange {
                text: "2".into(),
                ty: Boolean
            })
        );
    }

    #[test]
    fn a_signed_type_may_be_written_as_its_bit_pattern() {
        assert_eq!(p("0xFFFF", Integer16), Ok(Some(Value::Integer(-1))));
        assert_eq!(p("0x8000", Integer16), Ok(Some(Value::Integer(-32768))));
        assert!(p("0x10000", Integer16).is_err());
        assert!(p("65535", Integer16).is_err(), "only hex is a bit pattern");
    }

    #[test]
    fn node_id_arithmetic() {
        assert_eq!(
            p("$NODEID+0x180", Unsigned32),
            Ok(Some(Value::NodeRelative(0x180)))
        );
        assert_eq!(
            p("$nodeid + 384", Unsigned32),
            Ok(Some(Value::NodeRelative(384)))
        );
        assert_eq!(
            p("0x600+$NODEID", Unsigned32),
            Ok(Some(Value::NodeRelative(0x600)))
        );
        assert_eq!(p("$NODEID", Unsigned8), Ok(Some(Value::NodeRelative(0))));
        assert_eq!(p("$NODEID-1", Unsigned8), Ok(Some(Value::NodeRelative(-1))));
        assert_eq!(
            p("$NODEID+0x80000200", Unsigned32)
                .unwrap()
                .unwrap()
                .integer_on(5),
            Some(0x8000_0205)
        );
        // Node 127 + 0x90 does not fit a byte.
        assert!(matches!(
            p("$NODEID+0x90", Unsigned8),
            Err(ValueError::OutOfRange { .. })
        ));
        assert!(p("$NODEID*2", Unsigned32).is_err());
        assert!(p("1+$NODEID+1", Unsigned32).is_err());
        assert!(matches!(
            p("$NODEID", VisibleString),
            Err(ValueError::NodeIdInNonInteger { .. })
        ));
    }

    #[test]
    fn writes_what_it_reads() {
        let cases = [
            ("0x80000180", Unsigned32),
            ("$NODEID+0x180", Unsigned32),
            ("$NODEID-0x1", Unsigned16),
            ("$NODEID", Unsigned8),
            ("-7", Integer32),
            ("1", Boolean),
            ("1.5", Real32),
            ("-0.000125", Real64),
            ("gantry servo", VisibleString),
            ("00FF10", OctetString),
        ];
        for (text, ty) in cases {
            let v = p(text, ty).unwrap().unwrap();
            assert_eq!(p(&v.to_eds(ty), ty), Ok(Some(v.clone())), "{text}");
        }
    }

    #[test]
    fn bytes_both_ways() {
        let v = Value::NodeRelative(0x180);
        assert_eq!(v.to_le_bytes(Unsigned32, 3), Ok(vec![0x83, 0x01, 0, 0]));
        assert_eq!(
            Value::from_le_bytes(&[0xFF, 0xFF], Integer16),
            Ok(Value::Integer(-1))
        );
        assert_eq!(
            Value::Integer(-1).to_le_bytes(Integer16, 1),
            Ok(vec![0xFF, 0xFF])
        );
        assert!(Value::Integer(300).to_le_bytes(Unsigned8, 1).is_err());
        assert!(Value::from_le_bytes(&[1, 2, 3], Unsigned16).is_err());
        assert_eq!(
            Value::from_le_bytes(&[0, 0, 0xC0, 0x3F], Real32),
            Ok(Value::Real(1.5))
        );
        assert_eq!(
            Value::from_le_bytes(&[1, 0, 0], Unsigned24),
            Ok(Value::Integer(1))
        );
    }
}
