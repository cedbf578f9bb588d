//! What is wrong with an EDS or DCF, and where: the file, the line of the section (or of
//! the INI syntax error) and the section, e.g.
//! `x.eds:57: [6040]: DataType 0x0099 is not a CiA 301 type`.

use thiserror::Error;

use super::value::ValueError;

/// An EDS or DCF that cannot be read.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{}{}{}{kind}", .file, .line.map(|l| format!(":{l}")).unwrap_or_default(),
    .section.as_ref().map(|s| format!(": [{s}]: ")).unwrap_or_else(|| ": ".into()))]
pub struct EdsError {
    /// The file's name.
    pub file: String,
    /// The line (1-based) of the section, or of a syntax error.
    pub line: Option<usize>,
    /// The section.
    pub section: Option<String>,
    /// What (boxed: the error stays small on the happy path's `Result`s).
    pub kind: Box<EdsErrorKind>,
}

/// What is wrong.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum EdsErrorKind {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(String),
    /// Not INI (the parser's words).
    #[error("INI syntax: {0}")]
    Syntax(String),
    /// A key before the first section.
    #[error("{0} is outside any section")]
    KeyOutsideSection(String),
    /// A section twice.
    #[error("section appears again (first at line {first})")]
    DuplicateSection {
        /// Line of the first.
        first: usize,
    },
    /// A key twice in one section.
    #[error("{0} appears twice")]
    DuplicateKey(String),
    /// A section that must be there.
    #[error("missing section")]
    MissingSection,
    /// A key that must be there.
    #[error("{0} is missing")]
    MissingKey(String),
    /// A key whose value is not a number of the kind it must be.
    #[error("{key}={value} is not {what}")]
    BadNumber {
        /// Key.
        key: String,
        /// As written.
        value: String,
        /// What it must be ("a number", "0 or 1", "an UNSIGNED8").
        what: &'static str,
    },
    /// `DataType=` names no CiA 301 type.
    #[error("DataType 0x{0:04X} is not a CiA 301 type")]
    NotCia301Type(u16),
    /// `AccessType=`.
    #[error("AccessType {0} is not one of ro, wo, rw, rwr, rww, const")]
    BadAccess(String),
    /// `ObjectType=`.
    #[error("ObjectType {0} is not a CiA 301 object type (0x0, 0x2, 0x5–0x9)")]
    BadObjectType(String),
    /// A value that does not suit its entry.
    #[error("{key}: {source}")]
    BadValue {
        /// Key.
        key: &'static str,
        /// Why.
        source: ValueError,
    },
    /// `DefaultValue` outside `LowLimit..=HighLimit`.
    #[error("DefaultValue {value} is outside LowLimit..=HighLimit ({low}..={high})")]
    OutsideLimits {
        /// The default.
        value: i128,
        /// Low limit.
        low: i128,
        /// High limit.
        high: i128,
    },
    /// `SubNumber=` disagrees with the sub-sections.
    #[error("SubNumber={declared} but {found} sub-index sections")]
    SubNumber {
        /// Declared.
        declared: usize,
        /// Found.
        found: usize,
    },
    /// A sub-section's sub-index.
    #[error("sub-index {0} is not a sub-index (hex, 0 to FE)")]
    BadSubIndex(String),
    /// Sub 0 of an ARRAY or RECORD must be the UNSIGNED8 count (CiA 301 §7.4.3).
    #[error("sub-index 0 of an ARRAY or RECORD must be an UNSIGNED8 (highest sub-index), not {0}")]
    SubZeroType(String),
    /// An ARRAY's entries have one data type (CiA 301 Table 42).
    #[error("ARRAY entry {sub} is {found}, entry 1 is {first}")]
    ArrayTypes {
        /// Sub-index.
        sub: u8,
        /// Its type.
        found: String,
        /// Type of sub 1.
        first: String,
    },
    /// An ARRAY or RECORD without sub-objects.
    #[error("an ARRAY or RECORD needs SubNumber or CompactSubObj")]
    NoSubObjects,
    /// An object list entry.
    #[error("{key}={value} is not an object index")]
    BadIndex {
        /// Key.
        key: String,
        /// As written.
        value: String,
    },
    /// An object in two lists or twice in one.
    #[error("0x{0:04X} is listed twice")]
    ListedTwice(u16),
    /// A listed object without its section.
    #[error("0x{0:04X} is listed but has no section")]
    NoSection(u16),
    /// A section of an object no list names.
    #[error(
        "object section not named in any of MandatoryObjects, OptionalObjects, ManufacturerObjects"
    )]
    Unlisted,
    /// A mandatory object of CiA 301 is missing.
    #[error("0x{0:04X} is mandatory (CiA 301 §7.4.5) and not described")]
    MandatoryMissing(u16),
    /// `NrOfRXPDO` / `NrOfTXPDO` names PDOs whose objects are not described.
    #[error("{key}={count} but 0x{index:04X} is not described")]
    PdoObjectMissing {
        /// Key.
        key: &'static str,
        /// Its value.
        count: u16,
        /// The missing object.
        index: u16,
    },
    /// `NodeID=` of a DCF.
    #[error("NodeID={0} is not a node id (1 to 127)")]
    BadNodeId(String),
}

impl EdsError {
    /// An error in `file` without a place.
    pub fn file(file: &str, kind: EdsErrorKind) -> Self {
        Self {
            file: file.to_string(),
            line: None,
            section: None,
            kind: Box::new(kind),
        }
    }
}
