//! The errors of `truepos-hal-check`: what it prints after `truepos-hal-check: error:` before
//! it exits non-zero (a judged run that fails is a verdict, not an error).

use truepos_files::InputError;
use truepos_runtime::log::LogError;

use crate::check::SampleError;

/// An error of the judge or the benchmark; each says what its source says.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The machine description, a model file or the replayed run was refused.
    #[error(transparent)]
    Input(#[from] InputError),
    /// A sampler file could not be read or is malformed.
    #[error(transparent)]
    Samples(#[from] SampleError),
    /// The component's log could not be read, or the benchmark's log failed.
    #[error(transparent)]
    Log(#[from] LogError),
    /// The benchmark's service did not start (a model refused, or its log).
    #[error(transparent)]
    Start(#[from] truepos_runtime::StartError),
    /// `--expect-event` names events of a log that was not given.
    #[error("--expect-event needs --log")]
    ExpectEventWithoutLog,
    /// The benchmark's period is out of range, ms.
    #[error("period {0} ms must lie in (0, 1000]")]
    Period(f64),
    /// The benchmark's duration is not positive, s.
    #[error("duration {0} s must be > 0")]
    Duration(f64),
    /// The handler of SIGTERM or SIGINT could not be installed.
    #[error(transparent)]
    Signal(std::io::Error),
    /// The figures could not be written as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The messages of the errors of its own, word for word.
    #[test]
    fn messages_name_the_cause() {
        assert_eq!(
            Error::ExpectEventWithoutLog.to_string(),
            "--expect-event needs --log"
        );
        assert_eq!(
            Error::Period(0.0).to_string(),
            "period 0 ms must lie in (0, 1000]"
        );
        assert_eq!(
            Error::Duration(-1.0).to_string(),
            "duration -1 s must be > 0"
        );
        let bad = SampleError {
            file: "m.txt".into(),
            line: 3,
            message: "cannot read".into(),
        };
        assert_eq!(Error::from(bad).to_string(), "m.txt:3: cannot read");
    }
}
