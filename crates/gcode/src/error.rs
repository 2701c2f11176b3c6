//! The crate's one error type: every refusal names the program file and, where there is one,
//! the source line (and column, for what the pre-scan finds), the canonical command rs274
//! printed, and the reason.

use std::fmt;
use std::path::PathBuf;

/// Where in the program a refusal comes from.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Place {
    /// The program file as the user named it.
    pub file: PathBuf,
    /// 1-based source line, when known.
    pub line: Option<u64>,
    /// 1-based character column, when known (pre-scan).
    pub column: Option<usize>,
    /// rs274's counter of the canonical command being handled, when there is one.
    pub canon: Option<u64>,
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
            if let Some(c) = self.column {
                write!(f, ":{c}")?;
            }
        }
        Ok(())
    }
}

/// Why a program was not compensated.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// `rs274` could not be started.
    #[error("cannot run `{program}`: {source}; LinuxCNC's standalone interpreter comes with the Debian package linuxcnc-uspace (install it with scripts/install_linuxcnc.sh, or name it with --rs274)")]
    Rs274Missing {
        program: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file truepos reads or writes itself.
    #[error("{}: {doing}: {source}", path.display())]
    File {
        path: PathBuf,
        doing: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// The program or the output refused by the one door for files (a FIFO, a device, a
    /// link, the input as output, a program beyond its size limit).
    #[error(transparent)]
    Files(#[from] truepos_files::FileError),
    /// The program, or what rs274 made of it, cannot be compensated.
    #[error("{place}: {reason}{}", canon_suffix(.place))]
    Refused { place: Place, reason: String },
    /// rs274 refused the program (its exit status was not 0).
    #[error("{place}: LinuxCNC's interpreter refused the program: {message}{}", text.as_ref().map(|t| format!(" (at `{t}`)")).unwrap_or_default())]
    Interpreter {
        place: Place,
        message: String,
        text: Option<String>,
    },
    /// rs274 ran longer than allowed and was stopped.
    #[error("{}: rs274 did not finish within {seconds} s and was stopped (raise --time-limit for a longer program)", file.display())]
    TimedOut { file: PathBuf, seconds: f64 },
}

fn canon_suffix(place: &Place) -> String {
    place
        .canon
        .map(|c| format!(" (canonical command {c})"))
        .unwrap_or_default()
}

impl Error {
    /// The source line the error names, if any.
    pub fn line(&self) -> Option<u64> {
        match self {
            Error::Refused { place, .. } | Error::Interpreter { place, .. } => place.line,
            _ => None,
        }
    }

    pub(crate) fn file(
        path: impl Into<PathBuf>,
        doing: &'static str,
    ) -> impl FnOnce(std::io::Error) -> Error {
        let path = path.into();
        move |source| Error::File {
            path,
            doing,
            source,
        }
    }
}
