//! SDO abort codes (CiA 301 §7.2.4.3.17, Table 22): the 32-bit reason a client or server
//! gives when it ends a transfer, each with the spec's text so an operator reads why.

/// An SDO abort code. Any 32-bit value may arrive from a peer, so the type is total;
/// [`AbortCode::text`] names the Table 22 codes and says "unknown" for the rest.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AbortCode(pub u32);

macro_rules! abort_codes {
    ($($(#[$doc:meta])* $name:ident = $code:literal, $text:literal;)*) => {
        impl AbortCode {
            $( $(#[$doc])* #[doc = concat!("`", stringify!($code), "`: ", $text)] pub const $name: Self = Self($code); )*

            /// Every code of CiA 301 Table 22, in table order.
            pub const ALL: &'static [AbortCode] = &[$(Self::$name),*];

            /// The text of Table 22, or None for a code it does not list.
            pub const fn known_text(self) -> Option<&'static str> {
                match self.0 {
                    $($code => Some($text),)*
                    _ => None,
                }
            }
        }
    };
}

abort_codes! {
    TOGGLE_BIT_NOT_ALTERNATED = 0x0503_0000, "Toggle bit not alternated.";
    TIMED_OUT = 0x0504_0000, "SDO protocol timed out.";
    INVALID_COMMAND_SPECIFIER = 0x0504_0001, "Client/server command specifier not valid or unknown.";
    INVALID_BLOCK_SIZE = 0x0504_0002, "Invalid block size (block mode only).";
    INVALID_SEQUENCE_NUMBER = 0x0504_0003, "Invalid sequence number (block mode only).";
    CRC_ERROR = 0x0504_0004, "CRC error (block mode only).";
    OUT_OF_MEMORY = 0x0504_0005, "Out of memory.";
    UNSUPPORTED_ACCESS = 0x0601_0000, "Unsupported access to an object.";
    WRITE_ONLY = 0x0601_0001, "Attempt to read a write only object.";
    READ_ONLY = 0x0601_0002, "Attempt to write a read only object.";
    OBJECT_DOES_NOT_EXIST = 0x0602_0000, "Object does not exist in the object dictionary.";
    NOT_MAPPABLE = 0x0604_0041, "Object cannot be mapped to the PDO.";
    PDO_LENGTH_EXCEEDED = 0x0604_0042, "The number and length of the objects to be mapped would exceed PDO length.";
    PARAMETER_INCOMPATIBILITY = 0x0604_0043, "General parameter incompatibility reason.";
    INTERNAL_INCOMPATIBILITY = 0x0604_0047, "General internal incompatibility in the device.";
    HARDWARE_ERROR = 0x0606_0000, "Access failed due to an hardware error.";
    LENGTH_MISMATCH = 0x0607_0010, "Data type does not match, length of service parameter does not match.";
    LENGTH_TOO_HIGH = 0x0607_0012, "Data type does not match, length of service parameter too high.";
    LENGTH_TOO_LOW = 0x0607_0013, "Data type does not match, length of service parameter too low.";
    SUB_INDEX_DOES_NOT_EXIST = 0x0609_0011, "Sub-index does not exist.";
    INVALID_VALUE = 0x0609_0030, "Invalid value for parameter (download only).";
    VALUE_TOO_HIGH = 0x0609_0031, "Value of parameter written too high (download only).";
    VALUE_TOO_LOW = 0x0609_0032, "Value of parameter written too low (download only).";
    MAX_LESS_THAN_MIN = 0x0609_0036, "Maximum value is less than minimum value.";
    RESOURCE_NOT_AVAILABLE = 0x060A_0023, "Resource not available: SDO connection.";
    GENERAL_ERROR = 0x0800_0000, "General error.";
    CANNOT_STORE = 0x0800_0020, "Data cannot be transferred or stored to the application.";
    CANNOT_STORE_LOCAL_CONTROL = 0x0800_0021, "Data cannot be transferred or stored to the application because of local control.";
    CANNOT_STORE_DEVICE_STATE = 0x0800_0022, "Data cannot be transferred or stored to the application because of the present device state.";
    NO_OBJECT_DICTIONARY = 0x0800_0023, "Object dictionary dynamic generation fails or no object dictionary is present (e.g. object dictionary is generated from file and generation fails because of an file error).";
    NO_DATA = 0x0800_0024, "No data available.";
}

impl AbortCode {
    /// The text of the code (Table 22), or a note that the table does not list it.
    pub const fn text(self) -> &'static str {
        match self.known_text() {
            Some(t) => t,
            None => "Abort code not listed in CiA 301 Table 22 (manufacturer-specific or unknown).",
        }
    }
}

impl std::fmt::Display for AbortCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "0x{:08X} {}", self.0, self.text())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_22_has_31_codes_each_with_its_text() {
        assert_eq!(AbortCode::ALL.len(), 31);
        assert_eq!(AbortCode::ALL.first(), Some(&AbortCode(0x0503_0000)));
        assert_eq!(AbortCode::ALL.last(), Some(&AbortCode(0x0800_0024)));
        for (i, a) in AbortCode::ALL.iter().enumerate() {
            assert!(a.known_text().is_some(), "{a:?}");
            // In table order and distinct.
            if let Some(next) = AbortCode::ALL.get(i + 1) {
                assert!(next.0 > a.0, "{a} before {next}");
            }
        }
        assert_eq!(
            AbortCode::READ_ONLY.text(),
            "Attempt to write a read only object."
        );
        assert_eq!(
            AbortCode::OBJECT_DOES_NOT_EXIST.to_string(),
            "0x06020000 Object does not exist in the object dictionary."
        );
    }

    #[test]
    fn unknown_code_is_kept_and_named_unknown() {
        let a = AbortCode(0x1234_5678);
        assert_eq!(a.known_text(), None);
        assert!(a
            .to_string()
            .starts_with("0x12345678 Abort code not listed"));
    }
}
