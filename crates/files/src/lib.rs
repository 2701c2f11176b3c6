//! # truepos-files — one door for reading and writing files
//!
//! Every command of truepos, the service's hot reload and the CSV sink read and write files
//! through this crate, so that the rules below hold everywhere at once.
//!
//! **Reading** ([`read`](mod@read)): only a regular file is read — a FIFO, a device, a socket or a
//! directory is refused by name before anything is read from it; the file is opened with
//! `O_NONBLOCK`, so a FIFO put where a model was expected never blocks the reader (the reload
//! thread included); and every kind of file has a size limit ([`Limit`]), checked on the size
//! the file states and again while reading, so `/dev/zero` or a model with a 500 MB comment is
//! refused at once, naming the file, its size and the limit.
//!
//! **Writing** ([`write`](mod@write)): the output is first written to a temporary file created
//! exclusively (`O_EXCL`, a random name in the output's directory, so a planted file or link
//! of that name is never followed), synced, then renamed over the output — a reader sees the
//! old file or the whole new one. An output that is one of the command's inputs (same device
//! and inode), a device, a FIFO, a socket or a directory is refused before anything is
//! written. A symbolic link as the output is refused too, naming the file it points to: writing
//! through a link would let whoever planted it choose which file is replaced, and replacing the
//! link would silently detach whoever relies on it.
//!
//! ```
//! let dir = std::env::temp_dir().join(format!("truepos-files-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let out = dir.join("model.toml");
//! truepos_files::write::write_whole(&out, b"k = 1\n", &[]).unwrap();
//! let text = truepos_files::read::read_text(&out, truepos_files::MODEL).unwrap();
//! assert_eq!(text, "k = 1\n");
//! let e = truepos_files::write::write_whole(&out, b"k = 2\n", &[("--model", &out)]).unwrap_err();
//! assert!(e.to_string().contains("is also this command's input --model"), "{e}");
//! # std::fs::remove_dir_all(&dir).unwrap();
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod input_error;
pub mod read;
pub mod toml_place;
pub mod write;

pub use input_error::InputError;

use std::fmt;
use std::path::{Path, PathBuf};

/// The largest file of one kind truepos reads, in bytes. A file beyond it is refused before it
/// is read, so a wrong path (a device, a log given as a model) cannot exhaust memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limit {
    /// What the file is, in the error message (`model`, `run`).
    pub kind: &'static str,
    /// The limit in bytes.
    pub bytes: u64,
    /// The environment variable that raises it (in MiB), where a user could need more.
    pub env: Option<&'static str>,
}

const MIB: u64 = 1024 * 1024;

/// A machine description (`machine.toml`): a few kB in practice.
pub const MACHINE: Limit = Limit {
    kind: "machine",
    bytes: 4 * MIB,
    env: None,
};
/// A model file (TOML or JSON, either form): tens of kB in practice; 16 MiB leaves room for
/// models with many terms while refusing a file no control could evaluate within a cycle.
pub const MODEL: Limit = Limit {
    kind: "model",
    bytes: 16 * MIB,
    env: None,
};
/// A recorded run, a probe log or any other data table (CSV or workbook): a month of 1 s logs
/// is a few hundred MB; raise it with `TRUEPOS_MAX_RUN_MB`.
pub const RUN: Limit = Limit {
    kind: "run",
    bytes: 2048 * MIB,
    env: Some("TRUEPOS_MAX_RUN_MB"),
};
/// A G-code program to compensate; raise it with `TRUEPOS_MAX_PROGRAM_MB`.
pub const PROGRAM: Limit = Limit {
    kind: "program",
    bytes: 256 * MIB,
    env: Some("TRUEPOS_MAX_PROGRAM_MB"),
};
/// A configuration a person writes: a scenario, a source's or sink's configuration, a
/// kinematics table description.
pub const CONFIG: Limit = Limit {
    kind: "configuration",
    bytes: 4 * MIB,
    env: None,
};
/// The service's SQLite log, read by `status`, `log`, `reidentify` and the live view: SQLite
/// reads it page by page, so its size bounds no memory and is not limited; only its type is
/// checked (a directory or a device is refused by name).
pub const LOG: Limit = Limit {
    kind: "log",
    bytes: u64::MAX,
    env: None,
};
/// A controller's compensation table or a kinematics error table.
pub const TABLE: Limit = Limit {
    kind: "table",
    bytes: 64 * MIB,
    env: None,
};

impl Limit {
    /// The limit in effect: the environment variable's MiB if it is set to a whole number,
    /// else the default. A malformed value is an error, so a typo does not silently keep the
    /// default.
    pub fn effective(&self) -> Result<u64, String> {
        let Some(var) = self.env else {
            return Ok(self.bytes);
        };
        match std::env::var(var) {
            Err(std::env::VarError::NotPresent) => Ok(self.bytes),
            Ok(v) => match v.trim().parse::<u64>() {
                Ok(mb) if mb > 0 => Ok(mb.saturating_mul(MIB)),
                _ => Err(format!(
                    "{var} = {v:?}: expected a whole number of MiB greater than 0"
                )),
            },
            Err(e) => Err(format!("{var}: {e}")),
        }
    }

    /// How a user raises the limit, for the end of a refusal.
    fn how_to_raise(&self) -> String {
        match self.env {
            Some(var) => format!(" (raise it with {var}=MiB)"),
            None => String::new(),
        }
    }
}

/// Why a file could not be read or written; the message names the file.
#[derive(Debug)]
pub struct FileError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong and what was expected.
    pub message: String,
    /// The system's error, where there is one.
    pub source: Option<std::io::Error>,
}

impl FileError {
    fn new(path: &Path, message: impl Into<String>) -> Self {
        Self {
            path: path.to_path_buf(),
            message: message.into(),
            source: None,
        }
    }

    fn io(path: &Path, doing: &str, e: std::io::Error) -> Self {
        Self {
            path: path.to_path_buf(),
            message: format!("{doing}: {e}"),
            source: Some(e),
        }
    }

    /// Whether the file does not exist (callers that treat a missing file apart).
    pub fn is_not_found(&self) -> bool {
        self.source
            .as_ref()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::NotFound)
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for FileError {}

/// What a file that is not a regular file is, for messages.
pub(crate) fn describe(ft: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_dir() {
        "a directory"
    } else if ft.is_symlink() {
        "a symbolic link"
    } else if ft.is_fifo() {
        "a FIFO (named pipe)"
    } else if ft.is_char_device() {
        "a character device"
    } else if ft.is_block_device() {
        "a block device"
    } else if ft.is_socket() {
        "a socket"
    } else if ft.is_file() {
        "a regular file"
    } else {
        "not a regular file"
    }
}

/// A fresh directory of this test process for one test.
#[cfg(test)]
pub(crate) fn test_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("truepos-files-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// 1-based line and column (in characters) of a byte offset in a file's text — where every
/// parser of the project names a mistake (`file:line:column`). An offset inside a character
/// counts as that character; one past the end as the end.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let mut start = offset;
    while !text.is_char_boundary(start) {
        start -= 1;
    }
    let before = &text[..start];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}
