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

    /// An error about `key` found before its file is known (a check of a configuration that
    /// was read already): [`InputError::in_file`] places it once the caller knows the file.
    pub fn at_key(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            file: PathBuf::new(),
            position: None,
            key: Some(key.into()).filter(|k: &String| !k.is_empty()),
            message: message.into(),
        }
    }

    /// The error placed in the file it came from: its name, and the line and column of the key
    /// in the file's text ([`crate::toml_place`]; the key without its leading `section.`, the
    /// table the whole file is, such as `modbus`). A key the file does not hold is named at the
    /// deepest table that does; a file that cannot be read again leaves the place unknown. An
    /// error that names its file already is kept as it is.
    pub fn in_file(self, path: &Path, section: &str) -> Self {
        if !self.file.as_os_str().is_empty() {
            return self;
        }
        let text = crate::read::read_text(path, crate::CONFIG).unwrap_or_default();
        let key = self.key.as_deref().unwrap_or_default();
        let in_text = key
            .strip_prefix(section)
            .and_then(|k| k.strip_prefix('.'))
            .unwrap_or(key);
        let position = crate::toml_place::place(&text, &crate::toml_place::steps(in_text));
        Self {
            file: path.to_path_buf(),
            position,
            ..self
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
    /// `FILE:LINE:COLUMN: `KEY`: MESSAGE`, each part only when known; an error not yet placed
    /// in a file ([`InputError::at_key`]) is `` `KEY`: MESSAGE ``.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut separator = "";
        if !self.file.as_os_str().is_empty() {
            write!(f, "{}", self.file.display())?;
            if let Some((line, column)) = self.position {
                write!(f, ":{line}:{column}")?;
            }
            separator = ": ";
        }
        if let Some(key) = &self.key {
            write!(f, "{separator}`{key}`")?;
            separator = ": ";
        }
        write!(f, "{separator}{}", self.message)
    }
}

impl std::error::Error for InputError {}

impl From<FileError> for InputError {
    fn from(e: FileError) -> Self {
        InputError::file(&e.path, e.message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_error_about_a_key_is_placed_in_its_file() {
        let e = InputError::at_key("modbus.channel[2].register", "expected a register");
        assert_eq!(
            e.to_string(),
            "`modbus.channel[2].register`: expected a register"
        );
        let dir = std::env::temp_dir().join(format!("truepos-input-error-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("modbus.toml");
        let text = "address = \"plc:502\"\n[[channel]]\nregister = 1\n[[channel]]\nregister = -4\n";
        std::fs::write(&f, text).unwrap();
        let placed = e.in_file(&f, "modbus");
        assert_eq!(placed.position, Some((5, 1)));
        assert_eq!(
            placed.to_string(),
            format!(
                "{}:5:1: `modbus.channel[2].register`: expected a register",
                f.display()
            )
        );
        // Placed once: a second placement keeps the first.
        assert_eq!(placed.clone().in_file(Path::new("/elsewhere"), "x"), placed);
        // A file that cannot be read names the file without a place.
        let lost =
            InputError::at_key("shdr.ping_ms", "expected 1 ms").in_file(&dir.join("no"), "shdr");
        assert_eq!(lost.position, None);
        assert!(
            lost.to_string()
                .ends_with("no: `shdr.ping_ms`: expected 1 ms"),
            "{lost}"
        );
        assert_eq!(InputError::at_key("", "no key").to_string(), "no key");
        std::fs::remove_dir_all(&dir).ok();
    }
}
