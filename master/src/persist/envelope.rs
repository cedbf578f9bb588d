//! The envelope of a parameter file: a first line naming the format and its version, the
//! body (TOML), and a last line with the CRC-32 of everything before it. Both lines are
//! TOML comments, so the file reads as TOML to a person or a tool; gantry itself accepts
//! it only whole. This gantry reads formats 1 and 2 (2 adds step-to-absolute-switch
//! homing, see [`super::params`]) and writes the lowest that holds what is saved:
//!
//! ```text
//! # gantry axis parameters, format 1
//! axis = "x"
//! commutation_offset = 1234
//! ...
//! # crc32 5e3a07c1
//! ```
//!
//! A file cut anywhere loses its last line or its final newline (truncated); any altered
//! byte changes the CRC (altered); another program's file or a format this gantry does
//! not read is named as such. [`open`] says which, [`seal`] writes the envelope.

use super::checksum::crc32;

/// The start of the first line of every parameter file; the format's number and a newline
/// follow.
pub const HEADER_STEM: &str = "# gantry axis parameters, format ";
/// The formats this gantry reads (and writes).
pub const FORMATS: std::ops::RangeInclusive<u32> = 1..=2;
/// The start of the last line; eight lower-case hex digits and a newline follow.
const TRAILER: &str = "# crc32 ";

/// What is wrong with a file's bytes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Corruption {
    /// The file is empty (a crash between creating and writing it, on a file system
    /// without ordered data).
    #[error("the file is empty")]
    Empty,
    /// The bytes are not text.
    #[error("the file is not UTF-8 text (byte {offset})")]
    NotText {
        /// Where the first invalid byte is.
        offset: usize,
    },
    /// The first line is not gantry's.
    #[error("the first line is not \"{HEADER_STEM}N\": not a gantry parameter file")]
    Foreign,
    /// A format this gantry does not read.
    #[error("format {found} is not one this gantry reads (formats 1 and 2; written by another version of gantry)")]
    Version {
        /// The format the file names.
        found: String,
    },
    /// The checksum line is missing or cut: the file was cut short.
    #[error("the file is truncated after {length} bytes (no complete checksum line at its end)")]
    Truncated {
        /// The file's length.
        length: usize,
    },
    /// The checksum does not match: the file was altered.
    #[error("the checksum does not match (stored {stored:08x}, the content's {computed:08x}): the file was altered or damaged")]
    Checksum {
        /// The CRC-32 the file carries.
        stored: u32,
        /// The CRC-32 of its content.
        computed: u32,
    },
}

/// The first line of a file of `format`, without its newline.
pub fn header(format: u32) -> String {
    format!("{HEADER_STEM}{format}")
}

/// `body` in the envelope of `format`: the header, the body (a newline added when it
/// lacks one) and the checksum line.
pub fn seal(body: &str, format: u32) -> String {
    let header = header(format);
    let mut text = String::with_capacity(header.len() + body.len() + 32);
    text.push_str(&header);
    text.push('\n');
    text.push_str(body);
    if !body.is_empty() && !body.ends_with('\n') {
        text.push('\n');
    }
    let crc = crc32(text.as_bytes());
    text.push_str(&format!("{TRAILER}{crc:08x}\n"));
    text
}

/// The format and the body of a sealed file, or what is wrong with it.
pub fn open(bytes: &[u8]) -> Result<(u32, &str), Corruption> {
    if bytes.is_empty() {
        return Err(Corruption::Empty);
    }
    let text = std::str::from_utf8(bytes).map_err(|e| Corruption::NotText {
        offset: e.valid_up_to(),
    })?;
    let first = text.split('\n').next().unwrap_or_default();
    let newline = text.contains('\n');
    // The format as written: one spelling per number (no sign, no leading zero).
    let version = first.strip_prefix(HEADER_STEM);
    let format = version
        .and_then(|v| v.parse::<u32>().ok())
        .filter(|f| header(*f) == first && FORMATS.contains(f) && newline);
    let Some(format) = format else {
        let digits = |v: &str| v.bytes().all(|b| b.is_ascii_digit());
        return Err(match version {
            // A header cut before its newline is a truncated file of ours.
            _ if HEADER_STEM.starts_with(first) => Corruption::Truncated {
                length: bytes.len(),
            },
            Some(v) if !newline && digits(v) => Corruption::Truncated {
                length: bytes.len(),
            },
            Some(v) => Corruption::Version {
                found: v.to_string(),
            },
            None => Corruption::Foreign,
        });
    };
    let truncated = Corruption::Truncated {
        length: bytes.len(),
    };
    // The last line: "# crc32 " and 8 hex digits, then the file's final newline.
    let content = text.strip_suffix('\n').ok_or_else(|| truncated.clone())?;
    let (covered, last) = content.rsplit_once('\n').ok_or_else(|| truncated.clone())?;
    let digits = last
        .strip_prefix(TRAILER)
        .ok_or_else(|| truncated.clone())?;
    // Lower-case only, as written: one spelling per value, so no flipped bit goes unseen.
    if digits.len() != 8
        || !digits
            .bytes()
            .all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
    {
        return Err(truncated);
    }
    let stored = u32::from_str_radix(digits, 16).map_err(|_| truncated.clone())?;
    // Everything before the checksum line, its newline included.
    let covered_len = covered.len() + 1;
    let computed = crc32(&bytes[..covered_len]);
    if stored != computed {
        return Err(Corruption::Checksum { stored, computed });
    }
    Ok((format, &text[first.len() + 1..covered_len]))
}

