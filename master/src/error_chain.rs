//! An error with its causes, in one line for people: `what failed: why: why deeper`.
//!
//! gantry's error types say what failed in their message and keep what caused it as their
//! [`Error::source`] (not in the message too, or it would be printed twice). So whatever
//! shows an error to a user walks the chain: `main` (anyhow's `{:#}`), the control
//! socket's error replies and the cycle thread's start-up report use [`Chain`].

use std::error::Error;
use std::fmt;

/// Displays an error and each of its sources, joined by `": "`.
pub struct Chain<'a>(pub &'a (dyn Error + 'static));

impl fmt::Display for Chain<'_> {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{}", self.0)?;
        let mut cause = self.0.source();
        while let Some(e) = cause {
            write!(f, ": {e}")?;
            cause = e.source();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("reading the drive table")]
    struct Outer(#[source] std::io::Error);

    #[test]
    fn the_chain_names_every_cause_once() {
        let e = Outer(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "no such file",
        ));
        assert_eq!(
            Chain(&e).to_string(),
            "reading the drive table: no such file"
        );
        let bare = std::io::Error::other("plain");
        assert_eq!(Chain(&bare).to_string(), "plain");
    }
}
