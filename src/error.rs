//! Errors that name where the problem is: file, prim path, attribute.
//!
//! Pipeline TDs read these in farm logs, so every error raised while reading a
//! stage carries the prim path and, where one is involved, the attribute name.
//! The file is attached once, at the top, by [`Error::in_file`].

use std::fmt;
use std::path::{Path, PathBuf};

use crate::rule::Rule;

/// A painterly error: what went wrong and where.
#[derive(Debug, Clone, PartialEq)]
pub struct Error {
    /// The USD file (or output path) involved, when known.
    pub file: Option<PathBuf>,
    /// The prim path, when the problem is on a prim.
    pub prim: Option<String>,
    /// The attribute or relationship name, when one is involved.
    pub attribute: Option<String>,
    /// What is wrong, in words a TD can act on.
    pub message: String,
    /// A command-line usage error (exit 2), e.g. an output path with the
    /// wrong extension, found after argument parsing.
    pub usage: bool,
    /// The schema rule this breaks, for problems `inspect` reports.
    pub rule: Option<Rule>,
}

/// Result alias used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An error with a message only.
    pub fn msg(message: impl Into<String>) -> Self {
        Error {
            file: None,
            prim: None,
            attribute: None,
            message: message.into(),
            usage: false,
            rule: None,
        }
    }

    /// A usage error: the command line asks for something impossible (exit 2).
    pub fn usage(message: impl Into<String>) -> Self {
        Error {
            usage: true,
            ..Error::msg(message)
        }
    }

    /// The process exit code for this error: 2 for usage, else 1.
    pub fn exit_code(&self) -> i32 {
        if self.usage {
            2
        } else {
            1
        }
    }

    /// An error about a prim.
    pub fn prim(prim: impl fmt::Display, message: impl Into<String>) -> Self {
        Error {
            prim: Some(prim.to_string()),
            ..Error::msg(message)
        }
    }

    /// An error about one attribute (or relationship) of a prim.
    pub fn attr(prim: impl fmt::Display, attribute: &str, message: impl Into<String>) -> Self {
        Error {
            prim: Some(prim.to_string()),
            attribute: Some(attribute.to_string()),
            ..Error::msg(message)
        }
    }

    /// Names the rule this error breaks (see [`Rule`]).
    pub fn rule(mut self, rule: Rule) -> Self {
        self.rule = Some(rule);
        self
    }

    /// Names the rule unless a more specific one is already set: for the
    /// places that collect errors from code that does not know the rule.
    pub fn or_rule(mut self, rule: Rule) -> Self {
        self.rule.get_or_insert(rule);
        self
    }

    /// Attaches the file this error concerns, unless one is already set.
    pub fn in_file(mut self, file: &Path) -> Self {
        if self.file.is_none() {
            self.file = Some(file.to_path_buf());
        }
        self
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{}: ", file.display())?;
        }
        match (&self.prim, &self.attribute) {
            (Some(p), Some(a)) => write!(f, "{p}.{a}: ")?,
            (Some(p), None) => write!(f, "{p}: ")?,
            (None, Some(a)) => write!(f, "{a}: ")?,
            (None, None) => {}
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

/// `x` as a message should show it: in exponent notation when very small or
/// large (Rust's `{}` writes 1e-300 with 300 digits), else as `{}` does.
pub fn readable(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-4..1e15).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_names_file_prim_and_attribute() {
        let e = Error::attr("/Fish/Paint/Spikes", "painterly:restPoints", "3 points, expected 4")
            .in_file(Path::new("fish.usda"));
        assert_eq!(
            e.to_string(),
            "fish.usda: /Fish/Paint/Spikes.painterly:restPoints: 3 points, expected 4"
        );
    }
}
