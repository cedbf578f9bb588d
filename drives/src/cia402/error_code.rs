//! Drive error codes (object 0x603F; the same codes as CiA 301 emergency messages) as text,
//! so a faulted axis says *what* the drive reported, not just a number.

/// Codes with a specific meaning (CiA 402 / ETG.6010 annex; a drive may use more).
const KNOWN: &[(u16, &str)] = &[
    (0x0000, "no error"),
    (0x1000, "generic error"),
    (0x2310, "continuous over-current"),
    (0x2320, "short circuit at outputs"),
    (0x3110, "mains over-voltage"),
    (0x3120, "mains under-voltage"),
    (0x3210, "DC link over-voltage"),
    (0x3220, "DC link under-voltage"),
    (0x4210, "excess temperature, device"),
    (0x4310, "excess temperature, drive"),
    (0x5441, "safe torque off active"),
    (
        0x6100,
        "internal software (gantry stops the axes with it after too many cycle overruns in a row)",
    ),
    (
        0x6320,
        "parameter error (gantry stops the axis: its set position has no 64-bit drive count; check the scaling and the travel)",
    ),
    (0x7121, "motor blocked"),
    (0x7300, "sensor (encoder) error"),
    (0x7305, "incremental sensor 1 fault"),
    (
        0x8100,
        "communication error (the master cannot reach the drive)",
    ),
    (0x8130, "life guard or heartbeat error"),
    (0x8400, "velocity control error"),
    (0x8611, "following error"),
    (0x8612, "reference limit"),
    (
        0x8700,
        "sync controller error (process data watchdog: the master stopped sending)",
    ),
    (
        0xFF00,
        "device specific (read 0x603F or the drive's manual)",
    ),
];

/// The error class of a code (its high nibble or byte), for codes not in the table.
fn class(code: u16) -> &'static str {
    match code >> 12 {
        0x1 => "generic error",
        0x2 => "current",
        0x3 => "voltage",
        0x4 => "temperature",
        0x5 => "device hardware",
        0x6 => "device software",
        0x7 => "additional modules",
        0x8 => "monitoring or communication",
        0x9 => "external error",
        0xF => "device specific",
        _ => "unknown class",
    }
}

/// Text for a drive error code: the specific meaning, or the class of the code.
pub fn describe(code: u16) -> &'static str {
    KNOWN
        .iter()
        .find(|(c, _)| *c == code)
        .map_or_else(|| class(code), |(_, text)| *text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_codes_classes_and_faults() {
        assert_eq!(describe(0x2310), "continuous over-current");
        assert_eq!(describe(0x2311), "current");
        assert_eq!(describe(0xFF42), "device specific");
        assert!(
            KNOWN.windows(2).all(|w| w[0].0 < w[1].0),
            "sorted, no duplicates"
        );
    }
}
