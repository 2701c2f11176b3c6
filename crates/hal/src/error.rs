//! Why the component could not start, or did not stop cleanly: what `truepos-hal` prints after
//! `truepos-hal: error:` before it exits non-zero.

use truepos_files::InputError;
use truepos_runtime::log::LogError;

use crate::ffi::HalError;

/// An error of `truepos-hal run`; each says what its source says.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The machine description or a model file was refused.
    #[error(transparent)]
    Input(#[from] InputError),
    /// HAL refused the component or one of its pins.
    #[error(transparent)]
    Hal(#[from] HalError),
    /// The log could not be opened, or failed and did not recover before the stop.
    #[error(transparent)]
    Log(#[from] LogError),
    /// The handler of SIGTERM or SIGINT could not be installed.
    #[error(transparent)]
    Signal(std::io::Error),
    /// The cycle-timing figures (`--stats`) could not be written.
    #[error(transparent)]
    Stats(std::io::Error),
    /// A model implausible for the machine or whose evaluation does not fit the cycle
    /// (`truepos_runtime::admission`).
    #[error("{0}")]
    Refused(String),
}

impl From<truepos_runtime::StartError> for Error {
    fn from(e: truepos_runtime::StartError) -> Self {
        match e {
            truepos_runtime::StartError::Refused(why) => Self::Refused(why),
            truepos_runtime::StartError::Log(e) => Self::Log(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The messages a user sees after `truepos-hal: error:`, word for word.
    #[test]
    fn messages_name_the_cause() {
        let hal = |e: HalError| Error::from(e).to_string();
        assert_eq!(
            hal(HalError::Library("not found".into())),
            "cannot load LinuxCNC's HAL library (install linuxcnc-uspace): not found"
        );
        assert_eq!(
            hal(HalError::Call {
                function: "hal_init",
                name: "truepos".into(),
                code: -22
            }),
            "hal_init(\"truepos\") failed with code -22 (is LinuxCNC or halrun running, and is \
             the name free?)"
        );
        assert_eq!(
            hal(HalError::Call {
                function: "hal_pin_float_new",
                name: "truepos.axis.x.pos".into(),
                code: -12
            }),
            "hal_pin_float_new(\"truepos.axis.x.pos\") failed with code -12"
        );
        assert_eq!(
            hal(HalError::OutOfMemory),
            "hal_malloc: HAL shared memory is exhausted"
        );
        assert_eq!(
            hal(HalError::BadName("a\0b".into())),
            "HAL name \"a\\0b\" must be at most 47 bytes long and contain no NUL"
        );
        let io = || std::io::Error::new(std::io::ErrorKind::PermissionDenied, "denied");
        assert_eq!(Error::Stats(io()).to_string(), "denied");
        assert_eq!(Error::Signal(io()).to_string(), "denied");
    }
}
