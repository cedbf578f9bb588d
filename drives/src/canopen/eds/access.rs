//! `AccessType=` of an EDS entry (CiA 306-1 §4.6.3) and which PDOs an entry with
//! `PDOMapping=1` may go into.

/// Which way a PDO goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PdoDirection {
    /// Receive PDO (RPDO): master → device, the device's process outputs.
    Receive,
    /// Transmit PDO (TPDO): device → master, the device's process inputs.
    Transmit,
}

impl PdoDirection {
    /// "RPDO" or "TPDO".
    pub const fn name(self) -> &'static str {
        match self {
            Self::Receive => "RPDO",
            Self::Transmit => "TPDO",
        }
    }
}

impl core::fmt::Display for PdoDirection {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// Access of an object entry by SDO, and with it the PDO direction it may be mapped in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AccessType {
    /// `ro`: read only (mappable into TPDOs).
    ReadOnly,
    /// `wo`: write only (mappable into RPDOs).
    WriteOnly,
    /// `rw`: read and write (mappable both ways).
    ReadWrite,
    /// `rwr`: read and write, on process input (mappable into TPDOs).
    ReadWriteInput,
    /// `rww`: read and write, on process output (mappable into RPDOs).
    ReadWriteOutput,
    /// `const`: read only, never changes (mappable into TPDOs).
    Const,
}

/// Every access type.
pub const ALL: [AccessType; 6] = [
    AccessType::ReadOnly,
    AccessType::WriteOnly,
    AccessType::ReadWrite,
    AccessType::ReadWriteInput,
    AccessType::ReadWriteOutput,
    AccessType::Const,
];

impl AccessType {
    /// The EDS spelling.
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::ReadOnly => "ro",
            Self::WriteOnly => "wo",
            Self::ReadWrite => "rw",
            Self::ReadWriteInput => "rwr",
            Self::ReadWriteOutput => "rww",
            Self::Const => "const",
        }
    }

    /// The access an EDS spells so (any case).
    pub fn parse(s: &str) -> Option<Self> {
        ALL.iter()
            .copied()
            .find(|a| a.as_str().eq_ignore_ascii_case(s.trim()))
    }

    /// An SDO upload is allowed.
    pub const fn readable(self) -> bool {
        !matches!(self, Self::WriteOnly)
    }

    /// An SDO download is allowed.
    pub const fn writable(self) -> bool {
        !matches!(self, Self::ReadOnly | Self::Const)
    }

    /// Whether an entry with `PDOMapping=1` and this access may be mapped in
    /// `direction`: CiA 306-1 §4.6.3 — `rww` is process output (RPDO), `rwr` process
    /// input (TPDO), `rw` either; what can only be read goes into TPDOs, what can only
    /// be written into RPDOs.
    pub const fn mappable_in(self, direction: PdoDirection) -> bool {
        match direction {
            PdoDirection::Receive => {
                matches!(
                    self,
                    Self::WriteOnly | Self::ReadWrite | Self::ReadWriteOutput
                )
            }
            PdoDirection::Transmit => matches!(
                self,
                Self::ReadOnly | Self::Const | Self::ReadWrite | Self::ReadWriteInput
            ),
        }
    }
}

impl core::fmt::Display for AccessType {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spellings_and_directions() {
        for a in ALL {
            assert_eq!(AccessType::parse(&a.as_str().to_uppercase()), Some(a));
        }
        assert_eq!(AccessType::parse("rx"), None);
        use PdoDirection::{Receive as R, Transmit as T};
        let table = [
            ("ro", false, true),
            ("wo", true, false),
            ("rw", true, true),
            ("rwr", false, true),
            ("rww", true, false),
            ("const", false, true),
        ];
        for (s, r, t) in table {
            let a = AccessType::parse(s).unwrap();
            assert_eq!((a.mappable_in(R), a.mappable_in(T)), (r, t), "{s}");
        }
        assert!(!AccessType::Const.writable() && !AccessType::WriteOnly.readable());
    }
}
