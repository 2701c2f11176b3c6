//! The binary's one error type: the libraries' errors kept typed (each already names its file,
//! line, column, key and expectation), a file the command itself could not read or write, and
//! a refusal the command makes on its own (a bad combination of options, a failed check).
//! `main` prints every one as `error: {e}`.

use std::path::{Path, PathBuf};

/// Why a subcommand failed.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// An input file (machine, model, run table, kinematics table, a source's or sink's
    /// configuration …) is not what it must be.
    #[error(transparent)]
    Input(#[from] truepos_files::InputError),
    /// The service's log could not be opened or read.
    #[error(transparent)]
    Log(#[from] truepos_runtime::log::LogError),
    /// The CSV sink could not be opened.
    #[error(transparent)]
    CsvSink(#[from] truepos_runtime::replay::CsvSinkError),
    /// The run tables do not make a data set.
    #[error(transparent)]
    Dataset(#[from] truepos_fit::dataset::DatasetError),
    /// A fitted model cannot be written in the model file format.
    #[error(transparent)]
    Export(#[from] truepos_fit::export::ExportError),
    /// The twin refused to run a scenario.
    #[error(transparent)]
    Sim(#[from] truepos_sim::SimError),
    /// The HTML report could not be written.
    #[error(transparent)]
    Report(#[from] truepos_report::ReportError),
    /// A CSV the command writes itself.
    #[error(transparent)]
    Csv(#[from] csv::Error),
    /// JSON the command prints itself.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A file the command reads or writes itself: `PATH: cannot read: …` (or without the verb
    /// where the path alone says enough).
    #[error("{}: {}{source}", path.display(), doing.map(|d| format!("{d}: ")).unwrap_or_default())]
    File {
        path: PathBuf,
        doing: Option<&'static str>,
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A file refused or failed by the one door for reading and writing files; the message
    /// names the file and the rule.
    #[error(transparent)]
    Files(#[from] truepos_files::FileError),
    /// Standard output went away or failed for another reason than a closed pipe.
    #[error("cannot write to standard output: {0}")]
    Stdout(#[source] std::io::Error),
    /// A library's error (or a checker's sentence) with what the command was doing when it
    /// came: `--reference …`, `FILE:LINE: …`, `writing CSV: …`.
    #[error("{prefix}{source}")]
    Context {
        prefix: String,
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A model could not be evaluated on a row of the run; the sentence names the channels.
    #[error("{0}")]
    Model(String),
    /// The command's own refusal, in its own sentence.
    #[error("{0}")]
    Refused(String),
}

impl CliError {
    /// A refusal in the command's own words.
    pub fn refused(message: impl Into<String>) -> Self {
        CliError::Refused(message.into())
    }

    /// `PREFIX…`: `source` after what the command was doing, as the `map_err` of the call.
    pub fn context<E: Into<Box<dyn std::error::Error + Send + Sync>>>(
        prefix: impl Into<String>,
    ) -> impl FnOnce(E) -> Self {
        let prefix = prefix.into();
        move |source| CliError::Context {
            prefix,
            source: source.into(),
        }
    }

    /// `PATH: DOING: …` (`PATH: …` without `doing`), as the `map_err` of an I/O or CSV call on
    /// `path`.
    pub fn file<'a, E: Into<Box<dyn std::error::Error + Send + Sync>>>(
        path: &'a Path,
        doing: Option<&'static str>,
    ) -> impl FnOnce(E) -> Self + 'a {
        move |source| CliError::File {
            path: path.to_path_buf(),
            doing,
            source: source.into(),
        }
    }
}

impl From<truepos_runtime::StartError> for CliError {
    fn from(e: truepos_runtime::StartError) -> Self {
        match e {
            truepos_runtime::StartError::Refused(why) => Self::Refused(why),
            truepos_runtime::StartError::Log(e) => Self::Log(e),
        }
    }
}
