//! The one error type of every file the project reads: it names the file, the line and column,
//! the key and what was expected, so that a person can fix the file without reading code.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::{line_column, FileError};

/// Bad input: a file that cannot be read or does not say what it must.
#[derive(Debug, Clone, PartialEq)]
pub struct InputError {
    /// The file.
    pub file: PathBuf,
    /// 1-based line and column, where the problem has a place in the file.
    pub position: Option<(usize, usize)>,
    /// The key (`axis[1].travel`) or column the problem is about, if any.
    pub key: Option<String>,
    /// What is wrong and what was expected.
    pub message: String,
}

impl InputError {
    /// An error about the file as a whole (cannot be read, empty, …).
    pub fn file(file: &Path, message: impl Into<String>) -> Self {
        Self {
            file: file.to_path_buf(),
            position: None,
            key: None,
            message: message.into(),
        }
    }

    /// An error at a byte span of the file's text.
    pub fn at_span(
        file: &Path,
        text: &str,
        span: Range<usize>,
        key: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            file: file.to_path_buf(),
            position: Some(line_column(text, span.start)),
            key: Some(key.into()).filter(|k: &String| !k.is_empty()),
            message: message.into(),
        }
    }

    /// An error at a known line and column.
    pub fn at(
        file: &Path,
        line: usize,
        column: usize,
        key: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            file: file.to_path_buf(),
            position: Some((line, column)),
            key: Some(key.into()).filter(|k: &String| !k.is_empty()),
            message: message.into(),
        }
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some((line, column)) = self.position {
            write!(f, ":{line}:{column}")?;
        }
        if let Some(key) = &self.key {
            write!(f, ": `{key}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for InputError {}

impl From<FileError> for InputError {
    fn from(e: FileError) -> Self {
        InputError::file(&e.path, e.message)
    }
}
