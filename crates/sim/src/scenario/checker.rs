//! Errors that name their place in a TOML text: file, line, column, key path and what was
//! expected. Scenarios and twin descriptions (`crate::params`) check their values with it.

use std::path::PathBuf;

use truepos_files::InputError;

/// A TOML syntax or type error as an [`InputError`].
pub(crate) fn toml_error(src: &str, file: &str, e: &toml::de::Error) -> InputError {
    InputError {
        file: PathBuf::from(file),
        position: e.span().map(|s| truepos_files::line_column(src, s.start)),
        key: e
            .span()
            .map(|s| truepos_files::toml_place::key_on_line(src, s.start))
            .filter(|k| !k.is_empty()),
        message: e.message().trim().to_string(),
    }
}

/// One step of a key path (indices from 0).
pub(crate) use truepos_files::toml_place::Step as Seg;

pub(crate) struct Checker<'a> {
    src: &'a str,
    file: &'a str,
}

impl<'a> Checker<'a> {
    /// A checker for the TOML text `src` of `file`.
    pub(crate) fn new(src: &'a str, file: &'a str) -> Self {
        Self { src, file }
    }

    pub(crate) fn err(&self, path: &[Seg], expected: impl Into<String>) -> InputError {
        let mut key = String::new();
        for seg in path {
            match seg {
                Seg::Key(k) => {
                    if !key.is_empty() {
                        key.push('.');
                    }
                    key.push_str(k);
                }
                Seg::Index(i) => key.push_str(&format!("[{i}]")),
            }
        }
        InputError {
            file: PathBuf::from(self.file),
            position: truepos_files::toml_place::place(self.src, path),
            key: Some(key).filter(|k| !k.is_empty()),
            message: format!("expected {}", expected.into()),
        }
    }

    pub(super) fn positive(&self, path: &[Seg], v: f64) -> Result<f64, InputError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.err(path, format!("a positive number, got {v}")))
        }
    }

    pub(super) fn non_negative(&self, path: &[Seg], v: f64) -> Result<f64, InputError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.err(path, format!("a number ≥ 0, got {v}")))
        }
    }

    pub(crate) fn within(
        &self,
        path: &[Seg],
        v: f64,
        lo: f64,
        hi: f64,
        what: &str,
    ) -> Result<f64, InputError> {
        if v.is_finite() && v >= lo && v <= hi {
            Ok(v)
        } else {
            Err(self.err(path, format!("{what} between {lo} and {hi}, got {v}")))
        }
    }
}
