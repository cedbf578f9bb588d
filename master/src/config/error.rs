//! Configuration errors: where (file and line) and what (key and reason).

use thiserror::Error;

/// A configuration that cannot be used.
#[derive(Clone, Debug, Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("cannot read {path}")]
    Read {
        /// The file.
        path: String,
        /// Why (shared: the error stays `Clone`).
        #[source]
        source: std::sync::Arc<std::io::Error>,
    },
    /// The file is not valid for gantry: malformed TOML, an unknown key, a wrong type,
    /// a missing key or a value out of range.
    #[error("{path}:{line}: {key}{}{reason}", if key.is_empty() { "" } else { ": " })]
    Invalid {
        /// The file.
        path: String,
        /// 1-based line.
        line: usize,
        /// The key, e.g. `axis[1].max.speed` (empty when TOML itself is malformed).
        key: String,
        /// What is wrong.
        reason: String,
    },
}

/// 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text.get(..offset).unwrap_or("").matches('\n').count() + 1
}

/// The line where `key` (e.g. `axis[0].defaults.speed`) is written, searching from the
/// start of its section (`span`) to the next `[[…]]`: into sub-tables (`[axis.defaults]`
/// or inline `defaults = { … }`), then the key itself; the section start if not found.
fn line_of_key(text: &str, span: std::ops::Range<usize>, key: &str) -> usize {
    let start = span.start.min(text.len());
    let rest = text.get(start..).unwrap_or("");
    // The section ends at the next array-of-tables header after its first line.
    let end = rest
        .match_indices("\n[[")
        .next()
        .map_or(rest.len(), |(i, _)| i + 1);
    let region = rest.get(..end).unwrap_or(rest);
    let mut parts: Vec<&str> = key.split('.').collect();
    if parts.len() > 1 {
        parts.remove(0); // axis[i] / bus / rt: the section itself
    }
    let Some((last, tables)) = parts.split_last() else {
        return line_of(text, start);
    };
    let mut offset = 0;
    let lines: Vec<(usize, &str)> = region
        .split_inclusive('\n')
        .scan(0, |at, l| {
            let here = *at;
            *at += l.len();
            Some((here, l))
        })
        .collect();
    let assigns = |l: &str, k: &str| {
        l.trim_start()
            .strip_prefix(k)
            .is_some_and(|r| r.trim_start().starts_with('='))
    };
    for table in tables {
        match lines.iter().find(|(at, l)| {
            *at >= offset && {
                let t = l.trim();
                (t.starts_with('[') && t.trim_end_matches(']').ends_with(&format!(".{table}")))
                    || assigns(l, table)
            }
        }) {
            // Inline table: the key is on this line.
            Some((at, l)) if assigns(l, table) => return line_of(text, start + at),
            Some((at, _)) => offset = *at,
            None => return line_of(text, start),
        }
    }
    lines
        .iter()
        .find(|(at, l)| *at >= offset && assigns(l, last))
        .map_or(line_of(text, start + offset), |(at, _)| {
            line_of(text, start + at)
        })
}

impl ConfigError {
    /// An error of the TOML layer (syntax, unknown key, type).
    pub(super) fn from_toml(path: &str, text: &str, e: &toml::de::Error) -> Self {
        let span = e.span().unwrap_or(0..0);
        let message = e.message().to_string();
        let unknown = message
            .strip_prefix("unknown field `")
            .and_then(|m| m.split('`').next())
            .map(str::to_string);
        let line = match &unknown {
            Some(key) => line_of_key(text, span.start..text.len(), &format!("section.{key}")),
            None => line_of(text, span.start),
        };
        // Name the key written on that line, when there is one (`key = value`).
        let key = text
            .lines()
            .nth(line - 1)
            .and_then(|l| l.split_once('='))
            .map(|(k, _)| k.trim())
            .filter(|k| !k.is_empty() && !k.starts_with('[') && !k.starts_with('#'))
            .unwrap_or("")
            .to_string();
        Self::Invalid {
            path: path.into(),
            line,
            key,
            reason: message,
        }
    }

    /// A value that parsed but makes no sense.
    pub(super) fn invalid(
        path: &str,
        text: &str,
        span: std::ops::Range<usize>,
        key: String,
        reason: String,
    ) -> Self {
        Self::Invalid {
            path: path.into(),
            line: line_of_key(text, span, &key),
            key,
            reason,
        }
    }
}