#[cfg(test)]
mod tests {
    use super::*;

    const BODY: &str = "axis = \"x\"\ncommutation_offset = -1234\n";

    #[test]
    fn a_sealed_body_opens_to_itself() {
        for format in FORMATS {
            let sealed = seal(BODY, format);
            assert!(
                sealed.starts_with(&format!(
                    "# gantry axis parameters, format {format}\n{BODY}# crc32 "
                )),
                "{sealed}"
            );
            assert_eq!(open(sealed.as_bytes()).unwrap(), (format, BODY));
            // A body without its last newline gets one.
            assert_eq!(
                open(seal("a = 1", format).as_bytes()).unwrap(),
                (format, "a = 1\n")
            );
            assert_eq!(open(seal("", format).as_bytes()).unwrap(), (format, ""));
            // The file as a whole is TOML (the envelope's lines are comments).
            let v: toml::Table = toml::from_str(&sealed).unwrap();
            assert_eq!(v["commutation_offset"].as_integer(), Some(-1234));
        }
    }

    #[test]
    fn every_cut_of_a_file_is_found() {
        for format in FORMATS {
            let sealed = seal(BODY, format);
            for len in 0..sealed.len() {
                let cut = &sealed.as_bytes()[..len];
                let e = open(cut).unwrap_err();
                assert!(
                    matches!(
                        e,
                        Corruption::Empty
                            | Corruption::Truncated { .. }
                            | Corruption::Checksum { .. }
                    ),
                    "format {format} cut at {len}: {e:?}"
                );
            }
        }
    }

    #[test]
    fn every_altered_byte_and_every_flipped_bit_is_found() {
        for format in FORMATS {
            let sealed = seal(BODY, format).into_bytes();
            for i in 0..sealed.len() {
                for bit in 0..8 {
                    let mut bad = sealed.clone();
                    bad[i] ^= 1 << bit;
                    assert!(
                        open(&bad).is_err(),
                        "format {format}: bit {bit} of byte {i} flipped went unnoticed"
                    );
                }
            }
        }
        let sealed = seal(BODY, 1).into_bytes();
        // An edit by hand that keeps the form: a digit changed.
        let edited = String::from_utf8(sealed).unwrap().replace("-1234", "-1235");
        assert!(matches!(
            open(edited.as_bytes()),
            Err(Corruption::Checksum { .. })
        ));
    }

    #[test]
    fn foreign_files_and_other_versions_are_named() {
        assert_eq!(open(b"[home]\nspeed = 1\n"), Err(Corruption::Foreign));
        // A later format (the checksum is right: another gantry wrote it so).
        let v3 = seal(BODY, 3);
        assert_eq!(
            open(v3.as_bytes()),
            Err(Corruption::Version { found: "3".into() })
        );
        assert!(Corruption::Version { found: "3".into() }
            .to_string()
            .contains("formats 1 and 2"));
        // Format 1 and 2 spelled otherwise are not this gantry's.
        for odd in ["01", "+2", "2 ", "0"] {
            let text = seal(BODY, 1).replacen("format 1", &format!("format {odd}"), 1);
            assert_eq!(
                open(text.as_bytes()),
                Err(Corruption::Version { found: odd.into() }),
                "{odd:?}"
            );
        }
        assert_eq!(
            open(&[0x23, 0xff, 0x0a]),
            Err(Corruption::NotText { offset: 1 })
        );
        // Junk after the checksum line: the last line is no checksum line.
        let extra = seal(BODY, 2) + "x = 1\n";
        assert!(matches!(
            open(extra.as_bytes()),
            Err(Corruption::Truncated { .. })
        ));
    }
}
